// EverettTable: validation, interpolation, derivatives, antidiagonal integrals and the
// construction helpers (FOD data, relay masses).
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_everett {

using namespace ptest;
using preisach::cell_weights;
using preisach::everett_from_fod;
using preisach::everett_from_weights;

namespace {

const double NaN = std::numeric_limits<double>::quiet_NaN();
const double Inf = std::numeric_limits<double>::infinity();

Eigen::VectorXd vec(std::initializer_list<double> v) {
    Eigen::VectorXd r(Eigen::Index(v.size()), 1);
    Eigen::Index k = 0;
    for (double x : v) r[k++] = x;
    return r;
}

RowMatrixXd lower(Eigen::Index n, double value) {
    RowMatrixXd m = RowMatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j) m(i, j) = value * double(i - j);
    return m;
}

// Both kinds of table: a uniform grid (the fast locate path) and a non-uniform one.
std::vector<EverettTable> both_tables() {
    return {analytic_table(uniform_levels(13)), analytic_table(nonuniform_levels(11))};
}

// Distance of x to the nearest grid level.
double dist_to_grid(const EverettTable& t, double x) {
    double d = HUGE_VAL;
    for (double l : t.levels()) d = std::min(d, std::abs(x - l));
    return d;
}

}  // namespace

TEST_CASE("everett: construction validation") {
    const RowMatrixXd v3 = lower(3, 0.5);
    SUBCASE("accepts a valid table") { CHECK_NOTHROW(EverettTable(vec({0.0, 1.0, 2.0}), v3, 0.0)); }
    SUBCASE("non-increasing levels") {
        CHECK_THROWS_WITH_AS(EverettTable(vec({0.0, 1.0, 1.0}), v3, 0.0), doctest::Contains("strictly increasing"),
                             std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({0.0, 2.0, 1.0}), v3, 0.0), std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({2.0, 1.0, 0.0}), v3, 0.0), std::invalid_argument);
    }
    SUBCASE("too few levels") {
        CHECK_THROWS_AS(EverettTable(vec({0.0}), RowMatrixXd::Zero(1, 1), 0.0), std::invalid_argument);
    }
    SUBCASE("wrong shape") {
        CHECK_THROWS_WITH_AS(EverettTable(vec({0.0, 1.0, 2.0}), RowMatrixXd::Zero(3, 4), 0.0),
                             doctest::Contains("shape (3, 4)"), std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({0.0, 1.0, 2.0}), RowMatrixXd::Zero(2, 2), 0.0), std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({0.0, 1.0, 2.0}), RowMatrixXd::Zero(4, 3), 0.0), std::invalid_argument);
    }
    SUBCASE("NaN and inf") {
        CHECK_THROWS_WITH_AS(EverettTable(vec({0.0, NaN, 2.0}), v3, 0.0), doctest::Contains("levels[1]"),
                             std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({0.0, 1.0, Inf}), v3, 0.0), std::invalid_argument);
        RowMatrixXd bad = v3;
        bad(2, 1) = NaN;
        CHECK_THROWS_WITH_AS(EverettTable(vec({0.0, 1.0, 2.0}), bad, 0.0), doctest::Contains("(2, 1)"),
                             std::invalid_argument);
        bad(2, 1) = -Inf;
        CHECK_THROWS_AS(EverettTable(vec({0.0, 1.0, 2.0}), bad, 0.0), std::invalid_argument);
        CHECK_THROWS_AS(EverettTable(vec({0.0, 1.0, 2.0}), v3, NaN), std::invalid_argument);
    }
    SUBCASE("entries on and above the diagonal are ignored") {
        RowMatrixXd up = v3;
        up(0, 0) = NaN;
        up(0, 2) = NaN;
        up(1, 1) = 7.0;
        const EverettTable t(vec({0.0, 1.0, 2.0}), up, 0.0), ref(vec({0.0, 1.0, 2.0}), v3, 0.0);
        for (std::size_t i = 0; i < 3; ++i) {
            CHECK(t.node(i, i) == 0.0);
            for (std::size_t j = 0; j < 3; ++j) CHECK(t.node(i, j) == ref.node(i, j));
        }
        CHECK(t(1.0, 1.0) == 0.0);
        CHECK(t(1.5, 1.2) == ref(1.5, 1.2));
        CHECK(t(2.0, 1.0) == doctest::Approx(0.5));
    }
}

TEST_CASE("everett: accessors and y_max") {
    const Eigen::VectorXd l = nonuniform_levels(9);
    const EverettTable t = analytic_table(l, 0.25);
    CHECK(t.size() == 9);
    CHECK(t.u_min() == U_MIN);
    CHECK(t.u_max() == U_MAX);
    CHECK(t.y_min() == 0.25);
    CHECK_FALSE(t.uniform());
    CHECK(analytic_table(uniform_levels(9)).uniform());
    CHECK(t.y_max() == doctest::Approx(0.25 + 2.0 * E_exact(U_MAX, U_MIN)).epsilon(1e-14));
}

TEST_CASE("everett: interpolation is exact at the nodes") {
    for (const EverettTable& t : both_tables()) {
        const auto& l = t.levels();
        for (std::size_t i = 0; i < l.size(); ++i)
            for (std::size_t j = 0; j < i; ++j) {
                INFO("node (" << i << ", " << j << ")");
                CHECK(t(l[i], l[j]) == doctest::Approx(E_exact(l[i], l[j])).epsilon(1e-14));
                CHECK(t.node(i, j) == E_exact(l[i], l[j]));
            }
    }
}

TEST_CASE("everett: E(u, u) = 0 and E vanishes continuously at the diagonal") {
    std::mt19937 g(11);
    for (const EverettTable& t : both_tables()) {
        std::vector<double> us(t.levels());
        for (int k = 0; k < 200; ++k) us.push_back(uniform(g, U_MIN, U_MAX));
        for (double u : us) {
            INFO("u = " << u);
            CHECK(t(u, u) == 0.0);
            // From located positions (no alpha <= beta short cut): zero up to rounding.
            CHECK(std::abs(t.value(t.locate(u, true), t.locate(u, true))) <= 1e-15);
            CHECK(std::abs(t.value(t.locate(u, false), t.locate(u, false))) <= 1e-15);
            // Approaching the diagonal: |E(u + eps, u)| <= (max slope) * eps.
            for (double eps : {1e-3, 1e-6, 1e-9}) {
                if (u + eps > U_MAX) continue;
                CHECK(std::abs(t(u + eps, u)) <= 20.0 * eps);
            }
        }
    }
}

TEST_CASE("everett: continuous across cell boundaries") {
    std::mt19937 g(12);
    const double eps = 1e-9;
    for (const EverettTable& t : both_tables()) {
        const auto& l = t.levels();
        for (std::size_t k = 1; k + 1 < l.size(); ++k) {
            const double x = l[k];
            for (int r = 0; r < 20; ++r) {
                // Crossing alpha = x at a beta below it (including beta in the cell just below x).
                const double beta = uniform(g, U_MIN, x - 2.0 * eps);
                INFO("grid line " << x << ", beta = " << beta);
                const double left = t(x - eps, beta), right = t(x + eps, beta), at = t(x, beta);
                CHECK(std::abs(right - left) < 1e-6);
                CHECK(std::abs(at - left) < 1e-6);
                // Crossing beta = x at an alpha above it.
                const double alpha = uniform(g, x + 2.0 * eps, U_MAX);
                INFO("alpha = " << alpha);
                const double lo = t(alpha, x - eps), hi = t(alpha, x + eps), on = t(alpha, x);
                CHECK(std::abs(hi - lo) < 1e-6);
                CHECK(std::abs(on - lo) < 1e-6);
            }
            // Crossing both at once near the node on the diagonal's neighbour cells.
            if (k >= 2) {
                const double b = l[k - 1];
                CHECK(std::abs(t(x + eps, b + eps) - t(x - eps, b - eps)) < 1e-6);
                CHECK(std::abs(t(x + eps, b - eps) - t(x - eps, b + eps)) < 1e-6);
            }
        }
        // A coarse check that the interpolant really approximates E_exact between nodes.
        for (int r = 0; r < 200; ++r) {
            const double a = uniform(g, U_MIN, U_MAX), b = uniform(g, U_MIN, a);
            CHECK(std::abs(t(a, b) - E_exact(a, b)) < 0.3);  // E spans ~15; bilinear error ~h^2 E''/8
        }
    }
}

TEST_CASE("everett: from_weights and cell_weights are inverses") {
    std::mt19937 g(13);
    for (const Eigen::VectorXd& l : {uniform_levels(8), nonuniform_levels(10)}) {
        const Eigen::Index m = l.size() - 1;
        RowMatrixXd w = RowMatrixXd::Zero(m, m);
        for (Eigen::Index i = 0; i < m; ++i)
            for (Eigen::Index j = 0; j <= i; ++j) w(i, j) = uniform(g, 0.0, 1.0);
        const EverettTable t = everett_from_weights(l, w, 0.7);
        CHECK(t.y_min() == 0.7);
        const RowMatrixXd back = cell_weights(t);
        REQUIRE(back.rows() == m);
        REQUIRE(back.cols() == m);
        for (Eigen::Index i = 0; i < m; ++i)
            for (Eigen::Index j = 0; j < m; ++j) {
                INFO("cell (" << i << ", " << j << ")");
                CHECK(back(i, j) == doctest::Approx(j <= i ? w(i, j) : 0.0).epsilon(1e-12));
            }
        // E(l_a, l_b) = total mass of the cells inside the triangle b <= beta <= alpha <= a.
        for (Eigen::Index a = 0; a <= m; ++a)
            for (Eigen::Index b = 0; b <= a; ++b) {
                double mass = 0.0;
                for (Eigen::Index i = b; i < a; ++i)
                    for (Eigen::Index j = b; j <= i; ++j) mass += w(i, j);
                CHECK(t.node(std::size_t(a), std::size_t(b)) == doctest::Approx(mass).epsilon(1e-12));
            }
        // And the other way round: table -> masses -> table.
        const EverettTable e = analytic_table(l);
        const EverettTable e2 = everett_from_weights(l, cell_weights(e), e.y_min());
        for (std::size_t i = 0; i < e.size(); ++i)
            for (std::size_t j = 0; j < i; ++j) CHECK(e2.node(i, j) == doctest::Approx(e.node(i, j)).epsilon(1e-12));
        // Cell masses of a positive density are positive.
        const RowMatrixXd we = cell_weights(e);
        for (Eigen::Index i = 0; i < m; ++i)
            for (Eigen::Index j = 0; j <= i; ++j) CHECK(we(i, j) > 0.0);
    }
    SUBCASE("validation") {
        const Eigen::VectorXd l = uniform_levels(4);
        CHECK_THROWS_AS(everett_from_weights(l, RowMatrixXd::Zero(4, 4), 0.0), std::invalid_argument);
        RowMatrixXd w = RowMatrixXd::Zero(3, 3);
        w(2, 1) = NaN;
        CHECK_THROWS_WITH_AS(everett_from_weights(l, w, 0.0), doctest::Contains("weights[2, 1]"),
                             std::invalid_argument);
    }
}

TEST_CASE("everett: from_fod") {
    std::mt19937 g(14);
    const Eigen::VectorXd l = nonuniform_levels(7);
    const Eigen::Index n = l.size();
    RowMatrixXd y = RowMatrixXd::Constant(n, n, NaN);  // above the diagonal: unused
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j <= i; ++j) y(i, j) = uniform(g, -5.0, 5.0);
    const EverettTable t = everett_from_fod(l, y);
    double mean0 = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) mean0 += y(i, 0);
    mean0 /= double(n);
    CHECK(t.y_min() == doctest::Approx(mean0).epsilon(1e-14));
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j) {
            INFO("node (" << i << ", " << j << ")");
            CHECK(t.node(std::size_t(i), std::size_t(j)) == doctest::Approx(0.5 * (y(i, i) - y(i, j))).epsilon(1e-14));
            CHECK(t(l[i], l[j]) == doctest::Approx(0.5 * (y(i, i) - y(i, j))).epsilon(1e-14));
        }
    SUBCASE("validation") {
        CHECK_THROWS_AS(everett_from_fod(l, RowMatrixXd::Zero(n, n - 1)), std::invalid_argument);
        RowMatrixXd bad = y;
        bad(4, 2) = NaN;
        CHECK_THROWS_WITH_AS(everett_from_fod(l, bad), doctest::Contains("y_grid[4, 2]"), std::invalid_argument);
        bad = y;
        bad(3, 3) = Inf;
        CHECK_THROWS_WITH_AS(everett_from_fod(l, bad), doctest::Contains("y_grid[3, 3]"), std::invalid_argument);
    }
}

TEST_CASE("everett: d_alpha and d_beta match central differences inside cells") {
    std::mt19937 g(15);
    const double h = 1e-6;
    for (const EverettTable& t : both_tables()) {
        int checked_square = 0, checked_diag = 0;
        for (int r = 0; r < 4000 && (checked_square < 300 || checked_diag < 100); ++r) {
            const double a = uniform(g, U_MIN, U_MAX), b = uniform(g, U_MIN, a);
            if (dist_to_grid(t, a) < 1e-4 || dist_to_grid(t, b) < 1e-4 || a - b < 1e-4) continue;
            const bool same_cell = t.locate(a).i == t.locate(b).i;
            if (same_cell) ++checked_diag; else ++checked_square;
            const double fa = (t(a + h, b) - t(a - h, b)) / (2.0 * h);
            const double fb = (t(a, b + h) - t(a, b - h)) / (2.0 * h);
            INFO("alpha = " << a << ", beta = " << b << (same_cell ? " (diagonal half-cell)" : ""));
            CHECK(t.d_alpha(a, b) == doctest::Approx(fa).epsilon(1e-6).scale(1.0));
            CHECK(t.d_beta(a, b) == doctest::Approx(fb).epsilon(1e-6).scale(1.0));
        }
        CHECK(checked_square >= 300);
        CHECK(checked_diag >= 100);
    }
    SUBCASE("one-sided at grid lines: d_alpha from above, d_beta from below") {
        const EverettTable t = analytic_table(nonuniform_levels(11));
        const auto& l = t.levels();
        for (std::size_t k = 2; k + 1 < l.size(); ++k) {
            const double b = 0.5 * (l[0] + l[1]);
            const double up = (t(l[k] + h, b) - t(l[k], b)) / h;
            CHECK(t.d_alpha(l[k], b) == doctest::Approx(up).epsilon(1e-5));
            const double a = 0.5 * (l[l.size() - 1] + l[l.size() - 2]);
            const double down = (t(a, l[k]) - t(a, l[k] - h)) / h;
            CHECK(t.d_beta(a, l[k]) == doctest::Approx(down).epsilon(1e-5));
        }
    }
}

TEST_CASE("everett: antidiagonal_integral equals a Riemann sum of -dE/dbeta") {
    std::mt19937 g(16);
    for (const EverettTable& t : both_tables()) {
        for (int r = 0; r < 40; ++r) {
            const auto [c, b0, b1] = random_antidiagonal(g);
            const int m = 20000;
            const double db = (b1 - b0) / m, fd = 1e-7;
            double sum = 0.0;
            for (int k = 0; k < m; ++k) {
                const double beta = b0 + (k + 0.5) * db, alpha = c - beta;
                sum -= (t(alpha, beta + fd) - t(alpha, beta - fd)) / (2.0 * fd) * db;
            }
            INFO("c = " << c << ", beta in [" << b0 << ", " << b1 << "]");
            CHECK(t.antidiagonal_integral(c, b0, b1) == doctest::Approx(sum).epsilon(1e-5).scale(1.0));
            // Additive in the interval, zero for an empty one.
            const double mid = uniform(g, b0, b1);
            CHECK(t.antidiagonal_integral(c, b0, mid) + t.antidiagonal_integral(c, mid, b1) ==
                  doctest::Approx(t.antidiagonal_integral(c, b0, b1)).epsilon(1e-12).scale(1.0));
            CHECK(t.antidiagonal_integral(c, b1, b0) == 0.0);
            CHECK(t.antidiagonal_integral(c, b0, b0) == 0.0);
        }
        // The whole antidiagonal of the anhysteretic-like line c = U_MIN + U_MAX from the edge to the
        // diagonal is the mass between the line and the edge, so it is positive.
        const double c = U_MIN + U_MAX;
        CHECK(t.antidiagonal_integral(c, U_MIN, 0.5 * c) > 0.0);
    }
}

}  // namespace unity_test_everett

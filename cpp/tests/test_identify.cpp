// Identification core: Mayergoyz with gaps, weight density and kappa, projection to mu >= 0
// (identify.hpp), and the linear regressor / normal equations (regressor.hpp).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/identify.hpp>
#include <preisach/regressor.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_identify {

using namespace ptest;
using preisach::accumulate_normal_equations;
using preisach::cell_weights;
using preisach::EverettRegressor;
using preisach::everett_from_fod;
using preisach::everett_from_weights;
using preisach::GapPolicy;
using preisach::InputPolicy;
using preisach::mayergoyz;
using preisach::project_nonnegative;
using preisach::regressor_rows;
using preisach::weight_density;

namespace {

const double NaN = std::numeric_limits<double>::quiet_NaN();

// FOD grid y(i, j) = y_min + 2 E(i, 0) - 2 E(i, j) of a table, NaN above the diagonal.
RowMatrixXd fod_grid(const EverettTable& t) {
    const auto n = Eigen::Index(t.size());
    RowMatrixXd y = RowMatrixXd::Constant(n, n, NaN);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j <= i; ++j)
            y(i, j) = t.y_min() + 2.0 * t.node(std::size_t(i), 0) - 2.0 * (j < i ? t.node(std::size_t(i), std::size_t(j)) : 0.0);
    return y;
}

double max_node_diff(const EverettTable& a, const EverettTable& b) {
    double m = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
        for (std::size_t j = 0; j < i; ++j) m = std::max(m, std::abs(a.node(i, j) - b.node(i, j)));
    return m;
}

std::string message_of(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "";
}

// Output of theta . row for the current regressor row.
double row_dot(const EverettRegressor& r, const std::vector<double>& theta) {
    double y = 0.0;
    for (std::size_t k = 0; k < r.row_index().size(); ++k) y += r.row_value()[k] * theta[r.row_index()[k]];
    return y;
}

std::vector<double> theta_of(const EverettTable& t) {
    std::vector<double> th;
    for (std::size_t i = 1; i < t.size(); ++i)
        for (std::size_t j = 0; j < i; ++j) th.push_back(t.node(i, j));
    th.push_back(t.y_min());
    return th;
}

}  // namespace

TEST_CASE("mayergoyz: a complete grid gives everett_from_fod exactly") {
    for (const auto& lv : {uniform_levels(9), nonuniform_levels(8)}) {
        const EverettTable t = analytic_table(lv);
        const RowMatrixXd y = fod_grid(t);
        const auto r = mayergoyz(lv, y, GapPolicy::raise);
        const EverettTable ref = everett_from_fod(lv, y);
        CHECK(max_node_diff(r.table, ref) == 0.0);
        CHECK(r.table.y_min() == doctest::Approx(ref.y_min()).epsilon(1e-15));
        CHECK(r.filled.empty());
        CHECK(r.n_ymin == t.size());
    }
}

TEST_CASE("mayergoyz: gaps raise naming the node, or are filled by the documented rules") {
    const auto lv = uniform_levels(13);
    const EverettTable t = analytic_table(lv);
    RowMatrixXd y = fod_grid(t);
    y(9, 4) = NaN;   // interior gap
    y(11, 0) = NaN;  // a curve that did not reach u_min: rule 1
    for (Eigen::Index j = 0; j < 4; ++j) y(12, j) = NaN;  // the top curve stopped early (j = 0 by rule 1)
    const std::string msg = message_of([&] { mayergoyz(lv, y, GapPolicy::raise); });
    CHECK(msg.find("y_grid[9, 4]") != std::string::npos);
    CHECK(msg.find("alpha = ") != std::string::npos);
    CHECK(msg.find("gaps='fill'") != std::string::npos);

    const auto r = mayergoyz(lv, y, GapPolicy::fill);
    CHECK(r.filled.size() == 6);
    CHECK(r.filled_column0 == 2);
    // rule 1: E(i, 0) = (y_ii - y_min) / 2 with y_min the mean of the measured end points
    CHECK(r.table.node(11, 0) == doctest::Approx(0.5 * (y(11, 11) - r.table.y_min())).epsilon(1e-14));
    CHECK(r.table.y_min() == doctest::Approx(t.y_min()).epsilon(1e-14));
    // rule 2 reproduces the smooth analytic surface closely (its density is smooth but not linear)
    const double scale = t.node(12, 0);
    CHECK(max_node_diff(r.table, t) < 2e-3 * scale);
    // measured nodes are unchanged
    CHECK(r.table.node(9, 3) == doctest::Approx(t.node(9, 3)).epsilon(1e-13));
}

TEST_CASE("mayergoyz: the gap fill reproduces a linear density and kappa exactly") {
    const auto lv = uniform_levels(11);
    const double h = lv[1] - lv[0];
    RowMatrixXd w = RowMatrixXd::Zero(10, 10);
    for (Eigen::Index i = 0; i < 10; ++i) {
        const double a = 0.5 * (lv[i] + lv[i + 1]);
        w(i, i) = (0.5 + 0.1 * a) * h;  // kappa linear along the diagonal
        for (Eigen::Index j = 0; j < i; ++j) {
            const double b = 0.5 * (lv[j] + lv[j + 1]);
            w(i, j) = (1.0 + 0.3 * a - 0.2 * b) * h * h;  // v linear in alpha and beta
        }
    }
    const EverettTable t = everett_from_weights(lv, w, -2.0);
    RowMatrixXd y = fod_grid(t);
    y(7, 2) = y(7, 3) = y(8, 3) = NaN;  // a hole
    for (Eigen::Index j = 1; j < 5; ++j) y(10, j) = NaN;  // the top curve stopped early
    const auto r = mayergoyz(lv, y, GapPolicy::fill);
    CHECK(r.filled.size() == 7);
    CHECK(max_node_diff(r.table, t) < 1e-9);
}

TEST_CASE("mayergoyz: a row without its turning point is filled whole, no end point at all is an error") {
    const auto lv = uniform_levels(7);
    const EverettTable t = analytic_table(lv);
    RowMatrixXd y = fod_grid(t);
    y(4, 4) = NaN;
    const auto r = mayergoyz(lv, y, GapPolicy::fill);
    REQUIRE(r.rows_without_turning_point.size() == 1);
    CHECK(r.rows_without_turning_point[0] == 4);
    CHECK(r.filled.size() == 4);
    CHECK(message_of([&] { mayergoyz(lv, y, GapPolicy::raise); }).find("turning point") != std::string::npos);
    RowMatrixXd z = fod_grid(t);
    for (Eigen::Index i = 0; i < 7; ++i) z(i, 0) = NaN;
    CHECK(message_of([&] { mayergoyz(lv, z, GapPolicy::fill); }).find("y_min is unknown") != std::string::npos);
    RowMatrixXd w = fod_grid(t);
    w(3, 1) = std::numeric_limits<double>::infinity();
    CHECK(message_of([&] { mayergoyz(lv, w, GapPolicy::fill); }).find("y_grid[3, 1]") != std::string::npos);
}

TEST_CASE("weight density: v times the cell areas plus kappa times the widths is the total mass") {
    for (const auto& lv : {uniform_levels(11), nonuniform_levels(10)}) {
        const EverettTable t = analytic_table(lv);
        const auto d = weight_density(t);
        const RowMatrixXd w = cell_weights(t);
        double total = 0.0;
        const std::size_t m = t.size() - 1;
        for (std::size_t i = 0; i < m; ++i) {
            const double hi = lv[Eigen::Index(i + 1)] - lv[Eigen::Index(i)];
            total += d.kappa[Eigen::Index(i)] * hi;
            CHECK(d.kappa[Eigen::Index(i)] * hi == doctest::Approx(w(Eigen::Index(i), Eigen::Index(i))));
            CHECK(std::isnan(d.v(Eigen::Index(i), Eigen::Index(i))));
            for (std::size_t j = 0; j < i; ++j)
                total += d.v(Eigen::Index(i), Eigen::Index(j)) * hi * (lv[Eigen::Index(j + 1)] - lv[Eigen::Index(j)]);
        }
        CHECK(total == doctest::Approx(t.node(t.size() - 1, 0)).epsilon(1e-12));
        // density of E_exact: mu = exp(0.3 s)(2 - 0.09 d^2) + 0.6 d, at a cell centre (to O(h^2))
        const std::size_t i = 6, j = 2;
        const double a = 0.5 * (lv[6] + lv[7]), b = 0.5 * (lv[2] + lv[3]);
        const double mu = std::exp(0.3 * (a + b)) * (2.0 - 0.09 * (a - b) * (a - b)) + 0.6 * (a - b);
        CHECK(d.v(Eigen::Index(i), Eigen::Index(j)) == doctest::Approx(mu).epsilon(0.02));
    }
}

TEST_CASE("projection: a table in Mp is unchanged, otherwise all masses >= 0 with y_min and y_max kept") {
    const auto lv = uniform_levels(9);
    const EverettTable t = analytic_table(lv);
    const auto same = project_nonnegative(t);
    CHECK(same.n_negative == 0);
    CHECK(max_node_diff(same.table, t) == 0.0);
    CHECK(same.mass_moved == 0.0);

    RowMatrixXd w = cell_weights(t);
    w(5, 2) = -0.05;
    w(7, 7) = -0.02;  // a negative kappa cell too
    w(3, 0) = -0.01;
    const EverettTable bad = everett_from_weights(lv, w, -1.0);
    const auto p = project_nonnegative(bad);
    CHECK(p.converged);
    CHECK(p.n_negative == 3);
    CHECK(p.negative_mass == doctest::Approx(-0.08));
    const RowMatrixXd wp = cell_weights(p.table);
    for (Eigen::Index i = 0; i < wp.rows(); ++i)
        for (Eigen::Index j = 0; j <= i; ++j) CHECK(wp(i, j) >= -1e-15);  // round-off only
    CHECK(p.kept_y_max);
    CHECK(p.table.y_max() == doctest::Approx(bad.y_max()).epsilon(1e-12));
    CHECK(p.table.y_min() == bad.y_min());
    // the mass moved is at least what had to be removed from the negative cells
    CHECK(p.mass_moved >= 0.08 - 1e-12);
    CHECK(p.max_node_change > 0.0);
    CHECK(p.max_node_change < 0.05);
    // it is the nearest such table: nudging any node of the result into the feasible set
    // does not get closer to the original (first-order optimality along feasible directions)
    double d0 = 0.0;
    for (std::size_t i = 0; i < bad.size(); ++i)
        for (std::size_t j = 0; j < i; ++j) d0 += std::pow(p.table.node(i, j) - bad.node(i, j), 2);
    std::mt19937 g(3);
    for (int trial = 0; trial < 200; ++trial) {
        RowMatrixXd e = RowMatrixXd::Zero(9, 9);
        for (Eigen::Index i = 0; i < 9; ++i)
            for (Eigen::Index j = 0; j < i; ++j) e(i, j) = p.table.node(std::size_t(i), std::size_t(j)) + 1e-4 * uniform(g, -1, 1);
        e(8, 0) = p.table.node(8, 0);
        const EverettTable cand(lv, e, -1.0);
        const RowMatrixXd wc = cell_weights(cand);
        bool feasible = true;
        for (Eigen::Index i = 0; i < wc.rows(); ++i)
            for (Eigen::Index j = 0; j <= i; ++j) feasible = feasible && wc(i, j) >= 0.0;
        if (!feasible) continue;
        double d1 = 0.0;
        for (std::size_t i = 0; i < 9; ++i)
            for (std::size_t j = 0; j < i; ++j) d1 += std::pow(cand.node(i, j) - bad.node(i, j), 2);
        CHECK(d1 >= d0 - 1e-12);
    }
    CHECK_THROWS_AS(project_nonnegative(bad, true, 0.0), std::invalid_argument);
}

TEST_CASE("projection: y_max cannot be kept when E(u_max, u_min) < 0") {
    const auto lv = uniform_levels(4);
    RowMatrixXd w = RowMatrixXd::Zero(3, 3);
    w(0, 0) = 0.1;
    w(2, 0) = -0.5;
    const EverettTable bad = everett_from_weights(lv, w, 0.0);
    REQUIRE(bad.node(3, 0) < 0.0);
    const auto p = project_nonnegative(bad);
    CHECK_FALSE(p.kept_y_max);
    const RowMatrixXd wp = cell_weights(p.table);
    for (Eigen::Index i = 0; i < 3; ++i)
        for (Eigen::Index j = 0; j <= i; ++j) CHECK(wp(i, j) >= -1e-15);
}

TEST_CASE("regressor: row . theta equals the simulator, from every kind of state, on both grids") {
    std::mt19937 g(11);
    for (const auto& lv : {uniform_levels(13), nonuniform_levels(11)}) {
        const EverettTable t = analytic_table(lv);
        const auto theta = theta_of(t);
        for (int run = 0; run < 12; ++run) {
            const State s0 = random_start(g);
            const auto u = run % 2 ? random_walk(g, 3000, 0.3, 0.15) : random_inputs(g, 400, U_MIN - 0.2, U_MAX + 0.2);
            Simulator sim(t, s0);
            EverettRegressor reg(lv, s0);
            CHECK(row_dot(reg, theta) == doctest::Approx(sim.output()).epsilon(1e-12));
            double worst = 0.0;
            for (std::size_t k = 0; k < u.size(); ++k) {
                const double ys = sim.step_checked(u[k], InputPolicy::clamp, k);
                reg.step(u[k], InputPolicy::clamp, k);
                worst = std::max(worst, std::abs(row_dot(reg, theta) - ys));
                // indices ascending and unique, the offset last with coefficient 1
                const auto& ix = reg.row_index();
                CHECK(std::is_sorted(ix.begin(), ix.end()));
                CHECK(std::adjacent_find(ix.begin(), ix.end()) == ix.end());
                CHECK(ix.back() == reg.n_nodes());
                CHECK(reg.row_value().back() == 1.0);
            }
            CHECK(worst < 1e-12);
            CHECK(reg.state() == sim.state());
        }
    }
}

TEST_CASE("regressor: a row asked for after skipped samples is the row of one asked at every sample") {
    // rows are built lazily (a fit on every k-th sample pays only for those); skipping must not
    // change a row, to the bit
    std::mt19937 g(23);
    const auto lv = nonuniform_levels(9);
    for (int run = 0; run < 6; ++run) {
        const State s0 = random_start(g);
        const auto u = random_walk(g, 2000, 0.0, 0.25);
        EverettRegressor every(lv, s0), some(lv, s0);
        std::size_t asked = 0;
        for (std::size_t k = 0; k < u.size(); ++k) {
            every.step(u[k], InputPolicy::clamp, k);
            some.step(u[k], InputPolicy::clamp, k);
            const auto& ix = every.row_index();
            if ((k * 7 + std::size_t(run)) % 5 != 0) continue;  // irregular skips, incl. runs
            ++asked;
            CHECK(some.row_index() == ix);
            CHECK(some.row_value() == every.row_value());
        }
        CHECK(asked > 300);
        CHECK(some.state() == every.state());
    }
}

TEST_CASE("regressor: errors name the sample, the raise policy and a range mismatch") {
    const auto lv = uniform_levels(5);
    EverettRegressor reg(lv, State::negative_saturation(U_MIN, U_MAX));
    CHECK(message_of([&] { reg.step(NaN, InputPolicy::clamp, 7); }).find("u[7]") != std::string::npos);
    CHECK(message_of([&] { reg.step(U_MAX + 1.0, InputPolicy::raise, 3); }).find("u[3]") != std::string::npos);
    CHECK_THROWS_AS(EverettRegressor(lv, State::negative_saturation(U_MIN, U_MAX + 1.0)), std::invalid_argument);
}

TEST_CASE("normal equations with a basis: per-fold cross products sum r_t a_t^T of the rows with it") {
    std::mt19937 g(9);
    const auto lv = nonuniform_levels(7);
    const auto u = random_walk(g, 900, 0.0, 0.2);
    std::vector<double> y(u.size());
    for (auto& v : y) v = uniform(g, -2.0, 2.0);
    std::vector<std::int32_t> fold(u.size());
    for (std::size_t k = 0; k < u.size(); ++k) fold[k] = k < 50 ? -1 : std::int32_t(k % 2);
    const std::size_t nb = 4, p = 7 * 6 / 2 + 1;
    std::vector<double> basis(u.size() * nb, 0.0);  // hat functions in time: two nonzeros per sample
    for (std::size_t k = 0; k < u.size(); ++k) {
        const double s = double(k) / double(u.size()) * double(nb - 1);
        const std::size_t j = std::min(std::size_t(s), nb - 2);
        basis[k * nb + j] = 1.0 - (s - double(j));
        basis[k * nb + j + 1] = s - double(j);
    }
    const State s0 = State::negative_saturation(U_MIN, U_MAX);
    std::vector<double> gram(2 * p * p), rhs(2 * p), yy(2), ysum(2), cross(2 * p * nb, 7.0);
    std::vector<std::int64_t> count(2);
    const preisach::BasisCross with{basis.data(), nb, cross.data()};
    accumulate_normal_equations_into(lv, s0, u.data(), y.data(), fold.data(), u.size(), 2, InputPolicy::clamp,
                                     {gram.data(), rhs.data(), yy.data(), ysum.data(), count.data()}, nullptr,
                                     preisach::Interpolation::bilinear, &with);
    const auto ne = accumulate_normal_equations(lv, s0, u.data(), y.data(), fold.data(), u.size(), 2,
                                                InputPolicy::clamp);
    const auto rows = regressor_rows(lv, s0, u.data(), u.size(), InputPolicy::clamp);
    for (std::size_t f = 0; f < 2; ++f) {
        RowMatrixXd C = RowMatrixXd::Zero(Eigen::Index(p), Eigen::Index(nb));
        for (std::size_t k = 0; k < u.size(); ++k) {
            if (fold[k] != std::int32_t(f)) continue;
            for (auto q = rows.indptr[k]; q < rows.indptr[k + 1]; ++q)
                for (std::size_t j = 0; j < nb; ++j)
                    C(Eigen::Index(rows.indices[std::size_t(q)]), Eigen::Index(j)) +=
                        rows.data[std::size_t(q)] * basis[k * nb + j];
        }
        const Eigen::Map<const RowMatrixXd> got(cross.data() + f * p * nb, Eigen::Index(p), Eigen::Index(nb));
        CHECK((got - C).cwiseAbs().maxCoeff() < 1e-12 * C.cwiseAbs().maxCoeff());
        // the normal equations themselves are those without the basis
        const Eigen::Map<const RowMatrixXd> G(gram.data() + f * p * p, Eigen::Index(p), Eigen::Index(p));
        CHECK((G - ne[f].gram).cwiseAbs().maxCoeff() == 0.0);
    }
}

TEST_CASE("normal equations: per-fold sums of r r^T, r y and y^2, and fold -1 only advances the state") {
    std::mt19937 g(5);
    const auto lv = nonuniform_levels(8);
    const EverettTable t = analytic_table(lv);
    const auto u = random_walk(g, 1500, 0.0, 0.2);
    std::vector<double> y(u.size());
    for (auto& v : y) v = uniform(g, -2.0, 2.0);
    std::vector<std::int32_t> fold(u.size());
    for (std::size_t k = 0; k < u.size(); ++k) fold[k] = k < 100 ? -1 : std::int32_t(k % 3);
    const State s0 = State::neutral(U_MIN, U_MAX, 0.4);
    State fin;
    const auto ne = accumulate_normal_equations(lv, s0, u.data(), y.data(), fold.data(), u.size(), 3,
                                                InputPolicy::clamp, &fin);
    const auto rows = regressor_rows(lv, s0, u.data(), u.size(), InputPolicy::clamp);
    CHECK(fin == rows.final_state);
    const std::size_t p = 8 * 7 / 2 + 1;
    for (int f = 0; f < 3; ++f) {
        RowMatrixXd G = RowMatrixXd::Zero(Eigen::Index(p), Eigen::Index(p));
        Eigen::VectorXd b = Eigen::VectorXd::Zero(Eigen::Index(p));
        double yy = 0.0;
        std::size_t count = 0;
        for (std::size_t k = 0; k < u.size(); ++k) {
            if (fold[k] != f) continue;
            Eigen::VectorXd r = Eigen::VectorXd::Zero(Eigen::Index(p));
            for (auto q = rows.indptr[k]; q < rows.indptr[k + 1]; ++q)
                r[Eigen::Index(rows.indices[std::size_t(q)])] = rows.data[std::size_t(q)];
            G += r * r.transpose();
            b += r * y[k];
            yy += y[k] * y[k];
            ++count;
        }
        const auto& e = ne[std::size_t(f)];
        CHECK(e.count == count);
        CHECK((e.gram - G).cwiseAbs().maxCoeff() < 1e-9 * G.cwiseAbs().maxCoeff());
        CHECK((e.rhs - b).cwiseAbs().maxCoeff() < 1e-9 * b.cwiseAbs().maxCoeff());
        CHECK(e.yy == doctest::Approx(yy));
        CHECK((e.gram - e.gram.transpose()).cwiseAbs().maxCoeff() == 0.0);
    }
    // with the true table and y = model output the normal equations are solved exactly by theta
    Simulator sim(t, s0);
    for (std::size_t k = 0; k < u.size(); ++k) y[k] = sim.step(u[k]);
    const auto ne2 = accumulate_normal_equations(lv, s0, u.data(), y.data(), fold.data(), u.size(), 3,
                                                 InputPolicy::clamp);
    const auto th = theta_of(t);
    Eigen::VectorXd theta(static_cast<Eigen::Index>(th.size()));
    for (std::size_t k = 0; k < th.size(); ++k) theta[Eigen::Index(k)] = th[k];
    for (const auto& e : ne2) CHECK((e.gram * theta - e.rhs).cwiseAbs().maxCoeff() < 1e-9 * e.rhs.cwiseAbs().maxCoeff());
    std::vector<std::int32_t> badfold(u.size(), 3);
    CHECK(message_of([&] {
              accumulate_normal_equations(lv, s0, u.data(), y.data(), badfold.data(), u.size(), 3, InputPolicy::clamp);
          }).find("fold[0]") != std::string::npos);
}

}  // namespace unity_test_identify

// Inverter: the exact inverse of the simulator, on monotone and non-monotone tables, from
// saturated, staircase and neutral (antidiagonal) states, with unreachable targets.
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/inverse.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_inverse {

using namespace ptest;
using preisach::Inverter;

namespace {

// Random start with a staircase too: saturation, neutral or a few random extrema.
State random_state(std::mt19937& g) {
    if (std::uniform_int_distribution<int>(0, 3)(g) < 3) return random_start(g);
    Simulator sim(analytic_table(uniform_levels(5)), State::negative_saturation(U_MIN, U_MAX));
    for (double x : random_inputs(g, 6)) sim.step(x);
    return sim.state();
}

// Targets that the model reaches from `s`: the outputs of a random walk.
std::vector<double> reachable_targets(const EverettTable& t, const State& s, std::mt19937& g, std::size_t n) {
    return simulate(t, s, random_walk(g, n, s.input(), 0.12));
}

// A table with negative cells: the analytic E minus a bump of negative weight.
EverettTable nonmonotone_table(const Eigen::VectorXd& levels) {
    const Eigen::Index n = levels.size();
    RowMatrixXd v = RowMatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j) {
            const double a = levels[i], b = levels[j];
            // -2.5 * (area of the triangle T(a, b) inside the square [0.2, 1.2] x [-0.6, 0.4])
            const double lo = std::max(b, -0.6), hi = std::min(a, 1.2);
            double bump = 0.0;
            const int m = 60;
            for (int k = 0; k < m; ++k) {  // integrate the alpha extent over beta'
                const double bb = -0.6 + (double(k) + 0.5) / m;
                if (bb < lo || bb > 0.4) continue;
                const double top = std::min(hi, a), bot = std::max(bb, 0.2);
                if (top > bot) bump += (top - bot) / m;
            }
            v(i, j) = E_exact(a, b) - 2.5 * bump;
        }
    return EverettTable(levels, v, Y_MIN);
}

}  // namespace

TEST_CASE("inverse: simulate(inverse(y)) == y and the input is recovered on a monotone table") {
    std::mt19937 g(7);
    for (const auto& levels : {uniform_levels(41), nonuniform_levels(33)}) {
        const EverettTable t = analytic_table(levels);
        for (int trial = 0; trial < 30; ++trial) {
            const State s = random_state(g);
            const auto u_true = random_walk(g, 400, s.input(), 0.12);
            const auto y = simulate(t, s, u_true);
            Inverter inv(t, s);
            CHECK(inv.monotone());
            std::vector<double> u(y.size()), yo(y.size());
            std::vector<std::uint8_t> ok(y.size());
            inv.run(y.data(), u.data(), yo.data(), ok.data(), y.size());
            CHECK(inv.unreachable() == 0);
            CHECK(max_abs_diff(simulate(t, s, u), y) < 1e-9);
            CHECK(max_abs_diff(yo, y) < 1e-9);
            CHECK(max_abs_diff(simulate(t, s, u), yo) == 0.0);  // the inverter steps the same simulator
            // mu > 0 everywhere: the input is unique, so the inverse finds the walk itself
            CHECK(max_abs_diff(u, u_true) < 1e-8);
            const State fin = inv.state();
            Simulator ref(t, s);
            for (double x : u_true) ref.step(x);
            REQUIRE(fin.pieces().size() == ref.state().pieces().size());
            CHECK(std::abs(fin.input() - ref.state().input()) < 1e-8);
        }
    }
}

TEST_CASE("inverse: step by step equals the array run, from a neutral state (quadratic pieces)") {
    std::mt19937 g(11);
    const EverettTable t = analytic_table(uniform_levels(25));
    for (double l : {-0.7, 0.0, 0.3, 1.6}) {
        const State s = State::neutral(U_MIN, U_MAX, l);
        const auto y = reachable_targets(t, s, g, 300);
        Inverter a(t, s), b(t, s);
        std::vector<double> u(y.size()), yo(y.size());
        a.run(y.data(), u.data(), yo.data(), nullptr, y.size());
        for (std::size_t k = 0; k < y.size(); ++k) {
            CHECK(b.step(y[k]) == u[k]);
            CHECK(std::abs(b.output() - y[k]) < 1e-9);
        }
        CHECK(a.unreachable() == 0);
        CHECK(a.state() == b.state());
    }
    // A single large jump through the whole antidiagonal piece and back.
    const State s = State::neutral(U_MIN, U_MAX, 0.5);
    Inverter inv(t, s);
    Simulator sim(t, s);
    for (double u : {1.9, -0.9, 1.2, -0.2}) {
        const double y = Simulator(t, s).step(u);
        inv.reset(s);
        CHECK(std::abs(inv.step(y) - u) < 1e-9);
        CHECK(std::abs(inv.output() - y) < 1e-9);
    }
}

TEST_CASE("inverse: unreachable targets give the saturation, counted, never thrown") {
    const EverettTable t = analytic_table(uniform_levels(21));
    Inverter inv(t, State::neutral(U_MIN, U_MAX, 0.2));
    CHECK(inv.step(t.y_max() + 1.0) == U_MAX);
    CHECK(inv.output() == doctest::Approx(t.y_max()).epsilon(1e-14));
    CHECK(inv.unreachable() == 1);
    CHECK(inv.step(t.y_max() + 5.0) == U_MAX);  // already there: stays
    CHECK(inv.unreachable() == 2);
    CHECK(inv.step(t.y_min() - 0.1) == U_MIN);
    CHECK(inv.output() == doctest::Approx(t.y_min()));
    CHECK(inv.unreachable() == 3);
    const double y_mid = 0.5 * (t.y_min() + t.y_max());
    inv.step(y_mid);
    CHECK(inv.output() == doctest::Approx(y_mid).epsilon(1e-13));
    CHECK(inv.unreachable() == 3);
    CHECK_THROWS_AS(inv.step(std::nan("")), std::invalid_argument);
    std::vector<double> y = {0.0, HUGE_VAL}, u(2), yo(2);
    const State before = inv.state();
    CHECK_THROWS_AS(inv.run(y.data(), u.data(), yo.data(), nullptr, 2), std::invalid_argument);
    CHECK(inv.state() == before);  // checked before the state moved
}

TEST_CASE("inverse: a flat table region is reached at its start") {
    // Everett values constant in alpha for alpha > 1 (no relays up there): a rise beyond 1 V
    // leaves the output flat, so the saturation output is first reached at 1 V.
    const auto levels = uniform_levels(31);
    const Eigen::Index n = levels.size();
    RowMatrixXd v = RowMatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j) v(i, j) = E_exact(std::min(levels[i], 1.0), std::min(levels[j], 1.0));
    const EverettTable t(levels, v, Y_MIN);
    Inverter inv(t, State::negative_saturation(U_MIN, U_MAX));
    CHECK(inv.step(t.y_max()) == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(inv.unreachable() == 0);
}

TEST_CASE("inverse: a non-monotone table takes the smallest input excursion reaching the target") {
    std::mt19937 g(5);
    const EverettTable t = nonmonotone_table(uniform_levels(31));
    Inverter probe(t, State::negative_saturation(U_MIN, U_MAX));
    REQUIRE_FALSE(probe.monotone());
    int reached = 0, checked = 0;
    for (int trial = 0; trial < 40; ++trial) {
        const State s = random_state(g);
        Simulator walk(t, s);
        for (double x : random_walk(g, 30, s.input(), 0.2)) walk.step(x);
        const State s1 = walk.state();
        const double y0 = walk.output();
        for (int k = 0; k < 6; ++k) {
            const double target = y0 + uniform(g, -6.0, 6.0);
            Inverter inv(t, s1);
            bool ok = false;
            const double u = inv.solve(target, ok);
            inv.step(target);
            CHECK(inv.input() == u);
            // Brute force: the output along both excursions on a fine input grid.
            double best_exc = HUGE_VAL;
            for (int dir : {-1, 1}) {
                double prev = y0;
                const int m = 3000;
                for (int q = 1; q <= m; ++q) {
                    const double uu = s1.input() + dir * (dir > 0 ? U_MAX - s1.input() : s1.input() - U_MIN) * q / m;
                    const double yy = Simulator(t, s1).step(uu);
                    if ((prev - target) * (yy - target) <= 0.0) {
                        best_exc = std::min(best_exc, std::abs(uu - s1.input()));
                        break;
                    }
                    prev = yy;
                }
            }
            if (ok) {
                ++reached;
                CHECK(std::abs(inv.output() - target) < 1e-9);
                CHECK(best_exc < HUGE_VAL);
                // the sampled first crossing lies at most one grid step of the brute force beyond it
                CHECK(std::abs(u - s1.input()) <= best_exc + 1e-9);
                CHECK(std::abs(u - s1.input()) >= best_exc - (U_MAX - U_MIN) / 3000.0 - 1e-9);
            } else {
                CHECK(best_exc == HUGE_VAL);
                CHECK(inv.unreachable() == 1);
            }
            ++checked;
        }
    }
    MESSAGE(reached << " of " << checked << " targets reached on the non-monotone table");
    CHECK(reached > checked / 2);
}

TEST_CASE("inverse: a reference returning exactly to an extremum or a saturation wipes out the same memory") {
    std::mt19937 g(13);
    const EverettTable t = analytic_table(uniform_levels(31));
    for (int trial = 0; trial < 40; ++trial) {
        const State s = random_state(g);
        // extrema revisited exactly, and both saturations
        const double a = uniform(g, U_MIN, U_MAX), b = uniform(g, U_MIN, a);
        const std::vector<double> u = {a, b, 0.5 * (a + b), b, a, U_MAX, b, U_MIN, a, b, a};
        const auto y = simulate(t, s, u);
        Inverter inv(t, s);
        Simulator truth(t, s);
        for (std::size_t k = 0; k < u.size(); ++k) {
            inv.step(y[k]);
            truth.step(u[k]);
            CHECK(std::abs(inv.output() - y[k]) < 1e-9);
            CHECK(inv.depth() == truth.depth());
        }
        CHECK(inv.unreachable() == 0);
        const State si = inv.state(), st = truth.state();
        REQUIRE(si.pieces().size() == st.pieces().size());
        for (std::size_t k = 0; k < si.pieces().size(); ++k) {
            CHECK(std::abs(si.pieces()[k].b0 - st.pieces()[k].b0) < 1e-9);
            CHECK(std::abs(si.pieces()[k].v - st.pieces()[k].v) < 1e-9);
        }
    }
}

}  // namespace unity_test_inverse

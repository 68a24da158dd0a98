// Simulator: against an independent brute-force relay model, the Preisach properties
// (wiping-out, congruent minor loops), saturation, FOD reproduction, readout, input policy,
// slopes and the neutral state.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_simulator {

using namespace ptest;
using preisach::apply_inputs;
using preisach::InputPolicy;
using preisach::readout;

namespace {

const double NaN = std::numeric_limits<double>::quiet_NaN();

// Fine table for comparisons against the continuum (its nodes include every node of the
// N = 20, 40, 80 relay grids).
const EverettTable& fine_table() {
    static const EverettTable t = analytic_table(uniform_levels(241));
    return t;
}

double dist_to_grid(const EverettTable& t, double x) {
    double d = HUGE_VAL;
    for (double l : t.levels()) d = std::min(d, std::abs(x - l));
    return d;
}

// Slope of the diagonal half-cell containing u: 2 E(l_{i+1}, l_i) / (l_{i+1} - l_i).
double diagonal_slope(const EverettTable& t, double u) {
    const auto& l = t.levels();
    std::size_t i = 0;
    while (i + 2 < l.size() && u >= l[i + 1]) ++i;
    return 2.0 * t.node(i + 1, i) / (l[i + 1] - l[i]);
}

// Max |simulator - relay grid| over a random walk from `start`.
double brute_force_error(std::size_t n_relays, const State& start, const std::vector<double>& u) {
    RelayGrid grid(n_relays, start);
    Simulator sim(fine_table(), start);
    double err = std::abs(sim.output() - grid.output());
    for (double x : u) err = std::max(err, std::abs(sim.step(x) - grid.step(x)));
    return err;
}

void check_convergence(const std::vector<State>& starts, std::uint32_t seed) {
    std::mt19937 g(seed);
    std::vector<std::vector<double>> walks;
    for (std::size_t k = 0; k < starts.size(); ++k) walks.push_back(random_walk(g, 1500, starts[k].input(), 0.15));
    std::vector<double> errs;
    for (std::size_t n : {20u, 40u, 80u}) {
        double e = 0.0;
        for (std::size_t k = 0; k < starts.size(); ++k) e = std::max(e, brute_force_error(n, starts[k], walks[k]));
        errs.push_back(e);
        MESSAGE("N = " << n << ": max |simulator - relay grid| = " << e);
    }
    // The relay grid is first order in 1/N: the difference must roughly halve.
    CHECK(errs[1] < 0.7 * errs[0]);
    CHECK(errs[2] < 0.7 * errs[1]);
    // One row of relays switching at once moves y by about 2 h max|dE/dalpha| ~ 1 at N = 80 (y spans ~30).
    CHECK(errs[2] < 0.8);
}

}  // namespace

TEST_CASE("simulator: converges to a brute-force relay grid from the saturations") {
    check_convergence({State::negative_saturation(U_MIN, U_MAX), State::positive_saturation(U_MIN, U_MAX)}, 101);
}

TEST_CASE("simulator: converges to a brute-force relay grid from neutral states") {
    check_convergence({State::neutral(U_MIN, U_MAX, -0.4), State::neutral(U_MIN, U_MAX, 0.5),
                       State::neutral(U_MIN, U_MAX, 1.3)},
                      102);
}

TEST_CASE("simulator: equals the relay grid exactly for inputs on the grid nodes") {
    // Table and relay grid on the same N = 30 grid: with every extremum on a node the relay
    // sums telescope into Everett values at nodes, which the table holds exactly.
    const std::size_t n = 30;
    const EverettTable t = analytic_table(uniform_levels(n + 1));
    std::mt19937 g(103);
    std::uniform_int_distribution<int> node(0, int(n));
    for (const State& start : {State::negative_saturation(U_MIN, U_MAX), State::positive_saturation(U_MIN, U_MAX)}) {
        RelayGrid grid(n, start);
        Simulator sim(t, start);
        CHECK(sim.output() == doctest::Approx(grid.output()).epsilon(1e-12));
        for (int k = 0; k < 2000; ++k) {
            const double u = t.levels()[std::size_t(node(g))];
            const double ys = sim.step(u), yb = grid.step(u);
            REQUIRE_MESSAGE(std::abs(ys - yb) < 1e-10, "step " << k << ", u = " << u);
        }
    }
}

TEST_CASE("simulator: saturation outputs") {
    const EverettTable t = analytic_table(nonuniform_levels(17));
    const double y_max = Y_MIN + 2.0 * E_exact(U_MAX, U_MIN);
    CHECK(t.y_max() == doctest::Approx(y_max).epsilon(1e-14));
    CHECK(readout(t, State::negative_saturation(U_MIN, U_MAX)) == Y_MIN);
    CHECK(readout(t, State::positive_saturation(U_MIN, U_MAX)) == doctest::Approx(y_max).epsilon(1e-14));
    std::mt19937 g(104);
    for (int r = 0; r < 50; ++r) {
        Simulator sim(t, random_start(g));
        for (double u : random_inputs(g, 30)) sim.step(u);
        CHECK(sim.step(U_MAX) == doctest::Approx(y_max).epsilon(1e-13));
        CHECK(sim.depth() == 1);
        CHECK(sim.state() == State::positive_saturation(U_MIN, U_MAX));
        for (double u : random_inputs(g, 30)) sim.step(u);
        CHECK(sim.step(U_MIN) == doctest::Approx(Y_MIN).epsilon(1e-13).scale(1.0));
        CHECK(sim.depth() == 0);
        CHECK(sim.state() == State::negative_saturation(U_MIN, U_MAX));
    }
}

TEST_CASE("simulator: wiping-out") {
    const EverettTable t = analytic_table(nonuniform_levels(21));
    std::mt19937 g(105);
    for (int r = 0; r < 400; ++r) {
        const State start = random_start(g);
        const std::vector<double> history = random_inputs(g, std::size_t(std::uniform_int_distribution<int>(0, 25)(g)));
        Simulator with(t, start), without(t, start);
        for (double u : history) {
            with.step(u);
            without.step(u);
        }
        const double c = with.input();
        const double v = uniform(g, U_MIN, U_MAX);
        // Excursion strictly between the last input and the final one: wiped out by v.
        const std::vector<double> excursion =
            random_inputs(g, std::size_t(std::uniform_int_distribution<int>(1, 12)(g)), std::min(c, v), std::max(c, v));
        for (double u : excursion) with.step(u);
        const double y_with = with.step(v), y_without = without.step(v);
        INFO("case " << r << ": c = " << c << ", v = " << v);
        CHECK(y_with == doctest::Approx(y_without).epsilon(1e-12).scale(1.0));
        CHECK(with.state() == without.state());
        CHECK(with.depth() == without.depth());
        // And the two stay identical afterwards.
        double worst = 0.0;
        for (double u : random_inputs(g, 20)) worst = std::max(worst, std::abs(with.step(u) - without.step(u)));
        CHECK(worst < 1e-10);
    }
    SUBCASE("returning past the previous extremum wipes out a whole loop") {
        // ... M, m, then a loop between m and a value below M, then an input above M: the result is
        // as if the input had gone from m straight above M.
        for (int r = 0; r < 200; ++r) {
            Simulator a(t, random_start(g)), b(t, State::negative_saturation(U_MIN, U_MAX));
            for (double u : random_inputs(g, 10)) a.step(u);
            b.reset(a.state());
            const double m = uniform(g, U_MIN, U_MAX - 0.2);
            const double M = uniform(g, m + 0.1, U_MAX);
            for (Simulator* s : {&a, &b}) {
                s->step(M);
                s->step(m);
            }
            for (int k = 0; k < 5; ++k) {
                a.step(uniform(g, m, M));
                a.step(uniform(g, m, M));
            }
            const double top = uniform(g, M, U_MAX);
            CHECK(a.step(top) == doctest::Approx(b.step(top)).epsilon(1e-12).scale(1.0));
            CHECK(a.state() == b.state());
        }
    }
}

TEST_CASE("simulator: congruent minor loops") {
    const EverettTable t = analytic_table(nonuniform_levels(19));
    std::mt19937 g(106);
    int distinct = 0;
    const int cases = 300;
    for (int r = 0; r < cases; ++r) {
        const double u1 = uniform(g, U_MIN, U_MAX - 0.2);
        const double u2 = uniform(g, u1 + 0.1, U_MAX);
        const bool from_below = r % 2 == 0;  // loop u1 -> u2 -> u1, or u2 -> u1 -> u2
        std::vector<std::vector<double>> dys;
        std::vector<double> y0s;
        for (int h = 0; h < 2; ++h) {
            Simulator sim(t, random_start(g));
            for (double u : random_inputs(g, std::size_t(std::uniform_int_distribution<int>(0, 20)(g)))) sim.step(u);
            // Arrive at the loop's start from beyond its other end (the loop's two extrema are then
            // consecutive in the history).
            if (from_below) {
                sim.step(uniform(g, u2, U_MAX));
                sim.step(u1);
            } else {
                sim.step(uniform(g, U_MIN, u1));
                sim.step(u2);
            }
            const double y0 = sim.output();
            y0s.push_back(y0);
            std::vector<double> dy;
            for (int cycle = 0; cycle < 2; ++cycle)
                for (int k = 1; k <= 40; ++k) {
                    const double x = k <= 20 ? double(k) / 20.0 : double(40 - k) / 20.0;  // 0 -> 1 -> 0
                    const double u = from_below ? u1 + (u2 - u1) * x : u2 - (u2 - u1) * x;
                    dy.push_back(sim.step(u) - y0);
                }
            dys.push_back(dy);
        }
        if (std::abs(y0s[0] - y0s[1]) > 1e-3) ++distinct;
        INFO("case " << r << ": loop between " << u1 << " and " << u2);
        CHECK(max_abs_diff(dys[0], dys[1]) < 1e-10);
        // A closed loop returns to its start.
        CHECK(std::abs(dys[0].back()) < 1e-10);
    }
    CHECK(distinct > cases * 9 / 10);  // the histories really differed
}

TEST_CASE("simulator: FOD curves reproduce the FOD table at the nodes") {
    // A consistent FOD table (all curves start at the same y_min) on a non-uniform grid,
    // with a perturbation so that no structure of E_exact helps.
    const Eigen::VectorXd l = nonuniform_levels(12);
    const Eigen::Index n = l.size();
    std::mt19937 g(107);
    RowMatrixXd y = RowMatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j <= i; ++j)
            y(i, j) = j == 0 ? 0.4 : 0.4 + 2.0 * (E_exact(l[i], U_MIN) - E_exact(l[i], l[j])) + uniform(g, -0.1, 0.1);
    const EverettTable t = preisach::everett_from_fod(l, y);
    CHECK(t.y_min() == doctest::Approx(0.4).epsilon(1e-15));
    for (Eigen::Index i = 0; i < n; ++i) {
        Simulator sim(t, State::negative_saturation(U_MIN, U_MAX));
        if (i > 0) CHECK(sim.step(l[i]) == doctest::Approx(y(i, i)).epsilon(1e-13));
        for (Eigen::Index j = i; j-- > 0;) {
            INFO("FOD curve " << i << " at node " << j);
            CHECK(sim.step(l[j]) == doctest::Approx(y(i, j)).epsilon(1e-13));
        }
    }
}

TEST_CASE("simulator: readout, state and reset agree with the simulation") {
    const EverettTable t = analytic_table(nonuniform_levels(15));
    std::mt19937 g(108);
    for (int r = 0; r < 200; ++r) {
        const State start = random_start(g);
        Simulator sim(t, start);
        CHECK(readout(t, start) == sim.output());
        const std::vector<double> u = random_inputs(g, std::size_t(std::uniform_int_distribution<int>(1, 30)(g)));
        for (double x : u) sim.step(x);
        const State s = sim.state();
        CHECK(s.input() == u.back());
        CHECK(readout(t, s) == doctest::Approx(sim.output()).epsilon(1e-12).scale(1.0));
        CHECK(apply_inputs(start, u) == s);
        // A simulator restarted from the state continues exactly like the original.
        Simulator again(t, s);
        const std::vector<double> tail = random_inputs(g, 30);
        double worst = 0.0;
        for (double x : tail) worst = std::max(worst, std::abs(sim.step(x) - again.step(x)));
        CHECK(worst < 1e-10);
        CHECK(sim.state() == again.state());
    }
    SUBCASE("reset rejects a state of another range") {
        Simulator sim(t, State::negative_saturation(U_MIN, U_MAX));
        CHECK_THROWS_WITH_AS(sim.reset(State::negative_saturation(U_MIN, U_MAX + 1.0)),
                             doctest::Contains("differs from the model"), std::invalid_argument);
        CHECK_THROWS_AS(Simulator(t, State::negative_saturation(-5.0, U_MAX)), std::invalid_argument);
    }
    SUBCASE("accessors") {
        Simulator sim(t, State::neutral(U_MIN, U_MAX, 0.3));
        CHECK(sim.input() == 0.3);
        CHECK(&sim.table() == &t);
        CHECK(sim.depth() == 1);
    }
}

TEST_CASE("simulator: step and run give identical outputs") {
    const EverettTable t = analytic_table(nonuniform_levels(15));
    std::mt19937 g(109);
    for (int r = 0; r < 20; ++r) {
        const State start = random_start(g);
        const std::vector<double> u = random_walk(g, 500, start.input(), 0.2);
        Simulator a(t, start), b(t, start);
        std::vector<double> ya(u.size()), yb(u.size());
        for (std::size_t k = 0; k < u.size(); ++k) ya[k] = a.step(u[k]);
        b.run(u.data(), yb.data(), u.size(), InputPolicy::raise);
        CHECK(ya == yb);
        CHECK(a.state() == b.state());
        CHECK(a.output() == yb.back());
    }
}

TEST_CASE("simulator: input policy") {
    const EverettTable t = analytic_table(nonuniform_levels(15));
    std::mt19937 g(110);
    std::vector<double> u = random_inputs(g, 20);
    u[5] = U_MAX + 0.7;
    u[9] = U_MIN - 3.0;
    u[14] = U_MAX + 1e-9;
    std::vector<double> clamped = u;
    for (double& x : clamped) x = std::min(std::max(x, U_MIN), U_MAX);
    const State start = State::neutral(U_MIN, U_MAX, 0.2);
    SUBCASE("clamp: out-of-range inputs act as the range ends") {
        Simulator sim(t, start);
        std::vector<double> y(u.size());
        sim.run(u.data(), y.data(), u.size(), InputPolicy::clamp);
        CHECK(y == simulate(t, start, clamped));
        CHECK(y[5] == doctest::Approx(t.y_max()));
        CHECK(y[9] == doctest::Approx(Y_MIN).scale(1.0));
    }
    SUBCASE("raise: the message names the sample") {
        Simulator sim(t, start);
        std::vector<double> y(u.size());
        CHECK_THROWS_WITH_AS(sim.run(u.data(), y.data(), u.size(), InputPolicy::raise),
                             doctest::Contains("input u[5] = "), std::invalid_argument);
        // The samples before the bad one were applied.
        CHECK(sim.input() == u[4]);
        CHECK_THROWS_WITH_AS(sim.step_checked(U_MIN - 1.0, InputPolicy::raise, 77), doctest::Contains("u[77]"),
                             std::invalid_argument);
        CHECK(sim.step_checked(U_MAX, InputPolicy::raise, 0) == doctest::Approx(t.y_max()));  // the ends are inside
    }
    SUBCASE("NaN and inf are rejected under both policies") {
        for (InputPolicy policy : {InputPolicy::clamp, InputPolicy::raise}) {
            std::vector<double> v = clamped;
            v[3] = NaN;
            Simulator sim(t, start);
            std::vector<double> y(v.size());
            CHECK_THROWS_WITH_AS(sim.run(v.data(), y.data(), v.size(), policy),
                                 doctest::Contains("input u[3] is not finite"), std::invalid_argument);
            v[3] = 0.0;
            v[12] = -std::numeric_limits<double>::infinity();
            Simulator sim2(t, start);
            CHECK_THROWS_WITH_AS(sim2.run(v.data(), y.data(), v.size(), policy),
                                 doctest::Contains("input u[12] is not finite"), std::invalid_argument);
        }
    }
}

TEST_CASE("simulator: slopes") {
    const EverettTable t = analytic_table(nonuniform_levels(13));
    std::mt19937 g(111);
    const double d = 1e-7;
    int checked = 0, steps = 0;
    for (int r = 0; r < 60; ++r) {
        Simulator sim(t, random_start(g));
        double prev = sim.input();
        for (double u : random_inputs(g, 40)) {
            sim.step(u);
            const preisach::Slopes sl = sim.slopes();
            CHECK(sl.lower() == std::min(sl.rising, sl.falling));
            CHECK(sl.upper() == std::max(sl.rising, sl.falling));
            // At a reversal the slope in the new direction is that of the diagonal half-cell.
            if (u > prev) {
                CHECK(sl.falling == doctest::Approx(diagonal_slope(t, u)).epsilon(1e-12));
                ++steps;
            } else if (u < prev) {
                CHECK(sl.rising == doctest::Approx(diagonal_slope(t, u)).epsilon(1e-12));
                ++steps;
            }
            prev = u;
            // One-sided finite differences, away from grid lines and memory corners (where the
            // slope jumps).
            bool smooth = dist_to_grid(t, u) > 1e-4 && u - U_MIN > 1e-4 && U_MAX - u > 1e-4;
            const State s = sim.state();
            for (std::size_t k = 0; k < s.pieces().size(); ++k) {
                const Piece& p = s.pieces()[k];
                for (double x : {p.b0, p.phi_start(), p.phi(s.piece_end(k))})
                    if (std::abs(x - u) < 1e-4 && !(k + 1 == s.pieces().size() && x == u)) smooth = false;
                if (p.antidiag && dist_to_grid(t, p.v - u) < 1e-4) smooth = false;
            }
            if (!smooth) continue;
            ++checked;
            Simulator up = sim, down = sim;
            const double y = sim.output();
            const double fd_up = (up.step(u + d) - y) / d, fd_down = (y - down.step(u - d)) / d;
            INFO("case " << r << ", u = " << u);
            CHECK(sl.rising == doctest::Approx(fd_up).epsilon(1e-5).scale(1.0));
            CHECK(sl.falling == doctest::Approx(fd_down).epsilon(1e-5).scale(1.0));
        }
    }
    CHECK(checked > 1000);
    CHECK(steps > 2000);
    SUBCASE("along a branch") {
        // The major descending branch y = y_max - 2 E(u_max, u): slope -2 dE/dbeta(u_max, u), and
        // the one-sided difference along the branch itself, at points inside cells.
        Simulator sim(t, State::positive_saturation(U_MIN, U_MAX));
        for (double u = U_MAX - 0.013; u > U_MIN + 0.02; u -= 0.037) {
            sim.step(u);
            if (dist_to_grid(t, u) < 1e-4) continue;
            Simulator b = sim;
            b.step(u - d);
            const double fd = (sim.output() - b.output()) / d;
            CHECK(sim.slopes().falling == doctest::Approx(fd).epsilon(1e-5));
            CHECK(sim.slopes().falling == doctest::Approx(-2.0 * t.d_beta(U_MAX, u)).epsilon(1e-12));
        }
        CHECK(sim.slopes().rising > 0.0);
    }
    SUBCASE("at the range ends") {
        Simulator lo(t, State::negative_saturation(U_MIN, U_MAX));
        CHECK(lo.slopes().falling == 0.0);
        CHECK(lo.slopes().rising == doctest::Approx(diagonal_slope(t, U_MIN)));
        Simulator hi(t, State::positive_saturation(U_MIN, U_MAX));
        CHECK(hi.slopes().rising == 0.0);
        CHECK(hi.slopes().falling > 0.0);
    }
}

TEST_CASE("simulator: the neutral state is the limit of a decaying oscillation") {
    const EverettTable t = analytic_table(nonuniform_levels(16));
    std::mt19937 g(112);
    const double mid = 0.5 * (U_MIN + U_MAX);
    for (double l : {-0.7, 0.1, mid, 0.9, 1.6}) {
        // Above the middle of the range the neutral boundary starts with the edge alpha = u_max:
        // start from positive saturation and fall first; otherwise from negative saturation.
        const bool high = l > mid;
        const double a0 = high ? U_MAX - l : l - U_MIN;
        const State neutral = State::neutral(U_MIN, U_MAX, l);
        const double y_ref = readout(t, neutral);
        // A later input history that only partly wipes out the memory of the oscillation.
        const std::vector<double> response = random_inputs(g, 40, l - 0.7 * a0, l + 0.7 * a0);
        const std::vector<double> resp_ref = simulate(t, neutral, response);
        std::vector<double> err, resp_err;
        for (double q : {0.7, 0.9, 0.99}) {
            Simulator sim(t, high ? State::positive_saturation(U_MIN, U_MAX) : State::negative_saturation(U_MIN, U_MAX));
            double a = a0;
            int k = 0;
            if (high) {
                a *= q;
                k = 1;
            }
            for (; a > 1e-13 * a0; a *= q, ++k) sim.step(l + (k % 2 == 0 ? a : -a));
            sim.step(l);
            err.push_back(std::abs(sim.output() - y_ref));
            std::vector<double> resp(response.size());
            for (std::size_t i = 0; i < response.size(); ++i) resp[i] = sim.step(response[i]);
            resp_err.push_back(max_abs_diff(resp, resp_ref));
        }
        INFO("l = " << l << ": output errors " << err[0] << ", " << err[1] << ", " << err[2] << "; response errors "
                    << resp_err[0] << ", " << resp_err[1] << ", " << resp_err[2]);
        // The staircase's triangles shrink like (1 - q)^2.
        CHECK(err[1] < 0.5 * err[0]);
        CHECK(err[2] < 0.05 * err[1]);
        CHECK(err[2] < 1e-3);
        CHECK(resp_err[1] < 0.5 * resp_err[0]);
        CHECK(resp_err[2] < 0.05 * resp_err[1]);
        CHECK(resp_err[2] < 1e-3);
    }
}

}  // namespace unity_test_simulator

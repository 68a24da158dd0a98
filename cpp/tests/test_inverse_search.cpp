// Inverter search cost: the binary search over cells (monotone models) finds the same inputs
// as the walk, at a bounded number of cells per step, and the allocation-free antidiagonal
// integral is the sorted-cuts one.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/inverse.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_inverse_search {

using namespace ptest;
using preisach::Inverter;

namespace {

// The integral as it was computed before (collect the cuts, sort them, midpoint rule), with
// the public d_beta (it differs from the table's interior derivative only at a grid line,
// i.e. in sub-intervals one rounding wide).
double antidiagonal_reference(const EverettTable& t, double c, double b0, double b1) {
    if (!(b1 > b0)) return 0.0;
    const auto& L = t.levels();
    std::vector<double> cuts{b0};
    for (auto it = std::upper_bound(L.begin(), L.end(), b0); it != L.end() && *it < b1; ++it) cuts.push_back(*it);
    for (auto it = std::upper_bound(L.begin(), L.end(), c - b1); it != L.end() && *it < c - b0; ++it)
        cuts.push_back(c - *it);
    cuts.push_back(b1);
    std::sort(cuts.begin(), cuts.end());
    double total = 0.0;
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double lo = cuts[k], hi = cuts[k + 1];
        if (!(hi > lo)) continue;
        const double m = 0.5 * (lo + hi);
        total -= t.d_beta(c - m, m) * (hi - lo);
    }
    return total;
}

// A staircase of many pieces: a decaying random oscillation from `s`.
State deep_state(const EverettTable& t, const State& s, std::mt19937& g, int turns) {
    Simulator sim(t, s);
    double lo = U_MIN, hi = U_MAX;
    for (int k = 0; k < turns; ++k) {
        const double w = 0.5 * (hi - lo);
        lo += uniform(g, 0.05, 0.2) * w;
        hi -= uniform(g, 0.05, 0.2) * w;
        sim.step(k % 2 ? lo : hi);
    }
    return sim.state();
}

}  // namespace

TEST_CASE("everett: the merged antidiagonal integral equals the sorted-cuts sum") {
    std::mt19937 g(3);
    for (const auto& levels : {uniform_levels(201), nonuniform_levels(57)}) {
        const EverettTable t = analytic_table(levels);
        for (int k = 0; k < 2000; ++k) {
            const double b0 = uniform(g, U_MIN, U_MAX), b1 = uniform(g, b0, U_MAX);
            // c on a grid line sum now and then (cuts of both kinds coincide)
            const double c = k % 5 == 0 ? levels[k % 50] + levels[(3 * k) % 50] : uniform(g, 2 * U_MIN, 2 * U_MAX);
            const double ref = antidiagonal_reference(t, c, b0, b1);
            CHECK(std::abs(t.antidiagonal_integral(c, b0, b1) - ref) <= 1e-14 * (1.0 + std::abs(ref)));
        }
        CHECK(t.antidiagonal_integral(0.3, 0.5, 0.5) == 0.0);
    }
}

TEST_CASE("inverse: on a 201-level table a step searches a bounded number of cells and is exact") {
    std::mt19937 g(17);
    for (const auto& levels : {uniform_levels(201), nonuniform_levels(201)}) {
        const EverettTable t = analytic_table(levels);
        std::vector<State> starts;
        for (double l : {-0.9, -0.2, 0.5, 1.1, 1.8}) starts.push_back(State::neutral(U_MIN, U_MAX, l));
        starts.push_back(State::negative_saturation(U_MIN, U_MAX));
        starts.push_back(State::positive_saturation(U_MIN, U_MAX));
        starts.push_back(deep_state(t, State::neutral(U_MIN, U_MAX, 0.4), g, 12));
        for (const State& s : starts) {
            const std::size_t pieces = s.pieces().size();
            // full-range jumps both ways, and random jumps
            std::vector<double> u_true{U_MAX - 1e-3, U_MIN + 1e-3};
            for (int k = 0; k < 20; ++k) u_true.push_back(uniform(g, U_MIN, U_MAX));
            for (double u : u_true) {
                const double y = Simulator(t, s).step(u);
                Inverter inv(t, s);
                REQUIRE(inv.monotone());
                const double got = inv.step(y);
                CHECK(std::abs(inv.output() - y) < 1e-9);
                CHECK(std::abs(got - u) < 1e-8);  // mu > 0: the input is unique
                // binary searches leave at most a few cells per stack piece to walk (a walk
                // would visit up to 2 x 200 here)
                CHECK(inv.cells_walked() <= 4 * (pieces + 2));
            }
        }
    }
}

TEST_CASE("inverse: a long random reference on a 201-level table, step by step") {
    std::mt19937 g(23);
    const EverettTable t = analytic_table(uniform_levels(201));
    for (double l : {-0.5, 0.6}) {
        const State s = State::neutral(U_MIN, U_MAX, l);
        const auto u_true = random_walk(g, 3000, s.input(), 0.3);
        const auto y = simulate(t, s, u_true);
        Inverter inv(t, s);
        double err = 0.0, du = 0.0;
        std::size_t worst = 0, over = 0;
        for (std::size_t k = 0; k < y.size(); ++k) {
            const std::size_t before = inv.cells_walked(), depth = inv.depth();
            du = std::max(du, std::abs(inv.step(y[k]) - u_true[k]));
            err = std::max(err, std::abs(inv.output() - y[k]));
            const std::size_t walked = inv.cells_walked() - before;
            worst = std::max(worst, walked);
            if (walked > 4 * (depth + 2)) ++over;  // a few cells per stack piece crossed at most
        }
        CHECK(err < 1e-9);
        CHECK(du < 1e-8);
        CHECK(inv.unreachable() == 0);
        MESSAGE("most cells walked in one step: " << worst);
        CHECK(over == 0);
    }
}

}  // namespace unity_test_inverse_search

// run_batch: threaded runs equal sequential ones; errors name the row.
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_batch {

using namespace ptest;
using preisach::InputPolicy;
using preisach::run_batch;

namespace {

struct Batch {
    std::size_t m, n;
    std::vector<double> U;
    std::vector<State> states;
};

Batch make_batch(std::mt19937& g, std::size_t m, std::size_t n) {
    Batch b{m, n, {}, {}};
    for (std::size_t r = 0; r < m; ++r) {
        b.states.push_back(random_start(g));
        const std::vector<double> row = random_walk(g, n, b.states.back().input(), 0.2);
        b.U.insert(b.U.end(), row.begin(), row.end());
    }
    return b;
}

}  // namespace

TEST_CASE("batch: threaded runs equal sequential runs") {
    const EverettTable t = analytic_table(nonuniform_levels(15));
    std::mt19937 g(201);
    const Batch b = make_batch(g, 7, 300);
    // Sequential reference, row by row.
    std::vector<double> ref(b.m * b.n);
    std::vector<State> ref_final;
    for (std::size_t r = 0; r < b.m; ++r) {
        Simulator sim(t, b.states[r]);
        sim.run(b.U.data() + r * b.n, ref.data() + r * b.n, b.n, InputPolicy::raise);
        ref_final.push_back(sim.state());
    }
    for (unsigned threads : {1u, 2u, 3u, 0u, 64u}) {
        INFO("threads = " << threads);
        std::vector<double> Y(b.m * b.n, std::numeric_limits<double>::quiet_NaN());
        const std::vector<State> finals = run_batch(t, b.states, b.U.data(), Y.data(), b.m, b.n, InputPolicy::raise,
                                                    threads);
        CHECK(Y == ref);
        REQUIRE(finals.size() == b.m);
        for (std::size_t r = 0; r < b.m; ++r) CHECK(finals[r] == ref_final[r]);
    }
    SUBCASE("one state for every row") {
        std::vector<double> Y1(b.m * b.n), Y2(b.m * b.n);
        const std::vector<State> one{b.states[2]};
        run_batch(t, one, b.U.data(), Y1.data(), b.m, b.n, InputPolicy::raise, 1);
        run_batch(t, one, b.U.data(), Y2.data(), b.m, b.n, InputPolicy::raise, 2);
        CHECK(Y1 == Y2);
        for (std::size_t r = 0; r < b.m; ++r) {
            const std::vector<double> row(b.U.begin() + std::ptrdiff_t(r * b.n), b.U.begin() + std::ptrdiff_t((r + 1) * b.n));
            const std::vector<double> y = simulate(t, b.states[2], row);
            CHECK(std::vector<double>(Y2.begin() + std::ptrdiff_t(r * b.n), Y2.begin() + std::ptrdiff_t((r + 1) * b.n)) == y);
        }
    }
    SUBCASE("clamp policy is passed on") {
        Batch c = b;
        c.U[3 * c.n + 10] = U_MAX + 5.0;
        std::vector<double> Y(c.m * c.n);
        run_batch(t, c.states, c.U.data(), Y.data(), c.m, c.n, InputPolicy::clamp, 2);
        CHECK(Y[3 * c.n + 10] == doctest::Approx(t.y_max()));
        CHECK_THROWS_WITH_AS(run_batch(t, c.states, c.U.data(), Y.data(), c.m, c.n, InputPolicy::raise, 2),
                             doctest::Contains("row 3: input u[10]"), std::invalid_argument);
    }
    SUBCASE("empty batch") {
        const std::vector<State> one{b.states[0]};
        const std::vector<State> finals = run_batch(t, one, nullptr, nullptr, 0, 0, InputPolicy::raise, 2);
        CHECK(finals.empty());
    }
}

TEST_CASE("batch: errors name the row") {
    const EverettTable t = analytic_table(nonuniform_levels(15));
    std::mt19937 g(202);
    Batch b = make_batch(g, 6, 50);
    b.U[4 * b.n + 7] = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> Y(b.m * b.n);
    for (unsigned threads : {1u, 2u}) {
        INFO("threads = " << threads);
        CHECK_THROWS_WITH_AS(run_batch(t, b.states, b.U.data(), Y.data(), b.m, b.n, InputPolicy::clamp, threads),
                             "row 4: input u[7] is not finite", std::invalid_argument);
    }
    // Two bad rows: the lowest is reported, whichever thread met it first.
    b.U[1 * b.n + 30] = U_MIN - 1.0;
    for (unsigned threads : {1u, 2u}) {
        CHECK_THROWS_WITH_AS(run_batch(t, b.states, b.U.data(), Y.data(), b.m, b.n, InputPolicy::raise, threads),
                             doctest::Contains("row 1: input u[30] = "), std::invalid_argument);
        CHECK_THROWS_WITH_AS(run_batch(t, b.states, b.U.data(), Y.data(), b.m, b.n, InputPolicy::clamp, threads),
                             doctest::Contains("row 4: "), std::invalid_argument);
    }
    // A bad starting state is reported with its row as well.
    std::vector<State> states = b.states;
    states[2] = State::negative_saturation(U_MIN, U_MAX + 1.0);
    b.U[4 * b.n + 7] = 0.0;
    b.U[1 * b.n + 30] = 0.0;
    CHECK_THROWS_WITH_AS(run_batch(t, states, b.U.data(), Y.data(), b.m, b.n, InputPolicy::raise, 2),
                         doctest::Contains("row 2: state"), std::invalid_argument);
    // The number of states must match.
    const std::vector<State> two(2, State::negative_saturation(U_MIN, U_MAX));
    CHECK_THROWS_WITH_AS(run_batch(t, two, b.U.data(), Y.data(), b.m, b.n, InputPolicy::raise, 2),
                         doctest::Contains("one state or one per input row (6), got 2"), std::invalid_argument);
}

}  // namespace unity_test_batch

// The play operator of preisach/play.hpp (diagnosis: rate-dependent threshold dilation).
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>
#include <preisach/moving.hpp>
#include <preisach/play.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_play {

namespace {

std::vector<double> play(const std::vector<double>& x, const std::vector<double>& w, double z0) {
    std::vector<double> z(x.size());
    preisach::play_operator(x.data(), w.data(), x.size(), z0, z.data());
    return z;
}

// A relay (+1 at u >= a, -1 at u <= b, else hold) over an input sequence.
std::vector<int> relay(const std::vector<double>& u, double a, double b, int start) {
    std::vector<int> out(u.size());
    int s = start;
    for (std::size_t k = 0; k < u.size(); ++k) {
        if (u[k] >= a) s = 1;
        else if (u[k] <= b) s = -1;
        out[k] = s;
    }
    return out;
}

}  // namespace

TEST_CASE("play operator: zero width is the identity, and |z - x| <= w always") {
    std::mt19937 g(7);
    const auto x = ptest::random_walk(g, 5000, 0.3, 0.05);
    std::vector<double> w0(x.size(), 0.0);
    const auto z0 = play(x, w0, 0.0);
    for (std::size_t k = 0; k < x.size(); ++k) CHECK(z0[k] == x[k]);

    std::vector<double> w(x.size());
    for (auto& v : w) v = ptest::uniform(g, 0.0, 0.2);
    const auto z = play(x, w, 5.0);  // starts far away: the first sample pulls it within w
    for (std::size_t k = 0; k < x.size(); ++k) CHECK(std::abs(z[k] - x[k]) <= w[k] + 1e-15);
}

TEST_CASE("play operator: a reversal is seen only after the input moved back by 2 w") {
    // ramp up 0 -> 1, then down; constant half-width 0.1
    std::vector<double> x;
    for (int k = 0; k <= 100; ++k) x.push_back(0.01 * k);
    for (int k = 1; k <= 100; ++k) x.push_back(1.0 - 0.01 * k);
    const std::vector<double> w(x.size(), 0.1);
    const auto z = play(x, w, -0.1);
    CHECK(z[100] == doctest::Approx(0.9));  // lags the rising input by w
    for (int k = 101; k <= 120; ++k) CHECK(z[std::size_t(k)] == doctest::Approx(0.9));  // holds for 2 w
    CHECK(z[130] == doctest::Approx(x[130] + 0.1));  // then follows the falling input w above it
}

TEST_CASE("play operator: a relay driven through a play of width w is a relay with thresholds a + w, b - w") {
    std::mt19937 g(11);
    for (int trial = 0; trial < 20; ++trial) {
        const auto x = ptest::random_walk(g, 3000, 0.5, 0.04);
        const double w = ptest::uniform(g, 0.0, 0.3);
        const double b = ptest::uniform(g, ptest::U_MIN + 0.3, ptest::U_MAX - 0.6);
        const double a = b + ptest::uniform(g, 0.0, 0.5);
        const std::vector<double> wv(x.size(), w);
        // start both at -1 with the play at x[0] - w (the state a rising input leaves)
        const auto z = play(x, wv, x[0] - w);
        const auto r1 = relay(z, a, b, -1);
        const auto r2 = relay(x, a + w, b - w, -1);
        int mismatches = 0;
        for (std::size_t k = 0; k < x.size(); ++k) mismatches += r1[k] != r2[k];
        INFO("trial " << trial << ", w = " << w);
        CHECK(mismatches == 0);
    }
}

TEST_CASE("play operator: errors name the sample") {
    const std::vector<double> x = {0.0, std::numeric_limits<double>::quiet_NaN()};
    const std::vector<double> w = {0.1, 0.1};
    CHECK_THROWS_WITH_AS(play(x, w, 0.0), "x[1] is not finite", std::invalid_argument);
    const std::vector<double> x2 = {0.0, 1.0};
    const std::vector<double> w2 = {0.1, -0.5};
    CHECK_THROWS_AS(play(x2, w2, 0.0), std::invalid_argument);
    CHECK_THROWS_AS(play(x2, w, std::numeric_limits<double>::infinity()), std::invalid_argument);
}

TEST_CASE("moving model: zero feedback is the classical model, feedback equals a hand-written loop") {
    const auto lv = ptest::uniform_levels(15);
    const auto table = ptest::analytic_table(lv);
    std::mt19937 g(5);
    const auto u = ptest::random_walk(g, 2000, 0.5, 0.05);
    const auto s0 = preisach::State::negative_saturation(ptest::U_MIN, ptest::U_MAX);
    std::vector<double> y(u.size()), ue(u.size());
    {
        preisach::Simulator sim(table, s0);
        preisach::simulate_moving(sim, u.data(), u.size(), 0.0, 0.0, 0.0, 1.0, y.data(), ue.data());
        CHECK(ptest::max_abs_diff(y, ptest::simulate(table, s0, u)) == 0.0);
        CHECK(ptest::max_abs_diff(ue, u) == 0.0);
    }
    const double a = 0.05, b = -0.02, c = 0.01, yc = 0.3, span = 2.0;
    preisach::Simulator sim(table, s0);
    preisach::simulate_moving(sim, u.data(), u.size(), a, b, yc, span, y.data(), ue.data(), c);
    preisach::Simulator ref(table, s0);
    double prev = ref.output();
    double worst = 0.0;
    for (std::size_t k = 0; k < u.size(); ++k) {
        const double d = prev - yc, q = d / span;  // a d + b d^2/span + c d^3/span^2, Horner form
        const double e = std::min(std::max(u[k] + d * (a + q * (b + c * q)), ptest::U_MIN), ptest::U_MAX);
        prev = ref.step(e);
        worst = std::max(worst, std::abs(prev - y[k]) + std::abs(e - ue[k]));
    }
    CHECK(worst == 0.0);
    preisach::Simulator bad(table, s0);
    CHECK_THROWS_AS(preisach::simulate_moving(bad, u.data(), u.size(), a, b, yc, 0.0, y.data(), ue.data()),
                    std::invalid_argument);
}

TEST_CASE("feedback spline: reproduces straight lines, is constant outside its range, checks its arguments") {
    const double lo = -1.0, hi = 3.0;
    const std::size_t nc = 7;
    const double h = (hi - lo) / static_cast<double>(nc - 3);
    std::vector<double> c(nc);
    for (std::size_t i = 0; i < nc; ++i) c[i] = 0.3 * (lo + (static_cast<double>(i) - 1.0) * h) - 0.2;
    const preisach::FeedbackSpline f(lo, hi, c.data(), nc);
    for (double y = lo; y <= hi; y += 0.137) CHECK(f(y) == doctest::Approx(0.3 * y - 0.2).epsilon(1e-12));
    CHECK(f(hi) == doctest::Approx(0.3 * hi - 0.2));
    CHECK(f(hi + 5.0) == f(hi));
    CHECK(f(lo - 5.0) == f(lo));
    CHECK_THROWS_AS(preisach::FeedbackSpline(1.0, 1.0, c.data(), nc), std::invalid_argument);
    CHECK_THROWS_AS(preisach::FeedbackSpline(lo, hi, c.data(), 3), std::invalid_argument);
}

TEST_CASE("feedback spline model: a straight-line spline is the linear moving model") {
    const auto lv = ptest::uniform_levels(15);
    const auto table = ptest::analytic_table(lv);
    std::mt19937 g(7);
    const auto u = ptest::random_walk(g, 2000, 0.5, 0.05);
    const auto s0 = preisach::State::negative_saturation(ptest::U_MIN, ptest::U_MAX);
    const double a = 0.04, yc = 0.1;
    // a range wide enough that the output never leaves it (the spline is clamped outside)
    const double lo = -50.0, hi = 50.0;
    const std::size_t nc = 6;
    const double h = (hi - lo) / static_cast<double>(nc - 3);
    std::vector<double> c(nc);
    for (std::size_t i = 0; i < nc; ++i) c[i] = a * (lo + (static_cast<double>(i) - 1.0) * h - yc);
    std::vector<double> y(u.size()), ue(u.size()), y2(u.size()), ue2(u.size());
    preisach::Simulator sim(table, s0);
    preisach::simulate_feedback_spline(sim, u.data(), u.size(), preisach::FeedbackSpline(lo, hi, c.data(), nc),
                                       y.data(), ue.data());
    preisach::Simulator ref(table, s0);
    preisach::simulate_moving(ref, u.data(), u.size(), a, 0.0, yc, 1.0, y2.data(), ue2.data());
    CHECK(ptest::max_abs_diff(ue, ue2) < 1e-12);
    CHECK(ptest::max_abs_diff(y, y2) < 1e-9);
    std::vector<double> bad(u);
    bad[5] = std::numeric_limits<double>::quiet_NaN();
    preisach::Simulator sim2(table, s0);
    CHECK_THROWS_AS(preisach::simulate_feedback_spline(sim2, bad.data(), bad.size(),
                                                       preisach::FeedbackSpline(lo, hi, c.data(), nc), y.data(),
                                                       ue.data()),
                    std::invalid_argument);
}

}  // namespace unity_test_play

// Physics blocks (preisach/blocks): exact discretisation against closed-form responses,
// steady states, seeding, the moving Preisach stage and chains.
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/blocks.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_blocks {

using namespace preisach::blocks;
using preisach::EverettTable;
using preisach::Simulator;
using preisach::State;

namespace {

std::vector<double> step_response(Block& b, std::size_t n, double from = 0.0, double to = 1.0) {
    b.reset(from);
    std::vector<double> y(n);
    for (std::size_t k = 0; k < n; ++k) y[k] = b.step(to);
    return y;
}

std::shared_ptr<const EverettTable> ptable() {
    static const auto t = std::make_shared<const EverettTable>(ptest::analytic_table(ptest::uniform_levels(61)));
    return t;
}

}  // namespace

TEST_CASE("structural mode: exact samples of the second-order step response") {
    const double dt = 1e-3, fn = 37.62, zeta = 0.02;
    StructuralMode m(dt, fn, zeta);
    const auto y = step_response(m, 400);
    const double wn = 2 * M_PI * fn, wd = wn * std::sqrt(1 - zeta * zeta);
    for (std::size_t k = 0; k < y.size(); ++k) {
        const double t = double(k + 1) * dt;  // output at the end of sample interval k
        const double exact = 1 - std::exp(-zeta * wn * t) * (std::cos(wd * t) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(wd * t));
        CHECK(y[k] == doctest::Approx(exact).epsilon(1e-9).scale(1.0));
    }
    // it rings: the first peak overshoots by exp(-pi zeta / sqrt(1 - zeta^2))
    const double peak = *std::max_element(y.begin(), y.end());
    CHECK(peak - 1 == doctest::Approx(std::exp(-M_PI * zeta / std::sqrt(1 - zeta * zeta))).epsilon(0.02));
    // steady state: reset(x0) is an equilibrium
    CHECK(m.reset(0.7) == 0.7);
    for (int k = 0; k < 50; ++k) CHECK(m.step(0.7) == doctest::Approx(0.7).epsilon(1e-12));
    CHECK_THROWS_AS(StructuralMode(dt, 600.0, 0.02), std::invalid_argument);  // above Nyquist
    CHECK_THROWS_AS(StructuralMode(dt, fn, -0.1), std::invalid_argument);
}

TEST_CASE("input lag: exact first-order step response") {
    InputLag lag(1e-3, 5e-3);
    const auto y = step_response(lag, 50);
    for (std::size_t k = 0; k < y.size(); ++k)
        CHECK(y[k] == doctest::Approx(1 - std::exp(-double(k + 1) * 1e-3 / 5e-3)).epsilon(1e-12));
}

TEST_CASE("input lag widens Preisach loops in proportion to the rate") {
    // Loop width (max over the cycle of y_falling - y_rising at equal input) grows with frequency.
    auto width = [](double f) {
        const double dt = 1e-4;
        Chain c([&] {
            std::vector<std::unique_ptr<Block>> b;
            b.push_back(std::make_unique<InputLag>(dt, 2e-3));
            b.push_back(std::make_unique<PreisachStage>(dt, ptable(), State::negative_saturation(-1, 2)));
            return b;
        }());
        c.reset(-1.0);
        const std::size_t n = std::size_t(std::lround(2.0 / f / dt));
        double area = 0.0, u_old = 0.5, y_old = c.step(0.5);
        for (std::size_t k = 1; k <= n; ++k) {
            const double u = 0.5 + 1.5 * std::sin(2 * M_PI * f * double(k) * dt);
            const double y = c.step(u);
            if (double(k) * dt > 1.0 / f) area += 0.5 * (y + y_old) * (u - u_old);  // second cycle
            u_old = u;
            y_old = y;
        }
        return std::abs(area);
    };
    const double a1 = width(1.0), a20 = width(20.0);
    CHECK(a20 > a1 * 1.05);
}

TEST_CASE("creep: logarithmic approach to the input after a step") {
    const double dt = 1e-2;
    Creep c(dt, 0.02, 0.1, 100.0);
    CHECK(c.n_lags() == 4);
    const auto y = step_response(c, 100000);
    CHECK(y.front() == doctest::Approx(1 - 4 * 0.02).epsilon(0.01));  // first move (1 - n rate)
    for (std::size_t k = 1; k < y.size(); ++k) CHECK(y[k] >= y[k - 1]);  // monotone creep
    CHECK(y.back() == doctest::Approx(1.0).epsilon(1e-6));  // equilibrium is the input
    // about `rate` per decade between tau_min and tau_max: y(10 s) - y(1 s) ~ 0.02
    const double d = y[999] - y[99];
    CHECK(d > 0.012);
    CHECK(d < 0.028);
    CHECK_THROWS_AS(Creep(dt, 0.3, 0.1, 100.0), std::invalid_argument);
}

TEST_CASE("delay and moving average") {
    Delay d(1e-3, 3);
    d.reset(-1.0);
    std::vector<double> x{1, 2, 3, 4, 5, 6}, y(x.size());
    d.run(x.data(), y.data(), x.size());
    CHECK(y == std::vector<double>{-1, -1, -1, 1, 2, 3});
    Delay none(1e-3, 0);
    CHECK(none.step(4.5) == 4.5);

    MovingAverage m(1e-3, 10);
    m.reset(0.0);
    std::mt19937 g(3);
    std::vector<double> u(5000);
    for (auto& v : u) v = ptest::uniform(g, -1e3, 1e3);
    std::vector<double> out(u.size());
    m.run(u.data(), out.data(), u.size());
    for (std::size_t k = 9; k < u.size(); ++k) {
        double s = 0;
        for (std::size_t j = k - 9; j <= k; ++j) s += u[j];
        CHECK(out[k] == doctest::Approx(s / 10).epsilon(1e-12).scale(1.0));
    }
    CHECK_THROWS_AS(MovingAverage(1e-3, 0), std::invalid_argument);
}

TEST_CASE("offset drift: linear rate exactly, random walk seeded and reproducible") {
    OffsetDrift lin(1e-3, 0.5, 0.0, 1);
    lin.reset(0.0);
    double y = 0;
    for (int k = 0; k < 1000; ++k) y = lin.step(2.0);
    CHECK(y == doctest::Approx(2.0 + 0.5).epsilon(1e-9));

    OffsetDrift rw(1e-3, 0.0, 0.01, 42), rw2(1e-3, 0.0, 0.01, 42), other(1e-3, 0.0, 0.01, 43);
    std::vector<double> x(20000, 0.0), a(x.size()), b(x.size()), c(x.size());
    rw.reset(0);
    rw2.reset(0);
    other.reset(0);
    rw.run(x.data(), a.data(), x.size());
    rw2.run(x.data(), b.data(), x.size());
    other.run(x.data(), c.data(), x.size());
    CHECK(a == b);
    CHECK(a != c);
    rw.reset(0);
    rw.run(x.data(), b.data(), x.size());
    CHECK(a == b);  // reset re-seeds
    // variance of the increments over 1 s is sigma^2 (within sampling error)
    double s2 = 0;
    std::size_t n = 0;
    for (std::size_t k = 1000; k < a.size(); k += 1000, ++n) s2 += (a[k] - a[k - 1000]) * (a[k] - a[k - 1000]);
    CHECK(std::sqrt(s2 / double(n)) == doctest::Approx(0.01).epsilon(0.5));
}

TEST_CASE("preisach stage: equals the simulator without feedback, moving gain breaks congruency") {
    const auto t = ptable();
    const State s0 = State::negative_saturation(-1, 2);
    PreisachStage st(1e-3, t, s0, 0.0);
    Simulator sim(*t, s0);
    std::mt19937 g(7);
    const auto u = ptest::random_walk(g, 3000, 0.0, 0.05);
    for (double v : u) CHECK(st.step(v) == sim.step_checked(v, preisach::InputPolicy::clamp, 0));
    CHECK(st.state() == sim.state());

    // Minor loop between 0 and 1 after two histories (max 1.2 then max 2): heights of the
    // loop (y(1) - y(0) on the rising branch) are equal for the classical model, not for
    // the moving one.
    auto loop_height = [&](double k, double peak) {
        PreisachStage p(1e-3, t, s0, k);
        for (double v : {peak, 0.0, 1.0, 0.0}) p.step(v);
        const double y0 = p.output();
        p.step(1.0);
        return p.output() - y0;
    };
    CHECK(loop_height(0.0, 1.2) == doctest::Approx(loop_height(0.0, 2.0)).epsilon(1e-12));
    CHECK(std::abs(loop_height(0.1, 1.2) - loop_height(0.1, 2.0)) > 1e-3);
    CHECK_THROWS_AS(st.step(std::nan("")), std::invalid_argument);
}

TEST_CASE("chain: run equals stepping, copies are independent, sample times must agree") {
    const double dt = 1e-3;
    std::vector<std::unique_ptr<Block>> b;
    b.push_back(std::make_unique<InputLag>(dt, 3e-3));
    b.push_back(std::make_unique<PreisachStage>(dt, ptable(), State::negative_saturation(-1, 2), 0.05));
    b.push_back(std::make_unique<StructuralMode>(dt, 37.62, 0.05));
    b.push_back(std::make_unique<Creep>(dt, 0.01, 0.1, 10.0));
    b.push_back(std::make_unique<OffsetDrift>(dt, 1e-3, 1e-3, 5));
    b.push_back(std::make_unique<Delay>(dt, 2));
    b.push_back(std::make_unique<MovingAverage>(dt, 5));
    Chain c(std::move(b));
    Chain copy = c;
    std::mt19937 g(11);
    const auto u = ptest::random_walk(g, 4000, 0.5, 0.03);
    std::vector<double> y1(u.size()), y2(u.size());
    c.reset(u[0]);
    for (std::size_t k = 0; k < u.size(); ++k) y1[k] = c.step(u[k]);
    copy.reset(u[0]);
    copy.run(u.data(), y2.data(), u.size());
    for (std::size_t k = 0; k < u.size(); ++k) CHECK(y2[k] == doctest::Approx(y1[k]).epsilon(1e-12).scale(1.0));
    REQUIRE(c.preisach() != nullptr);
    CHECK(c.preisach()->moving_gain() == 0.05);

    std::vector<std::unique_ptr<Block>> bad;
    bad.push_back(std::make_unique<InputLag>(1e-3, 1e-3));
    bad.push_back(std::make_unique<Delay>(2e-3, 1));
    CHECK_THROWS_AS(Chain(std::move(bad)), std::invalid_argument);
}

}  // namespace unity_test_blocks

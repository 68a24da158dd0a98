// Rate-dependent model: K = 1 is the classical simulator bit for bit, a constant rate is the
// classical model of the blended table, wiping-out holds, the basis is a partition of unity,
// the filter is the stated first-order low-pass, and batch/closed-loop runs match single runs.
#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_rate_dependent {

using namespace ptest;
using preisach::ClosedLoopConfig;
using preisach::InputPolicy;
using preisach::RateBasis;
using preisach::RateDependentModel;
using preisach::RateSimulator;

namespace {

// A second and third analytic table on the same grid: scaled and sheared copies of E_exact.
EverettTable scaled_table(const Eigen::VectorXd& lv, double scale, double shear, double y_min) {
    const Eigen::Index n = lv.size();
    RowMatrixXd v = RowMatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < i; ++j)
            v(i, j) = scale * E_exact(lv[i], lv[j]) + shear * (lv[i] - lv[j]) * (lv[i] - lv[j]) * lv[i];
    return EverettTable(lv, v, y_min);
}

RateDependentModel three_tables(const Eigen::VectorXd& lv, double tau,
                                preisach::RateScale scale = preisach::RateScale::log) {
    return RateDependentModel({scaled_table(lv, 1.0, 0.0, Y_MIN), scaled_table(lv, 1.3, 0.05, Y_MIN - 0.2),
                               scaled_table(lv, 1.8, -0.04, Y_MIN - 0.5)},
                              {10.0, 20.0, 40.0}, tau, scale);
}

// A walk whose step size is constant: |du| = h every sample, reflected at the range ends
// only by reversing (so the rate stays h / dt).
std::vector<double> constant_rate_walk(std::mt19937& g, std::size_t n, double start, double h) {
    std::vector<double> u(n);
    double x = start, dir = 1.0;
    std::uniform_real_distribution<double> coin(0.0, 1.0);
    for (std::size_t k = 0; k < n; ++k) {
        if (coin(g) < 0.02) dir = -dir;
        if (x + dir * h > U_MAX || x + dir * h < U_MIN) dir = -dir;
        x += dir * h;
        u[k] = x;
    }
    return u;
}

}  // namespace

TEST_CASE("rate basis: hat functions in ln(rate), a partition of unity, constant outside the knots") {
    const RateBasis b(std::vector<double>{400.0, 800.0, 1600.0});
    double w[3];
    b.weights(0.0, w);
    CHECK(w[0] == 1.0);
    CHECK(w[1] == 0.0);
    b.weights(100.0, w);
    CHECK(w[0] == 1.0);
    b.weights(800.0, w);
    CHECK(w[1] == doctest::Approx(1.0).epsilon(1e-14));
    b.weights(400.0 * std::sqrt(2.0), w);  // halfway in ln between 400 and 800
    CHECK(w[0] == doctest::Approx(0.5).epsilon(1e-12));
    CHECK(w[1] == doctest::Approx(0.5).epsilon(1e-12));
    CHECK(w[2] == 0.0);
    b.weights(1e6, w);
    CHECK(w[2] == 1.0);
    std::mt19937 g(3);
    for (int k = 0; k < 200; ++k) {
        b.weights(std::exp(uniform(g, 4.0, 9.0)), w);
        CHECK(w[0] + w[1] + w[2] == doctest::Approx(1.0).epsilon(1e-14));
        CHECK(std::min({w[0], w[1], w[2]}) >= 0.0);
    }
    CHECK_THROWS_AS(RateBasis(std::vector<double>{}), std::invalid_argument);
    CHECK_THROWS_AS(RateBasis(std::vector<double>{2.0, 1.0}), std::invalid_argument);
    CHECK_THROWS_AS(RateBasis(std::vector<double>{0.0, 1.0}), std::invalid_argument);
}

TEST_CASE("rate basis: linear scale interpolates in the rate itself") {
    const RateBasis b(std::vector<double>{400.0, 800.0, 1600.0}, preisach::RateScale::linear);
    CHECK(b.scale() == preisach::RateScale::linear);
    double w[3];
    b.weights(600.0, w);  // halfway between 400 and 800 in v
    CHECK(w[0] == doctest::Approx(0.5).epsilon(1e-14));
    CHECK(w[1] == doctest::Approx(0.5).epsilon(1e-14));
    b.weights(1200.0, w);
    CHECK(w[1] == doctest::Approx(0.5).epsilon(1e-14));
    CHECK(w[2] == doctest::Approx(0.5).epsilon(1e-14));
    b.weights(100.0, w);
    CHECK(w[0] == 1.0);
    b.weights(2000.0, w);
    CHECK(w[2] == 1.0);
    // the log scale differs between the knots (ln-midpoint 400 sqrt 2 is not the v-midpoint)
    const RateBasis l(std::vector<double>{400.0, 800.0, 1600.0});
    double wl[3];
    l.weights(600.0, wl);
    CHECK(wl[1] > w[1] + 0.05);
    CHECK(preisach::parse_rate_scale("linear") == preisach::RateScale::linear);
    CHECK(std::string(preisach::rate_scale_name(preisach::RateScale::log)) == "log");
    CHECK_THROWS_AS(preisach::parse_rate_scale("ln"), std::invalid_argument);
}

TEST_CASE("rate model: one table is the classical simulator, bit for bit") {
    const auto lv = nonuniform_levels(37);
    const EverettTable t = analytic_table(lv);
    const RateDependentModel m({t}, {123.0}, 0.01);
    std::mt19937 g(11);
    for (int trial = 0; trial < 20; ++trial) {
        const State s0 = random_start(g);
        const auto u = trial % 2 ? random_walk(g, 3000, s0.input(), 0.05) : random_inputs(g, 500);
        Simulator ref(t, s0);
        RateSimulator sim(m, s0, uniform(g, 0.0, 1000.0), 1e-3);
        CHECK(sim.output() == ref.output());
        for (double x : u) {
            const double y = sim.step(x), yr = ref.step(x);
            REQUIRE(y == yr);
        }
        CHECK(sim.state() == ref.state());
        CHECK(sim.slopes().rising == ref.slopes().rising);
        CHECK(sim.slopes().falling == ref.slopes().falling);
    }
}

TEST_CASE("rate model: a constant rate is the classical model of the blended table") {
    const auto lv = uniform_levels(31);
    const auto m = three_tables(lv, 0.005);
    const double dt = 1e-3;
    std::mt19937 g(5);
    for (double rate : {5.0, 10.0, 14.0, 20.0, 31.0, 40.0, 90.0}) {
        const double h = rate * dt;
        const State s0 = State::neutral(U_MIN, U_MAX, 0.3);
        const auto u = constant_rate_walk(g, 4000, 0.3, h);
        const EverettTable blend = m.blended(rate);
        RateSimulator sim(m, s0, rate, dt);  // the filter starts at the rate it will see
        Simulator ref(blend, s0);
        double worst = 0.0;
        for (double x : u) worst = std::max(worst, std::abs(sim.step(x) - ref.step(x)));
        CHECK(worst < 1e-9);
        CHECK(sim.rate() == doctest::Approx(rate).epsilon(1e-9));
        CHECK(sim.state() == ref.state());
    }
}

TEST_CASE("rate model: the read-outs of the tables follow the shared boundary") {
    const auto lv = nonuniform_levels(25);
    const auto m = three_tables(lv, 0.02);
    std::mt19937 g(17);
    for (int trial = 0; trial < 10; ++trial) {
        const State s0 = random_start(g);
        const auto u = random_walk(g, 2000, s0.input(), 0.08);
        RateSimulator sim(m, s0, 0.0, 1e-3);
        std::vector<Simulator> refs;
        for (std::size_t k = 0; k < 3; ++k) refs.emplace_back(m.table(k), s0);
        double worst = 0.0, worst_y = 0.0;
        for (double x : u) {
            const double y = sim.step(x);
            double yy = 0.0;
            for (std::size_t k = 0; k < 3; ++k) {
                const double r = refs[k].step(x);
                worst = std::max(worst, std::abs(sim.readouts()[k] - r));
                yy += sim.weights()[k] * r;
            }
            worst_y = std::max(worst_y, std::abs(y - yy));
        }
        CHECK(worst < 1e-12);
        CHECK(worst_y < 1e-12);
    }
}

TEST_CASE("rate model: the filter is the stated first-order low-pass of |du/dt|") {
    const auto lv = uniform_levels(11);
    const double tau = 0.05, dt = 1e-3;
    const auto m = three_tables(lv, tau);
    RateSimulator sim(m, State::negative_saturation(U_MIN, U_MAX), 0.0, dt);
    std::vector<double> u(300), v(300), v2(300), y(300);
    for (std::size_t k = 0; k < u.size(); ++k) u[k] = U_MIN + 0.01 * double(k + 1);  // 10 V/s ramp
    sim.run(u.data(), y.data(), u.size(), InputPolicy::raise, v.data());
    preisach::filter_rate(u.data(), v2.data(), u.size(), U_MIN, 0.0, dt, tau);
    for (std::size_t k = 0; k < u.size(); ++k) {
        CHECK(v[k] == v2[k]);
        CHECK(v[k] == doctest::Approx(10.0 * (1.0 - std::exp(-double(k + 1) * dt / tau))).epsilon(1e-9));
    }
    // held input: the rate decays with tau and the output relaxes to the slowest table's
    std::vector<double> hold(2000, u.back()), yh(2000), vh(2000);
    sim.run(hold.data(), yh.data(), hold.size(), InputPolicy::raise, vh.data());
    CHECK(vh.back() == doctest::Approx(sim.rate()));
    CHECK(vh[99] == doctest::Approx(v.back() * std::exp(-0.1 / tau)).epsilon(1e-9));
    CHECK(yh.back() == doctest::Approx(readout(m.table(0), sim.state())).epsilon(1e-12));
    CHECK_THROWS_AS(RateSimulator(m, State::negative_saturation(U_MIN, U_MAX), -1.0, dt), std::invalid_argument);
    CHECK_THROWS_AS(RateSimulator(m, State::negative_saturation(U_MIN, U_MAX), 0.0, 0.0), std::invalid_argument);
}

TEST_CASE("rate model: wiping-out holds for any rate history") {
    const auto lv = uniform_levels(41);
    const auto m = three_tables(lv, 0.0);  // tau = 0: the rate is that of the last step
    const double dt = 1e-3;
    std::mt19937 g(23);
    for (int trial = 0; trial < 20; ++trial) {
        RateSimulator a(m, State::negative_saturation(U_MIN, U_MAX), 0.0, dt);
        RateSimulator b(m, State::negative_saturation(U_MIN, U_MAX), 0.0, dt);
        const double top = uniform(g, 0.5, 1.8), bottom = uniform(g, -0.9, 0.0);
        a.step(top);
        a.step(bottom);
        b.step(top);
        b.step(bottom);
        // b: minor excursions inside (bottom, top) at random rates, then both go to the same
        // final input with the same last step (so the same rate)
        for (int k = 0; k < 30; ++k) b.step(uniform(g, bottom + 1e-6, top - 1e-6));
        b.step(bottom + 0.25 * (top - bottom));
        a.step(bottom + 0.25 * (top - bottom));
        const double final_u = top + 0.05;
        const double ya = a.step(final_u), yb = b.step(final_u);
        CHECK(a.state() == b.state());
        CHECK(ya == doctest::Approx(yb).epsilon(1e-12));
    }
}

TEST_CASE("rate model: validation") {
    const auto lv = uniform_levels(11);
    const auto lv2 = uniform_levels(12);
    CHECK_THROWS_AS(RateDependentModel({}, {}, 0.0), std::invalid_argument);
    CHECK_THROWS_AS(RateDependentModel({analytic_table(lv)}, {1.0, 2.0}, 0.0), std::invalid_argument);
    CHECK_THROWS_AS(RateDependentModel({analytic_table(lv), analytic_table(lv2)}, {1.0, 2.0}, 0.0),
                    std::invalid_argument);
    CHECK_THROWS_AS(RateDependentModel({analytic_table(lv)}, {1.0}, -1.0), std::invalid_argument);
    const auto m = three_tables(lv, 0.0);
    RateSimulator sim(m, State::negative_saturation(U_MIN, U_MAX), 0.0, 1e-3);
    CHECK_THROWS_AS(sim.step_checked(U_MAX + 1.0, InputPolicy::raise, 0), std::invalid_argument);
    const double y_top = sim.step_checked(U_MAX + 1.0, InputPolicy::clamp, 0);
    CHECK(y_top == sim.output());
    CHECK(y_top == doctest::Approx(m.table(2).y_max()).epsilon(1e-12));  // a 3000 V/s step: the fastest table
    CHECK(sim.input() == U_MAX);
    CHECK_THROWS_AS(RateSimulator(m, State::negative_saturation(-5.0, 5.0), 0.0, 1e-3), std::invalid_argument);
}

TEST_CASE("rate model: batch and closed-loop batch equal single runs") {
    const auto lv = uniform_levels(21);
    const auto m = three_tables(lv, 0.01);
    std::mt19937 g(31);
    const std::size_t rows = 5, n = 800;
    std::vector<double> U(rows * n), Y(rows * n), V(rows * n);
    for (std::size_t r = 0; r < rows; ++r) {
        const auto u = random_walk(g, n, 0.0, 0.03);
        std::copy(u.begin(), u.end(), U.begin() + std::ptrdiff_t(r * n));
    }
    const State s0 = State::neutral(U_MIN, U_MAX, 0.0);
    const auto res = preisach::run_rate_batch(m, {s0}, {7.0}, 1e-3, U.data(), Y.data(), V.data(), rows, n,
                                              InputPolicy::clamp, 2);
    for (std::size_t r = 0; r < rows; ++r) {
        RateSimulator sim(m, s0, 7.0, 1e-3);
        for (std::size_t k = 0; k < n; ++k) REQUIRE(sim.step(U[r * n + k]) == Y[r * n + k]);
        CHECK(sim.state() == res.states[r]);
        CHECK(sim.rate() == res.rates[r]);
    }
    ClosedLoopConfig cfg;
    cfg.setpoint = 0.5;
    cfg.kp = 0.02;
    cfg.ki = 5.0;
    cfg.sample_time = 1e-3;
    cfg.enable_at = 100;
    std::vector<double> Uo(rows * n), Ua(rows * n), Yc(rows * n), UC(rows * n);
    for (std::size_t i = 0; i < Uo.size(); ++i) Uo[i] = 0.2 + 0.05 * (U[i] - 0.5);
    preisach::run_rate_closed_loop_batch(m, {s0}, {0.0}, Uo.data(), Ua.data(), Yc.data(), UC.data(), rows, n, cfg,
                                         InputPolicy::clamp, 2);
    for (std::size_t r = 0; r < rows; ++r) {
        RateSimulator sim(m, s0, 0.0, 1e-3);
        std::vector<double> u(n), y(n), uc(n);
        preisach::run_rate_closed_loop(sim, Uo.data() + r * n, u.data(), y.data(), uc.data(), n, cfg,
                                       InputPolicy::clamp);
        for (std::size_t k = 0; k < n; ++k) REQUIRE(y[k] == Yc[r * n + k]);
        CHECK(std::abs(0.5 - y.back()) < 0.05);  // the PI loop regulates
    }
    CHECK_THROWS_AS(preisach::run_rate_batch(m, {s0, s0}, {0.0, 0.0}, 1e-3, U.data(), Y.data(), nullptr, rows, n,
                                             InputPolicy::clamp),
                    std::invalid_argument);
}

TEST_CASE("rate model: the stacked regression rows reproduce the simulated output") {
    for (const auto scale : {preisach::RateScale::log, preisach::RateScale::linear}) {
        CAPTURE(preisach::rate_scale_name(scale));
        const auto lv = uniform_levels(9);
        const auto m = three_tables(lv, 0.01, scale);
        const double dt = 1e-3;
        std::mt19937 g(41);
        const std::size_t n = 3000;
        std::vector<double> u(n), y(n);
        // a walk whose speed changes: rates across all three knots
        double x = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            const double speed = 0.004 + 0.05 * std::abs(std::sin(double(k) * 0.003));
            x += speed * (std::sin(double(k) * 0.02) > 0 ? 1.0 : -1.0);
            x = std::min(std::max(x, U_MIN), U_MAX);
            u[k] = x;
        }
        const State s0 = State::neutral(U_MIN, U_MAX, 0.0);
        RateSimulator sim(m, s0, 0.0, dt);
        for (std::size_t k = 0; k < n; ++k) y[k] = sim.step(u[k]);
        preisach::RateRegression rr;
        rr.knots = m.knots();
        rr.scale = m.scale();
        rr.tau = m.tau();
        rr.sample_time = dt;
        const std::size_t nl = std::size_t(lv.size()), p1 = nl * (nl - 1) / 2 + 1, p = 3 * p1;
        std::vector<double> G(p * p), b(p), yy(1), ys(1);
        std::vector<std::int64_t> cnt(1);
        std::vector<std::int32_t> fold(n, 0);
        State fin;
        double vfin = -1.0;
        preisach::accumulate_rate_normal_equations_into(lv, s0, u.data(), y.data(), fold.data(), n, 1,
                                                        InputPolicy::raise, rr,
                                                        {G.data(), b.data(), yy.data(), ys.data(), cnt.data()}, &fin,
                                                        &vfin);
        Eigen::VectorXd theta = Eigen::VectorXd::Zero(Eigen::Index(p));
        for (std::size_t k = 0; k < 3; ++k) {
            const EverettTable& t = m.table(k);
            for (std::size_t i = 1; i < std::size_t(lv.size()); ++i)
                for (std::size_t j = 0; j < i; ++j)
                    theta[Eigen::Index(k * p1 + preisach::EverettRegressor::node_index(i, j))] = t.node(i, j);
            theta[Eigen::Index(k * p1 + p1 - 1)] = t.y_min();
        }
        const Eigen::Map<const preisach::RowMatrixXd> Gm(G.data(), Eigen::Index(p), Eigen::Index(p));
        const Eigen::Map<const Eigen::VectorXd> bm(b.data(), Eigen::Index(p));
        const double rss = theta.dot(Gm * theta) - 2.0 * theta.dot(bm) + yy[0];
        CHECK(std::abs(rss) < 1e-8 * yy[0]);
        CHECK(cnt[0] == std::int64_t(n));
        CHECK(fin == sim.state());
        CHECK(vfin == doctest::Approx(sim.rate()).epsilon(1e-12));
    }
}

TEST_CASE("rate stage: a block that is the rate simulator, in a chain with other blocks") {
    const auto lv = uniform_levels(15);
    const auto m = std::make_shared<const RateDependentModel>(three_tables(lv, 0.01, preisach::RateScale::linear));
    const double dt = 1e-3;
    const State s0 = State::neutral(U_MIN, U_MAX, 0.1);
    std::mt19937 g(17);
    const auto u = random_walk(g, 1500, 0.0, 0.02);
    preisach::blocks::RateStage stage(dt, m, s0, 12.0);
    CHECK(stage.kind() == "rate_preisach");
    RateSimulator sim(*m, s0, 12.0, dt);
    for (std::size_t k = 0; k < 700; ++k) REQUIRE(stage.step(u[k]) == sim.step(u[k]));
    // a clone continues exactly; reset returns to the starting state and rate
    const auto copy = stage.clone();
    for (std::size_t k = 700; k < u.size(); ++k) REQUIRE(copy->step(u[k]) == sim.step(u[k]));
    CHECK(stage.reset(0.0) == doctest::Approx(RateSimulator(*m, s0, 12.0, dt).output()).epsilon(1e-15));
    CHECK(stage.rate() == 12.0);
    CHECK(stage.state() == s0);
    // inputs outside the range are clamped; NaN raises
    CHECK(stage.step(U_MAX + 5.0) == doctest::Approx(stage.step(U_MAX)).epsilon(1e-12));
    CHECK_THROWS_AS(stage.step(std::nan("")), std::invalid_argument);
    CHECK_THROWS_AS(stage.set_initial_state(s0, -1.0), std::invalid_argument);
    // in a chain after an input lag: the same as lag then simulator
    std::vector<std::unique_ptr<preisach::blocks::Block>> blocks;
    blocks.push_back(std::make_unique<preisach::blocks::InputLag>(dt, 2e-3));
    blocks.push_back(std::make_unique<preisach::blocks::RateStage>(dt, m, s0, 0.0));
    preisach::blocks::Chain chain(std::move(blocks));
    chain.reset(0.1);
    preisach::blocks::InputLag lag(dt, 2e-3);
    lag.reset(0.1);
    RateSimulator ref(*m, s0, 0.0, dt);
    for (std::size_t k = 0; k < u.size(); ++k) REQUIRE(chain.step(u[k]) == ref.step(lag.step(u[k])));
}

TEST_CASE("rate stage: the PI loop around a chain is the rate model's closed loop") {
    const auto lv = uniform_levels(15);
    const auto m = std::make_shared<const RateDependentModel>(three_tables(lv, 0.01));
    const double dt = 1e-3;
    const State s0 = State::neutral(U_MIN, U_MAX, 0.0);
    ClosedLoopConfig cfg;
    cfg.setpoint = 0.4;
    cfg.kp = 0.02;
    cfg.ki = 5.0;
    cfg.sample_time = dt;
    cfg.average = 5;
    cfg.enable_at = 50;
    const std::size_t n = 900;
    std::vector<double> uo(n);
    for (std::size_t k = 0; k < n; ++k) uo[k] = 0.3 + 0.2 * std::sin(double(k) * 0.05);
    std::vector<double> u1(n), y1(n), c1(n), u2(n), y2(n), c2(n);
    RateSimulator sim(*m, s0, 0.0, dt);
    preisach::run_rate_closed_loop(sim, uo.data(), u1.data(), y1.data(), c1.data(), n, cfg, InputPolicy::clamp);
    std::vector<std::unique_ptr<preisach::blocks::Block>> blocks;
    blocks.push_back(std::make_unique<preisach::blocks::RateStage>(dt, m, s0, 0.0));
    preisach::blocks::Chain chain(std::move(blocks));
    preisach::run_pi_loop([&](double v, std::size_t) { return chain.step(v); }, m->u_min(), m->u_max(), uo.data(),
                          u2.data(), y2.data(), c2.data(), n, cfg, InputPolicy::clamp);
    for (std::size_t k = 0; k < n; ++k) {
        REQUIRE(u1[k] == u2[k]);
        REQUIRE(y1[k] == y2[k]);
        REQUIRE(c1[k] == c2[k]);
    }
}

}  // namespace unity_test_rate_dependent

// PI controller and closed-loop runner (control.hpp), neutral locus (neutral.hpp): controller
// arithmetic against Eq 5.2 by hand, error averaging, the loop against a plain reference loop,
// batch = single runs for any thread count, regulation to the setpoint, and N(l).
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <doctest/doctest.h>

#include <preisach/control.hpp>
#include <preisach/neutral.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_control {

using namespace ptest;
using preisach::ClosedLoopConfig;
using preisach::InputPolicy;
using preisach::PIController;

namespace {

const EverettTable& table() {
    static const EverettTable t = analytic_table(uniform_levels(61));
    return t;
}

// The loop of control.hpp written out plainly, with its own moving average and integral.
void reference_loop(const EverettTable& t, const State& s0, const std::vector<double>& u_open,
                    const ClosedLoopConfig& c, std::vector<double>& u, std::vector<double>& y,
                    std::vector<double>& uc) {
    Simulator sim(t, s0);
    const std::size_t n = u_open.size();
    u.assign(n, 0.0);
    y.assign(n, 0.0);
    uc.assign(n, 0.0);
    std::vector<double> errors;
    double integral = 0.0, prev = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        double v = u_open[k] + c.input_gain * prev;
        v = std::min(std::max(v, t.u_min()), t.u_max());
        u[k] = v;
        y[k] = sim.step(v);
        errors.push_back(c.setpoint - y[k]);
        const std::size_t m = std::min(errors.size(), c.average);
        double avg = 0.0;
        for (std::size_t j = errors.size() - m; j < errors.size(); ++j) avg += errors[j];
        avg /= double(m);
        if (k >= c.enable_at) {
            integral += avg;
            prev = c.kp * avg + c.ki * c.sample_time * integral;
        } else {
            prev = 0.0;
        }
        uc[k] = prev;
    }
}

std::vector<double> noisy_hold(std::mt19937& g, std::size_t n, double offset, double amp) {
    std::vector<double> u(n, offset);
    for (std::size_t k = n / 4; k < n; ++k) u[k] += uniform(g, -amp, amp);
    return u;
}

}  // namespace

TEST_CASE("PIController implements Eq 5.2 sample by sample") {
    PIController pi(2.0, 10.0, 0.1);
    CHECK(pi.update(1.0) == doctest::Approx(2.0 * 1.0 + 10.0 * 0.1 * 1.0));
    CHECK(pi.update(0.5) == doctest::Approx(2.0 * 0.5 + 10.0 * 0.1 * 1.5));
    CHECK(pi.update(-2.0) == doctest::Approx(2.0 * -2.0 + 10.0 * 0.1 * -0.5));
    CHECK(pi.integral() == doctest::Approx(-0.5));
    CHECK(pi.output() == doctest::Approx(-4.5));
    pi.reset();
    CHECK(pi.integral() == 0.0);
    CHECK(pi.update(1.0) == doctest::Approx(3.0));
}

TEST_CASE("PIController averages the error over the last N samples") {
    PIController pi(1.0, 0.0, 1e-3, 3);
    CHECK(pi.update(3.0) == doctest::Approx(3.0));           // mean of {3}
    CHECK(pi.update(6.0) == doctest::Approx(4.5));           // {3, 6}
    CHECK(pi.update(9.0) == doctest::Approx(6.0));           // {3, 6, 9}
    CHECK(pi.update(12.0) == doctest::Approx(9.0));          // {6, 9, 12}
    CHECK(pi.integral() == doctest::Approx(3.0 + 4.5 + 6.0 + 9.0));
    // observe fills the window without integrating
    PIController q(0.0, 1.0, 1.0, 2);
    CHECK(q.observe(4.0) == doctest::Approx(4.0));
    CHECK(q.integral() == 0.0);
    CHECK(q.update(2.0) == doctest::Approx(3.0));            // (4 + 2) / 2, integral 3
    // a long run: the running sum stays exact (recomputed every window)
    PIController r(1.0, 0.0, 1.0, 7);
    double last = 0.0;
    for (int k = 0; k < 10000; ++k) last = r.update(1e6 + (k % 7));
    CHECK(last == doctest::Approx(1e6 + 3.0).epsilon(1e-14));
}

TEST_CASE("PIController rejects bad parameters") {
    CHECK_THROWS_AS(PIController(1.0, 1.0, 0.0), std::invalid_argument);
    CHECK_THROWS_AS(PIController(1.0, 1.0, -1e-3), std::invalid_argument);
    CHECK_THROWS_AS(PIController(NAN, 1.0, 1e-3), std::invalid_argument);
    CHECK_THROWS_AS(PIController(1.0, 1.0, 1e-3, 0), std::invalid_argument);
    PIController pi(1.0, 1.0, 1e-3);
    CHECK_THROWS_AS(pi.update(NAN), std::invalid_argument);
}

TEST_CASE("closed loop equals the plain reference loop") {
    std::mt19937 g(7);
    for (std::size_t avg : {1u, 5u}) {
        ClosedLoopConfig c;
        // Loop gain kp * input_gain * dy/du stays below 0.4 (dy/du <= ~7 for this model): a
        // stable loop, so rounding differences are not amplified.
        c.setpoint = 0.3;
        c.kp = 0.04;
        c.ki = 8.0;
        c.sample_time = 1e-3;
        c.average = avg;
        c.enable_at = 200;
        c.input_gain = 1.5;
        const State s0 = State::neutral(U_MIN, U_MAX, 0.4);
        const auto u_open = noisy_hold(g, 3000, 0.4, 0.3);
        std::vector<double> ru, ry, ruc;
        reference_loop(table(), s0, u_open, c, ru, ry, ruc);
        Simulator sim(table(), s0);
        std::vector<double> u(3000), y(3000), uc(3000);
        preisach::run_closed_loop(sim, u_open.data(), u.data(), y.data(), uc.data(), 3000, c, InputPolicy::clamp);
        INFO("average = " << avg);
        CHECK(max_abs_diff(u, ru) < 1e-12);
        CHECK(max_abs_diff(y, ry) < 1e-12);
        CHECK(max_abs_diff(uc, ruc) < 1e-12);
        for (std::size_t k = 0; k < c.enable_at; ++k) REQUIRE(uc[k] == 0.0);
        // the simulator keeps the state the loop left
        CHECK(sim.output() == doctest::Approx(y.back()));
    }
}

TEST_CASE("closed loop regulates a Preisach model to the setpoint") {
    ClosedLoopConfig c;
    c.setpoint = 0.5;
    c.kp = 0.05;
    c.ki = 10.0;
    c.sample_time = 1e-3;
    const State s0 = State::negative_saturation(U_MIN, U_MAX);
    std::vector<double> u_open(4000, 0.0), u(4000), y(4000), uc(4000);
    Simulator sim(table(), s0);
    preisach::run_closed_loop(sim, u_open.data(), u.data(), y.data(), uc.data(), 4000, c, InputPolicy::clamp);
    CHECK(y.back() == doctest::Approx(0.5).epsilon(1e-6));
    CHECK(std::abs(c.setpoint - y[10]) > 0.1);  // it did have to move
}

TEST_CASE("closed-loop batch equals single runs for any thread count") {
    std::mt19937 g(11);
    ClosedLoopConfig c;
    c.setpoint = 0.2;
    c.kp = 0.05;
    c.ki = 10.0;
    c.average = 3;
    c.enable_at = 100;
    const std::size_t m = 5, n = 1500;
    std::vector<State> states;
    std::vector<double> U(m * n);
    for (std::size_t r = 0; r < m; ++r) {
        states.push_back(random_start(g));
        const auto row = noisy_hold(g, n, 0.3, 0.2);
        std::copy(row.begin(), row.end(), U.begin() + std::ptrdiff_t(r * n));
    }
    std::vector<double> U1(m * n), Y1(m * n), C1(m * n);
    for (unsigned threads : {1u, 2u, 3u}) {
        std::vector<double> Uo(m * n), Yo(m * n), Co(m * n);
        const auto finals = preisach::run_closed_loop_batch(table(), states, U.data(), Uo.data(), Yo.data(),
                                                            Co.data(), m, n, c, InputPolicy::clamp, threads);
        for (std::size_t r = 0; r < m; ++r) {
            Simulator sim(table(), states[r]);
            std::vector<double> u(n), y(n), uc(n);
            preisach::run_closed_loop(sim, U.data() + r * n, u.data(), y.data(), uc.data(), n, c,
                                      InputPolicy::clamp);
            for (std::size_t k = 0; k < n; ++k) {
                REQUIRE(Yo[r * n + k] == y[k]);
                REQUIRE(Co[r * n + k] == uc[k]);
                REQUIRE(Uo[r * n + k] == u[k]);
            }
            CHECK(finals[r] == sim.state());
        }
    }
}

TEST_CASE("closed loop: errors name what and where") {
    ClosedLoopConfig c;
    c.sample_time = 1e-3;
    const State s0 = State::negative_saturation(U_MIN, U_MAX);
    std::vector<double> u_open(10, 0.0), u(10), y(10), uc(10);
    u_open[4] = NAN;
    Simulator sim(table(), s0);
    try {
        preisach::run_closed_loop(sim, u_open.data(), u.data(), y.data(), uc.data(), 10, c, InputPolicy::clamp);
        FAIL("expected std::invalid_argument");
    } catch (const std::invalid_argument& e) {
        CHECK(std::string(e.what()).find("u[4]") != std::string::npos);
    }
    u_open[4] = 50.0;  // out of range with policy raise
    Simulator sim2(table(), s0);
    CHECK_THROWS_AS(preisach::run_closed_loop(sim2, u_open.data(), u.data(), y.data(), uc.data(), 10, c,
                                              InputPolicy::raise),
                    std::invalid_argument);
    std::vector<State> two{s0, s0};
    CHECK_THROWS_AS(preisach::run_closed_loop_batch(table(), two, u_open.data(), u.data(), y.data(), uc.data(), 3,
                                                    2, c, InputPolicy::clamp),
                    std::invalid_argument);
}

TEST_CASE("neutral locus: N(l) is the readout of psi_n^l, runs from y_min to y_max, increases") {
    const EverettTable& t = table();
    std::vector<double> l, N(41);
    for (int k = 0; k <= 40; ++k) l.push_back(U_MIN + (U_MAX - U_MIN) * k / 40.0);
    preisach::neutral_locus(t, l.data(), N.data(), l.size());
    for (std::size_t k = 0; k < l.size(); ++k)
        CHECK(N[k] == doctest::Approx(preisach::readout(t, State::neutral(U_MIN, U_MAX, l[k]))));
    CHECK(N.front() == doctest::Approx(t.y_min()));
    CHECK(N.back() == doctest::Approx(t.y_max()));
    for (std::size_t k = 1; k < N.size(); ++k) CHECK(N[k] > N[k - 1]);  // mu > 0: monotone (§2.8)
    // N lies inside the major loop
    for (std::size_t k = 1; k + 1 < l.size(); ++k) {
        const double y_up = Simulator(t, State::negative_saturation(U_MIN, U_MAX)).step(l[k]);
        const double y_dn = Simulator(t, State::positive_saturation(U_MIN, U_MAX)).step(l[k]);
        CHECK(N[k] >= y_up - 1e-12);
        CHECK(N[k] <= y_dn + 1e-12);
    }
    double bad = U_MAX + 1.0;
    CHECK_THROWS_AS(preisach::neutral_locus(t, &bad, N.data(), 1), std::invalid_argument);
}

}  // namespace unity_test_control

// Discrete PI regulation of a Preisach model (thesis chapter 5, Eq 5.2), pure C++.
//
// PIController implements
//     u_c(k) = K_p e(k) + K_i T_s sum_{j <= k} e(j)                             (Eq 5.2)
// where e is the regulation error (volts of output).  With averaging over N > 1 samples the
// controller's input is the mean of the last N errors (the thesis's experiments average the
// error over the previous 25 ms to suppress measurement noise), and both terms use it.
//
// run_closed_loop drives a Simulator in a clocked loop, as a DAQ trial runner would:
//     u(k)  = u_open(k) + g * u_c(k-1)          (u_c(-1) = 0: one-sample computation delay)
//     y(k)  = Gamma(psi after u(k))
//     e(k)  = setpoint - y(k)
//     u_c(k) = 0 for k < enable_at, else PIController::update(e(k))
// u_open is the open-loop part of the input (the hold offset plus any injected noise, volts
// of model input) and g the gain from controller units to model-input volts (e.g. the SA11
// amplifier gain when K_p, K_i are stated at the DAQ connector).  Before enable_at the errors
// still enter the averaging window (the moving average runs all the time), but nothing is
// integrated.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "batch.hpp"
#include "simulator.hpp"

namespace preisach {

class PIController {
public:
    PIController(double kp, double ki, double sample_time, std::size_t average = 1)
        : kp_(kp), ki_(ki), ts_(sample_time), buf_(average, 0.0) {
        if (!std::isfinite(kp)) throw std::invalid_argument("PI controller: kp is not finite");
        if (!std::isfinite(ki)) throw std::invalid_argument("PI controller: ki is not finite");
        if (!(sample_time > 0.0) || !std::isfinite(sample_time))
            throw std::invalid_argument("PI controller: sample_time must be positive and finite, got " +
                                        std::to_string(sample_time));
        if (average < 1) throw std::invalid_argument("PI controller: average must be >= 1 sample, got 0");
    }

    // Forget the integral, the averaging window and the output.
    void reset() noexcept {
        std::fill(buf_.begin(), buf_.end(), 0.0);
        head_ = 0;
        count_ = 0;
        sum_ = 0.0;
        integral_ = 0.0;
        output_ = 0.0;
    }

    // Push an error sample into the averaging window without acting (controller off);
    // returns the averaged error.
    double observe(double e) {
        if (!std::isfinite(e)) throw std::invalid_argument("PI controller: error sample is not finite");
        const std::size_t n = buf_.size();
        if (n == 1) return e;
        if (count_ == n) sum_ -= buf_[head_]; else ++count_;
        buf_[head_] = e;
        sum_ += e;
        head_ = head_ + 1 == n ? 0 : head_ + 1;
        // The running sum drifts by rounding; recompute it once per window.
        if (head_ == 0) {
            sum_ = 0.0;
            for (double v : buf_) sum_ += v;
        }
        return sum_ / double(count_);
    }

    // One controller step on the error sample e (volts): Eq 5.2 on the averaged error.
    double update(double e) {
        const double ea = observe(e);
        integral_ += ea;
        output_ = kp_ * ea + ki_ * ts_ * integral_;
        return output_;
    }

    double output() const noexcept { return output_; }
    double integral() const noexcept { return integral_; }  // sum of the (averaged) errors
    double kp() const noexcept { return kp_; }
    double ki() const noexcept { return ki_; }
    double sample_time() const noexcept { return ts_; }
    std::size_t average() const noexcept { return buf_.size(); }

private:
    double kp_, ki_, ts_;
    std::vector<double> buf_;
    std::size_t head_ = 0, count_ = 0;
    double sum_ = 0.0, integral_ = 0.0, output_ = 0.0;
};

struct ClosedLoopConfig {
    double setpoint = 0.0;       // desired output y_d (V)
    double kp = 1.5;             // proportional gain (controller units per output volt)
    double ki = 30.0;            // integral gain (controller units per output volt-second)
    double sample_time = 1e-3;   // T_s (s)
    std::size_t average = 1;     // samples in the error moving average (1: none)
    std::size_t enable_at = 0;   // first sample at which the controller acts
    double input_gain = 1.0;     // model-input volts per controller unit

    void validate() const {
        if (!std::isfinite(setpoint)) throw std::invalid_argument("closed loop: setpoint is not finite");
        if (!std::isfinite(input_gain)) throw std::invalid_argument("closed loop: input_gain is not finite");
        PIController(kp, ki, sample_time, average);  // checks the controller's parameters
    }
};

// The loop above around any plant: `step(v, k)` applies the model input v at sample k and
// returns the output; [lo, hi] is the input range (the clamp policy clamps v to it, the raise
// policy leaves the check to `step`).  u (the applied model input), y (output) and uc
// (controller output, controller units) receive n values each.
template <class Step>
void run_pi_loop(Step&& step, double lo, double hi, const double* u_open, double* u, double* y, double* uc,
                 std::size_t n, const ClosedLoopConfig& cfg, InputPolicy policy) {
    cfg.validate();
    PIController pi(cfg.kp, cfg.ki, cfg.sample_time, cfg.average);
    double c = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        double v = u_open[k] + cfg.input_gain * c;
        if (!std::isfinite(v))
            throw std::invalid_argument("closed loop: input u[" + std::to_string(k) + "] is not finite (u_open = " +
                                        std::to_string(u_open[k]) + ")");
        if (policy == InputPolicy::clamp) v = std::min(std::max(v, lo), hi);
        const double out = step(v, k);
        u[k] = v;
        y[k] = out;
        const double e = cfg.setpoint - out;
        c = k >= cfg.enable_at ? pi.update(e) : (pi.observe(e), 0.0);
        uc[k] = c;
    }
}

// Run n samples of the loop on `sim` (which keeps its state afterwards).  Outputs: u (the
// applied model input, after the input policy), y (model output) and uc (controller output,
// controller units), each of length n.
inline void run_closed_loop(Simulator& sim, const double* u_open, double* u, double* y, double* uc, std::size_t n,
                            const ClosedLoopConfig& cfg, InputPolicy policy) {
    run_pi_loop([&](double v, std::size_t k) { return sim.step_checked(v, policy, k); }, sim.table().u_min(),
                sim.table().u_max(), u_open, u, y, uc, n, cfg, policy);
}

// Row r of U_open (m x n, row-major) from states[r] (or states[0] for all rows) on
// `threads` worker threads (0: every core).  U, Y, UC receive m x n values; returns the final
// states.  The first error (lowest row) is rethrown with its row.
inline std::vector<State> run_closed_loop_batch(const EverettTable& table, const std::vector<State>& states,
                                                const double* U_open, double* U, double* Y, double* UC,
                                                std::size_t m, std::size_t n, const ClosedLoopConfig& cfg,
                                                InputPolicy policy, unsigned threads = 0) {
    check_row_states(states.size(), m);
    cfg.validate();
    std::vector<State> finals(m);
    for_each_row(m, threads, [&](std::size_t r) {
        Simulator sim(table, states.size() == 1 ? states[0] : states[r]);
        run_closed_loop(sim, U_open + r * n, U + r * n, Y + r * n, UC + r * n, n, cfg, policy);
        finals[r] = sim.state();
    });
    return finals;
}

}  // namespace preisach

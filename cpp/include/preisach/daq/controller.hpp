// Controllers of a trial: what the actuator output should be at each sample.
//
// A deliberately small interface so that open-loop waveforms, a PI regulator and a user's
// Python function all drive the same trial runner.  (preisach/control.hpp holds the PI
// controller of the regulation experiments; this one is the DAQ runner's own, with the
// enable time, error averaging and anti-windup a rig needs.)
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace preisach::daq {

// What the controller sees at sample k.  All values in physical units (volts at the
// actuator, volts of the measured output).
struct SampleInfo {
    std::size_t k;          // sample index, 0-based
    double t;               // nominal time of the sample (s)
    double y;               // primary measured input (physical)
    const double* inputs;   // every input channel (physical), inputs[0 .. n_inputs)
    std::size_t n_inputs;
    double u_prev;          // output applied at the previous sample (physical, after the safety limits)
};

class Controller {
public:
    virtual ~Controller() = default;
    virtual std::string kind() const = 0;
    // Number of samples the controller plans (0: open-ended, the trial gives the length).
    virtual std::size_t length() const { return 0; }
    virtual void reset() {}
    // The requested output (physical volts at the actuator).
    virtual double output(const SampleInfo& s) = 0;
    // The output actually applied after clamping and slew limiting (for anti-windup).
    virtual void applied(double /*u*/) {}
};

// Open loop: sample k outputs u[k]; after the end it holds the last value.
class WaveformController final : public Controller {
public:
    explicit WaveformController(std::vector<double> u) : u_(std::move(u)) {
        if (u_.empty()) throw std::invalid_argument("waveform: the waveform is empty");
        for (std::size_t i = 0; i < u_.size(); ++i)
            if (!std::isfinite(u_[i]))
                throw std::invalid_argument("waveform: sample u[" + std::to_string(i) + "] is not finite");
    }
    std::string kind() const override { return "waveform"; }
    std::size_t length() const override { return u_.size(); }
    double output(const SampleInfo& s) override { return u_[std::min(s.k, u_.size() - 1)]; }
    const std::vector<double>& waveform() const noexcept { return u_; }

private:
    std::vector<double> u_;
};

// Discrete PI regulator around a feed-forward waveform (thesis Eq 5.2):
//   u[k] = ff[k] + u_c[k],  u_c[k] = kp e[k] + ki Ts sum_{j<=k} e[j]   for k >= enable_at,
//   u_c = 0 before,  e[k] = setpoint - mean(y[k-average+1 .. k]).
// The error averaging is the thesis's experimental 25 ms mean (average = 25 at 1 ms).
// Anti-windup by conditional integration: when the applied output differs from the request
// (clamped or slew-limited) and the error pushes further the same way, the sample's integral
// increment is taken back.
class PIController final : public Controller {
public:
    PIController(double kp, double ki, double setpoint, double sample_time, std::vector<double> feedforward,
                 std::size_t enable_at = 0, std::size_t average = 1)
        : kp_(kp), ki_(ki), r_(setpoint), ts_(sample_time), ff_(std::move(feedforward)), on_(enable_at),
          avg_(average) {
        if (!std::isfinite(kp) || !std::isfinite(ki)) throw std::invalid_argument("pi: kp and ki must be finite");
        if (!std::isfinite(setpoint)) throw std::invalid_argument("pi: setpoint must be finite");
        if (!(std::isfinite(sample_time) && sample_time > 0))
            throw std::invalid_argument("pi: sample_time must be a positive number of seconds");
        if (ff_.empty()) throw std::invalid_argument("pi: the feed-forward waveform is empty");
        for (std::size_t i = 0; i < ff_.size(); ++i)
            if (!std::isfinite(ff_[i]))
                throw std::invalid_argument("pi: feed-forward sample ff[" + std::to_string(i) + "] is not finite");
        if (avg_ < 1) throw std::invalid_argument("pi: average must be >= 1 sample");
        reset();
    }
    std::string kind() const override { return "pi"; }
    std::size_t length() const override { return ff_.size(); }
    void reset() override {
        hist_.assign(avg_, 0.0);
        filled_ = 0;
        head_ = 0;
        integral_ = inc_ = e_ = uc_ = req_ = 0.0;
    }
    double output(const SampleInfo& s) override {
        hist_[head_] = s.y;
        head_ = (head_ + 1) % avg_;
        filled_ = std::min(filled_ + 1, avg_);
        double m = 0.0;
        for (std::size_t i = 0; i < filled_; ++i) m += hist_[i];
        e_ = r_ - m / double(filled_);
        inc_ = 0.0;
        if (s.k >= on_) {
            inc_ = ki_ * ts_ * e_;
            integral_ += inc_;
            uc_ = kp_ * e_ + integral_;
        } else {
            uc_ = 0.0;
        }
        return req_ = ff_[std::min(s.k, ff_.size() - 1)] + uc_;
    }
    void applied(double u) override {
        const double d = u - req_;
        if (std::abs(d) > 1e-12 * (1.0 + std::abs(req_)) && inc_ != 0.0 && (d > 0) == (inc_ < 0)) {
            integral_ -= inc_;
            uc_ -= inc_;
        }
    }
    double error() const noexcept { return e_; }
    double control() const noexcept { return uc_; }
    double integral() const noexcept { return integral_; }

private:
    double kp_, ki_, r_, ts_;
    std::vector<double> ff_;
    std::size_t on_, avg_;
    std::vector<double> hist_;
    std::size_t filled_ = 0, head_ = 0;
    double integral_ = 0.0, inc_ = 0.0, e_ = 0.0, uc_ = 0.0, req_ = 0.0;
};

// Any function of the sample (a C++ lambda, or a Python callable wrapped by the bindings,
// which re-acquire the GIL only for the call).
class FunctionController final : public Controller {
public:
    using Function = std::function<double(const SampleInfo&)>;
    FunctionController(Function f, std::size_t length) : f_(std::move(f)), n_(length) {
        if (!f_) throw std::invalid_argument("callback: the function is empty");
    }
    std::string kind() const override { return "callback"; }
    std::size_t length() const override { return n_; }
    double output(const SampleInfo& s) override { return f_(s); }

private:
    Function f_;
    std::size_t n_;
};

}  // namespace preisach::daq

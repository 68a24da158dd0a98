// A Preisach model with output feedback on its input (a generalised moving model), for diagnosis.
//
// The relays see the effective input
//     u_eff[k] = clamp(u[k] + a d + b d^2 / span + c d^3 / span^2, u_min, u_max),  d = y[k-1] - y_c,
// where y[k-1] is the previous output (the output of the initial state before the first
// sample).  With b = c = 0 this is Della Torre's moving model H_eff = H + alpha M written in
// volts; the quadratic term lets the feedback differ between the top and the bottom of the
// output range, the cubic one lets it saturate (or grow) toward both ends.  Minor loops then depend on the output level at which they sit (non-congruence),
// while wiping-out still holds for u_eff.  The feedback is explicit (one sample late), which
// differs from the implicit model by O(a dy) per sample.
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "simulator.hpp"

namespace preisach {

// Run n samples; writes the outputs y[0..n) and the effective inputs u_eff[0..n) (volts).
// Throws std::invalid_argument for non-finite parameters or inputs (naming the sample).
inline void simulate_moving(Simulator& sim, const double* u, std::size_t n, double a, double b, double y_c,
                            double span, double* y, double* u_eff, double c = 0.0) {
    if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c) || !std::isfinite(y_c))
        throw std::invalid_argument("simulate_moving: the feedback parameters a, b, c and y_c must be finite");
    if (!(span > 0.0) || !std::isfinite(span))
        throw std::invalid_argument("simulate_moving: span must be a positive finite number of volts, got " +
                                    std::to_string(span));
    const double lo = sim.state().u_min(), hi = sim.state().u_max();
    double prev = sim.output();
    for (std::size_t k = 0; k < n; ++k) {
        if (!std::isfinite(u[k])) throw std::invalid_argument("input u[" + std::to_string(k) + "] is not finite");
        const double d = prev - y_c, q = d / span;
        double ue = u[k] + d * (a + q * (b + c * q));
        ue = ue < lo ? lo : (ue > hi ? hi : ue);
        u_eff[k] = ue;
        prev = sim.step_checked(ue, InputPolicy::clamp, k);
        y[k] = prev;
    }
}

// A uniform cubic B-spline f(y) on [y_lo, y_hi] with n_coef >= 4 coefficients c[0..n_coef)
// (n_coef - 3 equal intervals; outside the range y is clamped to it, so f is constant there).
class FeedbackSpline {
public:
    FeedbackSpline(double y_lo, double y_hi, const double* coef, std::size_t n_coef)
        : lo_(y_lo), hi_(y_hi), c_(coef, coef + n_coef) {
        if (!std::isfinite(y_lo) || !std::isfinite(y_hi) || !(y_hi > y_lo))
            throw std::invalid_argument("feedback spline: y_hi must be a finite number of volts above y_lo");
        if (n_coef < 4)
            throw std::invalid_argument("feedback spline: at least 4 coefficients are needed, got " +
                                        std::to_string(n_coef));
        for (double v : c_)
            if (!std::isfinite(v)) throw std::invalid_argument("feedback spline: coefficients must be finite");
        intervals_ = n_coef - 3;
        h_ = (hi_ - lo_) / static_cast<double>(intervals_);
    }

    // f(y) (volts of input shift).
    double operator()(double y) const {
        const double yc = y < lo_ ? lo_ : (y > hi_ ? hi_ : y);
        double s = (yc - lo_) / h_;
        std::size_t j = static_cast<std::size_t>(s);
        if (j >= intervals_) j = intervals_ - 1;
        const double t = s - static_cast<double>(j), t2 = t * t, t3 = t2 * t, m = 1.0 - t;
        return (m * m * m * c_[j] + (3.0 * t3 - 6.0 * t2 + 4.0) * c_[j + 1] +
                (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * c_[j + 2] + t3 * c_[j + 3]) /
               6.0;
    }

private:
    double lo_, hi_, h_ = 1.0;
    std::vector<double> c_;
    std::size_t intervals_ = 1;
};

// A moving Preisach model whose feedback is a smooth function of the output:
//     u_eff[k] = clamp(u[k] + f(y[k-1]), u_min, u_max)
// with f a FeedbackSpline (y[k-1]: the previous output; the initial state's output before the
// first sample).  Writes y[0..n) and u_eff[0..n) (volts); throws std::invalid_argument for a
// non-finite input (naming the sample).
inline void simulate_feedback_spline(Simulator& sim, const double* u, std::size_t n, const FeedbackSpline& f,
                                     double* y, double* u_eff) {
    const double lo = sim.state().u_min(), hi = sim.state().u_max();
    double prev = sim.output();
    for (std::size_t k = 0; k < n; ++k) {
        if (!std::isfinite(u[k])) throw std::invalid_argument("input u[" + std::to_string(k) + "] is not finite");
        double ue = u[k] + f(prev);
        ue = ue < lo ? lo : (ue > hi ? hi : ue);
        u_eff[k] = ue;
        prev = sim.step_checked(ue, InputPolicy::clamp, k);
        y[k] = prev;
    }
}

}  // namespace preisach

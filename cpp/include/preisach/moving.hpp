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

}  // namespace preisach

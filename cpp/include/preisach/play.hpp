// The play (backlash) operator with a time-varying half-width, for diagnosis.
//
// The play operator z = P_w[x] with half-width w >= 0 follows the input only when the input
// pushes it: z[k] = min(x[k] + w[k], max(x[k] - w[k], z[k-1])).  Between pushes it holds
// its value, so a reversal of the input is seen by z only after the input has moved back by
// 2 w.  A Preisach model driven by z instead of x has every relay's thresholds moved apart
// by w (alpha + w, beta - w): with w = w(|du/dt|) this is the rate-dependent threshold
// dilation of rate-dependent Prandtl-Ishlinskii and Preisach models, the "loops widen with
// the input rate" candidate of preisach.diagnose.  Units: x, w and z in volts.
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace preisach {

// Run the play operator over n samples from the initial output z0 (volts); writes z[0..n).
// Returns the last output (the state to continue from).  Throws std::invalid_argument naming
// the first sample whose input or half-width is not finite or whose half-width is negative.
inline double play_operator(const double* x, const double* w, std::size_t n, double z0, double* z) {
    if (!std::isfinite(z0)) throw std::invalid_argument("z0: the initial output must be finite");
    double prev = z0;
    for (std::size_t k = 0; k < n; ++k) {
        const double xk = x[k], wk = w[k];
        if (!std::isfinite(xk)) throw std::invalid_argument("x[" + std::to_string(k) + "] is not finite");
        if (!(wk >= 0.0) || !std::isfinite(wk))
            throw std::invalid_argument("width[" + std::to_string(k) + "] = " + std::to_string(wk) +
                                        " V: the half-width must be finite and >= 0");
        const double lo = xk - wk, hi = xk + wk;
        prev = prev < lo ? lo : (prev > hi ? hi : prev);
        z[k] = prev;
    }
    return prev;
}

}  // namespace preisach

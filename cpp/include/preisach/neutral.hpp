// The locus of neutral states N(l) (thesis Eq 2.18), pure C++.
//
// N(l) = Gamma(psi_n^l): the output of the neutral state whose boundary is the horizontal
// segment s = l near r = 0 (Eq 2.17), held exactly as an antidiagonal boundary piece, so no
// staircase approximation enters.  One evaluation costs one antidiagonal integral over the
// grid (O(levels)).
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

#include "memory.hpp"
#include "simulator.hpp"

namespace preisach {

// N[i] = Gamma(psi_n^{l[i]}) for i < n; every l[i] must lie in [u_min, u_max] of the table.
inline void neutral_locus(const EverettTable& table, const double* l, double* N, std::size_t n) {
    const double lo = table.u_min(), hi = table.u_max();
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(l[i]) || l[i] < lo || l[i] > hi)
            throw std::invalid_argument("l[" + std::to_string(i) + "] = " + std::to_string(l[i]) +
                                        " V is outside the model's input range [" + std::to_string(lo) + ", " +
                                        std::to_string(hi) + "] V");
        N[i] = readout(table, State::neutral(lo, hi, l[i]));
    }
}

}  // namespace preisach

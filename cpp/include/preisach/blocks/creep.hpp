// Creep: the slow drift of a piezo actuator toward its equilibrium after the input changes.
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "block.hpp"

namespace preisach::blocks {

// Logarithmic creep as a sum of first-order lags with time constants one decade apart,
//   y = x + rate * sum_k (z_k - x),   tau_k dz_k/dt = x - z_k,
//   tau_k = tau_min * 10^k, k = 0 .. floor(log10(tau_max / tau_min)),
// each lag discretised exactly.  The equilibrium (every z_k = x) is the input itself, so a
// slow input passes unchanged and the Preisach model keeps describing the settled output;
// after a step of size D the output first moves by (1 - n rate) D and then creeps the rest of
// the way, about rate * D per decade of time between tau_min and tau_max -- the
// y(t) ~ y0 (1 + rate log10(t / t0)) law of piezo creep.  Physics: domain walls keep moving
// slowly under a constant field after the fast (hysteretic) response; manufacturers quote
// about 1-2 % of the last move per decade of time.  `rate` is that fraction (1 = 100 %).
class Creep final : public Block {
public:
    Creep(double dt, double rate = 0.01, double tau_min = 0.1, double tau_max = 100.0) : Block(dt) {
        rate_ = non_negative("creep", "rate", rate);
        tau_min_ = positive("creep", "tau_min", tau_min);
        tau_max_ = positive("creep", "tau_max", tau_max);
        if (tau_max_ < tau_min_)
            throw std::invalid_argument("creep: parameter tau_max (" + std::to_string(tau_max_) +
                                        " s) must be >= tau_min (" + std::to_string(tau_min_) + " s)");
        const int n = int(std::floor(std::log10(tau_max_ / tau_min_) + 1e-9)) + 1;
        if (rate_ * n >= 1.0)
            throw std::invalid_argument("creep: rate * number of decades (" + std::to_string(rate_ * n) +
                                        ") must be below 1, or a step would first move the output backwards");
        for (int k = 0; k < n; ++k) a_.push_back(-std::expm1(-dt / (tau_min_ * std::pow(10.0, k))));
        z_.assign(a_.size(), 0.0);
    }
    std::string kind() const override { return "creep"; }
    std::vector<Param> params() const override {
        return {{"rate", rate_, "1/decade"}, {"tau_min", tau_min_, "s"}, {"tau_max", tau_max_, "s"}};
    }
    double reset(double x0) override {
        z_.assign(a_.size(), x0);
        return x0;
    }
    double step(double x) override {
        check_input("creep", x);
        double s = 0.0;
        for (std::size_t k = 0; k < a_.size(); ++k) {
            z_[k] += a_[k] * (x - z_[k]);
            s += z_[k] - x;
        }
        return x + rate_ * s;
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<Creep>(*this); }
    std::size_t n_lags() const noexcept { return a_.size(); }

private:
    double rate_ = 0.0, tau_min_ = 0.0, tau_max_ = 0.0;
    std::vector<double> a_, z_;
};

}  // namespace preisach::blocks

// Sensor offset drift (output side).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "block.hpp"
#include "rng.hpp"

namespace preisach::blocks {

// y = x + d(t) with an offset that drifts linearly and as a random walk:
//   d[k+1] = d[k] + rate dt + sigma sqrt(dt) n[k],  n ~ N(0, 1) (seeded),  d = 0 after reset.
// Physics: the strain-gauge bridge and its amplifier drift with temperature (resistor and
// gauge-factor temperature coefficients, amplifier offset drift); over a trial of seconds to
// minutes this looks like a slow ramp plus a random walk.  The thesis trimmed the offset to
// 0 V before each run with variable resistors (section 3.1), which is why d starts at 0.
// rate in V/s, sigma in V/sqrt(s) (the random walk's standard deviation after 1 s).
class OffsetDrift final : public Block {
public:
    OffsetDrift(double dt, double rate = 0.0, double sigma = 0.0, std::uint64_t seed = 0)
        : Block(dt), seed_(seed), rng_(seed) {
        rate_ = finite("offset_drift", "rate", rate);
        sigma_ = non_negative("offset_drift", "sigma", sigma);
        sq_dt_ = std::sqrt(dt);
    }
    std::string kind() const override { return "offset_drift"; }
    std::vector<Param> params() const override {
        return {{"rate", rate_, "V/s"}, {"sigma", sigma_, "V/sqrt(s)"}, {"seed", double(seed_), "1"}};
    }
    double reset(double x0) override {
        d_ = 0.0;
        rng_.reseed(seed_);
        return x0;
    }
    double step(double x) override {
        check_input("offset_drift", x);
        d_ += rate_ * dt() + (sigma_ > 0.0 ? sigma_ * sq_dt_ * rng_.normal() : 0.0);
        return x + d_;
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<OffsetDrift>(*this); }
    double offset() const noexcept { return d_; }

private:
    double rate_ = 0.0, sigma_ = 0.0, sq_dt_ = 0.0, d_ = 0.0;
    std::uint64_t seed_;
    Rng rng_;
};

}  // namespace preisach::blocks

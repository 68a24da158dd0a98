// The virtual SS15 rig: a simulated DAQ device around a Preisach plant.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../blocks/chain.hpp"
#include "../blocks/rng.hpp"
#include "device.hpp"

namespace preisach::daq {

// The hardware around the plant, thesis section 3.1 and Appendix B.
struct VirtualRigConfig {
    double sample_time = 1e-3;      // s: the period the plant's blocks are discretised for
    // DAC (Quanser MultiQ analog output, +/-10 V) -> SA11 amplifier.  amp_gain/amp_offset are
    // the *true* amplifier of the virtual rig (Eq B.1b by default); the output channel's
    // calibration is what the experimenter believes, normally the same numbers.
    unsigned dac_bits = 0;          // DAC resolution (0: ideal)
    double amp_gain = -14.12;       // V/V  (Eq B.1b: V_in = -14.12 V_bin - 0.02)
    double amp_offset = -0.02;      // V
    double amp_limit = 150.0;       // V: the amplifier's output swing (its rails)
    // ADC (Quanser analog input): +/-5 V, 14 bit (0.61 mV, the 0.6 mV resolution of section
    // 3.1), white Gaussian measurement noise of adc_noise V rms added before conversion; a
    // reading at either end code is out of range and reads NaN (like comedi's OOR_NAN).
    double adc_min = -5.0;
    double adc_max = 5.0;
    unsigned adc_bits = 14;
    double adc_noise = 0.5e-3;      // V rms
    double sensor_gain = 1.0;       // V at the ADC per V of plant output (strain-gauge amplifier)
    double sensor_offset = 0.0;     // V
    std::uint64_t seed = 0;

    void validate() const {
        if (!(std::isfinite(sample_time) && sample_time > 0))
            throw std::invalid_argument("virtual rig: sample_time must be a positive number of seconds");
        if (dac_bits > 24 || adc_bits < 2 || adc_bits > 24)
            throw std::invalid_argument("virtual rig: dac_bits must be 0..24 and adc_bits 2..24");
        if (!(std::isfinite(amp_gain) && amp_gain != 0.0 && std::isfinite(amp_offset)))
            throw std::invalid_argument("virtual rig: amp_gain must be finite and non-zero, amp_offset finite");
        if (!(amp_limit > 0)) throw std::invalid_argument("virtual rig: amp_limit must be > 0 V");
        if (!(std::isfinite(adc_min) && std::isfinite(adc_max) && adc_min < adc_max))
            throw std::invalid_argument("virtual rig: ADC range must satisfy adc_min < adc_max");
        if (!(std::isfinite(adc_noise) && adc_noise >= 0))
            throw std::invalid_argument("virtual rig: adc_noise must be >= 0 V");
        if (!(std::isfinite(sensor_gain) && std::isfinite(sensor_offset)))
            throw std::invalid_argument("virtual rig: sensor_gain and sensor_offset must be finite");
    }
};

// Virtual SS15: DAC -> amplifier -> plant (a block chain with a Preisach stage) -> sensor ->
// noisy, quantised ADC.  One output channel (the amplifier's input, connector volts) and one
// input channel (the strain-gauge voltage at the ADC).  write() holds the DAC value over one
// sample period and advances the plant; read() returns the plant output reached so far.
class VirtualRig final : public Device {
public:
    VirtualRig(blocks::Chain plant, VirtualRigConfig cfg, Channel output, Channel input)
        : plant_(std::move(plant)), cfg_(cfg), rng_(cfg.seed) {
        cfg_.validate();
        if (plant_.size() == 0) throw std::invalid_argument("virtual rig: the plant chain is empty");
        if (std::abs(plant_.dt() - cfg_.sample_time) > 1e-12 * cfg_.sample_time)
            throw std::invalid_argument("virtual rig: the plant's blocks have sample time " + std::to_string(plant_.dt()) +
                                        " s but the rig samples every " + std::to_string(cfg_.sample_time) + " s");
        output.validate("output");
        input.validate("input");
        outs_ = {std::move(output)};
        ins_ = {std::move(input)};
        last_.assign(1, 0.0);
        reset();
    }

    std::string description() const override {
        const auto* p = plant_.preisach();
        std::string s = "virtual SS15 (" + std::to_string(plant_.size()) + " block";
        s += plant_.size() == 1 ? "" : "s";
        if (p) s += ", Preisach model on [" + std::to_string(p->table().u_min()) + ", " +
                    std::to_string(p->table().u_max()) + "] V";
        return s + ")";
    }
    bool simulated() const override { return true; }
    const std::vector<Channel>& outputs() const override { return outs_; }
    const std::vector<Channel>& inputs() const override { return ins_; }
    void start(double period) override {
        if (std::abs(period - cfg_.sample_time) > 1e-12 * cfg_.sample_time)
            throw std::invalid_argument("period: the virtual rig was built for a sample time of " +
                                        std::to_string(cfg_.sample_time) + " s, not " + std::to_string(period) +
                                        " s (its blocks are discretised for it)");
    }
    void read(double* volts) override { volts[0] = adc(y_); }
    void write(const double* volts) override {
        const double v = dac(volts[0]);
        last_[0] = v;
        u_ = std::min(std::max(cfg_.amp_gain * v + cfg_.amp_offset, -cfg_.amp_limit), cfg_.amp_limit);
        y_ = plant_.step(u_);
        t_ += cfg_.sample_time;
    }

    // Back to the plant's starting state with the DAC at 0 V, the noise re-seeded.
    void reset() {
        rng_.reseed(cfg_.seed);
        last_[0] = 0.0;
        u_ = std::min(std::max(cfg_.amp_offset, -cfg_.amp_limit), cfg_.amp_limit);
        y_ = plant_.reset(u_);
        t_ = 0.0;
    }
    // Change the Preisach stage's starting state and reset.
    void reset(const State& s) {
        auto* p = plant_.preisach();
        if (!p) throw std::invalid_argument("virtual rig: the plant has no Preisach stage to set a state on");
        p->set_initial_state(s);
        reset();
    }
    // The noise-free plant output (physical V), the amplifier output V_in (V), time (s).
    double plant_output() const noexcept { return y_; }
    double actuator_voltage() const noexcept { return u_; }
    double time() const noexcept { return t_; }
    State state() const {
        const auto* p = plant_.preisach();
        if (!p) throw std::invalid_argument("virtual rig: the plant has no Preisach stage");
        return p->state();
    }
    const blocks::Chain& plant() const noexcept { return plant_; }
    const VirtualRigConfig& config() const noexcept { return cfg_; }

private:
    double dac(double v) const {
        const double lo = outs_[0].range_min, hi = outs_[0].range_max;
        v = std::min(std::max(v, lo), hi);
        if (cfg_.dac_bits == 0) return v;
        const double steps = std::ldexp(1.0, int(cfg_.dac_bits)) - 1.0;
        return lo + std::round((v - lo) / (hi - lo) * steps) / steps * (hi - lo);
    }
    double adc(double y) {
        double v = cfg_.sensor_gain * y + cfg_.sensor_offset;
        if (cfg_.adc_noise > 0) v += cfg_.adc_noise * rng_.normal();
        const double codes = std::ldexp(1.0, int(cfg_.adc_bits));
        const double lsb = (cfg_.adc_max - cfg_.adc_min) / codes;
        const double code = std::floor((v - cfg_.adc_min) / lsb + 0.5);
        if (!(code > 0.0 && code < codes - 1.0)) return std::numeric_limits<double>::quiet_NaN();
        return cfg_.adc_min + code * lsb;
    }

    blocks::Chain plant_;
    VirtualRigConfig cfg_;
    blocks::Rng rng_;
    std::vector<Channel> outs_, ins_;
    double u_ = 0.0, y_ = 0.0, t_ = 0.0;
};

}  // namespace preisach::daq

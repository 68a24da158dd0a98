// Measurement-chain blocks: a pure delay and a moving-average filter (output side).
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "block.hpp"

namespace preisach::blocks {

// Pure delay of `samples` sample intervals: y[k] = x[k - samples].  Physics: conversion and
// transport latency of the measurement chain (strain-gauge amplifier filters, the ADC's
// pipeline, a controller that reads the previous sample).  samples = 0 passes through.
class Delay final : public Block {
public:
    Delay(double dt, std::size_t samples = 1) : Block(dt), buf_(samples, 0.0) {}
    std::string kind() const override { return "delay"; }
    std::vector<Param> params() const override { return {{"samples", double(buf_.size()), "samples"}}; }
    double reset(double x0) override {
        std::fill(buf_.begin(), buf_.end(), x0);
        head_ = 0;
        return x0;
    }
    double step(double x) override {
        check_input("delay", x);
        if (buf_.empty()) return x;
        const double y = buf_[head_];
        buf_[head_] = x;
        head_ = head_ + 1 == buf_.size() ? 0 : head_ + 1;
        return y;
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<Delay>(*this); }
    std::size_t samples() const noexcept { return buf_.size(); }

private:
    std::vector<double> buf_;
    std::size_t head_ = 0;
};

// Moving average of the last `length` samples (the current one included).  Physics: the
// thesis read its ADC through Simulink's moving-average block over the 10 most recent
// samples at 1 ms (Appendix B.1); it delays the signal by (length - 1)/2 samples and
// attenuates the structural mode.  The running sum is recomputed exactly once per window so
// rounding errors cannot accumulate.
class MovingAverage final : public Block {
public:
    MovingAverage(double dt, std::size_t length = 10) : Block(dt) {
        if (length < 1) throw std::invalid_argument("moving_average: parameter length must be >= 1 sample, got 0");
        buf_.assign(length, 0.0);
    }
    std::string kind() const override { return "moving_average"; }
    std::vector<Param> params() const override { return {{"length", double(buf_.size()), "samples"}}; }
    double reset(double x0) override {
        std::fill(buf_.begin(), buf_.end(), x0);
        head_ = 0;
        sum_ = x0 * double(buf_.size());
        return x0;
    }
    double step(double x) override {
        check_input("moving_average", x);
        sum_ += x - buf_[head_];
        buf_[head_] = x;
        if (++head_ == buf_.size()) {
            head_ = 0;
            sum_ = 0.0;
            for (double v : buf_) sum_ += v;
        }
        return sum_ / double(buf_.size());
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<MovingAverage>(*this); }
    std::size_t length() const noexcept { return buf_.size(); }

private:
    std::vector<double> buf_;
    std::size_t head_ = 0;
    double sum_ = 0.0;
};

}  // namespace preisach::blocks

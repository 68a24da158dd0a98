// The rate-dependent Preisach model (rate_dependent.hpp) as a block of a chain.
#pragma once

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../rate_dependent.hpp"
#include "block.hpp"

namespace preisach::blocks {

// A RateDependentModel with a starting boundary and filtered rate as a block, so that rate
// dependence combines with the other left-out physics in one chain:
//   input blocks (amplifier lag, ...) -> RateStage -> output blocks (creep, structural mode, ...).
// The filter's dt is the block's dt.  Inputs outside the model range are clamped (saturation);
// NaN/inf raise.  reset(x0) returns to the starting state and rate (x0 is ignored: a
// hysteretic system has no unique steady state for a constant input).
class RateStage final : public Block {
public:
    RateStage(double dt, std::shared_ptr<const RateDependentModel> model, const State& state, double rate)
        : Block(dt), model_(std::move(model)), initial_(state), rate0_(rate) {
        if (!model_) throw std::invalid_argument("rate_preisach: model is missing");
        sim_ = std::make_unique<RateSimulator>(*model_, initial_, rate0_, dt);
        y_ = sim_->output();
    }
    RateStage(const RateStage& o)
        : Block(o), model_(o.model_), initial_(o.initial_), rate0_(o.rate0_),
          sim_(std::make_unique<RateSimulator>(*o.sim_)), y_(o.y_) {}

    std::string kind() const override { return "rate_preisach"; }
    std::vector<Param> params() const override { return {{"rate", rate0_, "V/s"}}; }
    double reset(double) override {
        sim_->reset(initial_, rate0_);
        return y_ = sim_->output();
    }
    double step(double u) override {
        check_input("rate_preisach", u);
        return y_ = sim_->step(std::min(std::max(u, model_->u_min()), model_->u_max()));
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<RateStage>(*this); }

    // The boundary and filtered rate (V/s) the stage starts from after reset.
    void set_initial_state(const State& s, double rate) {
        RateSimulator probe(*model_, s, rate, dt());  // validates both against the model
        initial_ = s;
        rate0_ = rate;
    }
    const State& initial_state() const noexcept { return initial_; }
    double initial_rate() const noexcept { return rate0_; }
    // Current boundary, filtered rate (V/s) and output (V).
    State state() const { return sim_->state(); }
    double rate() const noexcept { return sim_->rate(); }
    double output() const noexcept { return y_; }
    const RateDependentModel& model() const noexcept { return *model_; }

private:
    std::shared_ptr<const RateDependentModel> model_;
    State initial_;
    double rate0_ = 0.0;
    std::unique_ptr<RateSimulator> sim_;
    double y_ = 0.0;
};

}  // namespace preisach::blocks

// The Preisach stage of a block chain, with an optional output feedback (moving model).
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../simulator.hpp"
#include "block.hpp"

namespace preisach::blocks {

// A classical Preisach model (an Everett table and a starting state) as a block, optionally
// made a *moving* Preisach model: the relays see the effective input
//   u_eff[k] = clamp(u[k] + moving_gain * y[k-1], u_min, u_max),
// the Della Torre moving model (H_eff = H + alpha M) with the output in volts.  Physics:
// the strain of the bimorph feeds back on the field its domains see (mechanical stress and
// depolarisation), so the output itself shifts the switching thresholds.  The classical
// model has congruent minor loops: loops between the same two inputs have the same shape
// whatever the history.  With moving_gain != 0 a loop that sits higher on the output axis
// sees its thresholds shifted by moving_gain * dy, so loops between the same inputs are
// sheared differently -- non-congruent minor loops, as the thesis's CML test showed ("not
// exactly congruent", Fig 3.14-3.16) -- while wiping-out still holds for u_eff.  Inputs
// outside the model range are clamped (saturation); NaN/inf raise.
//
// reset(x0) returns the stage to its starting state; x0 is ignored because a hysteretic
// system has no unique steady state for a constant input -- the starting state decides.
class PreisachStage final : public Block {
public:
    PreisachStage(double dt, std::shared_ptr<const EverettTable> table, const State& state, double moving_gain = 0.0)
        : Block(dt), table_(std::move(table)), initial_(state) {
        if (!table_) throw std::invalid_argument("preisach: table is missing");
        k_ = finite("preisach", "moving_gain", moving_gain);
        sim_ = std::make_unique<Simulator>(*table_, initial_);
        y_ = sim_->output();
    }
    PreisachStage(const PreisachStage& o)
        : Block(o), table_(o.table_), initial_(o.initial_), k_(o.k_),
          sim_(std::make_unique<Simulator>(*o.sim_)), y_(o.y_) {}

    std::string kind() const override { return "preisach"; }
    std::vector<Param> params() const override { return {{"moving_gain", k_, "V/V"}}; }
    double reset(double) override {
        sim_->reset(initial_);
        return y_ = sim_->output();
    }
    double step(double u) override {
        check_input("preisach", u);
        const double ue = std::min(std::max(u + k_ * y_, table_->u_min()), table_->u_max());
        return y_ = sim_->step(ue);
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<PreisachStage>(*this); }

    // The state the stage starts from after reset (and now, from the next reset on).
    void set_initial_state(const State& s) {
        Simulator probe(*table_, s);  // validates the state against the table's range
        initial_ = s;
    }
    const State& initial_state() const noexcept { return initial_; }
    // Current Preisach state, its (effective) input and output.
    State state() const { return sim_->state(); }
    double output() const noexcept { return y_; }
    const EverettTable& table() const noexcept { return *table_; }
    std::shared_ptr<const EverettTable> table_ptr() const noexcept { return table_; }
    double moving_gain() const noexcept { return k_; }

private:
    std::shared_ptr<const EverettTable> table_;
    State initial_;
    double k_ = 0.0;
    std::unique_ptr<Simulator> sim_;
    double y_ = 0.0;
};

}  // namespace preisach::blocks

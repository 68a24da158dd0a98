// A chain of blocks in series: input blocks -> Preisach stage -> output blocks.
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "block.hpp"
#include "preisach_stage.hpp"

namespace preisach::blocks {

// A series connection of blocks with a common sample time.  It is a value: copying clones
// every block, so a chain handed to a device or a fit is independent of the caller's.  Any
// block may appear anywhere; the augmented model of the architecture is
//   [input blocks..., PreisachStage, output blocks...].
// run() processes the whole array block by block (each block's loop stays hot), which gives
// the same result as stepping the chain sample by sample because the chain is feed-forward.
class Chain {
public:
    Chain() = default;
    explicit Chain(std::vector<std::unique_ptr<Block>> blocks) : blocks_(std::move(blocks)) { check(); }
    Chain(const Chain& o) { *this = o; }
    Chain(Chain&&) noexcept = default;
    Chain& operator=(const Chain& o) {
        if (this == &o) return *this;
        std::vector<std::unique_ptr<Block>> b;
        b.reserve(o.blocks_.size());
        for (const auto& p : o.blocks_) b.push_back(p->clone());
        blocks_ = std::move(b);
        return *this;
    }
    Chain& operator=(Chain&&) noexcept = default;

    std::size_t size() const noexcept { return blocks_.size(); }
    const Block& operator[](std::size_t i) const { return *blocks_.at(i); }
    Block& operator[](std::size_t i) { return *blocks_.at(i); }
    // Sample time (s); 0 for an empty chain.
    double dt() const noexcept { return blocks_.empty() ? 0.0 : blocks_.front()->dt(); }

    // Reset every block to the steady state for a constant input u0 (propagated through the
    // chain; a Preisach stage returns to its starting state) and return the output.
    double reset(double u0) {
        double x = u0;
        for (auto& b : blocks_) x = b->reset(x);
        return x;
    }
    double step(double u) {
        double x = u;
        for (auto& b : blocks_) x = b->step(x);
        return x;
    }
    void run(const double* u, double* y, std::size_t n) {
        if (y != u) std::copy(u, u + n, y);
        for (auto& b : blocks_) b->run(y, y, n);
    }

    // The first Preisach stage, or nullptr.
    PreisachStage* preisach() noexcept {
        for (auto& b : blocks_)
            if (auto* p = dynamic_cast<PreisachStage*>(b.get())) return p;
        return nullptr;
    }
    const PreisachStage* preisach() const noexcept { return const_cast<Chain*>(this)->preisach(); }

private:
    void check() const {
        for (std::size_t i = 0; i < blocks_.size(); ++i) {
            if (!blocks_[i]) throw std::invalid_argument("chain: block " + std::to_string(i) + " is missing");
            const double d0 = blocks_[0]->dt(), d = blocks_[i]->dt();
            if (std::abs(d - d0) > 1e-12 * d0)
                throw std::invalid_argument("chain: block " + std::to_string(i) + " (" + blocks_[i]->kind() +
                                            ") has sample time " + std::to_string(d) + " s but block 0 (" +
                                            blocks_[0]->kind() + ") has " + std::to_string(d0) + " s");
        }
    }
    std::vector<std::unique_ptr<Block>> blocks_;
};

}  // namespace preisach::blocks

// Physics blocks: the small dynamic systems that a classical Preisach model leaves out.
//
// A block is a single-input single-output discrete-time system sampled every `dt` seconds,
// with a few named parameters, an internal state, `reset`, `step` and a vectorised `run`.
// Blocks compose into a chain  input blocks -> Preisach stage -> output blocks  (chain.hpp)
// that the virtual rig uses to make realistic recordings and that diagnosis can fit.
//
// Sampling convention: `step(x)` advances the block over one sample interval with the input
// held at x (zero-order hold) and returns the output at the end of that interval.  Linear
// blocks are discretised exactly under this convention (matrix exponential), so their
// response does not depend on the sample time beyond the hold itself.
#pragma once

#include <cmath>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace preisach::blocks {

// A named parameter value with its unit (for documentation, printing and fitting).
struct Param {
    std::string name;
    double value;
    std::string unit;
};

class Block {
public:
    virtual ~Block() = default;

    // Short identifier of the block type, e.g. "structural_mode".
    virtual std::string kind() const = 0;
    // The block's parameters in constructor order (dt excluded).
    virtual std::vector<Param> params() const = 0;
    // Reset the state to the steady state for a constant input x0 (random generators are
    // re-seeded) and return the steady output.
    virtual double reset(double x0) = 0;
    // Advance one sample with input x (held); returns the output.
    virtual double step(double x) = 0;
    // Vectorised step over n samples; x and y may be the same array (in-place).
    virtual void run(const double* x, double* y, std::size_t n) {
        for (std::size_t i = 0; i < n; ++i) y[i] = step(x[i]);
    }
    virtual std::unique_ptr<Block> clone() const = 0;

    // Sample time (s).
    double dt() const noexcept { return dt_; }

protected:
    explicit Block(double dt) : dt_(dt) {
        if (!(std::isfinite(dt) && dt > 0.0))
            throw std::invalid_argument("dt: the sample time must be a positive finite number of seconds, got " +
                                        std::to_string(dt));
    }

    // Validation helpers: the message names the block kind and the parameter.
    static double finite(const char* kind, const char* name, double v) {
        if (!std::isfinite(v))
            throw std::invalid_argument(std::string(kind) + ": parameter " + name + " must be finite, got " +
                                        std::to_string(v));
        return v;
    }
    static double positive(const char* kind, const char* name, double v) {
        if (!(std::isfinite(v) && v > 0.0))
            throw std::invalid_argument(std::string(kind) + ": parameter " + name +
                                        " must be a positive finite number, got " + std::to_string(v));
        return v;
    }
    static double non_negative(const char* kind, const char* name, double v) {
        if (!(std::isfinite(v) && v >= 0.0))
            throw std::invalid_argument(std::string(kind) + ": parameter " + name + " must be finite and >= 0, got " +
                                        std::to_string(v));
        return v;
    }
    // Input check of step(): NaN/inf would silently poison the state.
    static void check_input(const char* kind, double x) {
        if (!std::isfinite(x)) throw std::invalid_argument(std::string(kind) + ": input is not finite");
    }

private:
    double dt_;
};

}  // namespace preisach::blocks

// Linear physics blocks, discretised exactly (zero-order hold, matrix exponential):
//   StructuralMode - the lightly damped bending mode of the bimorph (output side);
//   InputLag       - the SA11 amplifier driving the bimorph's capacitance (input side), which
//                    also makes the hysteresis rate dependent.
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "block.hpp"

namespace preisach::blocks {

// exp(M) of a small square matrix by scaling and squaring of the Taylor series; with the
// norm scaled below 1/2, 18 terms are accurate to rounding.
template <int N>
Eigen::Matrix<double, N, N> expm_small(const Eigen::Matrix<double, N, N>& m) {
    using Mat = Eigen::Matrix<double, N, N>;
    const double norm = m.cwiseAbs().rowwise().sum().maxCoeff();
    int squarings = 0;
    double scale = 1.0;
    while (norm * scale > 0.5) {
        scale *= 0.5;
        ++squarings;
    }
    const Mat a = m * scale;
    Mat term = Mat::Identity();
    Mat sum = Mat::Identity();
    for (int k = 1; k <= 18; ++k) {
        term = term * a / double(k);
        sum += term;
    }
    for (int k = 0; k < squarings; ++k) sum = sum * sum;
    return sum;
}

// Lightly damped structural mode: G(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2), wn = 2 pi f_n,
// unit DC gain, so it leaves slow (quasi-static) signals unchanged and makes steps ring at
// f_n.  Physics: the bimorph is a cantilever; the piezo moment (the hysteretic quantity the
// Preisach model describes) drives its first bending mode, and the strain gauges see the
// beam's response.  The thesis measured f_n = 37.62 Hz from a 7 V step (Fig 4.1/4.2); it
// does not report the damping, so zeta (default 0.02, typical of a bare metal/ceramic
// cantilever) is an assumption to be fitted.  The state [p, v / wn] evolves exactly as
// x[k+1] = Phi x[k] + Gamma u[k] with [Phi Gamma; 0 1] = exp([A B; 0 0] dt).
class StructuralMode final : public Block {
public:
    StructuralMode(double dt, double frequency = 37.62, double damping = 0.02) : Block(dt) {
        f_ = positive("structural_mode", "frequency", frequency);
        zeta_ = non_negative("structural_mode", "damping", damping);
        if (f_ >= 0.5 / dt)
            throw std::invalid_argument("structural_mode: parameter frequency (" + std::to_string(f_) +
                                        " Hz) must be below the Nyquist frequency 0.5/dt = " +
                                        std::to_string(0.5 / dt) + " Hz");
        const double wn = 6.283185307179586 * f_;
        Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
        m(0, 1) = wn;
        m(1, 0) = -wn;
        m(1, 1) = -2.0 * zeta_ * wn;
        m(1, 2) = wn;
        const Eigen::Matrix3d e = expm_small<3>(m * dt);
        phi_ = e.topLeftCorner<2, 2>();
        gamma_ = e.block<2, 1>(0, 2);
        reset(0.0);
    }
    std::string kind() const override { return "structural_mode"; }
    std::vector<Param> params() const override { return {{"frequency", f_, "Hz"}, {"damping", zeta_, "1"}}; }
    double reset(double x0) override {
        x_ << x0, 0.0;
        return x0;
    }
    double step(double u) override {
        check_input("structural_mode", u);
        x_ = phi_ * x_ + gamma_ * u;
        return x_(0);
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<StructuralMode>(*this); }
    double frequency() const noexcept { return f_; }
    double damping() const noexcept { return zeta_; }

private:
    double f_ = 0.0, zeta_ = 0.0;
    Eigen::Matrix2d phi_;
    Eigen::Vector2d gamma_;
    Eigen::Vector2d x_;
};

// First-order lag on the input: tau dz/dt = x - z, exact under zero-order hold,
// z[k+1] = z[k] + (1 - exp(-dt/tau)) (x[k] - z[k]); output z[k+1].
//
// Physics: the SA11 amplifier drives the bimorph, a capacitive load, through its output
// impedance, so the voltage across the piezo lags the command (an RC low-pass).  Placed before
// the Preisach stage it makes the hysteresis rate dependent: at an input rate du/dt the relays
// see u - tau du/dt (to first order), so rising branches shift right and falling branches left
// by tau |du/dt| and the loops in the (u, y) plane widen in proportion to the rate -- the
// widening with frequency the thesis observed between 1, 2 and 4 Hz (section 3.2.1).  This is
// preferred to rescaling the Everett function with the rate because it keeps the model a
// Preisach model of a (filtered) input, so wiping-out and congruency still hold for the
// piezo voltage, as they did in the measurements.
class InputLag final : public Block {
public:
    InputLag(double dt, double time_constant = 1e-3) : Block(dt) {
        tau_ = positive("input_lag", "time_constant", time_constant);
        a_ = -std::expm1(-dt / tau_);
        reset(0.0);
    }
    std::string kind() const override { return "input_lag"; }
    std::vector<Param> params() const override { return {{"time_constant", tau_, "s"}}; }
    double reset(double x0) override { return z_ = x0; }
    double step(double x) override {
        check_input("input_lag", x);
        z_ += a_ * (x - z_);
        return z_;
    }
    std::unique_ptr<Block> clone() const override { return std::make_unique<InputLag>(*this); }
    double time_constant() const noexcept { return tau_; }

private:
    double tau_ = 0.0, a_ = 0.0, z_ = 0.0;
};

}  // namespace preisach::blocks

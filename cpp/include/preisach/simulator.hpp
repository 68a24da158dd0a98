// Boundary-tracking Preisach simulator: O(1) amortized work per input sample.
//
// The output is y = y_min + 2 * sum_k C_k, where C_k is the contribution of boundary piece k:
//   constant piece M on [b0, b1]:      C = E(M, b0) - E(M, b1)
//   antidiagonal piece c on [b0, b1]:  C = integral_b0^b1 -dE/dbeta(c - beta, beta) dbeta
// For a staircase this is Mayergoyz's sum over the reduced memory sequence.  The simulator
// keeps the prefix sums S_k = sum_{j<k} C_j beside the stack of pieces, and the live
// contribution of the last piece, so a sample costs one table look-up unless a reversal
// pushes a piece or wiping-out pops pieces (each piece is pushed and popped once).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "everett.hpp"
#include "memory.hpp"

namespace preisach {

// What to do with inputs outside [u_min, u_max].
enum class InputPolicy { clamp, raise };

// One-sided slopes dy/du of the output at the current state (Appendix A): `rising` if the
// input increases next (A.13), `falling` if it decreases next (A.27).  At a reversal the
// subderivative interval (A.31) is [min, max] of the two.
struct Slopes {
    double rising;
    double falling;
    double lower() const noexcept { return std::min(rising, falling); }
    double upper() const noexcept { return std::max(rising, falling); }
};

class Simulator {
public:
    Simulator(const EverettTable& table, const State& state) : t_(&table) { reset(state); }

    void reset(const State& state) {
        state.validate();
        if (std::abs(state.u_min() - t_->u_min()) > 1e-9 * (t_->u_max() - t_->u_min()) ||
            std::abs(state.u_max() - t_->u_max()) > 1e-9 * (t_->u_max() - t_->u_min()))
            throw std::invalid_argument("state: its input range [" + std::to_string(state.u_min()) + ", " +
                                        std::to_string(state.u_max()) + "] differs from the model's [" +
                                        std::to_string(t_->u_min()) + ", " + std::to_string(t_->u_max()) + "]");
        st_ = state;
        cur_ = st_.input();
        const auto& p = st_.pieces();
        const std::size_t k = p.size();
        S_.assign(k, 0.0);
        Eb0_.assign(k, 0.0);
        double acc = 0.0;
        for (std::size_t i = 0; i < k; ++i) {
            S_[i] = acc;
            if (!p[i].antidiag) Eb0_[i] = (*t_)(p[i].v, p[i].b0);
            const double end = st_.piece_end(i);
            const double c = p[i].antidiag ? t_->antidiagonal_integral(p[i].v, p[i].b0, end)
                                           : Eb0_[i] - (*t_)(p[i].v, end);
            if (i + 1 < k) acc += c; else live_ = c;
        }
        if (k == 0) live_ = 0.0;
        rising_ = k > 0 && !p.back().antidiag && p.back().v == cur_;
        update_output();
    }

    // Advance by one input sample (volts, already inside the range); returns the output.
    double step(double u) {
        if (u > cur_) rise(u);
        else if (u < cur_) fall(u);
        return y_;
    }

    // Input policy applied, NaN/inf rejected; `index` only names the sample in errors.
    double step_checked(double u, InputPolicy policy, std::size_t index) {
        if (!std::isfinite(u)) throw std::invalid_argument("input u[" + std::to_string(index) + "] is not finite");
        if (u < t_->u_min() || u > t_->u_max()) {
            if (policy == InputPolicy::raise)
                throw std::invalid_argument("input u[" + std::to_string(index) + "] = " + std::to_string(u) +
                                            " V is outside the model range [" + std::to_string(t_->u_min()) + ", " +
                                            std::to_string(t_->u_max()) + "] V");
            u = std::min(std::max(u, t_->u_min()), t_->u_max());
        }
        return step(u);
    }

    void run(const double* u, double* y, std::size_t n, InputPolicy policy) {
        for (std::size_t i = 0; i < n; ++i) y[i] = step_checked(u[i], policy, i);
    }

    double output() const noexcept { return y_; }
    double input() const noexcept { return cur_; }
    const EverettTable& table() const noexcept { return *t_; }
    std::size_t depth() const noexcept { return st_.pieces().size(); }

    State state() const {
        State s = st_;
        s.set_input(cur_);
        return s;
    }

    Slopes slopes() const {
        const auto& p = st_.pieces();
        const EverettTable& t = *t_;
        double up = 0.0, down = 0.0;
        if (cur_ < t.u_max()) {
            double bstar = cur_;
            std::size_t k = p.size();
            while (k > 0 && p[k - 1].phi_start() <= cur_) bstar = p[--k].b0;
            up = 2.0 * t.d_alpha(cur_, bstar);
        }
        if (cur_ > t.u_min()) {
            std::size_t k = p.size();
            while (k > 0 && p[k - 1].b0 >= cur_) --k;
            if (k > 0) {
                down = -2.0 * t.d_beta(p[k - 1].phi(cur_), cur_);
            }
        }
        return {up, down};
    }

private:
    void update_output() noexcept { y_ = t_->y_min() + 2.0 * (st_.pieces().empty() ? 0.0 : S_.back() + live_); }

    void pop() {
        st_.mutable_pieces().pop_back();
        S_.pop_back();
        Eb0_.pop_back();
    }

    void rise(double u) {
        auto& p = st_.mutable_pieces();
        std::size_t k = p.size();
        // Fast path: the last piece is already rising and nothing below it is wiped out.
        if (rising_ && (k < 2 || p[k - 2].phi_start() > u)) {
            Piece& last = p[k - 1];
            last.v = u;
            live_ = (*t_)(u, last.b0);
            cur_ = u;
            update_output();
            return;
        }
        double bstar = cur_;
        bool popped = false;
        double s_top = 0.0;
        while (k > 0 && p[k - 1].phi_start() <= u) {
            bstar = p[k - 1].b0;
            s_top = S_[k - 1];
            pop();
            --k;
            popped = true;
        }
        double s_new = 0.0;
        if (k > 0) {
            const Piece& last = p[k - 1];
            double c = popped ? s_top - S_[k - 1] : live_;  // contribution of `last` up to bstar
            if (last.antidiag && last.v - bstar < u) {      // the rise cuts into the slope
                const double cut = last.v - u;
                c -= t_->antidiagonal_integral(last.v, cut, bstar);
                bstar = cut;
            }
            s_new = S_[k - 1] + c;
        } else {
            bstar = t_->u_min();
        }
        p.push_back(Piece{bstar, u, false});
        S_.push_back(s_new);
        Eb0_.push_back(0.0);
        live_ = (*t_)(u, bstar);
        rising_ = true;
        cur_ = u;
        update_output();
    }

    void fall(double u) {
        auto& p = st_.mutable_pieces();
        std::size_t k = p.size();
        if (rising_) {  // the rising piece becomes a falling one with M = the last input
            Eb0_[k - 1] = live_;
            rising_ = false;
        }
        double old_end = cur_;
        double c_old = live_;
        bool popped = false;
        while (k > 0 && p[k - 1].b0 >= u) {
            old_end = p[k - 1].b0;
            c_old = S_[k - 1];
            pop();
            --k;
            popped = true;
        }
        cur_ = u;
        if (k == 0) {
            live_ = 0.0;
            update_output();
            return;
        }
        const Piece& last = p[k - 1];
        if (last.antidiag) {
            if (popped) c_old -= S_[k - 1];
            live_ = c_old - t_->antidiagonal_integral(last.v, u, old_end);
        } else {
            live_ = Eb0_[k - 1] - (*t_)(last.v, u);
        }
        update_output();
    }

    const EverettTable* t_;
    State st_;
    std::vector<double> S_;    // S_[k]: sum of the contributions of the pieces below k
    std::vector<double> Eb0_;  // constant pieces: E(M, b0)
    double live_ = 0.0;        // contribution of the last piece up to the current input
    double cur_ = 0.0;         // current input
    double y_ = 0.0;           // current output
    bool rising_ = false;      // the last piece is the rising one (phi = current input)
};

// Read-out Gamma(psi): the output of a state without simulating.
inline double readout(const EverettTable& table, const State& state) { return Simulator(table, state).output(); }

// Apply a sequence of inputs to a state, geometry only (no table needed): used to build a
// state from an explicit sequence of extrema.
inline State apply_inputs(const State& start, const std::vector<double>& inputs) {
    Eigen::VectorXd lv(2);
    lv << start.u_min(), start.u_max();
    const RowMatrixXd zero = RowMatrixXd::Zero(2, 2);
    const EverettTable flat(lv, zero, 0.0);
    Simulator sim(flat, start);
    for (std::size_t i = 0; i < inputs.size(); ++i) sim.step_checked(inputs[i], InputPolicy::raise, i);
    return sim.state();
}

}  // namespace preisach

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
#include <limits>
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
        const double span = t_->u_max() - t_->u_min();
        if (std::abs(state.u_min() - t_->u_min()) > 1e-9 * span || std::abs(state.u_max() - t_->u_max()) > 1e-9 * span)
            throw std::invalid_argument("state: its input range [" + std::to_string(state.u_min()) + ", " +
                                        std::to_string(state.u_max()) + "] differs from the model's [" +
                                        std::to_string(t_->u_min()) + ", " + std::to_string(t_->u_max()) + "]");
        u_min_ = state.u_min();
        u_max_ = state.u_max();
        y_min_ = t_->y_min();
        cur_ = state.input();
        const auto& p = state.pieces();
        const std::size_t k = p.size();
        nodes_.clear();
        nodes_.reserve(std::max<std::size_t>(k, 64));
        double acc = 0.0;
        live_ = 0.0;
        ad_.clear();
        for (std::size_t i = 0; i < k; ++i) {
            Node nd{p[i], acc, p[i].antidiag ? 0.0 : (*t_)(p[i].v, p[i].b0)};
            const double end = state.piece_end(i);
            double c;
            if (p[i].antidiag) {  // its prefix integrals are built by prepare() (the inverter's)
                nd.ad = static_cast<int>(ad_.size());
                ad_.push_back(Antidiag{p[i].v, p[i].b0, end, {}, {}, {}, {}});
                c = t_->antidiagonal_integral(p[i].v, p[i].b0, end);
            } else {
                c = nd.Eb0 - (*t_)(p[i].v, end);
            }
            nodes_.push_back(nd);
            if (i + 1 < k) acc += c; else live_ = c;
        }
        rising_ = k > 0 && !p.back().antidiag && p.back().v == cur_;
        cur_pos_ = t_->position(cur_);
        if (k > 0 && !p.back().antidiag) fix_ = t_->position(rising_ ? p.back().b0 : p.back().v);
        set_limits();
        update_output();
    }

    // Advance by one input sample (volts, already inside the range); returns the output.
    double step(double u) {
        if (u == cur_) return y_;
        const bool up = u > cur_;
        // Inside (lo_, hi_) nothing is wiped out and no antidiagonal piece is cut: the last
        // piece is a constant one starting at lo_, and hi_ is where a rise would meet the
        // boundary above.  Continuing the branch or reversing only touches the last piece.
        if (u > lo_ && u < hi_) {
            const GridPos pu = t_->position(u);
            if (up == rising_) {  // continue along the branch, without a branch on direction
                const GridPos a{up ? pu.i : fix_.i, up ? pu.f : fix_.f};
                const GridPos b{up ? fix_.i : pu.i, up ? fix_.f : pu.f};
                const double v = t_->value(a, b);
                live_ = up ? v : eb0_ - v;
                double& m = nodes_.back().p.v;  // the rising piece follows the input
                m = up ? u : m;
            } else if (up) {  // reversal at a minimum: push a rising piece from cur_
                s_last_ += live_;
                nodes_.push_back(Node{Piece{cur_, u, false}, s_last_, 0.0, -1});
                lo_ = cur_;
                fix_ = cur_pos_;
                live_ = t_->value(pu, fix_);
                rising_ = true;
            } else {  // reversal at a maximum: the rising piece becomes a falling one
                Node& last = nodes_.back();
                last.Eb0 = eb0_ = live_;
                hi_ = cur_;
                fix_ = cur_pos_;
                live_ = eb0_ - t_->value(fix_, pu);
                rising_ = false;
            }
            cur_ = u;
            cur_pos_ = pu;
            update_output();
            return y_;
        }
        if (up) rise(u); else fall(u);
        return y_;
    }

    // Input policy applied, NaN/inf rejected; `index` only names the sample in errors.
    double step_checked(double u, InputPolicy policy, std::size_t index) {
        if (!(u >= u_min_ && u <= u_max_)) {  // one test for the common case; NaN fails it too
            if (!std::isfinite(u))
                throw std::invalid_argument("input u[" + std::to_string(index) + "] is not finite");
            if (policy == InputPolicy::raise)
                throw std::invalid_argument("input u[" + std::to_string(index) + "] = " + std::to_string(u) +
                                            " V is outside the model range [" + std::to_string(u_min_) + ", " +
                                            std::to_string(u_max_) + "] V");
            u = std::min(std::max(u, u_min_), u_max_);
        }
        return step(u);
    }

    void run(const double* u, double* y, std::size_t n, InputPolicy policy) {
        for (std::size_t i = 0; i < n; ++i) y[i] = step_checked(u[i], policy, i);
    }

    double output() const noexcept { return y_; }
    double input() const noexcept { return cur_; }
    const EverettTable& table() const noexcept { return *t_; }
    std::size_t depth() const noexcept { return nodes_.size(); }

    State state() const {
        std::vector<Piece> p;
        p.reserve(nodes_.size());
        for (const Node& nd : nodes_) p.push_back(nd.p);
        return State(u_min_, u_max_, cur_, std::move(p));
    }

    Slopes slopes() const {
        const EverettTable& t = *t_;
        double up = 0.0, down = 0.0;
        if (cur_ < u_max_) {
            double bstar = cur_;
            std::size_t k = nodes_.size();
            while (k > 0 && nodes_[k - 1].p.phi_start() <= cur_) bstar = nodes_[--k].p.b0;
            up = 2.0 * t.d_alpha(cur_, bstar);
        }
        if (cur_ > u_min_) {
            std::size_t k = nodes_.size();
            while (k > 0 && nodes_[k - 1].p.b0 >= cur_) --k;
            if (k > 0) down = -2.0 * t.d_beta(nodes_[k - 1].p.phi(cur_), cur_);
        }
        return {up, down};
    }

private:
    friend class Inverter;  // inverse.hpp reads the stack to search an excursion, then steps

    struct Node {
        Piece p;
        double S;    // sum of the contributions of the pieces below this one
        double Eb0;  // constant pieces: E(M, b0), once the piece has stopped rising
        int ad = -1; // antidiagonal pieces: index of their prefix integrals in ad_
    };

    // Prefix integrals of an antidiagonal piece phi = c - beta over [b0, end] (its extent
    // when the state was set: antidiagonal pieces are never created by stepping, only cut
    // or popped).  Between neighbouring break points x[k] (grid lines beta = l_k and
    // alpha = c - beta = l_k) the integrand -dE/dbeta(c - beta, beta) is linear: g[k] is
    // its value at the middle of [x[k], x[k+1]], s[k] its slope, P[k] = A(c, x[0], x[k]).
    // So A(c, lo, hi) costs two binary searches instead of a walk over the cells crossed
    // (the walk is done once, by prepare()).  The simulator itself keeps cutting pieces with
    // EverettTable::antidiagonal_integral (a walk over the wiped part only: each part of a
    // piece is wiped once, so it is amortised O(1) per sample), which keeps its outputs bit
    // for bit those of the rate-dependent simulator and of earlier versions.
    struct Antidiag {
        double c, b0, end;
        std::vector<double> x, P, g, s;

        bool built() const noexcept { return !x.empty(); }

        void build(const EverettTable& t) {
            const auto& L = t.levels();
            x.clear();
            x.push_back(b0);
            for (auto it = std::upper_bound(L.begin(), L.end(), b0); it != L.end() && *it < end; ++it)
                x.push_back(*it);
            for (auto it = std::upper_bound(L.begin(), L.end(), c - end); it != L.end() && *it < c - b0; ++it)
                x.push_back(c - *it);
            x.push_back(end);
            std::sort(x.begin(), x.end());
            x.erase(std::unique(x.begin(), x.end()), x.end());
            const std::size_t n = x.size();
            P.assign(n, 0.0);
            g.assign(n > 1 ? n - 1 : 0, 0.0);
            s.assign(g.size(), 0.0);
            for (std::size_t k = 0; k + 1 < n; ++k) {
                const double lo = x[k], hi = x[k + 1], d = hi - lo;
                const double q1 = lo + 0.25 * d, q3 = lo + 0.75 * d;  // interior: one cell each
                const double v1 = -t.d_beta(c - q1, q1), v3 = -t.d_beta(c - q3, q3);
                g[k] = 0.5 * (v1 + v3);
                s[k] = d > 0.0 ? (v3 - v1) / (0.5 * d) : 0.0;
                P[k + 1] = P[k] + g[k] * d;
            }
        }

        // A(c, x[0], b) for b in [b0, end] (clamped).
        double prefix(double b) const noexcept {
            if (!(b > x.front())) return 0.0;
            if (b >= x.back()) return P.back();
            const std::size_t k =
                static_cast<std::size_t>(std::upper_bound(x.begin(), x.end(), b) - x.begin()) - 1;
            const double tt = b - x[k], d = x[k + 1] - x[k];
            return P[k] + g[k] * tt + 0.5 * s[k] * tt * (tt - d);
        }
    };

    // Build the prefix integrals of every antidiagonal piece (the inverter searches them).
    void prepare() {
        for (Antidiag& a : ad_)
            if (!a.built()) a.build(*t_);
    }

    void update_output() noexcept { y_ = y_min_ + 2.0 * (s_last_ + live_); }

    // Limits of the fast path after the last piece changed (see step()): lo_ is the start
    // of a constant last piece; hi_ the value of phi just above the last piece (rising) or
    // the last piece's M (falling).  An antidiagonal or missing last piece disables it.
    void set_limits() noexcept {
        const std::size_t k = nodes_.size();
        s_last_ = k ? nodes_[k - 1].S : 0.0;
        const double inf = std::numeric_limits<double>::infinity();
        if (k == 0 || nodes_[k - 1].p.antidiag) {
            lo_ = inf;
            hi_ = -inf;
            return;
        }
        const Node& last = nodes_[k - 1];
        lo_ = last.p.b0;
        if (rising_) {
            hi_ = k >= 2 ? nodes_[k - 2].p.phi(last.p.b0) : inf;
        } else {
            hi_ = last.p.v;
            eb0_ = last.Eb0;
        }
    }

    void rise(double u) {
        std::size_t k = nodes_.size();
        double bstar = cur_;
        double s_top = 0.0;
        bool popped = false;
        while (k > 0 && nodes_[k - 1].p.phi_start() <= u) {
            bstar = nodes_[k - 1].p.b0;
            s_top = nodes_[k - 1].S;
            nodes_.pop_back();
            --k;
            popped = true;
        }
        double s_new = 0.0;
        if (k > 0) {
            const Node& last = nodes_[k - 1];
            double c = popped ? s_top - last.S : live_;  // contribution of `last` up to bstar
            if (last.p.antidiag && last.p.v - bstar < u) {  // the rise cuts into the slope
                const double cut = last.p.v - u;
                c -= t_->antidiagonal_integral(last.p.v, cut, bstar);
                bstar = cut;
            }
            s_new = last.S + c;
        } else {
            bstar = u_min_;
        }
        nodes_.push_back(Node{Piece{bstar, u, false}, s_new, 0.0, -1});
        fix_ = bstar == cur_ ? cur_pos_ : t_->position(bstar);
        cur_pos_ = t_->position(u);
        live_ = t_->value(cur_pos_, fix_);
        rising_ = true;
        cur_ = u;
        set_limits();
        update_output();
    }

    void fall(double u) {
        std::size_t k = nodes_.size();
        bool same_piece = false;
        if (rising_) {  // the rising piece becomes a falling one with M = the last input
            nodes_[k - 1].Eb0 = live_;
            fix_ = cur_pos_;
            rising_ = false;
            same_piece = true;
        }
        double old_end = cur_;
        double c_old = live_;
        bool popped = false;
        while (k > 0 && nodes_[k - 1].p.b0 >= u) {
            old_end = nodes_[k - 1].p.b0;
            c_old = nodes_[k - 1].S;
            nodes_.pop_back();
            --k;
            popped = true;
        }
        cur_ = u;
        cur_pos_ = t_->position(u);
        if (k == 0) {
            live_ = 0.0;
            set_limits();
            update_output();
            return;
        }
        const Node& last = nodes_[k - 1];
        if (last.p.antidiag) {
            if (popped) c_old -= last.S;
            live_ = c_old - t_->antidiagonal_integral(last.p.v, u, old_end);
        } else {
            if (popped || !same_piece) fix_ = t_->position(last.p.v);
            live_ = last.Eb0 - t_->value(fix_, cur_pos_);
        }
        set_limits();
        update_output();
    }

    const EverettTable* t_;
    std::vector<Node> nodes_;  // the boundary pieces, lowest beta first, with cached sums
    std::vector<Antidiag> ad_; // prefix integrals of the antidiagonal pieces of the start state
    double u_min_ = 0.0, u_max_ = 0.0, y_min_ = 0.0;
    GridPos cur_pos_{0, 0.0};  // grid position of the current input
    GridPos fix_{0, 0.0};      // grid position of the last constant piece's fixed coordinate
                               // (b0 while rising, M while falling)
    double live_ = 0.0;        // contribution of the last piece up to the current input
    double s_last_ = 0.0;      // S of the last piece
    double eb0_ = 0.0;         // E(M, b0) of the last piece while it falls
    double lo_ = 0.0, hi_ = 0.0;  // fast-path limits (see set_limits)
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

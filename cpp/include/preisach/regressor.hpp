// The output of a Preisach model as a linear function of its Everett table.
//
// For a fixed input history the output of the tabulated model (everett.hpp, simulator.hpp) is
//     y = y_min + 2 * sum_k C_k,
// and every piece contribution C_k is a linear combination of Everett table values: a constant
// piece M on [b0, b1] gives E(M, b0) - E(M, b1), each E(a, b) being the bilinear (on the
// diagonal: linear) interpolation of 4 nodes (cubic grids: 16); an antidiagonal piece gives the integral of
// -dE/dbeta along it, which is linear in the nodes too.  So for every sample
//     y_t = r_t . theta,   theta = (E(1, 0), E(2, 0), E(2, 1), ..., E(n-1, n-2), y_min),
// with the Everett nodes E(i, j), j < i, in row-major order of the lower triangle (node index
// i (i - 1) / 2 + j) and y_min last.  r_t is sparse: a few coefficients per boundary piece.
//
// EverettRegressor tracks the boundary exactly as Simulator does (same pieces, same wiping-out,
// same interpolation) but emits r_t instead of y_t; with the true table, r_t . theta equals the
// simulator's output to rounding.  accumulate_normal_equations() sums r_t r_t^T, r_t y_t and
// y_t^2 per cross-validation fold without forming the (samples x parameters) matrix.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "everett.hpp"
#include "memory.hpp"
#include "simulator.hpp"
#include "types.hpp"

namespace preisach {

class EverettRegressor {
public:
    EverettRegressor(const VectorRef& levels, const State& state,
                     Interpolation interpolation = Interpolation::bilinear)
        : grid_(levels, RowMatrixXd::Zero(levels.size(), levels.size()), 0.0, interpolation) {
        const std::size_t n = grid_.size();
        n_nodes_ = n * (n - 1) / 2;
        acc_.assign(n_nodes_ + 1, 0.0);
        mark_.assign(n_nodes_ + 1, 0);
        inv_width_.resize(n - 1);
        for (std::size_t k = 0; k + 1 < n; ++k) inv_width_[k] = 1.0 / (grid_.levels()[k + 1] - grid_.levels()[k]);
        reset(state);
    }

    std::size_t n_levels() const noexcept { return grid_.size(); }
    std::size_t n_nodes() const noexcept { return n_nodes_; }
    std::size_t n_params() const noexcept { return n_nodes_ + 1; }
    static std::size_t node_index(std::size_t i, std::size_t j) noexcept { return i * (i - 1) / 2 + j; }
    double u_min() const noexcept { return grid_.u_min(); }
    double u_max() const noexcept { return grid_.u_max(); }
    double input() const noexcept { return cur_; }
    std::size_t depth() const noexcept { return pieces_.size(); }

    void reset(const State& state) {
        state.validate();
        const double span = grid_.u_max() - grid_.u_min();
        if (std::abs(state.u_min() - grid_.u_min()) > 1e-9 * span || std::abs(state.u_max() - grid_.u_max()) > 1e-9 * span)
            throw std::invalid_argument("state: its input range [" + std::to_string(state.u_min()) + ", " +
                                        std::to_string(state.u_max()) + "] differs from the levels' [" +
                                        std::to_string(grid_.u_min()) + ", " + std::to_string(grid_.u_max()) + "]");
        pieces_ = state.pieces();
        cur_ = state.input();
        dirty_ = true;
    }

    State state() const { return State(grid_.u_min(), grid_.u_max(), cur_, pieces_); }

    // Advance by one input sample (volts); NaN/inf raise, out-of-range inputs are clamped or
    // raise per `policy`; `index` names the sample in errors.  Only the boundary moves here; the
    // row is built when it is next asked for (a fit that uses every k-th sample pays for those).
    void step(double u, InputPolicy policy, std::size_t index) {
        const double lo = grid_.u_min(), hi = grid_.u_max();
        if (!(u >= lo && u <= hi)) {
            if (!std::isfinite(u)) throw std::invalid_argument("input u[" + std::to_string(index) + "] is not finite");
            if (policy == InputPolicy::raise)
                throw std::invalid_argument("input u[" + std::to_string(index) + "] = " + std::to_string(u) +
                                            " V is outside the levels' range [" + std::to_string(lo) + ", " +
                                            std::to_string(hi) + "] V");
            u = std::min(std::max(u, lo), hi);
        }
        if (u == cur_) return;
        if (u > cur_) rise(u); else fall(u);
        dirty_ = true;
    }

    // The current row: parameter indices (ascending) and coefficients, so that
    // y = sum_k value[k] * theta[index[k]].
    const std::vector<std::uint32_t>& row_index() const {
        if (dirty_) build_row();
        return idx_;
    }
    const std::vector<double>& row_value() const {
        if (dirty_) build_row();
        return val_;
    }

private:
    // ---- boundary geometry (the rules of Simulator::rise / Simulator::fall) ----
    void rise(double u) {
        double bstar = cur_;
        while (!pieces_.empty() && pieces_.back().phi_start() <= u) {
            bstar = pieces_.back().b0;
            pieces_.pop_back();
        }
        if (!pieces_.empty()) {
            const Piece& last = pieces_.back();
            if (last.antidiag && last.v - bstar < u) bstar = last.v - u;  // the rise cuts into the slope
        } else {
            bstar = grid_.u_min();
        }
        pieces_.push_back(Piece{bstar, u, false});
        cur_ = u;
    }

    void fall(double u) {
        while (!pieces_.empty() && pieces_.back().b0 >= u) pieces_.pop_back();
        cur_ = u;
    }

    // ---- linear functionals ----
    // Coefficient c on the full-table entry (i, j) (antisymmetric extension above the diagonal).
    void add_entry(std::size_t i, std::size_t j, double c) const {
        if (c == 0.0 || i == j) return;
        if (j > i) {
            std::swap(i, j);
            c = -c;
        }
        add_param(node_index(i, j), c);
    }
    void add_param(std::size_t p, double c) const {
        if (!mark_[p]) {
            mark_[p] = 1;
            touched_.push_back(std::uint32_t(p));
        }
        acc_[p] += c;
    }
    // c * E(alpha, beta), alpha >= beta, interpolated as EverettTable::operator().
    void add_E(double alpha, double beta, double c) const {
        if (alpha <= beta) return;
        const GridPos a = grid_.locate(alpha), b = grid_.locate(beta);
        if (grid_.cubic()) {
            add_cubic(a, b, c, false);
            return;
        }
        add_entry(a.i, b.i, c * (1.0 - a.f) * (1.0 - b.f));
        add_entry(a.i + 1, b.i, c * a.f * (1.0 - b.f));
        add_entry(a.i, b.i + 1, c * (1.0 - a.f) * b.f);
        add_entry(a.i + 1, b.i + 1, c * a.f * b.f);
    }
    // c * dE/dbeta at a point strictly inside a cell (EverettTable::d_beta_interior).
    void add_d_beta(double alpha, double beta, double c) const {
        const GridPos b = grid_.locate(beta, true);
        GridPos a = grid_.locate(alpha, true);
        if (grid_.cubic()) {
            add_cubic(a, b, c, true);
            return;
        }
        if (a.i < b.i) a = {b.i, a.f};
        const double w = inv_width_[b.i] * c;
        if (a.i == b.i) {
            add_entry(a.i + 1, a.i, -w);
            return;
        }
        add_entry(a.i, b.i + 1, w * (1.0 - a.f));
        add_entry(a.i, b.i, -w * (1.0 - a.f));
        add_entry(a.i + 1, b.i + 1, w * a.f);
        add_entry(a.i + 1, b.i, -w * a.f);
    }
    // c * E(a, b) of a cubic grid (d_beta: c * dE/dbeta), over the 4 x 4 stencil.
    void add_cubic(GridPos a, GridPos b, double c, bool d_beta) const {
        double wa[4], wb[4];
        const std::size_t sa = grid_.stencil(a, wa, false), sb = grid_.stencil(b, wb, d_beta);
        for (std::size_t k = 0; k < 4; ++k)
            for (std::size_t l = 0; l < 4; ++l) add_entry(sa + k, sb + l, c * wa[k] * wb[l]);
    }
    // c * integral_b0^b1 -dE/dbeta(cc - beta, beta) dbeta (EverettTable::antidiagonal_integral).
    void add_antidiagonal(double cc, double b0, double b1, double c) const {
        if (!(b1 > b0)) return;
        const auto& lv = grid_.levels();
        cuts_.clear();
        cuts_.push_back(b0);
        const auto add_range = [&](double lo, double hi, bool mirrored) {
            auto first = std::upper_bound(lv.begin(), lv.end(), lo);
            for (auto it = first; it != lv.end() && *it < hi; ++it) cuts_.push_back(mirrored ? cc - *it : *it);
        };
        add_range(b0, b1, false);
        add_range(cc - b1, cc - b0, true);
        cuts_.push_back(b1);
        std::sort(cuts_.begin(), cuts_.end());
        for (std::size_t k = 0; k + 1 < cuts_.size(); ++k) {
            const double lo = cuts_[k], hi = cuts_[k + 1];
            if (!(hi > lo)) continue;
            const double m = 0.5 * (lo + hi);
            if (grid_.cubic()) {
                const double half = 0.5 * (hi - lo);
                for (int g = 0; g < 3; ++g) {
                    const double x = m + double(g - 1) * kGauss3X * half;
                    add_d_beta(cc - x, x, -c * kGauss3W[g] * half);
                }
            } else {
                add_d_beta(cc - m, m, -c * (hi - lo));
            }
        }
    }

    void build_row() const {
        const std::size_t k = pieces_.size();
        for (std::size_t q = 0; q < k; ++q) {
            const Piece& p = pieces_[q];
            const double end = q + 1 < k ? pieces_[q + 1].b0 : cur_;
            if (p.antidiag) {
                add_antidiagonal(p.v, p.b0, end, 2.0);
            } else {
                add_E(p.v, p.b0, 2.0);
                add_E(p.v, end, -2.0);
            }
        }
        add_param(n_nodes_, 1.0);  // y_min
        std::sort(touched_.begin(), touched_.end());
        idx_.clear();
        val_.clear();
        for (std::uint32_t p : touched_) {
            if (acc_[p] != 0.0) {
                idx_.push_back(p);
                val_.push_back(acc_[p]);
            }
            acc_[p] = 0.0;
            mark_[p] = 0;
        }
        touched_.clear();
        dirty_ = false;
    }

    EverettTable grid_;  // levels and cell look-up only (all values zero)
    std::vector<double> inv_width_;
    std::size_t n_nodes_ = 0;
    std::vector<Piece> pieces_;
    double cur_ = 0.0;
    // the row, built lazily from the boundary (logically const)
    mutable bool dirty_ = true;
    mutable std::vector<double> acc_;
    mutable std::vector<char> mark_;
    mutable std::vector<std::uint32_t> touched_;
    mutable std::vector<std::uint32_t> idx_;
    mutable std::vector<double> val_;
    mutable std::vector<double> cuts_;
};

// Rows of the linear map for every input sample, in compressed sparse row form: row t holds
// indices[indptr[t] .. indptr[t+1]) and data[...] (see EverettRegressor).
struct RegressorRows {
    std::vector<std::int64_t> indptr;
    std::vector<std::uint32_t> indices;
    std::vector<double> data;
    State final_state;
};

inline RegressorRows regressor_rows(const VectorRef& levels, const State& state, const double* u, std::size_t n,
                                    InputPolicy policy, Interpolation interpolation = Interpolation::bilinear) {
    EverettRegressor reg(levels, state, interpolation);
    RegressorRows r;
    r.indptr.reserve(n + 1);
    r.indptr.push_back(0);
    for (std::size_t t = 0; t < n; ++t) {
        reg.step(u[t], policy, t);
        r.indices.insert(r.indices.end(), reg.row_index().begin(), reg.row_index().end());
        r.data.insert(r.data.end(), reg.row_value().begin(), reg.row_value().end());
        r.indptr.push_back(std::int64_t(r.indices.size()));
    }
    r.final_state = reg.state();
    return r;
}

// Normal equations of the least-squares fit of theta to outputs y, one set per fold.
struct NormalEquations {
    RowMatrixXd gram;      // sum r_t r_t^T (n_params x n_params)
    Eigen::VectorXd rhs;   // sum r_t y_t
    double yy = 0.0;       // sum y_t^2
    double ysum = 0.0;     // sum y_t
    std::size_t count = 0; // samples
};

// Where accumulate_normal_equations_into() writes, for K folds and p parameters: gram (K x p x
// p, row-major), rhs (K x p), yy, ysum and count (K each).  Every buffer is overwritten.
struct NormalEquationsOut {
    double* gram;
    double* rhs;
    double* yy;
    double* ysum;
    std::int64_t* count;
};

// Cross products of the rows with a basis in time: cross (K x p x k, row-major) receives
// sum r_t a_t^T per fold, a_t the row t of `basis` (n x k, row-major), e.g. a drift's
// B-splines, to be profiled out of the normal equations.
struct BasisCross {
    const double* basis;
    std::size_t k;
    double* cross;
};

// Run the input from `state` and add every sample t with fold[t] in [0, n_folds) to the normal
// equations of that fold (fold[t] < 0: the sample only advances the state, e.g. a burn-in),
// straight into the caller's buffers.  `final_state` receives the boundary after the last sample;
// `with`, when given, the rows' cross products with a basis.
inline void accumulate_normal_equations_into(const VectorRef& levels, const State& state, const double* u,
                                             const double* y, const std::int32_t* fold, std::size_t n,
                                             int n_folds, InputPolicy policy, NormalEquationsOut out,
                                             State* final_state = nullptr,
                                             Interpolation interpolation = Interpolation::bilinear,
                                             const BasisCross* with = nullptr) {
    if (n_folds < 1) throw std::invalid_argument("n_folds: must be >= 1, got " + std::to_string(n_folds));
    EverettRegressor reg(levels, state, interpolation);
    const std::size_t p = reg.n_params(), K = std::size_t(n_folds);
    std::fill(out.gram, out.gram + K * p * p, 0.0);
    std::fill(out.rhs, out.rhs + K * p, 0.0);
    std::fill(out.yy, out.yy + K, 0.0);
    std::fill(out.ysum, out.ysum + K, 0.0);
    std::fill(out.count, out.count + K, std::int64_t(0));
    if (with) std::fill(with->cross, with->cross + K * p * with->k, 0.0);
    for (std::size_t t = 0; t < n; ++t) {
        if (fold[t] >= n_folds)
            throw std::invalid_argument("fold[" + std::to_string(t) + "] = " + std::to_string(fold[t]) +
                                        " is not below n_folds = " + std::to_string(n_folds));
        reg.step(u[t], policy, t);
        if (fold[t] < 0) continue;
        const double yt = y[t];
        if (!std::isfinite(yt)) throw std::invalid_argument("output y[" + std::to_string(t) + "] is not finite");
        const std::size_t f = std::size_t(fold[t]);
        double* G = out.gram + f * p * p;
        double* b = out.rhs + f * p;
        const auto& ix = reg.row_index();
        const auto& vx = reg.row_value();
        const std::size_t k = ix.size();
        for (std::size_t a = 0; a < k; ++a) {
            const double va = vx[a];
            double* row = G + std::size_t(ix[a]) * p;
            for (std::size_t c = a; c < k; ++c) row[ix[c]] += va * vx[c];  // upper triangle (ix ascending)
            b[ix[a]] += va * yt;
        }
        if (with) {  // only the basis row's nonzeros (a B-spline basis has a few)
            const double* at = with->basis + t * with->k;
            double* C = with->cross + f * p * with->k;
            for (std::size_t j = 0; j < with->k; ++j) {
                if (at[j] == 0.0) continue;
                for (std::size_t a = 0; a < k; ++a) C[std::size_t(ix[a]) * with->k + j] += vx[a] * at[j];
            }
        }
        out.yy[f] += yt * yt;
        out.ysum[f] += yt;
        ++out.count[f];
    }
    for (std::size_t f = 0; f < K; ++f) {  // mirror the upper triangle
        double* G = out.gram + f * p * p;
        for (std::size_t a = 0; a < p; ++a)
            for (std::size_t c = 0; c < a; ++c) G[a * p + c] = G[c * p + a];
    }
    if (final_state) *final_state = reg.state();
}

// The same, into NormalEquations objects (one per fold).
inline std::vector<NormalEquations> accumulate_normal_equations(const VectorRef& levels, const State& state,
                                                                const double* u, const double* y,
                                                                const std::int32_t* fold, std::size_t n,
                                                                int n_folds, InputPolicy policy,
                                                                State* final_state = nullptr,
                                                                Interpolation interpolation = Interpolation::bilinear) {
    if (n_folds < 1) throw std::invalid_argument("n_folds: must be >= 1, got " + std::to_string(n_folds));
    const std::size_t nl = std::size_t(levels.size());
    const std::size_t p = nl >= 2 ? nl * (nl - 1) / 2 + 1 : 1;
    const std::size_t K = std::size_t(n_folds);
    std::vector<double> gram(K * p * p), rhs(K * p), yy(K), ysum(K);
    std::vector<std::int64_t> count(K);
    accumulate_normal_equations_into(levels, state, u, y, fold, n, n_folds, policy,
                                     {gram.data(), rhs.data(), yy.data(), ysum.data(), count.data()},
                                     final_state, interpolation);
    std::vector<NormalEquations> ne(K);
    for (std::size_t f = 0; f < K; ++f) {
        ne[f].gram = Eigen::Map<const RowMatrixXd>(gram.data() + f * p * p, Eigen::Index(p), Eigen::Index(p));
        ne[f].rhs = Eigen::Map<const Eigen::VectorXd>(rhs.data() + f * p, Eigen::Index(p));
        ne[f].yy = yy[f];
        ne[f].ysum = ysum[f];
        ne[f].count = std::size_t(count[f]);
    }
    return ne;
}

}  // namespace preisach

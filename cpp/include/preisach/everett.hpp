// Everett function of a classical Preisach model, tabulated on a triangular grid.
//
// Conventions (volts in, volts out):
//   * relay gamma(alpha, beta) switches to +1 when u >= alpha and to -1 when u <= beta,
//     alpha >= beta; r = (alpha - beta)/2, s = (alpha + beta)/2;
//   * E(alpha, beta) = integral of the Preisach weight mu over the triangle
//     { beta <= beta' <= alpha' <= alpha }, so E(alpha, alpha) = 0;
//   * from FOD data (Mayergoyz): E = (y_alpha - y_alpha,beta) / 2;
//   * output at negative saturation y_min; at positive saturation
//     y_max = y_min + 2 E(u_max, u_min).
//
// The table holds E at the grid nodes (alpha_i, beta_j), j <= i.  Between nodes E is
// interpolated bilinearly in the square cells and linearly in the half-cells on the
// diagonal, which keeps E (and so the model output) continuous; E(u, u) = 0 (exactly from
// operator(), to rounding from the cell formula of value()).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "types.hpp"

namespace preisach {

// Where a value lies on the grid: cell index and fraction inside the cell, in [0, 1].
struct GridPos {
    std::size_t i;
    double f;
};

class EverettTable {
public:
    EverettTable() = default;

    // levels: strictly increasing grid, n >= 2.  values: n x n, values(i, j) =
    // E(levels[i], levels[j]) for j <= i; entries with j >= i are ignored (the diagonal is 0).
    EverettTable(const VectorRef& levels, const MatrixRef& values, double y_min)
        : levels_(levels.data(), levels.data() + levels.size()), y_min_(y_min) {
        const std::size_t n = levels_.size();
        if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels, got " + std::to_string(n));
        if (std::size_t(values.rows()) != n || std::size_t(values.cols()) != n)
            throw std::invalid_argument("Everett table: shape (" + std::to_string(values.rows()) + ", " +
                                        std::to_string(values.cols()) + ") does not match " + std::to_string(n) +
                                        " levels; expected (" + std::to_string(n) + ", " + std::to_string(n) + ")");
        for (std::size_t k = 0; k < n; ++k) {
            if (!std::isfinite(levels_[k]))
                throw std::invalid_argument("levels[" + std::to_string(k) + "] is not finite");
            if (k > 0 && !(levels_[k] > levels_[k - 1]))
                throw std::invalid_argument("levels must be strictly increasing; levels[" + std::to_string(k) +
                                            "] <= levels[" + std::to_string(k - 1) + "]");
        }
        if (!std::isfinite(y_min)) throw std::invalid_argument("y_min is not finite");
        table_.assign(n * n, 0.0);
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = 0; j < i; ++j) {
                const double v = values(Eigen::Index(i), Eigen::Index(j));
                if (!std::isfinite(v))
                    throw std::invalid_argument("Everett table entry (" + std::to_string(i) + ", " +
                                                std::to_string(j) + ") is not finite");
                table_[i * n + j] = v;
            }
        // Antisymmetric extension above the diagonal, E(a, b) = -E(b, a): the bilinear
        // interpolant of a diagonal cell is then exactly the linear one of its lower
        // half-cell, E = e (fa - fb), so every cell is interpolated without a branch.
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = i + 1; j < n; ++j) table_[i * n + j] = -table_[j * n + i];
        // Per-cell bilinear coefficients, one contiguous block of 4 per cell:
        // E = c0 + c1 fa + c2 fb + c3 fa fb on cell (i, j) (alpha cell i, beta cell j).
        coef_.assign((n - 1) * (n - 1) * 4, 0.0);
        for (std::size_t i = 0; i + 1 < n; ++i)
            for (std::size_t j = 0; j + 1 < n; ++j) {
                const double e00 = table_[i * n + j], e01 = table_[i * n + j + 1];
                const double e10 = table_[(i + 1) * n + j], e11 = table_[(i + 1) * n + j + 1];
                double* c = &coef_[(i * (n - 1) + j) * 4];
                c[0] = e00;
                c[1] = e10 - e00;
                c[2] = e01 - e00;
                c[3] = e11 - e10 - e01 + e00;
            }
        u_min_ = levels_.front();
        u_max_ = levels_.back();
        const double h = (u_max_ - u_min_) / double(n - 1);
        uniform_ = true;
        for (std::size_t k = 0; k < n; ++k)
            if (std::abs(levels_[k] - (u_min_ + h * double(k))) > 1e-9 * (u_max_ - u_min_)) uniform_ = false;
        inv_h_ = 1.0 / h;
        inv_width_.resize(n - 1);
        for (std::size_t k = 0; k + 1 < n; ++k) inv_width_[k] = 1.0 / (levels_[k + 1] - levels_[k]);
    }

    std::size_t size() const noexcept { return levels_.size(); }
    const std::vector<double>& levels() const noexcept { return levels_; }
    double u_min() const noexcept { return u_min_; }
    double u_max() const noexcept { return u_max_; }
    double y_min() const noexcept { return y_min_; }
    double y_max() const noexcept { return y_min_ + 2.0 * node(size() - 1, 0); }
    bool uniform() const noexcept { return uniform_; }
    // Table value at the node (i, j); for j > i this is the extension -E(levels_j, levels_i).
    double node(std::size_t i, std::size_t j) const noexcept { return table_[i * size() + j]; }

    // Cell and fraction of u for evaluating E (u inside the range).  The interpolant is
    // continuous, so at a grid line either neighbouring cell gives the same value; this is
    // the branch-light look-up of the simulator's hot loop.
    GridPos position(double u) const noexcept {
        if (uniform_) {
            const double x = (u - u_min_) * inv_h_;
            std::size_t i = static_cast<std::size_t>(x);
            i = i < levels_.size() - 2 ? i : levels_.size() - 2;
            return {i, x - double(i)};
        }
        return locate(u, true);
    }

    // Cell containing u, choosing the lower cell at an interior grid line (upper=false) or
    // the upper one (upper=true).  u is clamped to the grid range.
    GridPos locate(double u, bool upper = true) const noexcept {
        const std::size_t n = size();
        if (u <= u_min_) return {0, 0.0};
        if (u >= u_max_) return {n - 2, 1.0};
        std::size_t i;
        if (uniform_) {
            const double x = (u - u_min_) * inv_h_;
            i = static_cast<std::size_t>(x);
            if (i > n - 2) i = n - 2;
            const double f = x - double(i);
            if (!upper && f == 0.0 && i > 0) return {i - 1, 1.0};
            if (upper && f >= 1.0 && i + 2 < n) return {i + 1, 0.0};
            return {i, std::min(std::max(f, 0.0), 1.0)};
        } else {
            i = static_cast<std::size_t>(std::upper_bound(levels_.begin(), levels_.end(), u) - levels_.begin()) - 1;
            if (i > n - 2) i = n - 2;
        }
        double f = (u - levels_[i]) * inv_width_[i];
        if (!upper && f == 0.0 && i > 0) return {i - 1, 1.0};
        if (upper && f >= 1.0 && i + 2 < n) return {i + 1, 0.0};
        return {i, std::min(std::max(f, 0.0), 1.0)};
    }

    // E at (alpha, beta), alpha >= beta, from located positions: bilinear in the cell
    // (linear in the half-cell on the diagonal, through the antisymmetric extension).
    double value(GridPos a, GridPos b) const noexcept {
        const double* c = &coef_[(a.i * (size() - 1) + b.i) * 4];
        return c[0] + c[1] * a.f + (c[2] + c[3] * a.f) * b.f;
    }

    double operator()(double alpha, double beta) const noexcept {
        if (alpha <= beta) return 0.0;
        return value(locate(alpha), locate(beta));
    }

    // dE/dalpha at (alpha, beta) with alpha approached from above (the cell right of alpha).
    double d_alpha(double alpha, double beta) const noexcept {
        const GridPos a = locate(alpha, true);
        GridPos b = locate(std::min(beta, alpha), true);
        if (b.i > a.i) b = {a.i, 0.0};
        const std::size_t n = size();
        const double w = inv_width_[a.i];
        if (a.i == b.i) return table_[(a.i + 1) * n + a.i] * w;
        const double* r0 = &table_[a.i * n];
        const double* r1 = r0 + n;
        return ((r1[b.i] - r0[b.i]) * (1.0 - b.f) + (r1[b.i + 1] - r0[b.i + 1]) * b.f) * w;
    }

    // dE/dbeta at (alpha, beta) with beta approached from below (the cell left of beta).
    double d_beta(double alpha, double beta) const noexcept {
        GridPos b = locate(beta, false);
        GridPos a = locate(std::max(alpha, beta), false);
        if (a.i < b.i) a = {b.i, 1.0};
        const std::size_t n = size();
        const double w = inv_width_[b.i];
        if (a.i == b.i) return -table_[(a.i + 1) * n + a.i] * w;
        const double* r0 = &table_[a.i * n];
        const double* r1 = r0 + n;
        return ((r0[b.i + 1] - r0[b.i]) * (1.0 - a.f) + (r1[b.i + 1] - r1[b.i]) * a.f) * w;
    }

    // Integral of -dE/dbeta (alpha = c - beta, beta) over beta in [b0, b1], b0 <= b1.  This
    // is the contribution of a boundary segment of slope -1 in the (alpha, beta) plane (a
    // horizontal segment s = c/2 of the boundary in the (r, s) plane).  The integrand is
    // linear in beta inside every cell of the interpolation, so splitting at every grid
    // line crossed and using the midpoint rule on each piece is exact.
    double antidiagonal_integral(double c, double b0, double b1) const {
        if (!(b1 > b0)) return 0.0;
        // Break points: beta = levels[k] and beta = c - levels[k] inside (b0, b1), visited in
        // ascending order by merging the two sorted runs (no allocation, no sort: a cut of a
        // neutral state's piece in a real-time step walks the cells once).
        auto a = std::upper_bound(levels_.begin(), levels_.end(), b0);
        const auto a_end = std::lower_bound(a, levels_.end(), b1);
        // c - levels[k] ascending means levels[k] descending, from below c - b0 down to above c - b1
        auto m = std::lower_bound(levels_.begin(), levels_.end(), c - b0);
        const auto m_end = std::upper_bound(levels_.begin(), levels_.end(), c - b1);
        // b0 and b1 take their sorted places too: a mirrored cut c - levels[k] can round to
        // just outside [b0, b1], and the sum must be the one over the sorted cuts exactly.
        bool b0_left = true, b1_left = true;
        const auto next = [&](double& x) {  // the smallest cut not yet taken; false at the end
            int src = -1;
            if (b0_left) { x = b0; src = 0; }
            if (a != a_end && (src < 0 || *a < x)) { x = *a; src = 1; }
            if (m > m_end && (src < 0 || c - *(m - 1) < x)) { x = c - *(m - 1); src = 2; }
            if (b1_left && (src < 0 || b1 < x)) { x = b1; src = 3; }
            if (src == 0) b0_left = false;
            else if (src == 1) ++a;
            else if (src == 2) --m;
            else if (src == 3) b1_left = false;
            return src >= 0;
        };
        double total = 0.0, lo = 0.0, hi = 0.0;
        next(lo);
        while (next(hi)) {
            if (hi > lo) {
                const double mid = 0.5 * (lo + hi);
                total -= d_beta_interior(c - mid, mid) * (hi - lo);
            }
            lo = hi;
        }
        return total;
    }

private:
    // dE/dbeta at a point strictly inside a cell (no side preference needed).
    double d_beta_interior(double alpha, double beta) const noexcept {
        const GridPos b = locate(beta, true);
        GridPos a = locate(alpha, true);
        if (a.i < b.i) a = {b.i, a.f};
        const std::size_t n = size();
        const double w = inv_width_[b.i];
        if (a.i == b.i) return -table_[(a.i + 1) * n + a.i] * w;
        const double* r0 = &table_[a.i * n];
        const double* r1 = r0 + n;
        return ((r0[b.i + 1] - r0[b.i]) * (1.0 - a.f) + (r1[b.i + 1] - r1[b.i]) * a.f) * w;
    }

    std::vector<double> levels_;
    std::vector<double> table_;
    std::vector<double> coef_;
    std::vector<double> inv_width_;
    double y_min_ = 0.0;
    double u_min_ = 0.0, u_max_ = 0.0;
    double inv_h_ = 1.0;
    bool uniform_ = true;
};

// ---- construction helpers ----------------------------------------------------------------

// From FOD samples y(i, j) = y(alpha_i, beta_j), j <= i (Mayergoyz):
//   E_ij = (y_ii - y_ij) / 2 and y_min = mean of the FOD end points y(alpha_i, u_min).
inline EverettTable everett_from_fod(const VectorRef& levels, const MatrixRef& y) {
    const std::size_t n = std::size_t(levels.size());
    if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels");
    if (std::size_t(y.rows()) != n || std::size_t(y.cols()) != n)
        throw std::invalid_argument("y_grid: shape (" + std::to_string(y.rows()) + ", " + std::to_string(y.cols()) +
                                    ") does not match " + std::to_string(n) + " levels");
    RowMatrixXd e = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    double ymin = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double yii = y(Eigen::Index(i), Eigen::Index(i));
        if (!std::isfinite(yii))
            throw std::invalid_argument("y_grid[" + std::to_string(i) + ", " + std::to_string(i) +
                                        "] (the turning point of FOD curve " + std::to_string(i) + ") is not finite");
        for (std::size_t j = 0; j <= i; ++j) {
            const double yij = y(Eigen::Index(i), Eigen::Index(j));
            if (!std::isfinite(yij))
                throw std::invalid_argument("y_grid[" + std::to_string(i) + ", " + std::to_string(j) +
                                            "] is not finite; every node with j <= i is needed");
            e(Eigen::Index(i), Eigen::Index(j)) = 0.5 * (yii - yij);
        }
        ymin += y(Eigen::Index(i), 0);
    }
    return EverettTable(levels, e, ymin / double(n));
}

// From relay masses w(i, j) (j <= i < n-1) of the cells [levels_i, levels_i+1] x
// [levels_j, levels_j+1] (the diagonal cells are the half-cells below the diagonal):
// E(levels_a, levels_b) = sum of the masses inside the triangle T(levels_a, levels_b).
inline EverettTable everett_from_weights(const VectorRef& levels, const MatrixRef& w, double y_min) {
    const std::size_t n = std::size_t(levels.size());
    if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels");
    const std::size_t m = n - 1;
    if (std::size_t(w.rows()) != m || std::size_t(w.cols()) != m)
        throw std::invalid_argument("weights: shape (" + std::to_string(w.rows()) + ", " + std::to_string(w.cols()) +
                                    ") must be (" + std::to_string(m) + ", " + std::to_string(m) +
                                    "): one cell per pair of neighbouring levels");
    RowMatrixXd e = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t a = 1; a < n; ++a) {
        // E(a, b) = E(a-1, b) + sum_{j=b}^{a-1} w(a-1, j)
        double suffix = 0.0;
        for (std::size_t b = a; b-- > 0;) {
            const double v = w(Eigen::Index(a - 1), Eigen::Index(b));
            if (!std::isfinite(v))
                throw std::invalid_argument("weights[" + std::to_string(a - 1) + ", " + std::to_string(b) +
                                            "] is not finite");
            suffix += v;
            e(Eigen::Index(a), Eigen::Index(b)) = e(Eigen::Index(a - 1), Eigen::Index(b)) + suffix;
        }
    }
    return EverettTable(levels, e, y_min);
}

// Relay masses of the cells (inverse of everett_from_weights), (n-1) x (n-1), zero above
// the diagonal.
inline RowMatrixXd cell_weights(const EverettTable& t) {
    const std::size_t n = t.size(), m = n - 1;
    RowMatrixXd w = RowMatrixXd::Zero(Eigen::Index(m), Eigen::Index(m));
    for (std::size_t i = 0; i < m; ++i) {
        w(Eigen::Index(i), Eigen::Index(i)) = t.node(i + 1, i);
        for (std::size_t j = 0; j < i; ++j)
            w(Eigen::Index(i), Eigen::Index(j)) =
                t.node(i + 1, j) - t.node(i, j) - t.node(i + 1, j + 1) + t.node(i, j + 1);
    }
    return w;
}

}  // namespace preisach

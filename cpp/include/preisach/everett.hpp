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
// interpolated in one of two ways, both through the antisymmetric extension
// E(a, b) = -E(b, a) of the table (so E(u, u) = 0: exactly from operator(), to rounding from
// the cell formula of value()):
//   * bilinear (the default): bilinear in the square cells and linear in the half-cells on
//     the diagonal, which keeps E (and so the model output) continuous;
//   * cubic: the tensor product of 1-D cubic Hermite interpolants whose node slopes are
//     those of the parabola through the node and its two neighbours (one-sided at the ends
//     of the grid; on a uniform grid the Catmull-Rom spline).  E and its first derivatives
//     are continuous, the interpolant is exact for cubic surfaces away from the grid's ends
//     and still linear in the node values, from a 4 x 4 stencil of nodes instead of 2 x 2.
//     A smooth Preisach density tabulated on a coarse grid (the 21-level FOD grid) is
//     interpolated about ten times more closely than bilinearly.  Needs >= 4 levels.
// Either interpolant passes through the nodes, so the cell masses of cell_weights() (second
// differences of the nodes) are the relay masses of the cells in both.
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

// How E is interpolated between the table's nodes (see above).
enum class Interpolation { bilinear, cubic };

inline Interpolation parse_interpolation(const std::string& name) {
    if (name == "bilinear") return Interpolation::bilinear;
    if (name == "cubic") return Interpolation::cubic;
    throw std::invalid_argument("interpolation: expected 'bilinear' or 'cubic', got '" + name + "'");
}

inline const char* interpolation_name(Interpolation k) noexcept {
    return k == Interpolation::cubic ? "cubic" : "bilinear";
}

// Gauss-Legendre abscissae (on [-1, 1]) and weights of the 3-point rule, exact for the
// polynomials of degree <= 5 that -dE/dbeta is along an antidiagonal inside a cubic cell.
inline constexpr double kGauss3X = 0.7745966692414834;  // sqrt(3/5)
inline constexpr double kGauss3W[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};

class EverettTable {
public:
    EverettTable() = default;

    // levels: strictly increasing grid, n >= 2 (>= 4 for cubic).  values: n x n, values(i, j) =
    // E(levels[i], levels[j]) for j <= i; entries with j >= i are ignored (the diagonal is 0).
    EverettTable(const VectorRef& levels, const MatrixRef& values, double y_min,
                 Interpolation interpolation = Interpolation::bilinear)
        : levels_(levels.data(), levels.data() + levels.size()), y_min_(y_min), interp_(interpolation) {
        const std::size_t n = levels_.size();
        if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels, got " + std::to_string(n));
        if (interp_ == Interpolation::cubic && n < 4)
            throw std::invalid_argument("levels: cubic interpolation needs at least 4 grid levels, got " +
                                        std::to_string(n));
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
        if (interp_ == Interpolation::cubic) build_cubic();
    }

    std::size_t size() const noexcept { return levels_.size(); }
    const std::vector<double>& levels() const noexcept { return levels_; }
    double u_min() const noexcept { return u_min_; }
    double u_max() const noexcept { return u_max_; }
    double y_min() const noexcept { return y_min_; }
    double y_max() const noexcept { return y_min_ + 2.0 * node(size() - 1, 0); }
    bool uniform() const noexcept { return uniform_; }
    Interpolation interpolation() const noexcept { return interp_; }
    bool cubic() const noexcept { return interp_ == Interpolation::cubic; }
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
    // (Cubic tables: the cell's bicubic polynomial.)
    double value(GridPos a, GridPos b) const noexcept {
        if (interp_ == Interpolation::cubic) return cubic_value(a, b, false, false);
        const double* c = &coef_[(a.i * (size() - 1) + b.i) * 4];
        return c[0] + c[1] * a.f + (c[2] + c[3] * a.f) * b.f;
    }

    // The 1-D interpolation weights at p: the interpolant along one axis is
    // sum_k w[k] * node(start + k) for k < 4, with start the returned index (derivative: the
    // weights of d/du, per volt).  Cubic tables only.
    std::size_t stencil(GridPos p, double* w, bool derivative) const noexcept {
        const double* m = &herm_[p.i * 16];
        for (std::size_t k = 0; k < 4; ++k) {
            if (derivative)
                w[k] = (m[4 + k] + p.f * (2.0 * m[8 + k] + 3.0 * p.f * m[12 + k])) * inv_width_[p.i];
            else
                w[k] = m[k] + p.f * (m[4 + k] + p.f * (m[8 + k] + p.f * m[12 + k]));
        }
        return herm_start_[p.i];
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
        if (interp_ == Interpolation::cubic) return cubic_value(a, b, true, false);
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
        if (interp_ == Interpolation::cubic) return cubic_value(a, b, false, true);
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
    // line crossed and using the midpoint rule on each piece is exact (cubic tables: a
    // polynomial of degree <= 5, the 3-point Gauss rule is exact).
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
                if (interp_ == Interpolation::cubic) {
                    const double half = 0.5 * (hi - lo);
                    for (int g = 0; g < 3; ++g) {
                        const double x = mid + double(g - 1) * kGauss3X * half;
                        total -= kGauss3W[g] * half * d_beta_interior(c - x, x);
                    }
                } else {
                    total -= d_beta_interior(c - mid, mid) * (hi - lo);
                }
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
        if (interp_ == Interpolation::cubic) return cubic_value(a, b, false, true);
        if (a.i < b.i) a = {b.i, a.f};
        const std::size_t n = size();
        const double w = inv_width_[b.i];
        if (a.i == b.i) return -table_[(a.i + 1) * n + a.i] * w;
        const double* r0 = &table_[a.i * n];
        const double* r1 = r0 + n;
        return ((r0[b.i + 1] - r0[b.i]) * (1.0 - a.f) + (r1[b.i + 1] - r1[b.i]) * a.f) * w;
    }

    // The cell's bicubic polynomial sum_pq C[p][q] fa^p fb^q, or its derivative in alpha or
    // beta (per volt).
    double cubic_value(GridPos a, GridPos b, bool da, bool db) const noexcept {
        const double* c = &ccoef_[(a.i * (size() - 1) + b.i) * 16];
        double r[4];
        for (std::size_t p = 0; p < 4; ++p) {
            const double* q = c + 4 * p;
            r[p] = db ? q[1] + b.f * (2.0 * q[2] + 3.0 * b.f * q[3]) : q[0] + b.f * (q[1] + b.f * (q[2] + b.f * q[3]));
        }
        double v = da ? r[1] + a.f * (2.0 * r[2] + 3.0 * a.f * r[3]) : r[0] + a.f * (r[1] + a.f * (r[2] + a.f * r[3]));
        if (da) v *= inv_width_[a.i];
        if (db) v *= inv_width_[b.i];
        return v;
    }

    // The cubic Hermite basis per cell (herm_: 4 powers x 4 stencil nodes, herm_start_: the
    // stencil's first node) and the bicubic coefficients per cell pair (ccoef_).
    void build_cubic() {
        const std::size_t n = size(), m = n - 1;
        const std::vector<double>& x = levels_;
        // slope at node k of the parabola through three neighbouring nodes, as weights on
        // the nodes ts[k] .. ts[k] + 2
        std::vector<std::size_t> ts(n);
        std::vector<double> tw(3 * n);
        for (std::size_t k = 0; k < n; ++k) {
            double* w = &tw[3 * k];
            if (k == 0) {
                const double h0 = x[1] - x[0], h1 = x[2] - x[1];
                ts[k] = 0;
                w[0] = -(2.0 * h0 + h1) / (h0 * (h0 + h1));
                w[1] = (h0 + h1) / (h0 * h1);
                w[2] = -h0 / (h1 * (h0 + h1));
            } else if (k == n - 1) {
                const double h0 = x[n - 2] - x[n - 3], h1 = x[n - 1] - x[n - 2];
                ts[k] = n - 3;
                w[0] = h1 / (h0 * (h0 + h1));
                w[1] = -(h0 + h1) / (h0 * h1);
                w[2] = (2.0 * h1 + h0) / (h1 * (h0 + h1));
            } else {
                const double h0 = x[k] - x[k - 1], h1 = x[k + 1] - x[k];
                ts[k] = k - 1;
                w[0] = -h1 / (h0 * (h0 + h1));
                w[1] = (h1 - h0) / (h0 * h1);
                w[2] = h0 / (h1 * (h0 + h1));
            }
        }
        static constexpr double h00[4] = {1, 0, -3, 2}, h10[4] = {0, 1, -2, 1};
        static constexpr double h01[4] = {0, 0, 3, -2}, h11[4] = {0, 0, -1, 1};
        herm_.assign(m * 16, 0.0);
        herm_start_.resize(m);
        for (std::size_t i = 0; i < m; ++i) {
            const std::size_t s = std::min(i > 0 ? i - 1 : 0, n - 4);
            herm_start_[i] = s;
            const double h = x[i + 1] - x[i];
            double* M = &herm_[i * 16];  // M[4 p + k]: power p, stencil node s + k
            for (std::size_t p = 0; p < 4; ++p) {
                M[4 * p + (i - s)] += h00[p];
                M[4 * p + (i + 1 - s)] += h01[p];
                for (std::size_t c = 0; c < 3; ++c) {
                    M[4 * p + (ts[i] + c - s)] += h * h10[p] * tw[3 * i + c];
                    M[4 * p + (ts[i + 1] + c - s)] += h * h11[p] * tw[3 * (i + 1) + c];
                }
            }
        }
        ccoef_.assign(m * m * 16, 0.0);
        for (std::size_t i = 0; i < m; ++i)
            for (std::size_t j = 0; j < m; ++j) {
                const double* A = &herm_[i * 16];
                const double* B = &herm_[j * 16];
                const std::size_t sa = herm_start_[i], sb = herm_start_[j];
                double T[16];  // T[4 p + l] = sum_k A[p][k] node(sa + k, sb + l)
                for (std::size_t p = 0; p < 4; ++p)
                    for (std::size_t l = 0; l < 4; ++l) {
                        double v = 0.0;
                        for (std::size_t k = 0; k < 4; ++k) v += A[4 * p + k] * table_[(sa + k) * n + sb + l];
                        T[4 * p + l] = v;
                    }
                double* C = &ccoef_[(i * m + j) * 16];
                for (std::size_t p = 0; p < 4; ++p)
                    for (std::size_t q = 0; q < 4; ++q) {
                        double v = 0.0;
                        for (std::size_t l = 0; l < 4; ++l) v += T[4 * p + l] * B[4 * q + l];
                        C[4 * p + q] = v;
                    }
            }
    }

    std::vector<double> levels_;
    std::vector<double> table_;
    std::vector<double> coef_;
    std::vector<double> inv_width_;
    std::vector<double> herm_, ccoef_;
    std::vector<std::size_t> herm_start_;
    double y_min_ = 0.0;
    double u_min_ = 0.0, u_max_ = 0.0;
    double inv_h_ = 1.0;
    bool uniform_ = true;
    Interpolation interp_ = Interpolation::bilinear;
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

// The table's nodes as an n x n matrix (lower triangle; zero on and above the diagonal).
inline RowMatrixXd everett_nodes(const EverettTable& t) {
    const std::size_t n = t.size();
    RowMatrixXd e = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j) e(Eigen::Index(i), Eigen::Index(j)) = t.node(i, j);
    return e;
}

// The same nodes and y_min, interpolated by `k`.
inline EverettTable with_interpolation(const EverettTable& t, Interpolation k) {
    const Eigen::VectorXd lv = Eigen::Map<const Eigen::VectorXd>(t.levels().data(), Eigen::Index(t.size()));
    return EverettTable(lv, everett_nodes(t), t.y_min(), k);
}

// `t` tabulated on `levels` (inside t's range; every node is t's interpolant there),
// interpolated by `k`: e.g. a cubic table on a grid fine enough for the bilinear-only inverse.
inline EverettTable resample(const EverettTable& t, const VectorRef& levels, Interpolation k) {
    const std::size_t n = std::size_t(levels.size());
    const double span = t.u_max() - t.u_min(), tol = 1e-9 * span;
    if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels, got " + std::to_string(n));
    if (levels[0] < t.u_min() - tol || levels[Eigen::Index(n - 1)] > t.u_max() + tol)
        throw std::invalid_argument("levels: [" + std::to_string(levels[0]) + ", " +
                                    std::to_string(levels[Eigen::Index(n - 1)]) + "] V leaves the table's range [" +
                                    std::to_string(t.u_min()) + ", " + std::to_string(t.u_max()) + "] V");
    RowMatrixXd e = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j) e(Eigen::Index(i), Eigen::Index(j)) = t(levels[Eigen::Index(i)], levels[Eigen::Index(j)]);
    // y_min is the output at negative saturation of the grid: the same when the ranges agree
    return EverettTable(levels, e, t.y_min() + 2.0 * t(levels[0], t.u_min()), k);
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

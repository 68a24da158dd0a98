// Mayergoyz identification: FOD grid -> Everett table, weights, and projection to mu >= 0.
//
// Conventions (volts in, volts out), as in everett.hpp:
//   * y(i, j) is the output at beta = levels[j] on the first-order descending (FOD) curve that
//     rose from negative saturation to alpha = levels[i] (j <= i); y(i, i) is the turning point;
//   * Mayergoyz: E(i, j) = (y(i, i) - y(i, j)) / 2, and y_min is the mean of the measured FOD
//     end points y(i, 0) (every FOD curve merges at u_min);
//   * the relay mass of cell (i, j), j < i, [levels_i, levels_i+1] x [levels_j, levels_j+1], is
//     the mixed second difference w = E(i+1, j) - E(i, j) - E(i+1, j+1) + E(i, j+1); the
//     diagonal half-cell (i, i) holds w = E(i+1, i) (cell_weights in everett.hpp).
//
// Thesis Eq 2.12-2.14 split the weight into a density v(alpha, beta) (V/V^2) and a reversible
// part kappa(beta) delta(alpha - beta) on the diagonal (V/V).  On the grid:
//   v(i, j)  = w(i, j) / ((levels_i+1 - levels_i)(levels_j+1 - levels_j))    (j < i, V/V^2)
//   kappa(i) = w(i, i) / (levels_i+1 - levels_i)                              (V/V)
// kappa(i) is one half of the initial slope dy/dbeta of the FOD curves in that cell (Eq 2.14,
// with the linear interpolation of the diagonal half-cells); it includes the half-cell's share of
// v, which is O(h) smaller.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "everett.hpp"
#include "types.hpp"

namespace preisach {

// What to do with NaN nodes of an FOD grid (nodes the FOD finder could not read).
enum class GapPolicy {
    raise,  // refuse, naming the first missing node
    fill    // fill them by the documented rule (see mayergoyz())
};

struct MayergoyzResult {
    EverettTable table;
    // Nodes (i, j), j < i, whose Everett value was not measured and was filled; empty for
    // complete grids.  `filled_column0` of them came from the u_min rule, the rest from the
    // harmonic fill.
    std::vector<std::pair<std::size_t, std::size_t>> filled;
    std::size_t filled_column0 = 0;
    // Number of finite FOD end points y(i, 0) averaged into y_min.
    std::size_t n_ymin = 0;
    // Rows whose turning point y(i, i) was missing, so their off-diagonal readings were unusable.
    std::vector<std::size_t> rows_without_turning_point;
};

namespace detail {

inline std::string volts(double v) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.6g V", v);
    return buf;
}

inline void check_levels(const VectorRef& levels) {
    const Eigen::Index n = levels.size();
    if (n < 2) throw std::invalid_argument("levels: need at least 2 grid levels, got " + std::to_string(n));
    for (Eigen::Index k = 0; k < n; ++k) {
        if (!std::isfinite(levels[k])) throw std::invalid_argument("levels[" + std::to_string(k) + "] is not finite");
        if (k > 0 && !(levels[k] > levels[k - 1]))
            throw std::invalid_argument("levels must be strictly increasing; levels[" + std::to_string(k) +
                                        "] <= levels[" + std::to_string(k - 1) + "]");
    }
}

}  // namespace detail

// Roughness of a weight on the grid, as rows over the Everett nodes (node (i, j) has the flat
// index i * n + j).  With the cell masses w (mixed second differences of E), the density of
// the off-diagonal cells v = w / (h_i h_j) and kappa = w(i, i) / h_i on the diagonal, the rows
// are the second differences, scaled by hbar^2 (hbar^1 for kappa) with hbar the mean level
// spacing so that every row is in volts:
//   alpha direction  v(i-1, j) - 2 v(i, j) + v(i+1, j)   (three off-diagonal cells)
//   beta direction   v(i, j-1) - 2 v(i, j) + v(i, j+1)   (three off-diagonal cells)
//   diagonal         kappa(i-1) - 2 kappa(i) + kappa(i+1)
// The sum of their squares is the roughness that identify_lsq penalises and that the gap
// fill of mayergoyz() minimises.
inline std::vector<std::vector<std::pair<std::size_t, double>>> roughness_rows(const VectorRef& levels) {
    const std::size_t n = std::size_t(levels.size());
    std::vector<std::vector<std::pair<std::size_t, double>>> rows;
    if (n < 4) return rows;
    const std::size_t m = n - 1;
    const double hbar = (levels[Eigen::Index(n - 1)] - levels[0]) / double(m);
    const auto h = [&](std::size_t k) { return levels[Eigen::Index(k + 1)] - levels[Eigen::Index(k)]; };
    // c * w(i, j) as node coefficients (diagonal nodes are 0 and dropped)
    const auto add_w = [&](std::vector<std::pair<std::size_t, double>>& row, std::size_t i, std::size_t j, double c) {
        const auto put = [&](std::size_t a, std::size_t b, double s) {
            if (b < a) row.emplace_back(a * n + b, s * c);
        };
        put(i + 1, j, 1.0);
        if (j < i) {
            put(i, j, -1.0);
            put(i + 1, j + 1, -1.0);
            put(i, j + 1, 1.0);
        }
    };
    const auto dens = [&](std::size_t i, std::size_t j) { return i == j ? hbar / h(i) : hbar * hbar / (h(i) * h(j)); };
    for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = 0; j < i; ++j) {
            if (i >= 1 && j + 1 < i && i + 1 < m) {  // alpha direction: cells (i-1, j), (i, j), (i+1, j)
                std::vector<std::pair<std::size_t, double>> row;
                add_w(row, i - 1, j, dens(i - 1, j));
                add_w(row, i, j, -2.0 * dens(i, j));
                add_w(row, i + 1, j, dens(i + 1, j));
                rows.push_back(std::move(row));
            }
            if (j >= 1 && j + 1 < i) {  // beta direction: cells (i, j-1), (i, j), (i, j+1)
                std::vector<std::pair<std::size_t, double>> row;
                add_w(row, i, j - 1, dens(i, j - 1));
                add_w(row, i, j, -2.0 * dens(i, j));
                add_w(row, i, j + 1, dens(i, j + 1));
                rows.push_back(std::move(row));
            }
        }
    for (std::size_t i = 1; i + 1 < m; ++i) {  // kappa along the diagonal
        std::vector<std::pair<std::size_t, double>> row;
        add_w(row, i - 1, i - 1, dens(i - 1, i - 1));
        add_w(row, i, i, -2.0 * dens(i, i));
        add_w(row, i + 1, i + 1, dens(i + 1, i + 1));
        rows.push_back(std::move(row));
    }
    return rows;
}

// Mayergoyz identification from an FOD grid that may have gaps (NaN nodes).
//
// Gap rule (gaps == fill), in two steps:
//   1. a missing end point y(i, 0) of a curve whose turning point y(i, i) is known is replaced
//      by y_min (every FOD curve ends at y_min), i.e. E(i, 0) = (y(i, i) - y_min) / 2;
//   2. every other missing Everett node takes the value that makes the weight smoothest: the
//      filled nodes minimise the sum of squared second differences of the cell densities
//      (roughness_rows: along alpha, along beta, and of kappa along the diagonal) with the
//      measured nodes held fixed; a 1e-12 harmonic term keeps the solution unique.  A
//      linear density (and kappa) is reproduced to rounding, so interior gaps and curves that stop
//      early are continued from the neighbouring nodes and curves.
// A row whose turning point y(i, i) is missing has all its off-diagonal nodes filled (its
// readings give E only up to an unknown constant); such rows are listed in the result.
// y_min is the mean of the finite y(i, 0) (i = 0 .. n-1); at least one must be finite.
inline MayergoyzResult mayergoyz(const VectorRef& levels, const MatrixRef& y, GapPolicy gaps) {
    detail::check_levels(levels);
    const std::size_t n = std::size_t(levels.size());
    if (std::size_t(y.rows()) != n || std::size_t(y.cols()) != n)
        throw std::invalid_argument("y_grid: shape (" + std::to_string(y.rows()) + ", " + std::to_string(y.cols()) +
                                    ") does not match " + std::to_string(n) + " levels; expected (" +
                                    std::to_string(n) + ", " + std::to_string(n) + ")");
    const auto Y = [&](std::size_t i, std::size_t j) { return y(Eigen::Index(i), Eigen::Index(j)); };
    const auto node_name = [&](std::size_t i, std::size_t j) {
        return "y_grid[" + std::to_string(i) + ", " + std::to_string(j) + "] (alpha = " +
               detail::volts(levels[Eigen::Index(i)]) + ", beta = " + detail::volts(levels[Eigen::Index(j)]) + ")";
    };
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j <= i; ++j)
            if (std::isinf(Y(i, j))) throw std::invalid_argument(node_name(i, j) + " is infinite");

    MayergoyzResult res;
    double ysum = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        if (std::isfinite(Y(i, 0))) {
            ysum += Y(i, 0);
            ++res.n_ymin;
        }
    if (res.n_ymin == 0)
        throw std::invalid_argument("y_grid: no FOD curve was read at beta = u_min = " +
                                    detail::volts(levels[0]) + " (column 0 is all NaN), so y_min is unknown");
    const double y_min = ysum / double(res.n_ymin);

    // Known Everett nodes; E(k, k) = 0.
    RowMatrixXd E = RowMatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
    std::vector<char> known(n * n, 0);
    for (std::size_t k = 0; k < n; ++k) known[k * n + k] = 1;
    for (std::size_t i = 1; i < n; ++i) {
        const double yii = Y(i, i);
        if (!std::isfinite(yii)) {
            bool any = false;
            for (std::size_t j = 0; j < i; ++j) any = any || std::isfinite(Y(i, j));
            if (gaps == GapPolicy::raise)
                throw std::invalid_argument(node_name(i, i) + " (the turning point of FOD curve " + std::to_string(i) +
                                            ") is NaN; every node with j <= i is needed (gaps='fill' fills them)");
            if (any) res.rows_without_turning_point.push_back(i);
            continue;
        }
        for (std::size_t j = 0; j < i; ++j) {
            double yij = Y(i, j);
            if (!std::isfinite(yij)) {
                if (gaps == GapPolicy::raise)
                    throw std::invalid_argument(node_name(i, j) +
                                                " is NaN: that FOD curve has no reading there; every node with j <= i "
                                                "is needed (gaps='fill' fills missing nodes)");
                if (j != 0) continue;
                yij = y_min;  // rule 1
                res.filled.emplace_back(i, j);
                ++res.filled_column0;
            }
            E(Eigen::Index(i), Eigen::Index(j)) = 0.5 * (yii - yij);
            known[i * n + j] = 1;
        }
    }

    // Rule 2: the remaining unknown nodes make the weight smoothest.
    std::vector<long> unk(n * n, -1);
    std::vector<std::pair<std::size_t, std::size_t>> cells;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j)
            if (!known[i * n + j]) {
                unk[i * n + j] = long(cells.size());
                cells.emplace_back(i, j);
            }
    if (!cells.empty()) {
        const Eigen::Index m = Eigen::Index(cells.size());
        // Roughness rows over the Everett nodes; split into unknown (R_u) and known (-> r_k) parts.
        std::vector<Eigen::Triplet<double>> trip;
        std::vector<double> rk;
        Eigen::Index nrows = 0;
        for (const auto& row : roughness_rows(levels)) {
            double known_part = 0.0;
            bool touches = false;
            for (const auto& [node, c] : row) {
                const long q = unk[node];
                if (q >= 0) {
                    trip.emplace_back(nrows, Eigen::Index(q), c);
                    touches = true;
                } else {
                    known_part += c * E(Eigen::Index(node / n), Eigen::Index(node % n));
                }
            }
            if (!touches) continue;  // a row of measured nodes only
            rk.push_back(known_part);
            ++nrows;
        }
        Eigen::SparseMatrix<double> R(nrows, m);
        R.setFromTriplets(trip.begin(), trip.end());
        Eigen::VectorXd r(nrows);
        for (Eigen::Index k = 0; k < nrows; ++k) r[k] = rk[std::size_t(k)];
        // A small harmonic term keeps the system definite where the roughness rows do not
        // reach (e.g. grids of 2 or 3 levels); it is 1e-12 of the roughness scale.
        std::vector<Eigen::Triplet<double>> ltrip;
        Eigen::VectorXd lrhs = Eigen::VectorXd::Zero(m);
        for (Eigen::Index q = 0; q < m; ++q) {
            const auto [i, j] = cells[std::size_t(q)];
            const long nb[4][2] = {{long(i) - 1, long(j)}, {long(i) + 1, long(j)}, {long(i), long(j) - 1},
                                   {long(i), long(j) + 1}};
            double diag = 0.0;
            for (const auto& z : nb) {
                if (z[0] < 0 || z[1] < 0 || z[0] >= long(n) || z[1] > z[0]) continue;  // outside the triangle
                const std::size_t a2 = std::size_t(z[0]), b2 = std::size_t(z[1]);
                diag += 1.0;
                const long c = unk[a2 * n + b2];
                if (c >= 0) ltrip.emplace_back(q, Eigen::Index(c), -1.0);
                else lrhs[q] += E(Eigen::Index(a2), Eigen::Index(b2));
            }
            ltrip.emplace_back(q, q, diag);
        }
        Eigen::SparseMatrix<double> Lh(m, m);
        Lh.setFromTriplets(ltrip.begin(), ltrip.end());
        Eigen::SparseMatrix<double> H = Eigen::SparseMatrix<double>(R.transpose()) * R;
        double hscale = 0.0;
        for (Eigen::Index q = 0; q < m; ++q) hscale = std::max(hscale, H.coeff(q, q));
        const double eps = 1e-12 * std::max(hscale, 1.0);
        H += eps * Lh;
        const Eigen::VectorXd g = -(R.transpose() * r) + eps * lrhs;
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(H);
        if (solver.info() != Eigen::Success)
            throw std::runtime_error("mayergoyz: the gap fill could not be factorised");
        const Eigen::VectorXd x = solver.solve(g);
        for (Eigen::Index q = 0; q < m; ++q) {
            const auto [i, j] = cells[std::size_t(q)];
            E(Eigen::Index(i), Eigen::Index(j)) = x[q];
            res.filled.emplace_back(i, j);
        }
    }
    res.table = EverettTable(levels, E, y_min);
    return res;
}

// Thesis Eq 2.12-2.14 on the grid: density v (V/V^2) of the off-diagonal cells and kappa
// (V/V) of the diagonal half-cells; see the header comment.  v is (n-1) x (n-1) with v(i, j)
// for j < i and NaN on and above the diagonal; kappa has n-1 entries, kappa(i) belonging to
// the diagonal cell [levels_i, levels_i+1].
struct WeightDensity {
    RowMatrixXd v;
    Eigen::VectorXd kappa;
};

inline WeightDensity weight_density(const EverettTable& t) {
    const RowMatrixXd w = cell_weights(t);
    const std::size_t m = t.size() - 1;
    const auto& lv = t.levels();
    WeightDensity d;
    d.v = RowMatrixXd::Constant(Eigen::Index(m), Eigen::Index(m), std::nan(""));
    d.kappa.resize(Eigen::Index(m));
    for (std::size_t i = 0; i < m; ++i) {
        const double hi = lv[i + 1] - lv[i];
        d.kappa[Eigen::Index(i)] = w(Eigen::Index(i), Eigen::Index(i)) / hi;
        for (std::size_t j = 0; j < i; ++j)
            d.v(Eigen::Index(i), Eigen::Index(j)) = w(Eigen::Index(i), Eigen::Index(j)) / (hi * (lv[j + 1] - lv[j]));
    }
    return d;
}

// ---- projection to mu >= 0 ----------------------------------------------------------------

struct ProjectionResult {
    EverettTable table;
    double mass_moved = 0.0;       // sum over cells |w' - w| (V)
    double total_mass = 0.0;       // sum over cells |w| before (V)
    double negative_mass = 0.0;    // sum over cells min(w, 0) before (V, <= 0)
    std::size_t n_negative = 0;    // cells with w < 0 before
    double max_node_change = 0.0;  // max |E' - E| over the nodes (V); outputs move by up to twice this
    double rms_node_change = 0.0;  // root mean square of E' - E over the n(n-1)/2 nodes (V)
    bool kept_y_max = true;        // y(u_max, u_max) = y_min + 2 E(u_max, u_min) unchanged
    std::size_t sweeps = 0;
    bool converged = false;
    double max_violation = 0.0;    // most negative cell mass the iteration left (V, as a positive number);
                                   // such masses are then set to 0, which moves E by about as much
};

// The Everett table nearest to `t` in least squares over the Everett nodes whose cell masses
// are all >= 0:
//     minimise sum_{j < i} (E'(i, j) - E(i, j))^2   subject to   w'(cell) >= 0 for every cell,
// with E'(k, k) = 0, y_min unchanged and, when keep_y_max and E(u_max, u_min) >= 0, the corner
// node E'(u_max, u_min) fixed, so y_max = y(u_max, u_max) is kept too.  Least squares in E (not
// in the masses) because the model output is a signed sum of Everett values: a change of E by
// d moves any output by at most 2|d|, so this projection changes the model's outputs as little
// as it can, and a negative cell is absorbed by its neighbours instead of by the whole plane.
//
// Solved by Hildreth's method (coordinate ascent on the dual, one cell constraint at a time;
// each update touches the <= 4 nodes of one cell), stopped when no cell mass is below
// -tol * scale and no multiplier moved by more than tol * scale in a sweep, scale being the
// total absolute mass; the masses still below zero (by at most that much when converged) are then
// set to zero and the table is rebuilt from the masses, so the result is in Mp (its cell masses,
// recomputed as mixed differences of the Everett values, are >= 0 up to round-off of about 1e-16
// of the total mass).  A table already in Mp is returned unchanged.
inline ProjectionResult project_nonnegative(const EverettTable& t, bool keep_y_max = true, double tol = 1e-12,
                                            std::size_t max_sweeps = 200000) {
    if (!(tol > 0.0) || !std::isfinite(tol)) throw std::invalid_argument("tol: must be finite and > 0");
    const std::size_t n = t.size(), m = n - 1;
    const RowMatrixXd w0 = cell_weights(t);
    ProjectionResult res;
    for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = 0; j <= i; ++j) {
            const double v = w0(Eigen::Index(i), Eigen::Index(j));
            res.total_mass += std::abs(v);
            if (v < 0.0) {
                res.negative_mass += v;
                ++res.n_negative;
            }
        }
    Eigen::VectorXd lv(static_cast<Eigen::Index>(n));
    for (std::size_t k = 0; k < n; ++k) lv[Eigen::Index(k)] = t.levels()[k];
    if (res.n_negative == 0) {
        res.table = t;
        res.converged = true;
        return res;
    }
    const double corner = t.node(n - 1, 0);
    res.kept_y_max = keep_y_max && corner >= 0.0;
    // free[i*n+j]: the node takes part in the projection
    std::vector<char> free_(n * n, 0);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j) free_[i * n + j] = 1;
    if (res.kept_y_max) free_[(n - 1) * n + 0] = 0;

    // Constraint of cell (i, j): sum_q s_q E(node_q) >= 0 over up to 4 nodes.
    struct Con {
        std::size_t idx[4];
        double sgn[4];
        int k;         // number of nodes
        double denom;  // sum of s_q^2 over free nodes
    };
    std::vector<Con> cons;
    cons.reserve(m * (m + 1) / 2);
    for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = 0; j <= i; ++j) {
            Con c{};
            const auto add = [&](std::size_t a, std::size_t b, double s) {
                if (b >= a) return;  // diagonal (0) or outside the triangle
                c.idx[c.k] = a * n + b;
                c.sgn[c.k] = s;
                ++c.k;
            };
            add(i + 1, j, 1.0);
            add(i, j, -1.0);
            add(i + 1, j + 1, -1.0);
            add(i, j + 1, 1.0);
            c.denom = 0.0;
            for (int q = 0; q < c.k; ++q)
                if (free_[c.idx[q]]) c.denom += 1.0;
            cons.push_back(c);
        }
    std::vector<double> x(n * n, 0.0);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j) x[i * n + j] = t.node(i, j);
    std::vector<double> lambda(cons.size(), 0.0);
    const double scale = std::max(res.total_mass, 1e-300);
    const double eps = tol * scale;
    const auto mass = [&](const Con& c) {
        double r = 0.0;
        for (int q = 0; q < c.k; ++q) r += c.sgn[q] * x[c.idx[q]];
        return r;
    };
    // Only constraints that are violated or carry a multiplier can change x: sweep those,
    // re-scanning every cell every 16 sweeps and before declaring convergence.
    std::vector<std::size_t> work;
    const auto rescan = [&]() {
        work.clear();
        double worst = 0.0;
        for (std::size_t k = 0; k < cons.size(); ++k) {
            const double r = mass(cons[k]);
            worst = std::min(worst, r);
            if (lambda[k] > 0.0 || r < 0.0) work.push_back(k);
        }
        return -worst;
    };
    rescan();
    for (std::size_t s = 0; s < max_sweeps; ++s) {
        double moved = 0.0;
        for (std::size_t k : work) {
            const Con& c = cons[k];
            if (c.denom == 0.0) continue;  // all nodes fixed: nothing to adjust
            const double d = std::max(-lambda[k], -mass(c) / c.denom);
            if (d == 0.0) continue;
            lambda[k] += d;
            for (int q = 0; q < c.k; ++q)
                if (free_[c.idx[q]]) x[c.idx[q]] += d * c.sgn[q];
            moved = std::max(moved, std::abs(d));
        }
        res.sweeps = s + 1;
        if (moved <= eps || s % 16 == 15) {
            const double violation = rescan();
            if (moved <= eps && violation <= eps) {
                res.converged = true;
                break;
            }
        }
    }
    // Masses within the tolerance of zero are set to exactly zero, so the result is in Mp.
    RowMatrixXd wp = RowMatrixXd::Zero(Eigen::Index(m), Eigen::Index(m));
    double worst = 0.0;
    for (std::size_t k = 0, i = 0; i < m; ++i)
        for (std::size_t j = 0; j <= i; ++j, ++k) {
            const double a = mass(cons[k]);
            worst = std::min(worst, a);
            wp(Eigen::Index(i), Eigen::Index(j)) = std::max(a, 0.0);
        }
    res.max_violation = -worst;
    res.table = everett_from_weights(lv, wp, t.y_min());
    double sq = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < i; ++j) {
            const double d = res.table.node(i, j) - t.node(i, j);
            res.max_node_change = std::max(res.max_node_change, std::abs(d));
            sq += d * d;
        }
    res.rms_node_change = std::sqrt(sq / double(n * (n - 1) / 2));
    for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = 0; j <= i; ++j)
            res.mass_moved += std::abs(wp(Eigen::Index(i), Eigen::Index(j)) - w0(Eigen::Index(i), Eigen::Index(j)));
    return res;
}

}  // namespace preisach

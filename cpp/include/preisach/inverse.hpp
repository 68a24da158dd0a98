// Exact inverse of a classical Preisach model: the input that drives the output to a target.
//
// The inverter owns a Simulator and so tracks the very same boundary stack: for each target y
// it finds an input u, then steps the simulator to u (so `simulate(inputs)` reproduces the
// outputs the inverter reports, bit for bit, from the same start state).
//
// Finding u is a search along a monotone excursion of the input, not an iteration.  Rising
// from the current input u0, the boundary stack is wiped out piece by piece; between two
// wipe-out points the output is
//   y(u) = y_min + 2 (B + E(u, b*))                       (last remaining piece constant)
//   y(u) = y_min + 2 (S_m + A(c, b0_m, c - u) + E(u, c - u))  (the rise cuts an antidiagonal piece)
// and falling it is y_min + 2 (S_m + E(M, b0_m) - E(M, u)) or y_min + 2 (S_m + A(c, b0_m, u)),
// with A the antidiagonal integral of everett.hpp.  E is bilinear in each table cell, so the
// output is linear in u inside a cell for the staircase pieces and quadratic between the
// break points of an antidiagonal piece (grid lines crossed by u and by c - u).  The search
// goes through the stack pieces outward from u0 and, inside a piece's stretch, takes the
// first cell whose end values bracket the target; the root is the closed-form solution of
// that cell's linear (or quadratic, fitted exactly through three evaluations) polynomial.
//
// Cost of one step (the real-time bound).  In a model with mu >= 0 the output is monotone
// along the excursion, so inside each stretch the bracketing cell is found by a binary
// search over the cell ends (E at a grid line is one look-up; an antidiagonal piece's
// integral at a break point is a prefix sum the simulator precomputes once per piece when
// the state is set, Simulator::prepare): O(log n) per stack piece crossed, n the levels,
// instead of a walk over up to 2 n cells.  Applying the input then cuts the stack as the
// simulator does (EverettTable::antidiagonal_integral walks the wiped part of an
// antidiagonal piece once: a neutral state's piece is wiped part by part over a run).
// Non-monotone models keep the walk (the first crossing need not be where a bisection lands).
//
// Which solution (the model need not be monotone):
//   * a target above the current output is looked for rising, below it falling; in a
//     model with mu >= 0 (class Mp) the output is non-decreasing along a rise and
//     non-increasing along a fall, so this finds the first input reaching the target;
//   * a model with cells of negative weight (mu < 0, e.g. the 2 and 4 Hz surfaces of
//     Table 3.1) is inverted as it is, not projected: both excursions are searched and the
//     one that reaches the target with the smaller input change |u - u0| is taken (ties:
//     the direction of the target);
//   * a target that no excursion reaches (beyond the saturated outputs, or a model whose
//     output cannot get there from this state) gives the input whose output is nearest to
//     it, the smaller excursion on ties; it is counted in `unreachable()` and never throws.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "everett.hpp"
#include "memory.hpp"
#include "simulator.hpp"

namespace preisach {

class Inverter {
public:
    // The closed-form roots need a bilinear table: a cubic one is inverted by way of
    // resample() on a finer grid (the Python layer does so).
    Inverter(const EverettTable& table, const State& state) : sim_(bilinear_only(table), state), t_(&table) {
        sim_.prepare();
        const std::size_t n = table.size();
        monotone_ = true;
        const double tol = 1e-12 * std::max(1.0, std::abs(table.node(n - 1, 0)));
        for (std::size_t i = 0; i + 1 < n && monotone_; ++i) {
            if (table.node(i + 1, i) < -tol) monotone_ = false;
            for (std::size_t j = 0; j < i && monotone_; ++j)
                if (table.node(i + 1, j) - table.node(i, j) - table.node(i + 1, j + 1) + table.node(i, j + 1) < -tol)
                    monotone_ = false;
        }
    }

    void reset(const State& state) {
        sim_.reset(state);
        sim_.prepare();
    }
    double input() const noexcept { return sim_.input(); }
    double output() const noexcept { return sim_.output(); }
    State state() const { return sim_.state(); }
    std::size_t depth() const noexcept { return sim_.depth(); }
    const EverettTable& table() const noexcept { return *t_; }
    // True when every cell weight is >= 0 (class Mp): one excursion is searched per target.
    bool monotone() const noexcept { return monotone_; }
    // Targets so far that no excursion reached (given the nearest reachable output).
    std::size_t unreachable() const noexcept { return unreachable_; }
    void clear_unreachable() noexcept { unreachable_ = 0; }
    // Table cells (or quadratic sub-intervals) examined one by one by the searches so far:
    // the work a step does beyond its binary searches (tests bound it per step).
    std::size_t cells_walked() const noexcept { return walked_; }

    // The input (volts, inside the model range) that the next target `y` needs, without
    // applying it; `reached` tells whether the output gets to `y` exactly (to rounding).
    double solve(double y, bool& reached) const {
        const double h = 0.5 * (y - t_->y_min());     // target in half-units: (y - y_min) / 2
        const double hnow = 0.5 * (sim_.output() - t_->y_min());
        const double u0 = sim_.input();
        reached = true;
        if (h == hnow) return u0;
        const bool up = h > hnow;
        Best b1{u0, std::abs(hnow - h)};
        double u1 = u0;
        const bool f1 = up ? scan_up(h, u1, b1) : scan_down(h, u1, b1);
        // the nearest output can equal the target to rounding though no piece's interior
        // holds it (a target exactly at a saturation, reached at the range end)
        const double rounding = 8.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(h));
        if (monotone_) {
            if (f1) return u1;
            reached = b1.err <= rounding;
            return b1.u;
        }
        Best b2{u0, std::abs(hnow - h)};
        double u2 = u0;
        const bool f2 = up ? scan_down(h, u2, b2) : scan_up(h, u2, b2);
        if (f1 && (!f2 || std::abs(u1 - u0) <= std::abs(u2 - u0))) return u1;
        if (f2) return u2;
        const Best& b = (b2.err < b1.err || (b2.err == b1.err && std::abs(b2.u - u0) < std::abs(b1.u - u0))) ? b2 : b1;
        reached = b.err <= rounding;
        return b.u;
    }

    // Drive the output to `y` (volts): returns the input applied.  Non-finite targets throw
    // std::invalid_argument naming `index`.
    double step(double y, std::size_t index = 0) {
        if (!std::isfinite(y))
            throw std::invalid_argument("target y[" + std::to_string(index) + "] is not finite");
        bool reached = true;
        const double u = solve(y, reached);
        if (!reached) ++unreachable_;
        sim_.step(u);
        return u;
    }

    // Invert n targets: inputs into u, the outputs they give into y_out, reached[k] = 1 where
    // target k was reached.  Every target is checked before the state changes.
    void run(const double* y, double* u, double* y_out, std::uint8_t* reached, std::size_t n) {
        for (std::size_t k = 0; k < n; ++k)
            if (!std::isfinite(y[k]))
                throw std::invalid_argument("target y[" + std::to_string(k) + "] is not finite");
        for (std::size_t k = 0; k < n; ++k) {
            bool ok = true;
            u[k] = solve(y[k], ok);
            if (!ok) ++unreachable_;
            y_out[k] = sim_.step(u[k]);
            if (reached) reached[k] = ok ? 1 : 0;
        }
    }

private:
    using Node = Simulator::Node;

    // A root within SNAP (a fraction of the cell) of a cell or segment end is put on the end:
    // a target that the reference reached by returning exactly to a previous extremum (or to
    // a saturation) then wipes out the same memory as the input that produced it did.
    static constexpr double SNAP = 1e-9;

    struct Best {
        double u;
        double err;  // |h(u) - h_target| in half-units
    };

    static void keep(Best& b, double u, double err) noexcept {
        if (err < b.err) b = {u, err};
    }

    // ---- rising: the output as a function of the input along u0 -> u_max ----------------
    bool scan_up(double h, double& u_out, Best& best) const {
        const auto& nd = sim_.nodes_;
        const double u0 = sim_.cur_, u_max = t_->u_max();
        std::size_t idx = nd.size();
        double bstar = u0, ua = u0, s_pop = 0.0;
        double hprev = 0.5 * (sim_.y_ - t_->y_min());  // h where the next segment starts
        bool popped = false;
        while (idx > 0 && nd[idx - 1].p.phi_start() <= u0) {  // the rising piece: popped by any rise
            bstar = nd[idx - 1].p.b0;
            s_pop = nd[idx - 1].S;
            popped = true;
            --idx;
        }
        for (;;) {
            if (ua >= u_max) return false;
            if (idx == 0) return lin_up(ua, u_max, t_->position(t_->u_min()), h, 0.0, hprev, u_out, best);
            const Node& m = nd[idx - 1];
            const double cm = popped ? s_pop - m.S : sim_.live_;  // contribution of m up to b*
            if (!m.p.antidiag) {
                const double ub = std::min(m.p.v, u_max);
                if (ub > ua && lin_up(ua, ub, t_->position(bstar), h, m.S + cm, hprev, u_out, best)) return true;
                ua = std::max(ua, ub);
            } else {
                const double c = m.p.v;
                const double t1 = std::min(c - bstar, u_max);  // the rise meets the slope
                if (t1 > ua && lin_up(ua, t1, t_->position(bstar), h, m.S + cm, hprev, u_out, best)) return true;
                ua = std::max(ua, t1);
                const double t2 = std::min(c - m.p.b0, u_max);  // the slope is wiped out
                if (t2 > ua) {
                    const auto& ad = sim_.ad_[static_cast<std::size_t>(m.ad)];
                    if (quad_up(ua, t2, m, ad, cm - ad.prefix(bstar), h, hprev, u_out, best)) return true;
                }
                ua = std::max(ua, t2);
            }
            bstar = m.p.b0;
            s_pop = m.S;
            popped = true;
            --idx;
        }
    }

    // y = y_min + 2 (base + E(u, b*)) on [ua, ub]: linear in u inside each alpha cell.
    // `hprev` is h where the segment starts (the end of the previous one, or the current
    // output): crossings are tested from it, so rounding at segment joints loses no target.
    bool lin_up(double ua, double ub, GridPos pb, double h, double base, double& hprev, double& u_out,
                Best& best) const {
        const EverettTable& t = *t_;
        const auto& L = t.levels();
        const double goal = h - base;
        const GridPos pa = t.locate(ua, true);
        std::size_t i = pa.i;
        double f0 = pa.f;
        // skip the cells whose start is still below the goal (binary search), unless the
        // target is in the first cell (small steps: the common case, one look-up)
        if (monotone_ && i + 2 < L.size() && ub > L[i + 1] && t.value(GridPos{i + 1, 0.0}, pb) < goal) {
            std::size_t lo = i + 2, hi = std::min<std::size_t>(
                static_cast<std::size_t>(std::lower_bound(L.begin(), L.end(), ub) - L.begin()), L.size() - 1);
            // largest i' in [i + 1, hi) with E(l_i', b*) < goal: the walk restarts at cell i'
            std::size_t found = i + 1;
            while (lo < hi) {
                const std::size_t mid = lo + (hi - lo) / 2;
                if (t.value(GridPos{mid, 0.0}, pb) < goal) {
                    found = mid;
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            if (found != i) {
                keep(best, L[found], std::abs(t.value(GridPos{found, 0.0}, pb) - goal));
                i = found;
                f0 = 0.0;
                hprev = base + t.value(GridPos{i, 0.0}, pb);
            }
        }
        for (;;) {
            ++walked_;
            const double l0 = L[i], w = L[i + 1] - l0;
            const bool last = ub <= L[i + 1];
            const double f1 = last ? (ub - l0) / w : 1.0;
            const double p = t.value(GridPos{i, 0.0}, pb), q = t.value(GridPos{i, 1.0}, pb) - p;
            const double e1 = p + q * f1;
            const double x1 = last ? ub : L[i + 1];
            if ((h - hprev) * (goal - e1) <= 0.0) {
                double f = q != 0.0 ? (goal - p) / q : f0;
                f = std::min(std::max(f, f0), f1);
                u_out = f1 - f < SNAP ? x1 : f - f0 < SNAP ? (i == pa.i ? ua : l0) : l0 + f * w;
                u_out = std::min(std::max(u_out, ua), ub);
                return true;
            }
            hprev = base + e1;
            keep(best, x1, std::abs(e1 - goal));
            if (last || i + 2 >= L.size()) return false;
            ++i;
            f0 = 0.0;
        }
    }

    // The rise cuts the antidiagonal piece m (phi = c - beta): on [ua, ub]
    // h(u) = S_m + A(c, b0_m, c - u) + E(u, c - u), quadratic between the points u = c - x[k]
    // (x the break points of the piece's prefix integrals).  A(c, b0_m, c - u) is taken as
    // `off + P(c - u)`, off = (m's contribution up to b*) - P(b*), as the simulator cuts it.
    template <class AD>
    bool quad_up(double ua, double ub, const Node& m, const AD& ad, double off, double h, double& hprev,
                 double& u_out, Best& best) const {
        const double c = m.p.v;
        const auto& X = ad.x;
        const double bhi = c - ua, blo = c - ub;  // beta runs down from bhi to blo
        // k: the next break point below bhi (beta), i.e. the next one above ua (u)
        std::ptrdiff_t k = (std::lower_bound(X.begin(), X.end(), bhi) - X.begin()) - 1;
        const std::ptrdiff_t k_end =
            std::upper_bound(X.begin(), X.end(), blo) - X.begin();  // first index with x > blo
        const auto at = [&](double u) { return m.S + off + ad.prefix(c - u) + (*t_)(u, c - u); };
        double x0 = ua;
        double g0 = at(x0);
        const auto below = [&](std::ptrdiff_t q) {  // h at the break point u = c - x[q] < target
            const double xq = X[static_cast<std::size_t>(q)];
            return m.S + off + ad.P[static_cast<std::size_t>(q)] + (*t_)(c - xq, xq) < h;
        };
        // skip the break points still below the goal, unless the target is before the first
        if (monotone_ && k >= k_end && below(k)) {
            std::ptrdiff_t lo = k_end, hi = k, found = k;  // smallest k' with h(c - x[k']) < h
            while (lo < hi) {
                const std::ptrdiff_t mid = lo + (hi - lo) / 2;
                if (below(mid)) {
                    found = mid;
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            if (found <= k) {
                const double xf = X[static_cast<std::size_t>(found)];
                x0 = c - xf;
                g0 = m.S + off + ad.P[static_cast<std::size_t>(found)] + (*t_)(x0, xf);
                hprev = g0;
                keep(best, x0, std::abs(g0 - h));
                k = found - 1;
            }
        }
        for (;;) {
            ++walked_;
            const bool inner = k >= k_end;
            const double x1 = inner ? c - X[static_cast<std::size_t>(k)] : ub;
            if (x1 > x0) {
                const double xm = 0.5 * (x0 + x1);
                const double gm = at(xm), g1 = at(x1);
                if (quad_root(x0, x1, g0, gm, g1, h, hprev, u_out, best)) return true;
                x0 = x1;
                g0 = g1;
            }
            if (!inner) return false;
            --k;
        }
    }

    // ---- falling: the output as a function of the input along u0 -> u_min ---------------
    bool scan_down(double h, double& u_out, Best& best) const {
        const auto& nd = sim_.nodes_;
        const double u0 = sim_.cur_;
        std::size_t idx = nd.size();
        double ua = u0;
        double hprev = 0.5 * (sim_.y_ - t_->y_min());
        bool top = true;
        while (idx > 0) {
            const Node& m = nd[idx - 1];
            const double lb = m.p.b0;
            if (ua > lb) {
                if (!m.p.antidiag) {
                    const bool rising = top && sim_.rising_;
                    const double M = rising ? u0 : m.p.v;
                    const double eb0 = rising ? sim_.live_ : m.Eb0;
                    if (lin_down(ua, lb, t_->position(M), h, m.S + eb0, hprev, u_out, best)) return true;
                } else {
                    const double a_ua = top ? sim_.live_ : nd[idx].S - m.S;
                    if (quad_down(ua, lb, m, a_ua, h, hprev, u_out, best)) return true;
                }
            }
            ua = std::min(ua, lb);
            top = false;
            --idx;
        }
        return false;  // below the first piece the output is y_min: reached at its start already
    }

    // y = y_min + 2 (base - E(M, u)) on [lb, ua]: linear in u inside each beta cell.
    bool lin_down(double ua, double lb, GridPos pm, double h, double base, double& hprev, double& u_out,
                  Best& best) const {
        const EverettTable& t = *t_;
        const auto& L = t.levels();
        const double goal = base - h;  // E(M, u) wanted
        const GridPos pu = t.locate(ua, false);
        std::size_t j = pu.i;
        double f0 = pu.f;
        // skip the cells whose top is still above the goal, unless the target is in the first
        if (monotone_ && j > 0 && lb < L[j] && t.value(pm, GridPos{j - 1, 1.0}) < goal) {
            const std::size_t jl = static_cast<std::size_t>(
                std::max<std::ptrdiff_t>(std::upper_bound(L.begin(), L.end(), lb) - L.begin() - 1, 0));
            // smallest j' in [jl, j) with E(M, l_{j'+1}) < goal: the walk restarts there
            std::size_t lo = jl, hi = j - 1, found = j - 1;
            while (lo < hi) {
                const std::size_t mid = lo + (hi - lo) / 2;
                if (t.value(pm, GridPos{mid, 1.0}) < goal) {
                    found = mid;
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            if (found != j) {
                keep(best, L[found + 1], std::abs(t.value(pm, GridPos{found, 1.0}) - goal));
                j = found;
                f0 = 1.0;
                hprev = base - t.value(pm, GridPos{j, 1.0});
            }
        }
        for (;;) {
            ++walked_;
            const double l0 = L[j], w = L[j + 1] - l0;
            const bool last = lb >= l0;
            const double f1 = last ? (lb - l0) / w : 0.0;
            const double p = t.value(pm, GridPos{j, 0.0}), q = t.value(pm, GridPos{j, 1.0}) - p;
            const double e1 = p + q * f1;
            const double x1 = last ? lb : l0;
            if ((h - hprev) * (e1 - goal) <= 0.0) {  // h(u) = base - e(u)
                double f = q != 0.0 ? (goal - p) / q : f0;
                f = std::min(std::max(f, f1), f0);
                u_out = f - f1 < SNAP ? x1 : f0 - f < SNAP ? (j == pu.i ? ua : L[j + 1]) : l0 + f * w;
                u_out = std::min(std::max(u_out, lb), ua);
                return true;
            }
            hprev = base - e1;
            keep(best, x1, std::abs(e1 - goal));
            if (last || j == 0) return false;
            --j;
            f0 = 1.0;
        }
    }

    // The fall cuts the antidiagonal piece m: on [lb, ua] h(u) = S_m + A(c, b0_m, u),
    // quadratic between the break points x[k]; A(c, b0_m, u) = a_ua - (P(ua) - P(u)).
    bool quad_down(double ua, double lb, const Node& m, double a_ua, double h, double& hprev, double& u_out,
                   Best& best) const {
        const auto& ad = sim_.ad_[static_cast<std::size_t>(m.ad)];
        const auto& X = ad.x;
        const double off = m.S + a_ua - ad.prefix(ua);
        std::ptrdiff_t k = (std::lower_bound(X.begin(), X.end(), ua) - X.begin()) - 1;  // next x below ua
        const std::ptrdiff_t k_end = std::upper_bound(X.begin(), X.end(), lb) - X.begin();
        double x0 = ua, g0 = m.S + a_ua;
        // skip the break points still above the goal, unless the target is before the first
        if (monotone_ && k >= k_end && off + ad.P[static_cast<std::size_t>(k)] > h) {
            std::ptrdiff_t lo = k_end, hi = k, found = k;  // smallest k' with h(x[k']) > h
            while (lo < hi) {
                const std::ptrdiff_t mid = lo + (hi - lo) / 2;
                if (off + ad.P[static_cast<std::size_t>(mid)] > h) {
                    found = mid;
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            if (found <= k) {
                x0 = X[static_cast<std::size_t>(found)];
                g0 = off + ad.P[static_cast<std::size_t>(found)];
                hprev = g0;
                keep(best, x0, std::abs(g0 - h));
                k = found - 1;
            }
        }
        for (;;) {
            ++walked_;
            const bool inner = k >= k_end;
            const double x1 = inner ? X[static_cast<std::size_t>(k)] : lb;
            if (x1 < x0) {
                const double xm = 0.5 * (x0 + x1);
                const double gm = off + ad.prefix(xm), g1 = off + ad.prefix(x1);
                if (quad_root(x0, x1, g0, gm, g1, h, hprev, u_out, best)) return true;
                x0 = x1;
                g0 = g1;
            }
            if (!inner) return false;
            --k;
        }
    }

    // ---- shared pieces ---------------------------------------------------------------------
    // h(s) on x = x0 + s (x1 - x0), s in [0, 1], is the quadratic through (0, g0), (1/2, gm),
    // (1, g1); take its first root s (nearest x0) or update the nearest value.
    static bool quad_root(double x0, double x1, double g0, double gm, double g1, double h, double& hprev,
                          double& u_out, Best& best) {
        const double a = 2.0 * (g1 - 2.0 * gm + g0), b = g1 - g0 - a, c = g0 - h;
        const double tiny = 1e-14 * (std::abs(g0) + std::abs(g1) + std::abs(h) + 1e-300);
        double s = -1.0;
        if (std::abs(a) <= tiny) {
            if (b != 0.0) s = -c / b;
            else if (c == 0.0) s = 0.0;
        } else {
            const double disc = b * b - 4.0 * a * c;
            if (disc >= 0.0) {
                const double sq = std::sqrt(disc);
                const double qq = -0.5 * (b + (b >= 0.0 ? sq : -sq));  // stable roots qq/a, c/qq
                double r1 = qq / a, r2 = qq != 0.0 ? c / qq : r1;
                if (r1 > r2) std::swap(r1, r2);
                const double eps = 1e-12;
                if (r1 >= -eps && r1 <= 1.0 + eps) s = r1;
                else if (r2 >= -eps && r2 <= 1.0 + eps) s = r2;
            }
        }
        if (!(s >= -1e-12 && s <= 1.0 + 1e-12) && (h - hprev) * (h - g1) <= 0.0)
            s = std::abs(h - hprev) <= std::abs(h - g1) ? 0.0 : 1.0;  // a joint's rounding
        if (s >= -1e-12 && s <= 1.0 + 1e-12) {
            s = std::min(std::max(s, 0.0), 1.0);
            u_out = s > 1.0 - SNAP ? x1 : s < SNAP ? x0 : x0 + s * (x1 - x0);
            return true;
        }
        hprev = g1;
        keep(best, x1, std::abs(g1 - h));
        if (std::abs(a) > 0.0) {
            const double sv = -b / (2.0 * a);
            if (sv > 0.0 && sv < 1.0) keep(best, x0 + sv * (x1 - x0), std::abs(g0 + (b + a * sv) * sv - h));
        }
        return false;
    }

    Simulator sim_;
    static const EverettTable& bilinear_only(const EverettTable& t) {
        if (t.cubic())
            throw std::invalid_argument("table: the inverse needs a bilinear table; resample the cubic one on a "
                                        "finer grid (EverettTable.resample)");
        return t;
    }

    const EverettTable* t_;
    bool monotone_ = true;
    std::size_t unreachable_ = 0;
    mutable std::size_t walked_ = 0;
};

// Invert a whole target sequence from `state`: inputs, achieved outputs, reached flags, the
// final state and the number of unreachable targets.
struct InverseRun {
    std::vector<double> u, y;
    std::vector<std::uint8_t> reached;
    State final_state;
    std::size_t unreachable = 0;
};

inline InverseRun invert(const EverettTable& table, const State& state, const std::vector<double>& y) {
    Inverter inv(table, state);
    InverseRun r;
    r.u.resize(y.size());
    r.y.resize(y.size());
    r.reached.resize(y.size());
    inv.run(y.data(), r.u.data(), r.y.data(), r.reached.data(), y.size());
    r.final_state = inv.state();
    r.unreachable = inv.unreachable();
    return r;
}

}  // namespace preisach

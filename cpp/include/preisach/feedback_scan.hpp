// Profiled least-squares fit of a Preisach model whose relays see the input shifted by a linear
// output feedback, for many feedback gains at once: diagnosis' start-value scan of the
// non-congruence (moving-model) candidate.
//
// For every scan point k (gain a_k in V/V, zero y_k in V) and every recording the relays see
//     x_t = clamp(u_t + a_k (p_t - y_k), u_min, u_max)
// with p_t the feedback signal one sample late (series-parallel form: a measured output, not
// the simulated one, so the weights are a linear least-squares problem).  The weights theta of
// the tabulated model (regressor.hpp: P_t = r_t . theta) are solved from the normal equations
// over the rows (fold[t] == 0) of every recording, with a ridge toward theta0,
//     (sum r_t r_t^T + lam I) theta = sum r_t z_t + lam theta0,  lam = ridge * max(tr / p, 1e-300),
// tr the trace of the unridged sum; the point's value is sum (y_t - L(P)_t)^2 over those rows.
// Without output filters L is the identity and z = y.  With a chain L of linear output filters
// (each y = x + mix (H x - x), H = b / a in direct form II transposed, started at rest at its
// first input, as diagnosis' _LinearFilter blocks), the fit is linearised about a reference
// table: z_t = y_t - (L(P_ref)_t - P_ref_t), P_ref the reference table's output for the same
// relay input, and the prediction L(P) runs the fitted table.  Samples with fold[t] < 0 only
// advance the relays.  Every point is independent: they run on several threads (batch.hpp).
//
// The residuals are taken at every res_stride-th row of a recording, and every score_every-th
// of those counts in the SSE.  With a drift (no output filters), a smooth curve in time per
// recording, A c with A the recording's time basis (n x k) and c free, is fitted jointly with
// the weights: over the rows, with M = (A^T A + P)^-1 (fit_ginv, P the curve's penalty),
//     sum r_t r_t^T - B M B^T  and  sum r_t z_t - B M A^T z,  B = sum r_t a_t^T,
// replace the normal matrix and right-hand side (the drift profiled out); the residuals e at
// the residual rows are then freed of their own drift fit, e - A_s M_s A_s^T e (res_ginv = M_s,
// the same inverse at those rows), as diagnosis' Problem.residuals does.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "batch.hpp"
#include "everett.hpp"
#include "regressor.hpp"
#include "simulator.hpp"
#include "types.hpp"

namespace preisach {

// A linear output filter y = x + mix (H x - x), H(z) = b(z) / a(z) with a[0] = 1.
struct OutputFilter {
    std::vector<double> b, a;
    double mix = 1.0;

    void validate() const {
        if (b.empty() || a.empty()) throw std::invalid_argument("filters: b and a need at least one coefficient");
        if (a[0] != 1.0) throw std::invalid_argument("filters: a[0] must be 1, got " + std::to_string(a[0]));
        for (double v : b)
            if (!std::isfinite(v)) throw std::invalid_argument("filters: b is not finite");
        for (double v : a)
            if (!std::isfinite(v)) throw std::invalid_argument("filters: a is not finite");
        if (!std::isfinite(mix)) throw std::invalid_argument("filters: mix is not finite");
    }
};

// One filter running (direct form II transposed, as scipy.signal.lfilter).
class FilterRun {
public:
    explicit FilterRun(const OutputFilter& f) {
        const std::size_t n = std::max(f.a.size(), f.b.size());
        b_.assign(n, 0.0);
        a_.assign(n, 0.0);
        std::copy(f.b.begin(), f.b.end(), b_.begin());
        std::copy(f.a.begin(), f.a.end(), a_.begin());
        mix_ = f.mix;
        z_.assign(n - 1, 0.0);
        // at rest with a unit input: z_k = sum_{j > k} (b_j - a_j g), g = sum b / sum a
        double sb = 0.0, sa = 0.0;
        for (std::size_t j = 0; j < n; ++j) {
            sb += b_[j];
            sa += a_[j];
        }
        const double g = sb / sa;
        unit_.assign(n - 1, 0.0);
        double acc = 0.0;
        for (std::size_t j = n - 1; j >= 1; --j) {
            acc += b_[j] - a_[j] * g;
            unit_[j - 1] = acc;
        }
    }
    void start(double x0) {
        for (std::size_t k = 0; k < z_.size(); ++k) z_[k] = unit_[k] * x0;
    }
    double step(double x) {
        const std::size_t m = z_.size();
        const double h = b_[0] * x + (m ? z_[0] : 0.0);
        for (std::size_t k = 0; k + 1 < m; ++k) z_[k] = b_[k + 1] * x + z_[k + 1] - a_[k + 1] * h;
        if (m) z_[m - 1] = b_[m] * x - a_[m] * h;
        return x + mix_ * (h - x);
    }

private:
    std::vector<double> b_, a_, z_, unit_;
    double mix_ = 1.0;
};

// One recording of the scan (views, not copies): applied input u (V), feedback signal one
// sample late p (V), measured output y (V), fold labels (0: a row, < 0: state only), n
// samples; the output filters between the Preisach output and the reading, in order.
struct ScanRecording {
    const double* u;
    const double* p;
    const double* y;
    const std::int32_t* fold;
    std::size_t n;
    std::vector<OutputFilter> filters{};
    // the drift (see the file comment): k basis columns, basis n x k (row-major), fit_ginv and
    // res_ginv k x k (row-major, symmetric); k = 0: none
    std::size_t k = 0;
    const double* basis = nullptr;
    const double* fit_ginv = nullptr;
    const double* res_ginv = nullptr;
    std::size_t res_stride = 1;
    std::size_t score_every = 1;
};

namespace detail {

// The chain of a recording's filters, each started at rest at its first input.
struct FilterChain {
    std::vector<FilterRun> runs;
    bool started = false;
    explicit FilterChain(const std::vector<OutputFilter>& f) {
        for (const auto& x : f) runs.emplace_back(x);
    }
    double step(double x) {
        for (auto& r : runs) {
            if (!started) r.start(x);
            x = r.step(x);
        }
        started = true;
        return x;
    }
};

// The nonzero entries of a dense row-major n x k matrix, by row (CSR).
struct SparseRows {
    std::vector<std::size_t> ptr{0}, col;
    std::vector<double> val;
    SparseRows() = default;
    SparseRows(const double* a, std::size_t n, std::size_t k) {
        for (std::size_t t = 0; t < n; ++t) {
            for (std::size_t j = 0; j < k; ++j)
                if (a[t * k + j] != 0.0) {
                    col.push_back(j);
                    val.push_back(a[t * k + j]);
                }
            ptr.push_back(col.size());
        }
    }
};

}  // namespace detail

// Training SSE (V^2) of every scan point (see the file comment).  states[k * R + i] is the
// relays' initial state of recording i (of R) at point k; theta0 has n_params entries;
// `reference` (the table the output filters are linearised about) is needed when a recording
// has filters.
inline std::vector<double> feedback_gain_scan(const VectorRef& levels, const std::vector<ScanRecording>& recs,
                                              const std::vector<State>& states, const double* gains,
                                              const double* zeros, std::size_t n_points, double u_min,
                                              double u_max, double ridge, const double* theta0,
                                              const EverettTable* reference = nullptr, unsigned threads = 0,
                                              Interpolation interpolation = Interpolation::bilinear) {
    const std::size_t R = recs.size();
    bool filtered = false, drifting = false;
    for (std::size_t i = 0; i < recs.size(); ++i) {
        const ScanRecording& r = recs[i];
        for (const auto& f : r.filters) f.validate();
        filtered = filtered || !r.filters.empty();
        drifting = drifting || r.k > 0;
        if (r.res_stride < 1 || r.score_every < 1)
            throw std::invalid_argument("res_stride, score_every: recording " + std::to_string(i) +
                                        " needs both >= 1");
        if (r.k > 0 && (r.basis == nullptr || r.fit_ginv == nullptr || r.res_ginv == nullptr))
            throw std::invalid_argument("drift: recording " + std::to_string(i) +
                                        " needs its basis, fit_ginv and res_ginv");
    }
    if (filtered && drifting) throw std::invalid_argument("drift: not with output filters");
    // the drift bases' nonzeros by sample (a B-spline basis has a few per sample), and the
    // Cholesky factor L of fit_ginv = L L^T, shared by every point
    std::vector<detail::SparseRows> bases(recs.size());
    std::vector<Eigen::MatrixXd> chol(recs.size());
    for (std::size_t i = 0; i < recs.size(); ++i) {
        const ScanRecording& r = recs[i];
        if (r.k == 0) continue;
        bases[i] = detail::SparseRows(r.basis, r.n, r.k);
        const Eigen::Index kd = Eigen::Index(r.k);
        const Eigen::LLT<Eigen::MatrixXd> llt(Eigen::Map<const RowMatrixXd>(r.fit_ginv, kd, kd));
        if (llt.info() != Eigen::Success)
            throw std::invalid_argument("drift: recording " + std::to_string(i) + ": fit_ginv is not definite");
        chol[i] = llt.matrixL();
    }
    if (filtered && reference == nullptr)
        throw std::invalid_argument("reference: output filters need the reference table");
    if (states.size() != n_points * R)
        throw std::invalid_argument("states: need one per point and recording (" + std::to_string(n_points * R) +
                                    "), got " + std::to_string(states.size()));
    if (!(u_max > u_min))
        throw std::invalid_argument("u_max: must lie above u_min (" + std::to_string(u_min) + "), got " +
                                    std::to_string(u_max));
    if (!(ridge >= 0.0)) throw std::invalid_argument("ridge: must be >= 0, got " + std::to_string(ridge));
    for (std::size_t i = 0; i < R; ++i)
        for (std::size_t t = 0; t < recs[i].n; ++t) {
            if (recs[i].fold[t] > 0)
                throw std::invalid_argument("fold: recording " + std::to_string(i) + " sample " + std::to_string(t) +
                                            " is " + std::to_string(recs[i].fold[t]) + " (0: a row, < 0: state only)");
            if (recs[i].fold[t] == 0 && !std::isfinite(recs[i].y[t]))
                throw std::invalid_argument("y: recording " + std::to_string(i) + " sample " + std::to_string(t) +
                                            " is not finite");
        }
    std::vector<double> sse(n_points, 0.0);
    for_each_row(n_points, threads, [&](std::size_t k) {
        const double a = gains[k], yk = zeros[k];
        if (!std::isfinite(a) || !std::isfinite(yk))
            throw std::invalid_argument("gains, zeros: point " + std::to_string(k) + " is not finite");
        std::size_t p = 0;
        RowMatrixXd G;
        Eigen::VectorXd b;
        std::vector<std::uint32_t> idx;  // the residual rows, kept for the residuals
        std::vector<double> val, yrow;
        std::vector<std::size_t> ptr{0}, trow, first(R + 1, 0);  // trow: each one's sample
        for (std::size_t i = 0; i < R; ++i) {
            const ScanRecording& r = recs[i];
            first[i] = yrow.size();
            EverettRegressor reg(levels, states[k * R + i], interpolation);
            if (p == 0) {
                p = reg.n_params();
                G = RowMatrixXd::Zero(Eigen::Index(p), Eigen::Index(p));
                b = Eigen::VectorXd::Zero(Eigen::Index(p));
            }
            const Eigen::Index kd = Eigen::Index(r.k);
            RowMatrixXd B = RowMatrixXd::Zero(r.k > 0 ? Eigen::Index(p) : 0, kd);  // sum r_t a_t^T
            Eigen::VectorXd c = Eigen::VectorXd::Zero(kd);                          // sum a_t z_t
            std::size_t n_rows = 0;
            const bool lin = !r.filters.empty();
            std::optional<Simulator> ref;
            if (lin) ref.emplace(*reference, states[k * R + i]);
            detail::FilterChain chain(r.filters);
            for (std::size_t t = 0; t < r.n; ++t) {
                const double x = std::min(std::max(r.u[t] + a * (r.p[t] - yk), u_min), u_max);
                reg.step(x, InputPolicy::clamp, t);
                double yt = r.y[t];
                if (lin) {  // the output filters' correction at the reference table
                    const double pr = ref->step(x);
                    yt -= chain.step(pr) - pr;
                }
                if (r.fold[t] < 0) continue;
                const auto& ix = reg.row_index();
                const auto& vx = reg.row_value();
                for (std::size_t e0 = 0; e0 < ix.size(); ++e0) {
                    const double vc = vx[e0];
                    double* row = G.data() + std::size_t(ix[e0]) * p;
                    for (std::size_t e = e0; e < ix.size(); ++e) row[ix[e]] += vc * vx[e];  // upper triangle
                    b[Eigen::Index(ix[e0])] += vc * yt;
                }
                if (r.k > 0) {
                    const detail::SparseRows& a = bases[i];
                    for (std::size_t q = a.ptr[t]; q < a.ptr[t + 1]; ++q) {
                        const Eigen::Index j = Eigen::Index(a.col[q]);
                        const double aq = a.val[q];
                        for (std::size_t e0 = 0; e0 < ix.size(); ++e0) B(Eigen::Index(ix[e0]), j) += vx[e0] * aq;
                        c[j] += yt * aq;
                    }
                }
                if (filtered || n_rows++ % r.res_stride != 0) continue;  // filtered: simulated below
                idx.insert(idx.end(), ix.begin(), ix.end());
                val.insert(val.end(), vx.begin(), vx.end());
                yrow.push_back(yt);
                trow.push_back(t);
                ptr.push_back(idx.size());
            }
            if (r.k > 0) {  // the drift profiled out: B M B^T = (B L)(B L)^T, upper triangle only
                const Eigen::MatrixXd BL = B * chol[i];
                G.selfadjointView<Eigen::Upper>().rankUpdate(BL, -1.0);
                b.noalias() -= BL * (chol[i].transpose() * c);
            }
        }
        first[R] = yrow.size();
        if (p == 0) return;  // no recording
        const double lam = ridge * std::max(G.trace() / double(p), 1e-300);
        for (std::size_t c = 0; c < p; ++c) G(Eigen::Index(c), Eigen::Index(c)) += lam;
        for (std::size_t c = 0; c < p; ++c) b[Eigen::Index(c)] += lam * theta0[c];
        const Eigen::LLT<RowMatrixXd, Eigen::Upper> llt(G);
        if (llt.info() != Eigen::Success)
            throw std::invalid_argument("point " + std::to_string(k) + ": the normal equations are not definite");
        const Eigen::VectorXd theta = llt.solve(b);
        if (filtered) {  // run the fitted table and the filters; residuals at the rows
            const std::size_t nl = std::size_t(levels.size());
            RowMatrixXd v = RowMatrixXd::Zero(Eigen::Index(nl), Eigen::Index(nl));
            for (std::size_t ii = 1; ii < nl; ++ii)
                for (std::size_t jj = 0; jj < ii; ++jj)
                    v(Eigen::Index(ii), Eigen::Index(jj)) = theta[Eigen::Index(EverettRegressor::node_index(ii, jj))];
            const EverettTable table(levels, v, theta[Eigen::Index(p - 1)], interpolation);
            double s = 0.0;
            for (std::size_t i = 0; i < R; ++i) {
                const ScanRecording& r = recs[i];
                Simulator sim(table, states[k * R + i]);
                detail::FilterChain chain(r.filters);
                std::size_t n_rows = 0;
                for (std::size_t t = 0; t < r.n; ++t) {
                    const double x = std::min(std::max(r.u[t] + a * (r.p[t] - yk), u_min), u_max);
                    const double out = chain.step(sim.step(x));
                    if (r.fold[t] < 0 || n_rows++ % (r.res_stride * r.score_every) != 0) continue;
                    const double res = r.y[t] - out;
                    s += res * res;
                }
            }
            sse[k] = s;
            return;
        }
        double s = 0.0;
        std::vector<double> res;
        for (std::size_t i = 0; i < R; ++i) {
            const ScanRecording& r = recs[i];
            res.assign(first[i + 1] - first[i], 0.0);
            for (std::size_t q = first[i]; q < first[i + 1]; ++q) {
                double pred = 0.0;
                for (std::size_t e = ptr[q]; e < ptr[q + 1]; ++e) pred += val[e] * theta[Eigen::Index(idx[e])];
                res[q - first[i]] = yrow[q] - pred;
            }
            if (r.k > 0) {  // each recording's residual freed of its drift fit
                const detail::SparseRows& a = bases[i];
                Eigen::VectorXd d = Eigen::VectorXd::Zero(Eigen::Index(r.k));
                for (std::size_t q = first[i]; q < first[i + 1]; ++q)
                    for (std::size_t e = a.ptr[trow[q]]; e < a.ptr[trow[q] + 1]; ++e)
                        d[Eigen::Index(a.col[e])] += res[q - first[i]] * a.val[e];
                const Eigen::VectorXd w =
                    Eigen::Map<const RowMatrixXd>(r.res_ginv, Eigen::Index(r.k), Eigen::Index(r.k)) * d;
                for (std::size_t q = first[i]; q < first[i + 1]; ++q)
                    for (std::size_t e = a.ptr[trow[q]]; e < a.ptr[trow[q] + 1]; ++e)
                        res[q - first[i]] -= a.val[e] * w[Eigen::Index(a.col[e])];
            }
            for (std::size_t j = 0; j < res.size(); j += r.score_every) s += res[j] * res[j];
        }
        sse[k] = s;
    });
    return sse;
}

}  // namespace preisach

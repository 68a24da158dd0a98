// Profiled least-squares fit of a Preisach model whose relays see the input shifted by a linear
// output feedback, for many feedback gains at once: diagnosis' start-value scan of the
// non-congruence (moving-model) candidate.
//
// For every scan point k (gain a_k in V/V, zero y_k in V) and every recording the relays see
//     x_t = clamp(u_t + a_k (p_t - y_k), u_min, u_max)
// with p_t the feedback signal one sample late (series-parallel form: a measured output, not
// the simulated one, so the weights are a linear least-squares problem).  The weights theta of
// the tabulated model (regressor.hpp: y_t = r_t . theta) are solved from the normal equations
// over the rows (fold[t] == 0) of every recording, with a ridge toward theta0,
//     (sum r_t r_t^T + lam I) theta = sum r_t y_t + lam theta0,  lam = ridge * max(tr / p, 1e-300),
// tr the trace of the unridged sum; the point's value is sum (y_t - r_t . theta)^2 over those
// rows.  Samples with fold[t] < 0 only advance the relays.  Every point is independent: they
// run on several threads (batch.hpp), one boundary pass per point and recording.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "batch.hpp"
#include "regressor.hpp"
#include "types.hpp"

namespace preisach {

// One recording of the scan (views, not copies): applied input u (V), feedback signal one
// sample late p (V), measured output y (V), fold labels (0: a row, < 0: state only), n samples.
struct ScanRecording {
    const double* u;
    const double* p;
    const double* y;
    const std::int32_t* fold;
    std::size_t n;
};

// Training SSE (V^2) of every scan point (see the file comment).  states[k * R + i] is the
// relays' initial state of recording i (of R) at point k; theta0 has n_params entries.
inline std::vector<double> feedback_gain_scan(const VectorRef& levels, const std::vector<ScanRecording>& recs,
                                              const std::vector<State>& states, const double* gains,
                                              const double* zeros, std::size_t n_points, double u_min,
                                              double u_max, double ridge, const double* theta0,
                                              unsigned threads = 0) {
    const std::size_t R = recs.size();
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
        std::vector<std::uint32_t> idx;  // the rows, kept for the residuals
        std::vector<double> val, yrow;
        std::vector<std::size_t> ptr{0};
        for (std::size_t i = 0; i < R; ++i) {
            const ScanRecording& r = recs[i];
            EverettRegressor reg(levels, states[k * R + i]);
            if (p == 0) {
                p = reg.n_params();
                G = RowMatrixXd::Zero(Eigen::Index(p), Eigen::Index(p));
                b = Eigen::VectorXd::Zero(Eigen::Index(p));
            }
            for (std::size_t t = 0; t < r.n; ++t) {
                const double x = std::min(std::max(r.u[t] + a * (r.p[t] - yk), u_min), u_max);
                reg.step(x, InputPolicy::clamp, t);
                if (r.fold[t] < 0) continue;
                const double yt = r.y[t];
                const auto& ix = reg.row_index();
                const auto& vx = reg.row_value();
                for (std::size_t c = 0; c < ix.size(); ++c) {
                    const double vc = vx[c];
                    double* row = G.data() + std::size_t(ix[c]) * p;
                    for (std::size_t e = c; e < ix.size(); ++e) row[ix[e]] += vc * vx[e];  // upper triangle
                    b[Eigen::Index(ix[c])] += vc * yt;
                }
                idx.insert(idx.end(), ix.begin(), ix.end());
                val.insert(val.end(), vx.begin(), vx.end());
                yrow.push_back(yt);
                ptr.push_back(idx.size());
            }
        }
        if (p == 0) return;  // no recording
        const double lam = ridge * std::max(G.trace() / double(p), 1e-300);
        for (std::size_t c = 0; c < p; ++c) G(Eigen::Index(c), Eigen::Index(c)) += lam;
        for (std::size_t c = 0; c < p; ++c) b[Eigen::Index(c)] += lam * theta0[c];
        const Eigen::LLT<RowMatrixXd, Eigen::Upper> llt(G);
        if (llt.info() != Eigen::Success)
            throw std::invalid_argument("point " + std::to_string(k) + ": the normal equations are not definite");
        const Eigen::VectorXd theta = llt.solve(b);
        double s = 0.0;
        for (std::size_t q = 0; q + 1 < ptr.size(); ++q) {
            double pred = 0.0;
            for (std::size_t e = ptr[q]; e < ptr[q + 1]; ++e) pred += val[e] * theta[Eigen::Index(idx[e])];
            const double res = yrow[q] - pred;
            s += res * res;
        }
        sse[k] = s;
    });
    return sse;
}

}  // namespace preisach

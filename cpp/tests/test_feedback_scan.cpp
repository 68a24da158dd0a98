// The linear-feedback gain scan of diagnosis (feedback_scan.hpp) against a brute-force fit:
// dense regressor rows, ridge normal equations solved directly, residuals summed.
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/LU>
#include <doctest/doctest.h>

#include <preisach/feedback_scan.hpp>

#include "helpers.hpp"

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_feedback_scan {

using namespace ptest;

namespace {

struct Rec {
    std::vector<double> u, p, y;
    std::vector<std::int32_t> fold;
};

// A moving model (relays see u + a (y_prev - y0), clamped) from `s0`: its output and the
// output one sample late.
Rec moving_record(const EverettTable& t, const State& s0, std::vector<double> u, double a, double y0) {
    Rec r;
    r.u = std::move(u);
    Simulator sim(t, s0);
    double prev = sim.output();
    for (std::size_t k = 0; k < r.u.size(); ++k) {
        r.p.push_back(prev);
        const double x = std::min(std::max(r.u[k] + a * (prev - y0), U_MIN), U_MAX);
        prev = sim.step(x);
        r.y.push_back(prev);
    }
    for (std::size_t k = 0; k < r.u.size(); ++k) r.fold.push_back(k >= 40 && k % 3 == 0 ? 0 : -1);
    return r;
}

double brute_sse(const Eigen::VectorXd& lv, const std::vector<Rec>& recs, const std::vector<State>& s0, double a,
                 double y0, double ridge, const Eigen::VectorXd& theta0) {
    const auto p = Eigen::Index(theta0.size());
    RowMatrixXd G = RowMatrixXd::Zero(p, p);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(p);
    std::vector<Eigen::VectorXd> rows;
    std::vector<double> ys;
    for (std::size_t i = 0; i < recs.size(); ++i) {
        const Rec& r = recs[i];
        std::vector<double> x(r.u.size());
        for (std::size_t k = 0; k < x.size(); ++k) x[k] = std::min(std::max(r.u[k] + a * (r.p[k] - y0), U_MIN), U_MAX);
        const auto R = preisach::regressor_rows(lv, s0[i], x.data(), x.size(), preisach::InputPolicy::clamp);
        for (std::size_t k = 0; k < x.size(); ++k) {
            if (r.fold[k] != 0) continue;
            Eigen::VectorXd row = Eigen::VectorXd::Zero(p);
            for (auto q = R.indptr[k]; q < R.indptr[k + 1]; ++q)
                row[Eigen::Index(R.indices[std::size_t(q)])] = R.data[std::size_t(q)];
            G += row * row.transpose();
            b += row * r.y[k];
            rows.push_back(row);
            ys.push_back(r.y[k]);
        }
    }
    const double lam = ridge * G.trace() / double(p);
    G.diagonal().array() += lam;
    b += lam * theta0;
    const Eigen::VectorXd theta = G.ldlt().solve(b);
    double s = 0.0;
    for (std::size_t q = 0; q < rows.size(); ++q) s += std::pow(ys[q] - rows[q].dot(theta), 2);
    return s;
}

}  // namespace

TEST_CASE("feedback gain scan: the profiled SSE of every gain and zero, as a brute-force fit") {
    std::mt19937 g(11);
    const auto lv = nonuniform_levels(7);
    const EverettTable t = analytic_table(lv);
    const double a_true = 0.01, y0_true = 5.0;  // the output spans about -3.5 to 18 V
    const std::vector<State> s0{State::negative_saturation(U_MIN, U_MAX), State::neutral(U_MIN, U_MAX, 0.4)};
    std::vector<Rec> recs{moving_record(t, s0[0], random_walk(g, 700, 0.0, 0.15), a_true, y0_true),
                          moving_record(t, s0[1], random_walk(g, 500, 0.5, 0.15), a_true, y0_true)};
    const std::size_t p = 7 * 6 / 2 + 1;
    Eigen::VectorXd theta0 = Eigen::VectorXd::Zero(Eigen::Index(p));
    theta0[Eigen::Index(p - 1)] = Y_MIN;
    const std::vector<double> gains{-0.02, 0.0, a_true, 0.02, a_true};
    const std::vector<double> zeros{y0_true, 0.5, y0_true, 12.0, 15.0};
    std::vector<preisach::ScanRecording> views;
    for (const Rec& r : recs) views.push_back({r.u.data(), r.p.data(), r.y.data(), r.fold.data(), r.u.size()});
    std::vector<State> states;
    for (std::size_t k = 0; k < gains.size(); ++k) states.insert(states.end(), s0.begin(), s0.end());
    const double ridge = 1e-9;
    const auto sse = preisach::feedback_gain_scan(lv, views, states, gains.data(), zeros.data(), gains.size(),
                                                  U_MIN, U_MAX, ridge, theta0.data(), nullptr, 1);
    REQUIRE(sse.size() == gains.size());
    double yy = 0.0;
    for (const Rec& r : recs)
        for (std::size_t k = 0; k < r.y.size(); ++k) yy += r.fold[k] == 0 ? r.y[k] * r.y[k] : 0.0;
    for (std::size_t k = 0; k < gains.size(); ++k) {
        const double ref = brute_sse(lv, recs, s0, gains[k], zeros[k], ridge, theta0);
        CHECK(sse[k] == doctest::Approx(ref).epsilon(1e-6).scale(1e-12 * yy));
    }
    // the true feedback is fitted to rounding (the data are the model's own), the others are not
    CHECK(sse[2] < 1e-12 * yy);
    for (std::size_t k : {0, 1, 3, 4}) CHECK(sse[k] > 1e3 * sse[2]);
    // several threads give the same numbers
    const auto again = preisach::feedback_gain_scan(lv, views, states, gains.data(), zeros.data(), gains.size(),
                                                    U_MIN, U_MAX, ridge, theta0.data(), nullptr, 3);
    for (std::size_t k = 0; k < gains.size(); ++k) CHECK(again[k] == sse[k]);
}

namespace {

// The drift basis of a recording of n samples: 1, t, t^2 with t = k / n (row-major n x 3).
std::vector<double> drift_basis(std::size_t n) {
    std::vector<double> a;
    for (std::size_t k = 0; k < n; ++k) {
        const double t = double(k) / double(n);
        a.insert(a.end(), {1.0, t, t * t});
    }
    return a;
}

// (A^T A + pen I)^-1 over the given samples of a basis.
RowMatrixXd drift_ginv(const std::vector<double>& a, const std::vector<std::size_t>& rows, double pen) {
    RowMatrixXd g = pen * RowMatrixXd::Identity(3, 3);
    for (std::size_t t : rows) {
        const Eigen::Map<const Eigen::Vector3d> at(a.data() + 3 * t);
        g += at * at.transpose();
    }
    return g.inverse();
}

}  // namespace

TEST_CASE("feedback gain scan with a drift: weights and drift fitted jointly, as a brute-force fit") {
    std::mt19937 g(5);
    const auto lv = nonuniform_levels(6);
    const EverettTable t = analytic_table(lv);
    const double a_true = 0.01, y0_true = 5.0, pen = 1e-3, ridge = 1e-9;
    const std::size_t stride = 2, every = 3;
    const std::vector<State> s0{State::negative_saturation(U_MIN, U_MAX), State::neutral(U_MIN, U_MAX, 0.3)};
    std::vector<Rec> recs{moving_record(t, s0[0], random_walk(g, 600, 0.0, 0.15), a_true, y0_true),
                          moving_record(t, s0[1], random_walk(g, 450, 0.5, 0.15), a_true, y0_true)};
    std::vector<std::vector<double>> bases;
    std::vector<RowMatrixXd> fit_ginv, res_ginv;
    std::vector<std::vector<std::size_t>> fit_rows(2), res_rows(2);
    for (std::size_t i = 0; i < 2; ++i) {
        Rec& r = recs[i];
        for (std::size_t k = 0; k < r.y.size(); ++k) r.y[k] += 0.4 - 0.8 * double(k) / double(r.y.size());
        bases.push_back(drift_basis(r.y.size()));
        for (std::size_t k = 0; k < r.y.size(); ++k)
            if (r.fold[k] == 0) fit_rows[i].push_back(k);
        for (std::size_t q = 0; q < fit_rows[i].size(); q += stride) res_rows[i].push_back(fit_rows[i][q]);
        fit_ginv.push_back(drift_ginv(bases[i], fit_rows[i], pen));
        res_ginv.push_back(drift_ginv(bases[i], res_rows[i], pen));
    }
    const std::size_t p = 6 * 5 / 2 + 1;
    Eigen::VectorXd theta0 = Eigen::VectorXd::Zero(Eigen::Index(p));
    theta0[Eigen::Index(p - 1)] = Y_MIN;
    const std::vector<double> gains{a_true, 0.0, -0.01, 0.02};
    const std::vector<double> zeros{y0_true, 0.0, 3.0, 10.0};
    std::vector<preisach::ScanRecording> views;
    for (std::size_t i = 0; i < 2; ++i) {
        const Rec& r = recs[i];
        views.push_back({r.u.data(), r.p.data(), r.y.data(), r.fold.data(), r.u.size()});
        views.back().k = 3;
        views.back().basis = bases[i].data();
        views.back().fit_ginv = fit_ginv[i].data();
        views.back().res_ginv = res_ginv[i].data();
        views.back().res_stride = stride;
        views.back().score_every = every;
    }
    std::vector<State> states;
    for (std::size_t k = 0; k < gains.size(); ++k) states.insert(states.end(), s0.begin(), s0.end());
    const auto sse = preisach::feedback_gain_scan(lv, views, states, gains.data(), zeros.data(), gains.size(), U_MIN,
                                                  U_MAX, ridge, theta0.data(), nullptr, 2);
    double yy = 0.0;
    for (const Rec& r : recs)
        for (double v : r.y) yy += v * v;
    for (std::size_t kp = 0; kp < gains.size(); ++kp) {
        // the joint least squares of weights and both drifts (unknowns theta, c_0, c_1)
        const Eigen::Index q = Eigen::Index(p) + 6;
        RowMatrixXd J = RowMatrixXd::Zero(q, q);
        Eigen::VectorXd rhs = Eigen::VectorXd::Zero(q);
        std::vector<std::vector<Eigen::VectorXd>> rows(2);
        for (std::size_t i = 0; i < 2; ++i) {
            const Rec& r = recs[i];
            std::vector<double> x(r.u.size());
            for (std::size_t k = 0; k < x.size(); ++k)
                x[k] = std::min(std::max(r.u[k] + gains[kp] * (r.p[k] - zeros[kp]), U_MIN), U_MAX);
            const auto R = preisach::regressor_rows(lv, s0[i], x.data(), x.size(), preisach::InputPolicy::clamp);
            for (std::size_t k : fit_rows[i]) {
                Eigen::VectorXd row = Eigen::VectorXd::Zero(q);
                for (auto e = R.indptr[k]; e < R.indptr[k + 1]; ++e)
                    row[Eigen::Index(R.indices[std::size_t(e)])] = R.data[std::size_t(e)];
                rows[i].push_back(row.head(Eigen::Index(p)));
                for (Eigen::Index j = 0; j < 3; ++j) row[Eigen::Index(p) + 3 * Eigen::Index(i) + j] = bases[i][3 * k + j];
                J += row * row.transpose();
                rhs += row * r.y[k];
            }
            for (Eigen::Index j = 0; j < 3; ++j) J(Eigen::Index(p) + 3 * Eigen::Index(i) + j, Eigen::Index(p) + 3 * Eigen::Index(i) + j) += pen;
        }
        // the ridge on the weights, scaled by the trace of their normal matrix with the drift profiled out
        const auto P = Eigen::Index(p);
        const RowMatrixXd schur = J.topLeftCorner(P, P) - J.topRightCorner(P, 6) *
                                                              J.bottomRightCorner(6, 6).inverse() *
                                                              J.bottomLeftCorner(6, P);
        const double lam = ridge * schur.trace() / double(p);
        J.topLeftCorner(P, P).diagonal().array() += lam;
        rhs.head(P) += lam * theta0;
        const Eigen::VectorXd theta = J.ldlt().solve(rhs).head(P);
        double ref = 0.0;
        for (std::size_t i = 0; i < 2; ++i) {  // residuals at every stride-th row, freed of their drift fit
            std::vector<double> e;
            Eigen::Vector3d d = Eigen::Vector3d::Zero();
            for (std::size_t m = 0; m < fit_rows[i].size(); m += stride) {
                const std::size_t k = fit_rows[i][m];
                e.push_back(recs[i].y[k] - rows[i][m].dot(theta));
                d += e.back() * Eigen::Map<const Eigen::Vector3d>(bases[i].data() + 3 * k);
            }
            const Eigen::Vector3d w = res_ginv[i] * d;
            for (std::size_t j = 0; j < e.size(); j += every) {
                const std::size_t k = res_rows[i][j];
                ref += std::pow(e[j] - Eigen::Map<const Eigen::Vector3d>(bases[i].data() + 3 * k).dot(w), 2);
            }
        }
        CHECK(sse[kp] == doctest::Approx(ref).epsilon(1e-6).scale(1e-12 * yy));
    }
    // the drift is in the basis: the true feedback fits to the penalty's shrinkage, the others do not
    for (std::size_t k : {1, 2, 3}) CHECK(sse[k] > 100.0 * sse[0]);
}

TEST_CASE("feedback gain scan: errors name the argument") {
    const auto lv = uniform_levels(4);
    const std::vector<double> u(10, 0.0), y(10, 1.0);
    std::vector<std::int32_t> fold(10, 0);
    const std::vector<preisach::ScanRecording> views{{u.data(), u.data(), y.data(), fold.data(), u.size()}};
    const std::vector<double> theta0(7, 0.0), gains{0.1}, zeros{0.0};
    const std::vector<State> one{State::negative_saturation(U_MIN, U_MAX)};
    const auto run = [&](const std::vector<State>& st, double ridge) {
        return preisach::feedback_gain_scan(lv, views, st, gains.data(), zeros.data(), 1, U_MIN, U_MAX, ridge,
                                            theta0.data(), nullptr, 1);
    };
    CHECK_THROWS_WITH_AS(run({}, 1e-7), doctest::Contains("states"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(run(one, -1.0), doctest::Contains("ridge"), std::invalid_argument);
    fold[3] = 2;
    CHECK_THROWS_WITH_AS(run(one, 1e-7), doctest::Contains("fold"), std::invalid_argument);
    fold[3] = 0;
    auto filtered = views;
    filtered[0].filters.push_back({{0.5}, {1.0, -0.5}, 1.0});
    CHECK_THROWS_WITH_AS(preisach::feedback_gain_scan(lv, filtered, one, gains.data(), zeros.data(), 1, U_MIN, U_MAX,
                                                      1e-7, theta0.data(), nullptr, 1),
                         doctest::Contains("reference"), std::invalid_argument);
    filtered[0].filters[0].a[0] = 2.0;
    CHECK_THROWS_WITH_AS(preisach::feedback_gain_scan(lv, filtered, one, gains.data(), zeros.data(), 1, U_MIN, U_MAX,
                                                      1e-7, theta0.data(), nullptr, 1),
                         doctest::Contains("a[0]"), std::invalid_argument);
}

namespace {

// y = x + mix (H x - x), H = b / a in direct form I from a constant past at x[0] (at rest).
std::vector<double> filter_di(const preisach::OutputFilter& f, const std::vector<double>& x) {
    double sb = 0.0, sa = 0.0;
    for (double v : f.b) sb += v;
    for (double v : f.a) sa += v;
    const double g = sb / sa;
    std::vector<double> h(x.size()), out(x.size());
    for (std::size_t n = 0; n < x.size(); ++n) {
        double acc = 0.0;
        for (std::size_t j = 0; j < f.b.size(); ++j) acc += f.b[j] * (n >= j ? x[n - j] : x[0]);
        for (std::size_t j = 1; j < f.a.size(); ++j) acc -= f.a[j] * (n >= j ? h[n - j] : g * x[0]);
        h[n] = acc;
        out[n] = x[n] + f.mix * (h[n] - x[n]);
    }
    return out;
}

std::vector<double> chain_di(const std::vector<preisach::OutputFilter>& fs, std::vector<double> x) {
    for (const auto& f : fs) x = filter_di(f, x);
    return x;
}

}  // namespace

TEST_CASE("feedback gain scan with output filters: linearised about the reference, as a brute-force fit") {
    std::mt19937 g(3);
    const auto lv = nonuniform_levels(6);
    const EverettTable t = analytic_table(lv);
    const double a_true = 0.01, y0_true = 5.0;
    const State s0 = State::negative_saturation(U_MIN, U_MAX);
    Rec r = moving_record(t, s0, random_walk(g, 600, 0.0, 0.15), a_true, y0_true);
    // a first-order lag and a lightly damped second-order filter (half of its output mixed in)
    const std::vector<preisach::OutputFilter> fs{{{0.4}, {1.0, -0.6}, 1.0},
                                                 {{0.02, 0.03}, {1.0, -1.7, 0.75}, 0.5}};
    r.y = chain_di(fs, r.y);  // the reading: the moving model's output through the filters
    const std::size_t p = 6 * 5 / 2 + 1;
    Eigen::VectorXd theta0 = Eigen::VectorXd::Zero(Eigen::Index(p));
    theta0[Eigen::Index(p - 1)] = Y_MIN;
    // the reference: the true table scaled (the linearisation is then not exact)
    RowMatrixXd vals = RowMatrixXd::Zero(6, 6);
    for (Eigen::Index i = 0; i < 6; ++i)
        for (Eigen::Index j = 0; j < i; ++j) vals(i, j) = 0.9 * E_exact(lv[i], lv[j]);
    const EverettTable ref(lv, vals, Y_MIN + 0.2);
    const std::vector<double> gains{a_true, 0.0, -0.01, a_true};
    const std::vector<double> zeros{y0_true, 0.0, 3.0, 10.0};
    std::vector<preisach::ScanRecording> views{{r.u.data(), r.p.data(), r.y.data(), r.fold.data(), r.u.size(), fs}};
    const std::vector<State> states(gains.size(), s0);
    const double ridge = 1e-9;
    const auto sse = preisach::feedback_gain_scan(lv, views, states, gains.data(), zeros.data(), gains.size(), U_MIN,
                                                  U_MAX, ridge, theta0.data(), &ref, 2);
    double yy = 0.0;
    for (std::size_t k = 0; k < r.y.size(); ++k) yy += r.fold[k] == 0 ? r.y[k] * r.y[k] : 0.0;
    for (std::size_t k = 0; k < gains.size(); ++k) {
        std::vector<double> x(r.u.size());
        for (std::size_t q = 0; q < x.size(); ++q)
            x[q] = std::min(std::max(r.u[q] + gains[k] * (r.p[q] - zeros[k]), U_MIN), U_MAX);
        const auto pref = simulate(ref, s0, x);
        const auto lref = chain_di(fs, pref);
        const auto R = preisach::regressor_rows(lv, s0, x.data(), x.size(), preisach::InputPolicy::clamp);
        RowMatrixXd G = RowMatrixXd::Zero(Eigen::Index(p), Eigen::Index(p));
        Eigen::VectorXd b = Eigen::VectorXd::Zero(Eigen::Index(p));
        for (std::size_t q = 0; q < x.size(); ++q) {
            if (r.fold[q] != 0) continue;
            Eigen::VectorXd row = Eigen::VectorXd::Zero(Eigen::Index(p));
            for (auto e = R.indptr[q]; e < R.indptr[q + 1]; ++e)
                row[Eigen::Index(R.indices[std::size_t(e)])] = R.data[std::size_t(e)];
            G += row * row.transpose();
            b += row * (r.y[q] - (lref[q] - pref[q]));
        }
        const double lam = ridge * G.trace() / double(p);
        G.diagonal().array() += lam;
        b += lam * theta0;
        const Eigen::VectorXd th = G.ldlt().solve(b);
        RowMatrixXd v = RowMatrixXd::Zero(6, 6);
        for (std::size_t i = 1; i < 6; ++i)
            for (std::size_t j = 0; j < i; ++j)
                v(Eigen::Index(i), Eigen::Index(j)) = th[Eigen::Index(i * (i - 1) / 2 + j)];
        const EverettTable fitted(lv, v, th[Eigen::Index(p - 1)]);
        const auto pred = chain_di(fs, simulate(fitted, s0, x));
        double ref_sse = 0.0;
        for (std::size_t q = 0; q < x.size(); ++q)
            if (r.fold[q] == 0) ref_sse += std::pow(r.y[q] - pred[q], 2);
        CHECK(sse[k] == doctest::Approx(ref_sse).epsilon(1e-6).scale(1e-12 * yy));
    }
    // linearised about the true table, the true feedback explains the reading to rounding
    const auto exact = preisach::feedback_gain_scan(lv, views, states, gains.data(), zeros.data(), gains.size(),
                                                    U_MIN, U_MAX, ridge, theta0.data(), &t, 1);
    CHECK(exact[0] < 1e-12 * yy);
    for (std::size_t k : {1, 2, 3}) CHECK(exact[k] > 1e3 * exact[0]);
}

}  // namespace unity_test_feedback_scan

// Bindings of the diagnosis kernels (preisach/play.hpp, preisach/moving.hpp,
// preisach/feedback_scan.hpp).
#include <preisach/feedback_scan.hpp>
#include <preisach/moving.hpp>
#include <preisach/play.hpp>

#include "common.hpp"

#include <optional>
#include <tuple>

void register_diagnose(py::module_& m) {
    m.def(
        "play_operator",
        [](const InArray& x, const InArray& width, double z0) {
            std::size_t n = 0, nw = 0;
            const double* px = as_vector(x, "x", n);
            const double* pw = as_vector(width, "width", nw);
            if (nw != n)
                throw std::invalid_argument("width: expected " + std::to_string(n) + " samples like x, got " +
                                            std::to_string(nw));
            py::array_t<double> z(static_cast<py::ssize_t>(n));
            double* pz = z.mutable_data();
            double last = z0;
            {
                py::gil_scoped_release release;
                last = preisach::play_operator(px, pw, n, z0, pz);
            }
            return py::make_tuple(z, last);
        },
        py::arg("x"), py::arg("width"), py::arg("z0"),
        "Play (backlash) operator with time-varying half-width (volts): z[k] = clip(z[k-1], x[k] - w[k], "
        "x[k] + w[k]) from z[-1] = z0; returns (z, last output).");

    m.def(
        "simulate_moving",
        [](const preisach::EverettTable& table, const InArray& u, const preisach::State& state, double a, double b,
           double y_c, double span, double c) {
            std::size_t n = 0;
            const double* pu = as_vector(u, "u", n);
            py::array_t<double> y(static_cast<py::ssize_t>(n)), ue(static_cast<py::ssize_t>(n));
            double* py_ = y.mutable_data();
            double* pe = ue.mutable_data();
            preisach::Simulator sim(table, state);
            {
                py::gil_scoped_release release;
                preisach::simulate_moving(sim, pu, n, a, b, y_c, span, py_, pe, c);
            }
            return py::make_tuple(y, ue, sim.state());
        },
        py::arg("table"), py::arg("u"), py::arg("state"), py::arg("a"), py::arg("b"), py::arg("y_c"),
        py::arg("span"), py::arg("c") = 0.0,
        "Preisach model with output feedback: u_eff[k] = clamp(u[k] + a d + b d^2 / span + c d^3 / span^2), "
        "d = y[k-1] - y_c (volts); returns (y, u_eff, final_state).");

    m.def(
        "simulate_feedback_spline",
        [](const preisach::EverettTable& table, const InArray& u, const preisach::State& state, double y_lo,
           double y_hi, const InArray& coefficients) {
            std::size_t n = 0, nc = 0;
            const double* pu = as_vector(u, "u", n);
            const double* pc = as_vector(coefficients, "coefficients", nc);
            const preisach::FeedbackSpline f(y_lo, y_hi, pc, nc);
            py::array_t<double> y(static_cast<py::ssize_t>(n)), ue(static_cast<py::ssize_t>(n));
            double* py_ = y.mutable_data();
            double* pe = ue.mutable_data();
            preisach::Simulator sim(table, state);
            {
                py::gil_scoped_release release;
                preisach::simulate_feedback_spline(sim, pu, n, f, py_, pe);
            }
            return py::make_tuple(y, ue, sim.state());
        },
        py::arg("table"), py::arg("u"), py::arg("state"), py::arg("y_lo"), py::arg("y_hi"), py::arg("coefficients"),
        "Preisach model with output feedback through a uniform cubic B-spline f on [y_lo, y_hi] (volts; "
        "constant outside): u_eff[k] = clamp(u[k] + f(y[k-1])); returns (y, u_eff, final_state).");

    m.def(
        "feedback_spline",
        [](const InArray& y, double y_lo, double y_hi, const InArray& coefficients) {
            std::size_t n = 0, nc = 0;
            const double* py_ = as_vector(y, "y", n);
            const double* pc = as_vector(coefficients, "coefficients", nc);
            const preisach::FeedbackSpline f(y_lo, y_hi, pc, nc);
            py::array_t<double> out(static_cast<py::ssize_t>(n));
            double* po = out.mutable_data();
            for (std::size_t k = 0; k < n; ++k) po[k] = f(py_[k]);
            return out;
        },
        py::arg("y"), py::arg("y_lo"), py::arg("y_hi"), py::arg("coefficients"),
        "The uniform cubic B-spline f(y) of simulate_feedback_spline at the outputs y (volts).");
    m.def(
        "feedback_gain_scan",
        [](const Eigen::VectorXd& levels, const std::vector<InArray>& u, const std::vector<InArray>& p,
           const std::vector<InArray>& y, const std::vector<py::array_t<std::int32_t, py::array::c_style |
                                                                           py::array::forcecast>>& fold,
           const std::vector<preisach::State>& states, const InArray& gains, const InArray& zeros, double u_min,
           double u_max, double ridge, const InArray& theta0,
           const std::vector<std::vector<std::tuple<std::vector<double>, std::vector<double>, double>>>& filters,
           const preisach::EverettTable* reference, unsigned threads, const std::string& interpolation,
           const std::vector<std::optional<std::tuple<InArray, InArray, InArray>>>& drift, std::size_t res_stride,
           std::size_t score_every) {
            const auto kind = preisach::parse_interpolation(interpolation);
            const std::size_t R = u.size();
            if (p.size() != R || y.size() != R || fold.size() != R)
                throw std::invalid_argument("u, p, y and fold: need one array per recording (got " +
                                            std::to_string(R) + ", " + std::to_string(p.size()) + ", " +
                                            std::to_string(y.size()) + ", " + std::to_string(fold.size()) + ")");
            if (!filters.empty() && filters.size() != R)
                throw std::invalid_argument("filters: need none or one list per recording (" + std::to_string(R) +
                                            "), got " + std::to_string(filters.size()));
            if (!drift.empty() && drift.size() != R)
                throw std::invalid_argument("drift: need none or one entry per recording (" + std::to_string(R) +
                                            "), got " + std::to_string(drift.size()));
            std::vector<preisach::ScanRecording> recs(R);
            for (std::size_t i = 0; i < R; ++i) {
                std::size_t nu = 0, np_ = 0, ny = 0;
                const double* pu = as_vector(u[i], "u", nu);
                const double* pp = as_vector(p[i], "p", np_);
                const double* py_ = as_vector(y[i], "y", ny);
                if (np_ != nu || ny != nu || fold[i].ndim() != 1 || std::size_t(fold[i].shape(0)) != nu)
                    throw std::invalid_argument("u, p, y and fold: recording " + std::to_string(i) +
                                                " needs 1-D arrays of one length");
                recs[i] = {pu, pp, py_, fold[i].data(), nu, {}};
                recs[i].res_stride = res_stride;
                recs[i].score_every = score_every;
                if (!filters.empty())
                    for (const auto& [fb, fa, mix] : filters[i]) recs[i].filters.push_back({fb, fa, mix});
                if (drift.empty() || !drift[i]) continue;
                const auto& [basis, fit_ginv, res_ginv] = *drift[i];
                const std::string at = "drift: recording " + std::to_string(i);
                if (basis.ndim() != 2 || std::size_t(basis.shape(0)) != nu || basis.shape(1) < 1)
                    throw std::invalid_argument(at + ": the basis must be " + std::to_string(nu) + " x k, k >= 1");
                const py::ssize_t kd = basis.shape(1);
                for (const auto* g : {&fit_ginv, &res_ginv})
                    if (g->ndim() != 2 || g->shape(0) != kd || g->shape(1) != kd)
                        throw std::invalid_argument(at + ": fit_ginv and res_ginv must be " + std::to_string(kd) +
                                                    " x " + std::to_string(kd));
                recs[i].k = std::size_t(kd);
                recs[i].basis = basis.data();
                recs[i].fit_ginv = fit_ginv.data();
                recs[i].res_ginv = res_ginv.data();
            }
            std::size_t k = 0, kz = 0, nt = 0;
            const double* pg = as_vector(gains, "gains", k);
            const double* pz = as_vector(zeros, "zeros", kz);
            const double* pt = as_vector(theta0, "theta0", nt);
            if (kz != k)
                throw std::invalid_argument("zeros: expected " + std::to_string(k) + " values like gains, got " +
                                            std::to_string(kz));
            const std::size_t nl = std::size_t(levels.size());
            const std::size_t n_par = nl >= 2 ? nl * (nl - 1) / 2 + 1 : 1;
            if (nt != n_par)
                throw std::invalid_argument("theta0: expected " + std::to_string(n_par) + " values, got " +
                                            std::to_string(nt));
            std::vector<double> sse;
            {
                py::gil_scoped_release release;
                sse = preisach::feedback_gain_scan(levels, recs, states, pg, pz, k, u_min, u_max, ridge, pt, reference,
                                                   threads, kind);
            }
            py::array_t<double> out(static_cast<py::ssize_t>(k));
            std::copy(sse.begin(), sse.end(), out.mutable_data());
            return out;
        },
        py::arg("levels"), py::arg("u"), py::arg("p"), py::arg("y"), py::arg("fold"), py::arg("states"),
        py::arg("gains"), py::arg("zeros"), py::arg("u_min"), py::arg("u_max"), py::arg("ridge"), py::arg("theta0"),
        py::arg("filters") = std::vector<std::vector<std::tuple<std::vector<double>, std::vector<double>, double>>>{},
        py::arg("reference").none(true) = nullptr, py::arg("threads") = 0, py::arg("interpolation") = "bilinear",
        py::arg("drift") = std::vector<std::optional<std::tuple<InArray, InArray, InArray>>>{},
        py::arg("res_stride") = 1, py::arg("score_every") = 1,
        "Training SSE (V^2) of a profiled Preisach fit whose relays see clamp(u + a (p - y0)) (volts), for every "
        "(gain a, zero y0): one list entry per recording (u, p the feedback signal one sample late, y, fold: 0 a "
        "row, < 0 state only), states[k * len(u) + i] the initial state of recording i at point k; ridge toward "
        "theta0 as lam = ridge * trace / p.  filters: per recording, the linear output filters (b, a with a[0] = 1, "
        "mix: y = x + mix (H x - x), started at rest) between the Preisach output and the reading, linearised about "
        "the `reference` table.  Residuals at every res_stride-th row, every score_every-th of them in the SSE.  drift: "
        "per recording None or (basis (n x k), fit_ginv, res_ginv (k x k)): a smooth curve in time fitted jointly "
        "(fit_ginv the inverse penalised normal matrix of the basis at the rows, res_ginv at the residual rows), "
        "not with filters.  The points run on `threads` threads (0: every core), the GIL released.");
}

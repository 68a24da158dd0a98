// Bindings of the rate-dependent Preisach model (preisach/rate_dependent.hpp).
#include "closed_loop_common.hpp"

#include <preisach/rate_dependent.hpp>

using preisach::ClosedLoopConfig;
using preisach::EverettTable;
using preisach::RateBasis;
using preisach::RateDependentModel;
using preisach::RateSimulator;
using preisach::State;

namespace {

py::array_t<double> vec(const std::vector<double>& v) {
    py::array_t<double> a{py::ssize_t(v.size())};
    std::copy(v.begin(), v.end(), a.mutable_data());
    return a;
}

}  // namespace

void register_rate(py::module_& m) {
    py::class_<RateDependentModel>(
        m, "RateDependentModel",
        "K Everett tables on one grid blended by hat functions on `knots` (V/s) of the first-order "
        "filtered input rate (time constant `tau`, s), interpolating in ln(rate) (scale='log') or in "
        "rate (scale='linear'): y = sum_k b_k(v) Gamma_k(psi).")
        .def(py::init([](std::vector<EverettTable> tables, std::vector<double> knots, double tau,
                         const std::string& scale) {
                 return RateDependentModel(std::move(tables), std::move(knots), tau,
                                           preisach::parse_rate_scale(scale));
             }),
             py::arg("tables"), py::arg("knots"), py::arg("tau"), py::arg("scale") = "log")
        .def_property_readonly("size", &RateDependentModel::size)
        .def_property_readonly("scale",
                               [](const RateDependentModel& r) { return std::string(preisach::rate_scale_name(r.scale())); })
        .def_property_readonly("knots", [](const RateDependentModel& r) { return vec(r.knots()); })
        .def_property_readonly("tau", &RateDependentModel::tau)
        .def_property_readonly("u_min", &RateDependentModel::u_min)
        .def_property_readonly("u_max", &RateDependentModel::u_max)
        .def_property_readonly("tables", &RateDependentModel::tables)
        .def("table", &RateDependentModel::table, py::arg("k"))
        .def("blended", &RateDependentModel::blended, py::arg("rate"),
             "The classical Everett table of a constant rate (V/s): sum_k b_k(rate) E_k.")
        .def(
            "weights",
            [](const RateDependentModel& r, const InArray& rate) {
                std::size_t n = 0;
                const double* pv = as_vector(rate, "rate", n);
                const std::size_t K = r.size();
                py::array_t<double> w({py::ssize_t(n), py::ssize_t(K)});
                double* pw = w.mutable_data();
                for (std::size_t i = 0; i < n; ++i) r.basis().weights(pv[i], pw + i * K);
                return w;
            },
            py::arg("rate"), "Basis weights b_k(rate), shape (n, K), for a 1-D array of rates (V/s).");

    py::class_<RateSimulator>(m, "RateSimulator", "Step-by-step simulation of a rate-dependent model.")
        .def(py::init<const RateDependentModel&, const State&, double, double>(), py::arg("model"), py::arg("state"),
             py::arg("rate"), py::arg("sample_time"), py::keep_alive<1, 2>())
        .def(
            "step",
            [](RateSimulator& s, double u, const std::string& out_of_range) {
                return s.step_checked(u, parse_policy(out_of_range), 0);
            },
            py::arg("u"), py::arg("out_of_range") = "clamp")
        .def(
            "run",
            [](RateSimulator& s, const InArray& u, const std::string& out_of_range) {
                const auto policy = parse_policy(out_of_range);
                std::size_t n = 0;
                const double* pu = as_vector(u, "u", n);
                py::array_t<double> y{py::ssize_t(n)};
                double* py_ = y.mutable_data();
                {
                    py::gil_scoped_release release;
                    s.run(pu, py_, n, policy);
                }
                return y;
            },
            py::arg("u"), py::arg("out_of_range") = "clamp")
        .def("reset", &RateSimulator::reset, py::arg("state"), py::arg("rate"))
        .def_property_readonly("output", &RateSimulator::output)
        .def_property_readonly("input", &RateSimulator::input)
        .def_property_readonly("rate", &RateSimulator::rate)
        .def_property_readonly("sample_time", &RateSimulator::sample_time)
        .def_property_readonly("state", &RateSimulator::state)
        .def_property_readonly("depth", &RateSimulator::depth)
        .def_property_readonly("weights", [](const RateSimulator& s) { return vec(s.weights()); })
        .def_property_readonly("readouts", [](const RateSimulator& s) { return vec(s.readouts()); })
        .def("slopes", [](const RateSimulator& s) {
            const auto d = s.slopes();
            return py::make_tuple(d.rising, d.falling);
        });

    py::class_<preisach::blocks::RateStage, preisach::blocks::Block>(
        m, "RateStage",
        "A rate-dependent Preisach model as a block (input V clamped to the model range, output V), from "
        "`state` and filtered rate `rate` (V/s); reset() returns to them. Chain it with the other physics "
        "blocks in a BlockChain.")
        .def(py::init([](double dt, const RateDependentModel& model, const State& state, double rate) {
                 return preisach::blocks::RateStage(dt, std::make_shared<const RateDependentModel>(model), state,
                                                    rate);
             }),
             py::arg("dt"), py::arg("model"), py::arg("state"), py::arg("rate") = 0.0)
        .def_property_readonly("state", &preisach::blocks::RateStage::state, "Current boundary.")
        .def_property_readonly("rate", &preisach::blocks::RateStage::rate, "Current filtered rate (V/s).")
        .def_property_readonly("output", &preisach::blocks::RateStage::output, "Last output (V).")
        .def_property_readonly("initial_state", &preisach::blocks::RateStage::initial_state)
        .def_property_readonly("initial_rate", &preisach::blocks::RateStage::initial_rate)
        .def("set_initial_state", &preisach::blocks::RateStage::set_initial_state, py::arg("state"),
             py::arg("rate"), "Start from `state` and `rate` (V/s) after the next reset().");

    m.def(
        "simulate_rate",
        [](const RateDependentModel& model, const InArray& u, const State& state, double rate, double sample_time,
           const std::string& out_of_range) {
            const auto policy = parse_policy(out_of_range);
            std::size_t n = 0;
            const double* pu = as_vector(u, "u", n);
            RateSimulator sim(model, state, rate, sample_time);
            py::array_t<double> y{py::ssize_t(n)}, v{py::ssize_t(n)};
            double *py_ = y.mutable_data(), *pv = v.mutable_data();
            {
                py::gil_scoped_release release;
                sim.run(pu, py_, n, policy, pv);
            }
            return py::make_tuple(y, v, sim.state(), sim.rate());
        },
        py::arg("model"), py::arg("u"), py::arg("state"), py::arg("rate"), py::arg("sample_time"),
        py::arg("out_of_range") = "clamp",
        "Run the input samples u (V, one per sample_time s) from `state` and filtered rate `rate` (V/s); returns "
        "(y, v, final_state, final_rate) with v the filtered rate after each sample.");

    m.def(
        "simulate_rate_batch",
        [](const RateDependentModel& model, const InArray& u, const std::vector<State>& states,
           const std::vector<double>& rates, double sample_time, const std::string& out_of_range, unsigned threads) {
            if (u.ndim() != 2)
                throw std::invalid_argument("u: expected a 2-D array (runs x samples), got " +
                                            std::to_string(u.ndim()) + " dimensions");
            const auto policy = parse_policy(out_of_range);
            const std::size_t rows = std::size_t(u.shape(0)), n = std::size_t(u.shape(1));
            py::array_t<double> y({py::ssize_t(rows), py::ssize_t(n)});
            const double* pu = u.data();
            double* py_ = y.mutable_data();
            preisach::RateBatchResult res;
            {
                py::gil_scoped_release release;
                res = preisach::run_rate_batch(model, states, rates, sample_time, pu, py_, nullptr, rows, n, policy,
                                               threads);
            }
            return py::make_tuple(y, res.states, vec(res.rates));
        },
        py::arg("model"), py::arg("u"), py::arg("states"), py::arg("rates"), py::arg("sample_time"),
        py::arg("out_of_range") = "clamp", py::arg("threads") = 0u,
        "Run every row of u from its state and rate on all cores; returns (y, final_states, final_rates).");

    m.def(
        "closed_loop_rate",
        [](RateSimulator& sim, const InArray& u_open, double setpoint, double kp, double ki, double sample_time,
           std::size_t average, std::size_t enable_at, double input_gain, const std::string& out_of_range) {
            const auto policy = parse_policy(out_of_range);
            const ClosedLoopConfig cfg = make_loop_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            return closed_loop_arrays(u_open, [&](const double* pu, double* a, double* b, double* c, std::size_t n) {
                preisach::run_rate_closed_loop(sim, pu, a, b, c, n, cfg, policy);
            });
        },
        py::arg("simulator"), py::arg("u_open"), py::arg("setpoint"), py::arg("kp"), py::arg("ki"),
        py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0, py::arg("input_gain") = 1.0,
        py::arg("out_of_range") = "clamp",
        "The PI loop of closed_loop around a RateSimulator (its state advances); returns (u, y, uc).");

    m.def(
        "closed_loop_rate_batch",
        [](const RateDependentModel& model, const std::vector<State>& states, const std::vector<double>& rates,
           const InArray& u_open, double setpoint, double kp, double ki, double sample_time, std::size_t average,
           std::size_t enable_at, double input_gain, const std::string& out_of_range, unsigned threads) {
            const auto policy = parse_policy(out_of_range);
            const ClosedLoopConfig cfg = make_loop_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            return closed_loop_batch_arrays(
                u_open,
                [&](const double* pu, double* a, double* b, double* c, std::size_t rows, std::size_t n) {
                    return preisach::run_rate_closed_loop_batch(model, states, rates, pu, a, b, c, rows, n, cfg,
                                                                policy, threads);
                },
                [](const preisach::RateBatchResult& res) { return py::make_tuple(res.states, vec(res.rates)); });
        },
        py::arg("model"), py::arg("states"), py::arg("rates"), py::arg("u_open"), py::arg("setpoint"), py::arg("kp"),
        py::arg("ki"), py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0,
        py::arg("input_gain") = 1.0, py::arg("out_of_range") = "clamp", py::arg("threads") = 0u,
        "The PI loop for every row of u_open on all cores (GIL released); returns "
        "(u, y, uc, final_states, final_rates).");

    m.def(
        "filter_rate",
        [](const InArray& u, double u0, double rate0, double sample_time, double tau) {
            std::size_t n = 0;
            const double* pu = as_vector(u, "u", n);
            if (!std::isfinite(tau) || tau < 0.0)
                throw std::invalid_argument("tau: must be >= 0 and finite (s), got " + std::to_string(tau));
            py::array_t<double> v{py::ssize_t(n)};
            double* pv = v.mutable_data();
            {
                py::gil_scoped_release release;
                preisach::filter_rate(pu, pv, n, u0, rate0, sample_time, tau);
            }
            return v;
        },
        py::arg("u"), py::arg("u0"), py::arg("rate0"), py::arg("sample_time"), py::arg("tau"),
        "Filtered rate v (V/s) after each sample of u (V): v += (1 - exp(-dt/tau)) (|du|/dt - v), from the "
        "previous input u0 and rate rate0.");

    m.def(
        "rate_normal_equations",
        [](const InArray& levels, const State& state, const InArray& u, const InArray& y,
           const py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>& fold, int n_folds,
           const std::vector<double>& knots, double tau, double sample_time, double rate0,
           const std::string& out_of_range, const std::string& scale) {
            const auto policy = parse_policy(out_of_range);
            std::size_t nl = 0, n = 0, ny = 0;
            const double* pl = as_vector(levels, "levels", nl);
            const double* pu = as_vector(u, "u", n);
            const double* pyv = as_vector(y, "y", ny);
            if (ny != n) throw std::invalid_argument("y: length " + std::to_string(ny) + " differs from u's " +
                                                     std::to_string(n));
            if (fold.ndim() != 1 || std::size_t(fold.shape(0)) != n)
                throw std::invalid_argument("fold: expected a 1-D array as long as u (" + std::to_string(n) + ")");
            if (n_folds < 1) throw std::invalid_argument("n_folds: must be >= 1, got " + std::to_string(n_folds));
            if (nl < 2) throw std::invalid_argument("levels: need at least 2 grid levels");
            const Eigen::Map<const Eigen::VectorXd> lv(pl, Eigen::Index(nl));
            preisach::RateRegression rr;
            rr.knots = knots;
            rr.tau = tau;
            rr.sample_time = sample_time;
            rr.rate0 = rate0;
            rr.scale = preisach::parse_rate_scale(scale);
            const std::size_t p = (nl * (nl - 1) / 2 + 1) * knots.size(), F = std::size_t(n_folds);
            py::array_t<double> G({py::ssize_t(F), py::ssize_t(p), py::ssize_t(p)}), b({py::ssize_t(F), py::ssize_t(p)}),
                yy{py::ssize_t(F)}, ys{py::ssize_t(F)};
            py::array_t<std::int64_t> cnt{py::ssize_t(F)};
            preisach::NormalEquationsOut out{G.mutable_data(), b.mutable_data(), yy.mutable_data(),
                                             ys.mutable_data(), cnt.mutable_data()};
            const std::int32_t* pf = fold.data();
            State fin;
            double vfin = 0.0;
            {
                py::gil_scoped_release release;
                preisach::accumulate_rate_normal_equations_into(lv, state, pu, pyv, pf, n, n_folds, policy, rr, out,
                                                                &fin, &vfin);
            }
            return py::make_tuple(G, b, yy, ys, cnt, fin, vfin);
        },
        py::arg("levels"), py::arg("state"), py::arg("u"), py::arg("y"), py::arg("fold"), py::arg("n_folds"),
        py::arg("knots"), py::arg("tau"), py::arg("sample_time"), py::arg("rate0") = 0.0,
        py::arg("out_of_range") = "clamp", py::arg("scale") = "log",
        "Normal equations of y_t = sum_k b_k(v_t) r_t . theta_k per fold (fold[t] < 0: burn-in); returns "
        "(gram (F, p, p), rhs (F, p), yy, ysum, count, final_state, final_rate), p = K (nodes + 1).");
}

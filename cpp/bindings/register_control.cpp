// Bindings of the PI regulation loop (preisach/control.hpp) and the neutral locus
// (preisach/neutral.hpp).
#include "common.hpp"

#include <preisach/control.hpp>
#include <preisach/neutral.hpp>

using preisach::ClosedLoopConfig;
using preisach::EverettTable;
using preisach::PIController;
using preisach::Simulator;
using preisach::State;

namespace {

ClosedLoopConfig make_config(double setpoint, double kp, double ki, double sample_time, std::size_t average,
                             std::size_t enable_at, double input_gain) {
    ClosedLoopConfig c;
    c.setpoint = setpoint;
    c.kp = kp;
    c.ki = ki;
    c.sample_time = sample_time;
    c.average = average;
    c.enable_at = enable_at;
    c.input_gain = input_gain;
    c.validate();
    return c;
}

}  // namespace

void register_control(py::module_& m) {
    py::class_<PIController>(m, "PIController",
                             "Discrete PI controller u_c(k) = kp e(k) + ki T_s sum e (Eq 5.2) on the error "
                             "averaged over the last `average` samples.")
        .def(py::init<double, double, double, std::size_t>(), py::arg("kp"), py::arg("ki"), py::arg("sample_time"),
             py::arg("average") = 1)
        .def("reset", &PIController::reset, "Forget the integral, the averaging window and the output.")
        .def("observe", &PIController::observe, py::arg("error"),
             "Push an error sample (V) into the averaging window without acting; returns the averaged error.")
        .def("update", &PIController::update, py::arg("error"),
             "One controller step on the error sample (V); returns u_c (controller units).")
        .def_property_readonly("output", &PIController::output)
        .def_property_readonly("integral", &PIController::integral)
        .def_property_readonly("kp", &PIController::kp)
        .def_property_readonly("ki", &PIController::ki)
        .def_property_readonly("sample_time", &PIController::sample_time)
        .def_property_readonly("average", &PIController::average);

    m.def(
        "closed_loop",
        [](Simulator& sim, const InArray& u_open, double setpoint, double kp, double ki, double sample_time,
           std::size_t average, std::size_t enable_at, double input_gain, const std::string& out_of_range) {
            const auto policy = parse_policy(out_of_range);
            const ClosedLoopConfig cfg = make_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            std::size_t n = 0;
            const double* pu = as_vector(u_open, "u_open", n);
            py::array_t<double> u{py::ssize_t(n)}, y{py::ssize_t(n)}, uc{py::ssize_t(n)};
            double *a = u.mutable_data(), *b = y.mutable_data(), *c = uc.mutable_data();
            {
                py::gil_scoped_release release;
                preisach::run_closed_loop(sim, pu, a, b, c, n, cfg, policy);
            }
            return py::make_tuple(u, y, uc);
        },
        py::arg("simulator"), py::arg("u_open"), py::arg("setpoint"), py::arg("kp"), py::arg("ki"),
        py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0, py::arg("input_gain") = 1.0,
        py::arg("out_of_range") = "clamp",
        "Run the PI loop on `simulator` (its state advances): u(k) = u_open(k) + input_gain * uc(k-1); "
        "returns (u, y, uc).");

    m.def(
        "closed_loop_batch",
        [](const EverettTable& t, const std::vector<State>& states, const InArray& u_open, double setpoint, double kp,
           double ki, double sample_time, std::size_t average, std::size_t enable_at, double input_gain,
           const std::string& out_of_range, unsigned threads) {
            if (u_open.ndim() != 2)
                throw std::invalid_argument("u_open: expected a 2-D array (runs x samples), got " +
                                            std::to_string(u_open.ndim()) + " dimensions");
            const auto policy = parse_policy(out_of_range);
            const ClosedLoopConfig cfg = make_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            const std::size_t rows = std::size_t(u_open.shape(0)), n = std::size_t(u_open.shape(1));
            py::array_t<double> u({py::ssize_t(rows), py::ssize_t(n)}), y({py::ssize_t(rows), py::ssize_t(n)}),
                uc({py::ssize_t(rows), py::ssize_t(n)});
            const double* pu = u_open.data();
            double *a = u.mutable_data(), *b = y.mutable_data(), *c = uc.mutable_data();
            std::vector<State> finals;
            {
                py::gil_scoped_release release;
                finals = preisach::run_closed_loop_batch(t, states, pu, a, b, c, rows, n, cfg, policy, threads);
            }
            return py::make_tuple(u, y, uc, finals);
        },
        py::arg("table"), py::arg("states"), py::arg("u_open"), py::arg("setpoint"), py::arg("kp"), py::arg("ki"),
        py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0, py::arg("input_gain") = 1.0,
        py::arg("out_of_range") = "clamp", py::arg("threads") = 0u,
        "Run the PI loop for every row of u_open from its state on all cores (GIL released); returns "
        "(u, y, uc, final_states).");

    m.def(
        "neutral_locus",
        [](const EverettTable& t, const InArray& l) {
            std::size_t n = 0;
            const double* pl = as_vector(l, "l", n);
            py::array_t<double> out{py::ssize_t(n)};
            double* po = out.mutable_data();
            {
                py::gil_scoped_release release;
                preisach::neutral_locus(t, pl, po, n);
            }
            return out;
        },
        py::arg("table"), py::arg("l"),
        "N(l) = Gamma(psi_n^l) (Eq 2.18, volts) for every offset l (volts) of a 1-D array, from the exact "
        "neutral boundary.");
}

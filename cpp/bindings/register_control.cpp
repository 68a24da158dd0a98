// Bindings of the PI regulation loop (preisach/control.hpp) and the neutral locus
// (preisach/neutral.hpp).
#include "closed_loop_common.hpp"

#include <preisach/control.hpp>
#include <preisach/neutral.hpp>

using preisach::ClosedLoopConfig;
using preisach::EverettTable;
using preisach::PIController;
using preisach::Simulator;
using preisach::State;


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
            const ClosedLoopConfig cfg = make_loop_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            return closed_loop_arrays(u_open, [&](const double* pu, double* a, double* b, double* c, std::size_t n) {
                preisach::run_closed_loop(sim, pu, a, b, c, n, cfg, policy);
            });
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
            const auto policy = parse_policy(out_of_range);
            const ClosedLoopConfig cfg = make_loop_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            return closed_loop_batch_arrays(
                u_open, [&](const double* pu, double* a, double* b, double* c, std::size_t rows, std::size_t n) {
                    return preisach::run_closed_loop_batch(t, states, pu, a, b, c, rows, n, cfg, policy, threads);
                },
                [](const std::vector<State>& finals) { return py::make_tuple(finals); });
        },
        py::arg("table"), py::arg("states"), py::arg("u_open"), py::arg("setpoint"), py::arg("kp"), py::arg("ki"),
        py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0, py::arg("input_gain") = 1.0,
        py::arg("out_of_range") = "clamp", py::arg("threads") = 0u,
        "Run the PI loop for every row of u_open from its state on all cores (GIL released); returns "
        "(u, y, uc, final_states).");

    m.def(
        "closed_loop_chain",
        [](preisach::blocks::Chain& chain, const InArray& u_open, double u_min, double u_max, double setpoint,
           double kp, double ki, double sample_time, std::size_t average, std::size_t enable_at, double input_gain) {
            if (!(u_min < u_max))
                throw std::invalid_argument("u_min, u_max: need u_min < u_max, got " + std::to_string(u_min) +
                                            ", " + std::to_string(u_max));
            if (std::abs(chain.dt() - sample_time) > 1e-9 * sample_time)
                throw std::invalid_argument("sample_time: " + std::to_string(sample_time) +
                                            " s differs from the chain's " + std::to_string(chain.dt()) + " s");
            const ClosedLoopConfig cfg = make_loop_config(setpoint, kp, ki, sample_time, average, enable_at, input_gain);
            return closed_loop_arrays(u_open, [&](const double* pu, double* a, double* b, double* c, std::size_t n) {
                preisach::run_pi_loop([&](double v, std::size_t) { return chain.step(v); }, u_min, u_max, pu, a, b,
                                      c, n, cfg, preisach::InputPolicy::clamp);
            });
        },
        py::arg("chain"), py::arg("u_open"), py::arg("u_min"), py::arg("u_max"), py::arg("setpoint"), py::arg("kp"),
        py::arg("ki"), py::arg("sample_time"), py::arg("average") = 1, py::arg("enable_at") = 0,
        py::arg("input_gain") = 1.0,
        "The PI loop of closed_loop around a BlockChain (its blocks advance), the applied input clamped to "
        "[u_min, u_max]; returns (u, y, uc).");

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

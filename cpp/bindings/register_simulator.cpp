// Bindings of the simulator (preisach/simulator.hpp, preisach/batch.hpp).
#include "common.hpp"

using preisach::EverettTable;
using preisach::Simulator;
using preisach::State;

namespace {

py::array_t<double> run_into(Simulator& sim, const InArray& u, const std::string& out_of_range) {
    const auto policy = parse_policy(out_of_range);
    std::size_t n = 0;
    const double* pu = as_vector(u, "u", n);
    py::array_t<double> y(static_cast<py::ssize_t>(n));
    double* py_ = y.mutable_data();
    {
        py::gil_scoped_release release;
        sim.run(pu, py_, n, policy);
    }
    return y;
}

}  // namespace

void register_simulator(py::module_& m) {
    py::class_<Simulator>(m, "Simulator", "Step-by-step simulation of one model from one state.")
        .def(py::init<const EverettTable&, const State&>(), py::arg("table"), py::arg("state"), py::keep_alive<1, 2>())
        .def(
            "step",
            [](Simulator& s, double u, const std::string& out_of_range) {
                return s.step_checked(u, parse_policy(out_of_range), 0);
            },
            py::arg("u"), py::arg("out_of_range") = "clamp")
        .def("run", &run_into, py::arg("u"), py::arg("out_of_range") = "clamp")
        .def("reset", &Simulator::reset, py::arg("state"))
        .def_property_readonly("output", &Simulator::output)
        .def_property_readonly("input", &Simulator::input)
        .def_property_readonly("state", &Simulator::state)
        .def_property_readonly("depth", &Simulator::depth)
        .def("slopes", [](const Simulator& s) {
            const auto d = s.slopes();
            return py::make_tuple(d.rising, d.falling);
        });

    m.def(
        "simulate",
        [](const EverettTable& t, const InArray& u, const State& state, const std::string& out_of_range) {
            Simulator sim(t, state);
            py::array_t<double> y = run_into(sim, u, out_of_range);
            return py::make_tuple(y, sim.state());
        },
        py::arg("table"), py::arg("u"), py::arg("state"), py::arg("out_of_range") = "clamp",
        "Run the input samples u (volts) from `state`; returns (y, final_state).");

    m.def(
        "simulate_batch",
        [](const EverettTable& t, const InArray& u, const std::vector<State>& states, const std::string& out_of_range,
           unsigned threads) {
            if (u.ndim() != 2)
                throw std::invalid_argument("u: expected a 2-D array (runs x samples), got " +
                                            std::to_string(u.ndim()) + " dimensions");
            const auto policy = parse_policy(out_of_range);
            const std::size_t m_ = std::size_t(u.shape(0)), n = std::size_t(u.shape(1));
            py::array_t<double> y({py::ssize_t(m_), py::ssize_t(n)});
            const double* pu = u.data();
            double* py_ = y.mutable_data();
            std::vector<State> finals;
            {
                py::gil_scoped_release release;
                finals = preisach::run_batch(t, states, pu, py_, m_, n, policy, threads);
            }
            return py::make_tuple(y, finals);
        },
        py::arg("table"), py::arg("u"), py::arg("states"), py::arg("out_of_range") = "clamp",
        py::arg("threads") = 0u, "Run every row of u from its state on all cores; returns (y, final_states).");

    m.def("readout", &preisach::readout, py::arg("table"), py::arg("state"),
          "Output Gamma(psi) of a state (volts), without simulating.");
}

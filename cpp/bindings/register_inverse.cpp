// Bindings of the exact inverse (preisach/inverse.hpp).
#include <chrono>

#include "common.hpp"
#include <preisach/inverse.hpp>

using preisach::EverettTable;
using preisach::Inverter;
using preisach::State;

namespace {

// Invert the targets y (volts): returns (u, y_achieved, reached) without copying y.
py::tuple run_into(Inverter& inv, const InArray& y) {
    std::size_t n = 0;
    const double* py_ = as_vector(y, "y", n);
    py::array_t<double> u(static_cast<py::ssize_t>(n)), yo(static_cast<py::ssize_t>(n));
    py::array_t<bool> ok(static_cast<py::ssize_t>(n));
    double* pu = u.mutable_data();
    double* pyo = yo.mutable_data();
    static_assert(sizeof(bool) == sizeof(std::uint8_t), "bool arrays are bytes");
    auto* pok = reinterpret_cast<std::uint8_t*>(ok.mutable_data());
    {
        py::gil_scoped_release release;
        inv.run(py_, pu, pyo, pok, n);
    }
    return py::make_tuple(u, yo, ok);
}

}  // namespace

void register_inverse(py::module_& m) {
    py::class_<Inverter>(m, "Inverter",
                         "Exact inverse of a Preisach model, target by target (tracks the simulator's state).")
        .def(py::init<const EverettTable&, const State&>(), py::arg("table"), py::arg("state"), py::keep_alive<1, 2>())
        .def("step", [](Inverter& inv, double y) { return inv.step(y); }, py::arg("y"),
             "Drive the output to y (volts); returns the input applied (volts).")
        .def(
            "solve",
            [](const Inverter& inv, double y) {
                bool reached = true;
                const double u = inv.solve(y, reached);
                return py::make_tuple(u, reached);
            },
            py::arg("y"), "Input the target y needs and whether it is reached, without applying it.")
        .def("run", &run_into, py::arg("y"), "Invert the targets y; returns (u, y_achieved, reached).")
        .def("reset", &Inverter::reset, py::arg("state"))
        .def("clear_unreachable", &Inverter::clear_unreachable)
        .def_property_readonly("input", &Inverter::input)
        .def_property_readonly("output", &Inverter::output)
        .def_property_readonly("state", &Inverter::state)
        .def_property_readonly("depth", &Inverter::depth)
        .def_property_readonly("monotone", &Inverter::monotone)
        .def_property_readonly("unreachable", &Inverter::unreachable);

    m.def(
        "invert",
        [](const EverettTable& t, const InArray& y, const State& state) {
            Inverter inv(t, state);
            py::tuple r = run_into(inv, y);
            return py::make_tuple(r[0], r[1], r[2], inv.state(), inv.unreachable());
        },
        py::arg("table"), py::arg("y"), py::arg("state"),
        "Invert the targets y (volts) from `state`; returns (u, y_achieved, reached, final_state, unreachable).");

    m.def(
        "invert_timed",
        [](const EverettTable& t, const InArray& y, const State& state) {
            std::size_t n = 0;
            const double* py_ = as_vector(y, "y", n);
            py::array_t<double> ns(static_cast<py::ssize_t>(n));
            double* pns = ns.mutable_data();
            Inverter inv(t, state);
            {
                py::gil_scoped_release release;
                using clock = std::chrono::steady_clock;
                for (std::size_t k = 0; k < n; ++k) {
                    const auto t0 = clock::now();
                    inv.step(py_[k], k);
                    pns[k] = std::chrono::duration<double, std::nano>(clock::now() - t0).count();
                }
            }
            return py::make_tuple(ns, inv.state());
        },
        py::arg("table"), py::arg("y"), py::arg("state"),
        "Benchmark helper: Inverter.step() over y, each timed in C++; returns (nanoseconds, final_state).");
}

// Bindings of the diagnosis kernels (preisach/play.hpp, preisach/moving.hpp).
#include <preisach/moving.hpp>
#include <preisach/play.hpp>

#include "common.hpp"

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
}

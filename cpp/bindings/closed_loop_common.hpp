// What the closed-loop bindings share (register_control.cpp, register_rate.cpp): the
// controller configuration from keyword arguments and the arrays in and out of a loop run.
#pragma once

#include "common.hpp"

#include <preisach/control.hpp>

// The loop's configuration from the bindings' keyword arguments (validated).
inline preisach::ClosedLoopConfig make_loop_config(double setpoint, double kp, double ki, double sample_time,
                                                   std::size_t average, std::size_t enable_at, double input_gain) {
    preisach::ClosedLoopConfig c;
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

// One loop run over the 1-D u_open: run(u_open, u, y, uc, n) with the GIL released; returns
// (u, y, uc).
template <class Run>
py::tuple closed_loop_arrays(const InArray& u_open, Run&& run) {
    std::size_t n = 0;
    const double* pu = as_vector(u_open, "u_open", n);
    py::array_t<double> u{py::ssize_t(n)}, y{py::ssize_t(n)}, uc{py::ssize_t(n)};
    double *a = u.mutable_data(), *b = y.mutable_data(), *c = uc.mutable_data();
    {
        py::gil_scoped_release release;
        run(pu, a, b, c, n);
    }
    return py::make_tuple(u, y, uc);
}

// Loop runs for every row of the 2-D U_open: run(U_open, U, Y, UC, rows, n), with the GIL
// released, returns the final states (any type), which finish() turns into a tuple with the
// GIL held; returns (U, Y, UC, *finish(finals)).
template <class Run, class Finish>
py::tuple closed_loop_batch_arrays(const InArray& u_open, Run&& run, Finish&& finish) {
    if (u_open.ndim() != 2)
        throw std::invalid_argument("u_open: expected a 2-D array (runs x samples), got " +
                                    std::to_string(u_open.ndim()) + " dimensions");
    const std::size_t rows = std::size_t(u_open.shape(0)), n = std::size_t(u_open.shape(1));
    py::array_t<double> u({py::ssize_t(rows), py::ssize_t(n)}), y({py::ssize_t(rows), py::ssize_t(n)}),
        uc({py::ssize_t(rows), py::ssize_t(n)});
    const double* pu = u_open.data();
    double *a = u.mutable_data(), *b = y.mutable_data(), *c = uc.mutable_data();
    decltype(run(pu, a, b, c, rows, n)) finals;
    {
        py::gil_scoped_release release;
        finals = run(pu, a, b, c, rows, n);
    }
    return py::make_tuple(u, y, uc) + py::tuple(finish(finals));
}

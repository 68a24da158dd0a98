// Shared by every binding file: pybind11 with numpy, Eigen and STL casters.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/operators.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <preisach/preisach.hpp>

namespace py = pybind11;

// Input arrays: contiguous float64, converted only when the caller passes another dtype.
using InArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

void register_everett(py::module_& m);
void register_state(py::module_& m);
void register_simulator(py::module_& m);
void register_inverse(py::module_& m);
void register_control(py::module_& m);
void register_identify(py::module_& m);
void register_diagnose(py::module_& m);
void register_blocks(py::module_& m);
void register_daq(py::module_& m);
void register_rate(py::module_& m);

// A 1-D float64 array viewed without a copy; `name` is used in error messages.
inline const double* as_vector(const InArray& a, const char* name, std::size_t& n) {
    if (a.ndim() != 1)
        throw std::invalid_argument(std::string(name) + ": expected a 1-D array, got " + std::to_string(a.ndim()) +
                                    " dimensions");
    n = std::size_t(a.shape(0));
    return a.data();
}

inline preisach::InputPolicy parse_policy(const std::string& s) {
    if (s == "clamp") return preisach::InputPolicy::clamp;
    if (s == "raise") return preisach::InputPolicy::raise;
    throw std::invalid_argument("out_of_range: expected 'clamp' or 'raise', got '" + s + "'");
}

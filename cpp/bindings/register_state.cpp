// Bindings of the Preisach state (preisach/memory.hpp).
#include "common.hpp"

using preisach::Piece;
using preisach::State;

namespace {

State make_state(double u_min, double u_max, double u, const InArray& b0, const InArray& v,
                 const py::array_t<bool, py::array::c_style | py::array::forcecast>& antidiag) {
    std::size_t n0 = 0, n1 = 0;
    const double* pb = as_vector(b0, "b0", n0);
    const double* pv = as_vector(v, "v", n1);
    if (antidiag.ndim() != 1 || std::size_t(antidiag.shape(0)) != n0 || n1 != n0)
        throw std::invalid_argument("state: b0, v and antidiag must be 1-D arrays of the same length");
    std::vector<Piece> pieces(n0);
    for (std::size_t k = 0; k < n0; ++k) pieces[k] = Piece{pb[k], pv[k], antidiag.data()[k]};
    return State(u_min, u_max, u, std::move(pieces));
}

template <class F>
py::array_t<double> field(const State& s, F f) {
    py::array_t<double> out(py::ssize_t(s.pieces().size()));
    auto r = out.mutable_unchecked<1>();
    for (std::size_t k = 0; k < s.pieces().size(); ++k) r(py::ssize_t(k)) = f(s.pieces()[k]);
    return out;
}

py::tuple state_tuple(const State& s) {
    py::array_t<bool> ad(py::ssize_t(s.pieces().size()));
    for (std::size_t k = 0; k < s.pieces().size(); ++k) ad.mutable_data()[k] = s.pieces()[k].antidiag;
    return py::make_tuple(s.u_min(), s.u_max(), s.input(), field(s, [](const Piece& p) { return p.b0; }),
                          field(s, [](const Piece& p) { return p.v; }), ad);
}

}  // namespace

void register_state(py::module_& m) {
    py::class_<State>(m, "State",
                      "Preisach boundary psi: pieces of phi(beta) (constant M, or antidiagonal alpha+beta = c) "
                      "and the current input (volts).")
        .def(py::init(&make_state), py::arg("u_min"), py::arg("u_max"), py::arg("u"), py::arg("b0"), py::arg("v"),
             py::arg("antidiag"))
        .def_static("negative_saturation", &State::negative_saturation, py::arg("u_min"), py::arg("u_max"))
        .def_static("positive_saturation", &State::positive_saturation, py::arg("u_min"), py::arg("u_max"))
        .def_static("neutral", &State::neutral, py::arg("u_min"), py::arg("u_max"), py::arg("l"))
        .def("apply", &preisach::apply_inputs, py::arg("inputs"),
             "The state reached by applying the input values in order (wiping-out applies).")
        .def_property_readonly("u_min", &State::u_min)
        .def_property_readonly("u_max", &State::u_max)
        .def_property_readonly("input", &State::input)
        .def_property_readonly("b0", [](const State& s) { return field(s, [](const Piece& p) { return p.b0; }); })
        .def_property_readonly("v", [](const State& s) { return field(s, [](const Piece& p) { return p.v; }); })
        .def_property_readonly("antidiag", [](const State& s) { return py::array(state_tuple(s)[5]); })
        .def("extrema", &State::extrema)
        .def("to_tuple", &state_tuple)
        .def(py::self == py::self)
        .def(py::self != py::self)
        .def("__copy__", [](const State& s) { return State(s); })
        .def("__deepcopy__", [](const State& s, const py::dict&) { return State(s); }, py::arg("memo"))
        .def(py::pickle(&state_tuple, [](const py::tuple& t) {
            if (t.size() != 6) throw std::invalid_argument("State: bad pickle state");
            return make_state(t[0].cast<double>(), t[1].cast<double>(), t[2].cast<double>(), t[3].cast<InArray>(),
                              t[4].cast<InArray>(),
                              t[5].cast<py::array_t<bool, py::array::c_style | py::array::forcecast>>());
        }));
}

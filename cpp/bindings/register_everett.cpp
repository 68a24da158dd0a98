// Bindings of the Everett table (preisach/everett.hpp).
#include "common.hpp"

using preisach::EverettTable;

namespace {

py::array_t<double> levels_array(const EverettTable& t) {
    return py::array_t<double>(py::ssize_t(t.size()), t.levels().data());
}

preisach::RowMatrixXd values_matrix(const EverettTable& t) {
    const auto n = Eigen::Index(t.size());
    preisach::RowMatrixXd v(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
        for (Eigen::Index j = 0; j < n; ++j) v(i, j) = j < i ? t.node(std::size_t(i), std::size_t(j)) : 0.0;
    return v;
}

}  // namespace

void register_everett(py::module_& m) {
    py::class_<EverettTable>(m, "EverettTable",
                             "Everett function E(alpha, beta) (volts) tabulated on a triangular grid of input "
                             "levels (volts), with the output y_min at negative saturation.")
        .def(py::init([](const Eigen::VectorXd& levels, const preisach::MatrixRef& values, double y_min,
                         const std::string& interpolation) {
                 return EverettTable(levels, values, y_min, preisach::parse_interpolation(interpolation));
             }),
             py::arg("levels"), py::arg("values"), py::arg("y_min"), py::arg("interpolation") = "bilinear",
             "interpolation: 'bilinear' (per cell) or 'cubic' (C1 bicubic Hermite over a 4 x 4 node stencil, "
             ">= 4 levels); both pass through the nodes.")
        .def_static("from_fod", &preisach::everett_from_fod, py::arg("levels"), py::arg("y_grid"),
                    "Mayergoyz: E = (y(a,a) - y(a,b)) / 2 from FOD samples y_grid[i, j] = y(levels[i], levels[j]).")
        .def_static("from_weights", &preisach::everett_from_weights, py::arg("levels"), py::arg("weights"),
                    py::arg("y_min"), "From relay masses per grid cell (volts), (n-1) x (n-1) lower-triangular.")
        .def_property_readonly("levels", &levels_array)
        .def_property_readonly("values", &values_matrix)
        .def_property_readonly("y_min", &EverettTable::y_min)
        .def_property_readonly("y_max", &EverettTable::y_max)
        .def_property_readonly("u_min", &EverettTable::u_min)
        .def_property_readonly("u_max", &EverettTable::u_max)
        .def_property_readonly("uniform", &EverettTable::uniform)
        .def_property_readonly("interpolation",
                               [](const EverettTable& t) { return preisach::interpolation_name(t.interpolation()); })
        .def(
            "with_interpolation",
            [](const EverettTable& t, const std::string& k) {
                return preisach::with_interpolation(t, preisach::parse_interpolation(k));
            },
            py::arg("interpolation"), "The same nodes and y_min, interpolated by 'bilinear' or 'cubic'.")
        .def(
            "resample",
            [](const EverettTable& t, const Eigen::VectorXd& levels, const std::string& k) {
                return preisach::resample(t, levels, preisach::parse_interpolation(k));
            },
            py::arg("levels"), py::arg("interpolation") = "bilinear",
            "This table's interpolant tabulated on other levels (volts, inside its range).")
        .def("__call__", py::vectorize([](EverettTable& t, double a, double b) { return t(a, b); }),
             py::arg("alpha"), py::arg("beta"))
        .def("d_alpha", py::vectorize([](EverettTable& t, double a, double b) { return t.d_alpha(a, b); }),
             py::arg("alpha"), py::arg("beta"))
        .def("d_beta", py::vectorize([](EverettTable& t, double a, double b) { return t.d_beta(a, b); }),
             py::arg("alpha"), py::arg("beta"))
        .def("antidiagonal_integral", &EverettTable::antidiagonal_integral, py::arg("c"), py::arg("b0"),
             py::arg("b1"))
        .def("cell_weights", &preisach::cell_weights)
        .def(py::pickle(
            [](const EverettTable& t) {
                return py::make_tuple(levels_array(t), values_matrix(t), t.y_min(),
                                      preisach::interpolation_name(t.interpolation()));
            },
            [](const py::tuple& s) {
                if (s.size() != 3 && s.size() != 4) throw std::invalid_argument("EverettTable: bad pickle state");
                const auto k = s.size() == 4 ? preisach::parse_interpolation(s[3].cast<std::string>())
                                             : preisach::Interpolation::bilinear;
                return EverettTable(s[0].cast<Eigen::VectorXd>(), s[1].cast<preisach::RowMatrixXd>(),
                                    s[2].cast<double>(), k);
            }));
}

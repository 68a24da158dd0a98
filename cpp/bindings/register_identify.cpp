// Bindings of the identification core (preisach/identify.hpp, preisach/regressor.hpp).
#include "common.hpp"

#include <tuple>

#include <preisach/identify.hpp>
#include <preisach/regressor.hpp>

using preisach::EverettTable;
using preisach::State;

namespace {

preisach::GapPolicy parse_gaps(const std::string& s) {
    if (s == "raise") return preisach::GapPolicy::raise;
    if (s == "fill") return preisach::GapPolicy::fill;
    throw std::invalid_argument("gaps: expected 'raise' or 'fill', got '" + s + "'");
}

template <class T>
py::array_t<T> to_array(const std::vector<T>& v) {
    return py::array_t<T>(py::ssize_t(v.size()), v.data());
}

using FoldArray = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;

// The input and output of the normal equations and their length, checked against the folds.
std::tuple<const double*, const double*, std::size_t> fold_series(const InArray& u, const InArray& y,
                                                                   const FoldArray& fold) {
    std::size_t nu = 0, ny = 0;
    const double* pu = as_vector(u, "u", nu);
    const double* py_ = as_vector(y, "y", ny);
    if (fold.ndim() != 1 || std::size_t(fold.shape(0)) != nu || ny != nu)
        throw std::invalid_argument("u, y and fold must be 1-D arrays of the same length (got " +
                                    std::to_string(nu) + ", " + std::to_string(ny) + ", " +
                                    std::to_string(fold.ndim() == 1 ? fold.shape(0) : -1) + ")");
    return {pu, py_, nu};
}

}  // namespace

void register_identify(py::module_& m) {
    py::class_<preisach::ProjectionResult>(
        m, "ProjectionResult",
        "Result of project_nonnegative: the nearest Everett table (least squares over the nodes) whose cell "
        "masses are all >= 0, and how much mass was moved (volts).")
        .def_readonly("table", &preisach::ProjectionResult::table)
        .def_readonly("mass_moved", &preisach::ProjectionResult::mass_moved)
        .def_readonly("total_mass", &preisach::ProjectionResult::total_mass)
        .def_readonly("negative_mass", &preisach::ProjectionResult::negative_mass)
        .def_readonly("n_negative", &preisach::ProjectionResult::n_negative)
        .def_readonly("max_node_change", &preisach::ProjectionResult::max_node_change)
        .def_readonly("rms_node_change", &preisach::ProjectionResult::rms_node_change)
        .def_readonly("kept_y_max", &preisach::ProjectionResult::kept_y_max)
        .def_readonly("sweeps", &preisach::ProjectionResult::sweeps)
        .def_readonly("converged", &preisach::ProjectionResult::converged)
        .def_readonly("max_violation", &preisach::ProjectionResult::max_violation);

    m.def(
        "mayergoyz",
        [](const Eigen::VectorXd& levels, const preisach::MatrixRef& y_grid, const std::string& gaps) {
            preisach::MayergoyzResult r;
            {
                py::gil_scoped_release release;
                r = preisach::mayergoyz(levels, y_grid, parse_gaps(gaps));
            }
            py::array_t<std::int64_t> filled({py::ssize_t(r.filled.size()), py::ssize_t(2)});
            auto f = filled.mutable_unchecked<2>();
            for (std::size_t k = 0; k < r.filled.size(); ++k) {
                f(py::ssize_t(k), 0) = std::int64_t(r.filled[k].first);
                f(py::ssize_t(k), 1) = std::int64_t(r.filled[k].second);
            }
            std::vector<std::int64_t> rows(r.rows_without_turning_point.begin(), r.rows_without_turning_point.end());
            return py::make_tuple(r.table, filled, r.filled_column0, r.n_ymin, to_array(rows));
        },
        py::arg("levels"), py::arg("y_grid"), py::arg("gaps") = "raise",
        "Mayergoyz identification from an FOD grid (volts) with NaN gaps: returns (table, filled_nodes (k, 2), "
        "n_filled_column0, n_ymin, rows_without_turning_point).");

    m.def(
        "weight_density",
        [](const EverettTable& t) {
            const auto d = preisach::weight_density(t);
            return py::make_tuple(d.v, d.kappa);
        },
        py::arg("table"),
        "Density v (V/V^2) of the off-diagonal cells ((n-1) x (n-1), NaN on and above the diagonal) and kappa "
        "(V/V) of the diagonal half-cells (n-1).");

    m.def(
        "project_nonnegative",
        [](const EverettTable& t, bool keep_y_max, double tol, std::size_t max_sweeps) {
            py::gil_scoped_release release;
            return preisach::project_nonnegative(t, keep_y_max, tol, max_sweeps);
        },
        py::arg("table"), py::arg("keep_y_max") = true, py::arg("tol") = 1e-12, py::arg("max_sweeps") = 200000,
        "Nearest table (least squares over the Everett nodes) with all cell masses >= 0; y_min is kept, and "
        "y_max when keep_y_max and possible.");

    m.def(
        "regressor_rows",
        [](const Eigen::VectorXd& levels, const InArray& u, const State& state, const std::string& out_of_range,
           const std::string& interpolation) {
            const auto policy = parse_policy(out_of_range);
            const auto kind = preisach::parse_interpolation(interpolation);
            std::size_t n = 0;
            const double* pu = as_vector(u, "u", n);
            preisach::RegressorRows r;
            {
                py::gil_scoped_release release;
                r = preisach::regressor_rows(levels, state, pu, n, policy, kind);
            }
            return py::make_tuple(to_array(r.indptr), to_array(r.indices), to_array(r.data), r.final_state);
        },
        py::arg("levels"), py::arg("u"), py::arg("state"), py::arg("out_of_range") = "clamp",
        py::arg("interpolation") = "bilinear",
        "Per-sample linear map from theta = (Everett nodes E(i, j), j < i, row-major; y_min) to the output, as "
        "CSR arrays (indptr, indices, data) plus the final state.");

    m.def(
        "normal_equations",
        [](const Eigen::VectorXd& levels, const InArray& u, const InArray& y, const State& state,
           const FoldArray& fold, int n_folds,
           const std::string& out_of_range, const std::string& interpolation) {
            const auto policy = parse_policy(out_of_range);
            const auto kind = preisach::parse_interpolation(interpolation);
            const auto [pu, py_, nu] = fold_series(u, y, fold);
            if (n_folds < 1) throw std::invalid_argument("n_folds: must be >= 1, got " + std::to_string(n_folds));
            const std::int32_t* pf = fold.data();
            const std::size_t nl = std::size_t(levels.size());
            const py::ssize_t K = n_folds, p = py::ssize_t(nl >= 2 ? nl * (nl - 1) / 2 + 1 : 1);
            py::array_t<double> gram({K, p, p}), rhs({K, p}), yy(K), ysum(K);
            py::array_t<std::int64_t> count(K);
            const preisach::NormalEquationsOut out{gram.mutable_data(), rhs.mutable_data(), yy.mutable_data(),
                                                   ysum.mutable_data(), count.mutable_data()};
            State final_state;
            {
                py::gil_scoped_release release;
                preisach::accumulate_normal_equations_into(levels, state, pu, py_, pf, nu, n_folds, policy, out,
                                                           &final_state, kind);
            }
            return py::make_tuple(gram, rhs, yy, ysum, count, final_state);
        },
        py::arg("levels"), py::arg("u"), py::arg("y"), py::arg("state"), py::arg("fold"), py::arg("n_folds"),
        py::arg("out_of_range") = "clamp", py::arg("interpolation") = "bilinear",
        "Normal equations of y ~ r_t . theta per fold (fold[t] < 0 skips sample t but still advances the state), "
        "accumulated in place: returns (gram (K, p, p), rhs (K, p), yy (K), ysum (K), count (K), final_state); "
        "the GIL is released.");

    m.def(
        "normal_equations_basis",
        [](const Eigen::VectorXd& levels, const InArray& u, const InArray& y, const State& state,
           const FoldArray& fold, const InArray& basis,
           const std::string& interpolation) {
            const auto kind = preisach::parse_interpolation(interpolation);
            const auto [pu, py_, nu] = fold_series(u, y, fold);
            if (basis.ndim() != 2 || std::size_t(basis.shape(0)) != nu || basis.shape(1) < 1)
                throw std::invalid_argument("basis: must be " + std::to_string(nu) + " x k with k >= 1");
            const std::int32_t* pf = fold.data();
            const std::size_t nl = std::size_t(levels.size());
            const py::ssize_t p = py::ssize_t(nl >= 2 ? nl * (nl - 1) / 2 + 1 : 1), k = basis.shape(1);
            py::array_t<double> gram({p, p}), rhs(p), cross({p, k}), yy(1), ysum(1);
            py::array_t<std::int64_t> count(1);
            const preisach::NormalEquationsOut out{gram.mutable_data(), rhs.mutable_data(), yy.mutable_data(),
                                                   ysum.mutable_data(), count.mutable_data()};
            const preisach::BasisCross with{basis.data(), std::size_t(k), cross.mutable_data()};
            State final_state;
            {
                py::gil_scoped_release release;
                preisach::accumulate_normal_equations_into(levels, state, pu, py_, pf, nu, 1,
                                                           preisach::InputPolicy::clamp, out, &final_state, kind,
                                                           &with);
            }
            return py::make_tuple(gram, rhs, cross, final_state);
        },
        py::arg("levels"), py::arg("u"), py::arg("y"), py::arg("state"), py::arg("fold"), py::arg("basis"),
        py::arg("interpolation") = "bilinear",
        "Normal equations of y ~ r_t . theta over the samples with fold[t] == 0 (fold[t] < 0 only advances the "
        "state; input clamped to the levels) with the rows' cross products with a basis in time (n x k): returns "
        "(gram (p, p), rhs (p), cross (p, k) = sum r_t a_t^T, final_state); the GIL is released.");
}

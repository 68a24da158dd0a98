// Bindings of the physics blocks (preisach/blocks): classes Block, StructuralMode, InputLag,
// Creep, Delay, MovingAverage, OffsetDrift, PreisachStage and BlockChain.
#include "common.hpp"

#include <preisach/blocks.hpp>

namespace pb = preisach::blocks;

namespace {

py::dict params_dict(const pb::Block& b) {
    py::dict d;
    for (const auto& p : b.params()) d[py::str(p.name)] = p.value;
    return d;
}

py::dict units_dict(const pb::Block& b) {
    py::dict d;
    for (const auto& p : b.params()) d[py::str(p.name)] = p.unit;
    return d;
}

std::string block_repr(const pb::Block& b) {
    std::string s = b.kind() + "(dt=" + py::repr(py::float_(b.dt())).cast<std::string>();
    for (const auto& p : b.params()) s += ", " + p.name + "=" + py::repr(py::float_(p.value)).cast<std::string>();
    return s + ")";
}

template <class R>
py::array_t<double> run_array(R& runner_like, const InArray& x) {
    std::size_t n = 0;
    const double* px = as_vector(x, "x", n);
    py::array_t<double> y(static_cast<py::ssize_t>(n));
    double* py_ = y.mutable_data();
    {
        py::gil_scoped_release release;
        runner_like.run(px, py_, n);
    }
    return y;
}

std::vector<std::unique_ptr<pb::Block>> clone_list(const py::iterable& blocks) {
    std::vector<std::unique_ptr<pb::Block>> out;
    std::size_t i = 0;
    for (const auto& item : blocks) {
        if (!py::isinstance<pb::Block>(item))
            throw py::type_error("blocks[" + std::to_string(i) + "]: expected a preisach block, got " +
                                 std::string(py::str(py::type::of(item).attr("__name__"))));
        out.push_back(item.cast<const pb::Block&>().clone());
        ++i;
    }
    return out;
}

}  // namespace

void register_blocks(py::module_& m) {
    py::class_<pb::Block>(m, "Block",
                          "A physics block: a discrete-time SISO system sampled every dt seconds. step(x) holds x "
                          "over one sample and returns the output at its end.")
        .def_property_readonly("kind", &pb::Block::kind, "Block type, e.g. 'structural_mode'.")
        .def_property_readonly("dt", &pb::Block::dt, "Sample time (s).")
        .def_property_readonly("params", &params_dict, "Parameters {name: value}.")
        .def_property_readonly("units", &units_dict, "Units of the parameters {name: unit}.")
        .def("reset", &pb::Block::reset, py::arg("x0") = 0.0,
             "Reset to the steady state for the constant input x0; returns the steady output.")
        .def("step", &pb::Block::step, py::arg("x"), "Advance one sample with input x; returns the output.")
        .def("run", &run_array<pb::Block>, py::arg("x"), "Step through the samples x (GIL released); returns y.")
        .def("copy", [](const pb::Block& b) { return b.clone(); }, "An independent copy (state included).")
        .def("__copy__", [](const pb::Block& b) { return b.clone(); })
        .def("__deepcopy__", [](const pb::Block& b, const py::dict&) { return b.clone(); }, py::arg("memo"))
        .def("__repr__", &block_repr);

    py::class_<pb::StructuralMode, pb::Block>(
        m, "StructuralMode",
        "Lightly damped bending mode wn^2/(s^2 + 2 zeta wn s + wn^2), unit DC gain, discretised exactly "
        "(zero-order hold via the matrix exponential). frequency in Hz (thesis: 37.62 Hz), damping zeta.")
        .def(py::init<double, double, double>(), py::arg("dt"), py::arg("frequency") = 37.62,
             py::arg("damping") = 0.02)
        .def_property_readonly("frequency", &pb::StructuralMode::frequency)
        .def_property_readonly("damping", &pb::StructuralMode::damping);

    py::class_<pb::InputLag, pb::Block>(
        m, "InputLag",
        "First-order lag (amplifier driving the piezo capacitance), exact under zero-order hold; before the "
        "Preisach stage it makes loops widen in proportion to the input rate. time_constant in s.")
        .def(py::init<double, double>(), py::arg("dt"), py::arg("time_constant") = 1e-3)
        .def_property_readonly("time_constant", &pb::InputLag::time_constant);

    py::class_<pb::Creep, pb::Block>(
        m, "Creep",
        "Logarithmic creep: y = x + rate * sum_k (z_k - x) over first-order lags one decade apart from tau_min "
        "to tau_max (s); rate is the fraction of a step crept per decade of time.")
        .def(py::init<double, double, double, double>(), py::arg("dt"), py::arg("rate") = 0.01,
             py::arg("tau_min") = 0.1, py::arg("tau_max") = 100.0)
        .def_property_readonly("n_lags", &pb::Creep::n_lags);

    py::class_<pb::Delay, pb::Block>(m, "Delay", "Pure delay of `samples` sample intervals.")
        .def(py::init<double, std::size_t>(), py::arg("dt"), py::arg("samples") = 1)
        .def_property_readonly("samples", &pb::Delay::samples);

    py::class_<pb::MovingAverage, pb::Block>(m, "MovingAverage",
                                             "Mean of the last `length` samples (thesis B.1: 10 samples at 1 ms).")
        .def(py::init<double, std::size_t>(), py::arg("dt"), py::arg("length") = 10)
        .def_property_readonly("length", &pb::MovingAverage::length);

    py::class_<pb::OffsetDrift, pb::Block>(
        m, "OffsetDrift",
        "Sensor offset drift y = x + d, d linear (rate, V/s) plus a seeded random walk (sigma, V/sqrt(s)).")
        .def(py::init<double, double, double, std::uint64_t>(), py::arg("dt"), py::arg("rate") = 0.0,
             py::arg("sigma") = 0.0, py::arg("seed") = 0)
        .def_property_readonly("offset", &pb::OffsetDrift::offset, "Current offset d (V).");

    py::class_<pb::PreisachStage, pb::Block>(
        m, "PreisachStage",
        "A Preisach model as a block; moving_gain k (V/V) feeds the output back, u_eff = u + k*y_prev "
        "(moving Preisach model: non-congruent minor loops). reset() returns to the starting state.")
        .def(py::init([](double dt, const preisach::EverettTable& t, const preisach::State& s, double k) {
                 return pb::PreisachStage(dt, std::make_shared<const preisach::EverettTable>(t), s, k);
             }),
             py::arg("dt"), py::arg("table"), py::arg("state"), py::arg("moving_gain") = 0.0)
        .def_property_readonly("moving_gain", &pb::PreisachStage::moving_gain)
        .def_property_readonly("state", &pb::PreisachStage::state, "Current Preisach state.")
        .def_property_readonly("initial_state", &pb::PreisachStage::initial_state)
        .def("set_initial_state", &pb::PreisachStage::set_initial_state, py::arg("state"),
             "Start from `state` after the next reset().")
        .def_property_readonly("output", &pb::PreisachStage::output, "Last output (V).")
        .def_property_readonly("table", [](const pb::PreisachStage& s) { return s.table(); });

    py::class_<pb::Chain>(m, "BlockChain",
                          "Blocks in series (input blocks -> PreisachStage -> output blocks), copied on "
                          "construction; all must share one sample time.")
        .def(py::init([](const py::iterable& blocks) { return pb::Chain(clone_list(blocks)); }), py::arg("blocks"))
        .def_property_readonly("dt", &pb::Chain::dt)
        .def("__len__", &pb::Chain::size)
        .def(
            "__getitem__",
            [](pb::Chain& c, std::ptrdiff_t i) -> pb::Block& {
                const auto n = std::ptrdiff_t(c.size());
                if (i < 0) i += n;
                if (i < 0 || i >= n) throw py::index_error("block index out of range");
                return c[std::size_t(i)];
            },
            py::arg("index"), py::return_value_policy::reference_internal)
        .def_property_readonly("kinds",
                               [](const pb::Chain& c) {
                                   std::vector<std::string> k;
                                   for (std::size_t i = 0; i < c.size(); ++i) k.push_back(c[i].kind());
                                   return k;
                               })
        .def("reset", &pb::Chain::reset, py::arg("u0") = 0.0,
             "Reset every block (steady state for the constant input u0); returns the output.")
        .def("step", &pb::Chain::step, py::arg("u"))
        .def("run", &run_array<pb::Chain>, py::arg("u"), "Run the samples u (GIL released); returns y.")
        .def_property_readonly("state",
                               [](const pb::Chain& c) {
                                   const auto* p = c.preisach();
                                   if (!p) throw py::value_error("the chain has no PreisachStage");
                                   return p->state();
                               })
        .def("copy", [](const pb::Chain& c) { return pb::Chain(c); })
        .def("__copy__", [](const pb::Chain& c) { return pb::Chain(c); })
        .def("__deepcopy__", [](const pb::Chain& c, const py::dict&) { return pb::Chain(c); }, py::arg("memo"));
}

// Bindings of the DAQ layer (preisach/daq): channels, safety limits, devices (virtual SS15
// rig, Comedi), controllers, and the trial runner, which runs with the GIL released.
#include "common.hpp"

#include <cerrno>
#include <limits>

#include <preisach/blocks.hpp>
#include <preisach/daq.hpp>

namespace pd = preisach::daq;
namespace pb = preisach::blocks;

namespace {

void check_idle(const pd::Device& d) {
    if (d.busy()) throw std::runtime_error(d.description() + " is running a trial; wait for it to finish");
}

py::array_t<double> read_now(pd::Device& d) {
    check_idle(d);
    py::array_t<double> v(static_cast<py::ssize_t>(d.inputs().size()));
    d.read(v.mutable_data());
    return v;
}

void write_now(pd::Device& d, const InArray& v) {
    check_idle(d);
    std::size_t n = 0;
    const double* p = as_vector(v, "volts", n);
    if (n != d.outputs().size())
        throw std::invalid_argument("volts: expected " + std::to_string(d.outputs().size()) + " value(s), one per output channel, got " +
                                    std::to_string(n));
    d.write(p);
}

std::vector<pd::MetaItem> to_meta(const py::dict& d) {
    std::vector<pd::MetaItem> out;
    for (const auto& kv : d) {
        const std::string k = py::str(kv.first);
        if (k == "end_status") throw std::invalid_argument("metadata key 'end_status' is reserved: the runner writes it");
        const py::handle v = kv.second;
        if (py::isinstance<py::bool_>(v))
            throw py::type_error("metadata '" + k + "': bool values are not supported; store an int or a str");
        if (py::isinstance<py::int_>(v)) out.emplace_back(k, v.cast<long long>());
        else if (py::isinstance<py::float_>(v)) out.emplace_back(k, v.cast<double>());
        else if (py::isinstance<py::str>(v)) out.emplace_back(k, v.cast<std::string>());
        else
            throw py::type_error("metadata '" + k + "': values must be str, int or float, got " +
                                 std::string(py::str(py::type::of(v).attr("__name__"))));
    }
    return out;
}

pd::Channel make_channel(const std::string& name, unsigned channel, std::pair<double, double> range, double gain,
                         double offset, const std::string& unit, int subdevice, unsigned aref) {
    pd::Channel c{name, channel, subdevice, range.first, range.second, {gain, offset}, unit, aref};
    c.validate("DAQ");
    return c;
}

}  // namespace

void register_daq(py::module_& m) {
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const pd::DeviceError& e) {
            py::object cls = py::module_::import("preisach.errors").attr("DeviceError");
            PyErr_SetString(cls.ptr(), e.what());
        } catch (const pd::RecordingIOError& e) {
            py::object exc = py::module_::import("builtins").attr("OSError")(e.error_code(), e.what(), e.path());
            PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(exc.ptr())), exc.ptr());
        }
    });

    m.def("comedi_available", &pd::comedi_available,
          "Whether this build has the Comedi backend (comedilib was found when it was compiled).");

    py::class_<pd::Channel>(m, "DaqChannel",
                            "An analog channel: card channel number, connector-volt range and the linear calibration "
                            "physical = gain * connector + offset.")
        .def(py::init(&make_channel), py::arg("name"), py::arg("channel"), py::arg("range"), py::arg("gain") = 1.0,
             py::arg("offset") = 0.0, py::arg("unit") = "V", py::arg("subdevice") = -1, py::arg("aref") = 0u)
        .def_readonly("name", &pd::Channel::name)
        .def_readonly("channel", &pd::Channel::channel)
        .def_readonly("subdevice", &pd::Channel::subdevice)
        .def_property_readonly("range", [](const pd::Channel& c) { return py::make_tuple(c.range_min, c.range_max); })
        .def_property_readonly("gain", [](const pd::Channel& c) { return c.cal.gain; })
        .def_property_readonly("offset", [](const pd::Channel& c) { return c.cal.offset; })
        .def_readonly("unit", &pd::Channel::unit)
        .def_readonly("aref", &pd::Channel::aref)
        .def("physical", [](const pd::Channel& c, double x) { return c.cal.physical(x); }, py::arg("connector"))
        .def("connector", [](const pd::Channel& c, double y) { return c.cal.connector(y); }, py::arg("physical"))
        .def("__repr__", [](const pd::Channel& c) {
            return "DaqChannel(name=" + py::repr(py::str(c.name)).cast<std::string>() + ", channel=" +
                   std::to_string(c.channel) + ", range=(" + pd::detail::num(c.range_min) + ", " +
                   pd::detail::num(c.range_max) + "), gain=" + pd::detail::num(c.cal.gain) +
                   ", offset=" + pd::detail::num(c.cal.offset) + ")";
        });

    py::class_<pd::Safety>(m, "DaqSafety",
                           "Safety limits: output [u_min, u_max] (V at the actuator), slew_rate and ramp_rate <= slew_rate (V/s), "
                           "primary input [y_min, y_max], and the budgets of missed deadlines: in total and in a row (< 0: unlimited).")
        .def(py::init([](double u_min, double u_max, double slew_rate, double ramp_rate, double y_min, double y_max,
                         long long max_missed, long long max_in_a_row) {
                 pd::Safety s{u_min, u_max, slew_rate, ramp_rate, y_min, y_max, max_missed, max_in_a_row};
                 s.validate();
                 return s;
             }),
             py::arg("u_min") = -135.0, py::arg("u_max") = 135.0, py::arg("slew_rate") = 1e4,
             py::arg("ramp_rate") = 500.0, py::arg("y_min") = -std::numeric_limits<double>::infinity(),
             py::arg("y_max") = std::numeric_limits<double>::infinity(), py::arg("max_missed_deadlines") = -1,
             py::arg("max_consecutive_missed") = 20)
        .def_readonly("u_min", &pd::Safety::u_min)
        .def_readonly("u_max", &pd::Safety::u_max)
        .def_readonly("slew_rate", &pd::Safety::slew_rate)
        .def_readonly("ramp_rate", &pd::Safety::ramp_rate)
        .def_readonly("y_min", &pd::Safety::y_min)
        .def_readonly("y_max", &pd::Safety::y_max)
        .def_readonly("max_missed_deadlines", &pd::Safety::max_missed_deadlines)
        .def_readonly("max_consecutive_missed", &pd::Safety::max_consecutive_missed);

    py::class_<pd::Device>(m, "DaqDevice", "A DAQ device (connector volts; the channels carry the calibrations).")
        .def_property_readonly("description", &pd::Device::description)
        .def_property_readonly("simulated", &pd::Device::simulated)
        .def_property_readonly("outputs", &pd::Device::outputs)
        .def_property_readonly("inputs", &pd::Device::inputs)
        .def_property_readonly("busy", &pd::Device::busy, "True while a trial runs on the device.")
        .def("last_output", &pd::Device::last_output, py::arg("index") = 0,
             "Connector volts last written to output `index`.")
        .def("read", &read_now, "Read every input once (connector volts; NaN when out of range).")
        .def("write", &write_now, py::arg("volts"), "Set every output once (connector volts).");

    py::class_<pd::VirtualRig, pd::Device>(
        m, "VirtualRig",
        "Virtual SS15: DAC -> SA11 amplifier (amp_gain, amp_offset) -> plant chain -> sensor -> ADC with "
        "Gaussian noise (adc_noise V rms, seeded) and adc_bits resolution over the input channel's range.")
        .def(py::init([](const pb::Chain& plant, const pd::Channel& output, const pd::Channel& input,
                         double sample_time, unsigned dac_bits, double amp_gain, double amp_offset, double amp_limit,
                         unsigned adc_bits, double adc_noise, double sensor_gain, double sensor_offset,
                         std::uint64_t seed) {
                 pd::VirtualRigConfig cfg;
                 cfg.sample_time = sample_time;
                 cfg.dac_bits = dac_bits;
                 cfg.amp_gain = amp_gain;
                 cfg.amp_offset = amp_offset;
                 cfg.amp_limit = amp_limit;
                 cfg.adc_min = input.range_min;
                 cfg.adc_max = input.range_max;
                 cfg.adc_bits = adc_bits;
                 cfg.adc_noise = adc_noise;
                 cfg.sensor_gain = sensor_gain;
                 cfg.sensor_offset = sensor_offset;
                 cfg.seed = seed;
                 return std::make_unique<pd::VirtualRig>(plant, cfg, output, input);
             }),
             py::arg("plant"), py::arg("output"), py::arg("input"), py::arg("sample_time") = 1e-3,
             py::arg("dac_bits") = 0u, py::arg("amp_gain") = -14.12, py::arg("amp_offset") = -0.02,
             py::arg("amp_limit") = 150.0, py::arg("adc_bits") = 14u, py::arg("adc_noise") = 0.5e-3,
             py::arg("sensor_gain") = 1.0, py::arg("sensor_offset") = 0.0, py::arg("seed") = 0)
        .def(
            "reset",
            [](pd::VirtualRig& r, const py::object& state) {
                check_idle(r);
                if (state.is_none()) r.reset();
                else r.reset(state.cast<const preisach::State&>());
            },
            py::arg("state") = py::none(),
            "Back to the starting state (or a new one) with the DAC at 0 V and the noise re-seeded.")
        .def_property_readonly("state",
                               [](const pd::VirtualRig& r) {
                                   check_idle(r);
                                   return r.state();
                               })
        .def_property_readonly("plant_output", &pd::VirtualRig::plant_output, "Noise-free plant output (V).")
        .def_property_readonly("actuator_voltage", &pd::VirtualRig::actuator_voltage, "Amplifier output V_in (V).")
        .def_property_readonly("time", &pd::VirtualRig::time, "Simulated time since the last reset (s).")
        .def_property_readonly("sample_time", [](const pd::VirtualRig& r) { return r.config().sample_time; })
        .def_property_readonly("plant", [](const pd::VirtualRig& r) {
            check_idle(r);
            return pb::Chain(r.plant());
        });

    py::class_<pd::ComediDevice, pd::Device>(
        m, "ComediDevice",
        "A Comedi DAQ card (Linux): opens `file`, configures the channels' subdevices and ranges, and converts "
        "with comedilib's softcal/hardcal polynomials. Raises preisach.errors.DeviceError naming the file.")
        .def(py::init([](const std::string& file, const std::vector<pd::Channel>& outputs,
                         const std::vector<pd::Channel>& inputs, const std::string& calibration_file,
                         double close_ramp_rate, double close_ramp_period) {
                 return std::make_unique<pd::ComediDevice>(
                     pd::make_comedilib_api(file), file, outputs, inputs,
                     pd::ComediOptions{calibration_file, close_ramp_rate, close_ramp_period});
             }),
             py::arg("file"), py::arg("outputs"), py::arg("inputs"), py::arg("calibration_file") = "",
             py::arg("close_ramp_rate") = 500.0, py::arg("close_ramp_period") = 1e-3)
        .def_static(
            "replay",
            [](const std::string& protocol, const std::string& file, const std::vector<pd::Channel>& outputs,
               const std::vector<pd::Channel>& inputs, const std::string& calibration_file, double close_ramp_rate,
               double close_ramp_period) {
                return std::make_unique<pd::ComediDevice>(
                    std::make_unique<pd::ComediReplay>(protocol), file, outputs, inputs,
                    pd::ComediOptions{calibration_file, close_ramp_rate, close_ramp_period});
            },
            py::arg("protocol"), py::arg("file"), py::arg("outputs"), py::arg("inputs"),
            py::arg("calibration_file") = "", py::arg("close_ramp_rate") = 500.0, py::arg("close_ramp_period") = 1e-3,
            "The device driven by a replayed comedilib protocol instead of a card (for tests; see comedi.hpp). The "
            "closing ramp does not sleep on a replay.")
        .def("close", &pd::ComediDevice::close, py::call_guard<py::gil_scoped_release>(),
             "Ramp the outputs to 0 V at the connector, at close_ramp_rate (V/s at the actuator, one write every "
             "close_ramp_period s), and close the file. Also done when the device is destroyed.")
        .def_property_readonly("close_ramp_rate", [](const pd::ComediDevice& d) { return d.options().close_ramp_rate; },
                               "Rate of the closing ramp to 0 V (V/s at the actuator).")
        .def_property_readonly("close_ramp_period", [](const pd::ComediDevice& d) { return d.options().close_ramp_period; },
                               "Time between two writes of the closing ramp (s).")
        .def_property_readonly("is_open", &pd::ComediDevice::is_open)
        .def_property_readonly("file", &pd::ComediDevice::file)
        .def_property_readonly("board", &pd::ComediDevice::board)
        .def_property_readonly("conversions", &pd::ComediDevice::conversions,
                               "'softcal' or 'hardcal' per channel (outputs, then inputs).")
        .def("verify_protocol",
             [](pd::ComediDevice& d) {
                 auto* r = dynamic_cast<pd::ComediReplay*>(&d.api());
                 if (!r) throw std::invalid_argument("verify_protocol: this device is not a replay");
                 r->verify();
                 return r->log();
             },
             "Replay devices: check every expected call was made; returns the calls made.");

    py::class_<pd::Controller>(m, "DaqController", "A trial controller (output in V at the actuator).")
        .def_property_readonly("kind", &pd::Controller::kind)
        .def("__len__", &pd::Controller::length);

    py::class_<pd::WaveformController, pd::Controller>(m, "DaqWaveformController",
                                                       "Open loop: sample k outputs u[k] (V).")
        .def(py::init([](const InArray& u) {
                 std::size_t n = 0;
                 const double* p = as_vector(u, "u", n);
                 return pd::WaveformController(std::vector<double>(p, p + n));
             }),
             py::arg("u"))
        .def_property_readonly("waveform", [](const pd::WaveformController& c) {
            return py::array_t<double>(py::ssize_t(c.waveform().size()), c.waveform().data());
        });

    py::class_<pd::PIController, pd::Controller>(
        m, "DaqPIController",
        "u[k] = feedforward[k] + kp e + ki Ts sum e for k >= enable_at (else feedforward[k]); "
        "e = setpoint - mean of the last `average` readings; conditional-integration anti-windup.")
        .def(py::init([](double kp, double ki, double setpoint, double sample_time, const InArray& ff,
                         std::size_t enable_at, std::size_t average) {
                 std::size_t n = 0;
                 const double* p = as_vector(ff, "feedforward", n);
                 return pd::PIController(kp, ki, setpoint, sample_time, std::vector<double>(p, p + n), enable_at,
                                         average);
             }),
             py::arg("kp"), py::arg("ki"), py::arg("setpoint"), py::arg("sample_time"), py::arg("feedforward"),
             py::arg("enable_at") = 0, py::arg("average") = 1)
        .def_property_readonly("error", &pd::PIController::error, "Last (averaged) error e (V).")
        .def_property_readonly("control", &pd::PIController::control, "Last PI output u_c (V).")
        .def_property_readonly("integral", &pd::PIController::integral, "Integral term ki Ts sum e (V).");

    py::class_<pd::FunctionController, pd::Controller>(
        m, "DaqCallbackController",
        "Calls func(k, t, y) -> u (V) every sample; the GIL is taken only for the call.")
        .def(py::init([](py::function f, std::size_t length) {
                 auto fn = [f](const pd::SampleInfo& s) -> double {
                     py::gil_scoped_acquire gil;
                     return f(s.k, s.t, s.y).cast<double>();
                 };
                 return pd::FunctionController(fn, length);
             }),
             py::arg("func"), py::arg("length"));

    py::class_<pd::TrialResult>(m, "DaqTrialResult", "How a trial went.")
        .def_readonly("path", &pd::TrialResult::path)
        .def_readonly("end_status", &pd::TrialResult::end_status)
        .def_readonly("reason", &pd::TrialResult::reason)
        .def_readonly("planned", &pd::TrialResult::planned)
        .def_readonly("samples", &pd::TrialResult::samples)
        .def_readonly("ramp_samples", &pd::TrialResult::ramp_samples)
        .def_readonly("dropped", &pd::TrialResult::dropped)
        .def_readonly("missed_deadlines", &pd::TrialResult::missed_deadlines)
        .def_readonly("missed", &pd::TrialResult::missed)
        .def_readonly("max_lateness", &pd::TrialResult::max_lateness)
        .def_readonly("mean_lateness", &pd::TrialResult::mean_lateness)
        .def_readonly("elapsed", &pd::TrialResult::elapsed)
        .def_readonly("final_output", &pd::TrialResult::final_output)
        .def_readonly("realtime", &pd::TrialResult::realtime)
        .def_readonly("priority", &pd::TrialResult::priority);

    py::class_<pd::TrialRunner>(m, "DaqTrialRunner",
                                "Runs one trial at a time; run() releases the GIL, request_stop() is thread-safe.")
        .def(py::init<>())
        .def(
            "run",
            [](pd::TrialRunner& r, pd::Device& dev, pd::Controller& ctl, const std::string& path, double period,
               std::size_t n_samples, bool realtime, std::size_t output, std::size_t input, bool overwrite, bool fsync,
               const py::dict& metadata, std::size_t buffer_rows, double spin, double t0, int priority,
               bool ramp_at_end, const pd::Safety& safety) {
                pd::TrialOptions o;
                o.path = path;
                o.period = period;
                o.n_samples = n_samples;
                o.realtime = realtime;
                o.output = output;
                o.input = input;
                o.overwrite = overwrite;
                o.fsync = fsync;
                o.metadata = to_meta(metadata);
                o.buffer_rows = buffer_rows;
                o.spin = spin;
                o.t0 = t0;
                o.priority = priority;
                o.ramp_at_end = ramp_at_end;
                py::gil_scoped_release release;
                return r.run(dev, ctl, o, safety);
            },
            py::arg("device"), py::arg("controller"), py::arg("path"), py::arg("period"), py::arg("n_samples") = 0,
            py::arg("realtime") = false, py::arg("output") = 0, py::arg("input") = 0, py::arg("overwrite") = false,
            py::arg("fsync") = true, py::arg("metadata") = py::dict(), py::arg("buffer_rows") = 65536,
            py::arg("spin") = 2e-4, py::arg("t0") = 0.0, py::arg("priority") = 0, py::arg("ramp_at_end") = false,
            py::arg("safety") = pd::Safety{})
        .def("request_stop", &pd::TrialRunner::request_stop, py::arg("reason") = "stop requested")
        .def_property_readonly("stop_requested", &pd::TrialRunner::stop_requested)
        .def_property_readonly("progress", &pd::TrialRunner::progress, "Samples taken so far.")
        .def_property_readonly("planned", &pd::TrialRunner::planned, "Samples planned.")
        .def_property_readonly("running", &pd::TrialRunner::running);
}

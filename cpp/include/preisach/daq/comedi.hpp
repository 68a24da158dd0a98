// Comedi backend: real DAQ cards on Linux through comedilib.
//
// The device logic talks to comedilib through the small ComediApi interface, so it can be
// checked without a board: ComediReplay plays back an expected call protocol (like
// pymeasure's expected_protocol) and fails on the first call that differs.  The real
// implementation, ComedilibApi (comedi_lib.hpp), exists only when comedilib was found at build
// time (PREISACH_HAVE_COMEDI).
//
// What the device does (ComediDevice):
//   * opens the device file (e.g. /dev/comedi0); a missing file is a DeviceError naming it;
//   * finds the analog output/input subdevices (or takes the configured ones), checks each
//     channel number, selects the range whose limits equal the channel's [range_min, range_max]
//     volts, and reads maxdata;
//   * takes comedilib's calibrated conversion polynomials: for a software-calibrated
//     subdevice (SDF_SOFT_CALIBRATED) the softcal polynomials from the calibration file
//     written by comedi_soft_calibrate (the default path, or the one configured); otherwise the
//     hardware-calibrated (hardcal) polynomials;
//   * converts with comedi_to_physical / comedi_from_physical; a reading of code 0 or maxdata
//     is out of range and becomes NaN (the runner then aborts the trial);
//   * reads with comedi_data_read and writes with comedi_data_write, one instruction per
//     channel per sample (software-timed, paced by the trial runner's clock);
//   * on close() (also from the destructor) ramps every output from its last value to 0 V at
//     the connector at ComediOptions::close_ramp_rate (V/s at the actuator, default 500 V/s,
//     the trial runner's Safety::ramp_rate), one write every close_ramp_period, instead of
//     stepping the actuator to 0 V at once; then closes the device file.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "device.hpp"

namespace preisach::daq {

// comedilib's comedi_polynomial_t: physical = sum_i c_i (x - origin)^i, i <= order.
struct ComediPoly {
    double coefficients[4] = {0, 0, 0, 0};
    double expansion_origin = 0.0;
    unsigned order = 0;
};

// Subdevice types and flags of comedi.h (values fixed by the kernel ABI).
constexpr int COMEDI_AI = 1;             // COMEDI_SUBD_AI
constexpr int COMEDI_AO = 2;             // COMEDI_SUBD_AO
constexpr int COMEDI_SOFT_CAL = 0x2000;  // SDF_SOFT_CALIBRATED

// The comedilib calls the device uses.  Every call returns what comedilib returns (-1 or a
// null result on failure); error() is comedi_strerror(comedi_errno()).
class ComediApi {
public:
    virtual ~ComediApi() = default;
    virtual bool open(const std::string& file) = 0;
    virtual void close() = 0;
    virtual std::string error() = 0;
    virtual std::string board_name() = 0;
    virtual int find_subdevice_by_type(int type, unsigned start) = 0;
    virtual int get_subdevice_type(unsigned subdevice) = 0;
    virtual int get_subdevice_flags(unsigned subdevice) = 0;
    virtual int get_n_channels(unsigned subdevice) = 0;
    virtual long long get_maxdata(unsigned subdevice, unsigned channel) = 0;
    // comedi_find_range with UNIT_volt
    virtual int find_range(unsigned subdevice, unsigned channel, double min, double max) = 0;
    // Parse the calibration file (empty: the default path); false when there is none.
    virtual bool load_calibration(const std::string& path) = 0;
    virtual int softcal_converter(unsigned subdevice, unsigned channel, unsigned range, bool to_physical,
                                  ComediPoly& poly) = 0;
    virtual int hardcal_converter(unsigned subdevice, unsigned channel, unsigned range, bool to_physical,
                                  ComediPoly& poly) = 0;
    virtual int data_read(unsigned subdevice, unsigned channel, unsigned range, unsigned aref, unsigned& data) = 0;
    virtual int data_write(unsigned subdevice, unsigned channel, unsigned range, unsigned aref, unsigned data) = 0;
    // comedi_to_physical / comedi_from_physical
    virtual double to_physical(unsigned data, const ComediPoly& poly) = 0;
    virtual unsigned from_physical(double volts, const ComediPoly& poly) = 0;
    // Wait between two writes of the closing ramp (s).  Not a comedilib call: the real
    // interface sleeps, the replay only adds the time up (ComediReplay::paused).
    virtual void pause(double seconds) {
        if (seconds > 0) std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    }
};

// comedilib's polynomial conversions, written out for the replay (the same arithmetic as
// comedi_to_physical and comedi_from_physical, including the rounding and clamping).
inline double poly_to_physical(unsigned data, const ComediPoly& p) {
    double x = double(data) - p.expansion_origin, term = 1.0, v = 0.0;
    for (unsigned i = 0; i <= p.order && i < 4; ++i) {
        v += p.coefficients[i] * term;
        term *= x;
    }
    return v;
}
inline unsigned poly_from_physical(double volts, const ComediPoly& p) {
    double x = volts - p.expansion_origin, term = 1.0, v = 0.0;
    for (unsigned i = 0; i <= p.order && i < 4; ++i) {
        v += p.coefficients[i] * term;
        term *= x;
    }
    if (!(v > 0.0)) return 0;  // comedilib clamps (and maps NaN to 0)
    if (v >= 4294967295.0) return 4294967295u;
    return unsigned(std::nearbyint(v));
}

// Plays back an expected protocol.  Each line is "call arg arg ... -> result", e.g.
//   open /dev/comedi0 -> 1
//   find_subdevice_by_type 2 0 -> 1
//   softcal_converter 1 1 0 from -> 1 : 0 8192 3276.75 0 0
//   data_read 0 1 0 0 -> 0 8192
// Calls are compared as text (numbers printed with %.17g); a mismatch throws
// std::logic_error naming the step, the expected and the actual call.  A failing call
// returns "-1 : message" (open too), and the message becomes error().  Converter results
// are "rc : order origin c0 c1 ...".  Conversion
// functions are pure and are not part of the protocol, nor are the pauses of the closing ramp
// (the replay does not sleep; paused() is their total).  Blank lines and '#' comments are
// ignored.
class ComediReplay final : public ComediApi {
public:
    explicit ComediReplay(const std::string& protocol) {
        std::istringstream in(protocol);
        std::string line;
        while (std::getline(in, line)) {
            const auto first = line.find_first_not_of(" \t");
            if (first == std::string::npos || line[first] == '#') continue;
            const auto arrow = line.find("->");
            if (arrow == std::string::npos)
                throw std::invalid_argument("comedi protocol line '" + line + "' has no '->'");
            steps_.push_back({trim(line.substr(0, arrow)), trim(line.substr(arrow + 2))});
        }
    }
    // Steps consumed so far / in total; verify() throws unless every step was used.
    std::size_t consumed() const noexcept { return pos_; }
    std::size_t size() const noexcept { return steps_.size(); }
    void verify() const {
        if (pos_ != steps_.size())
            throw std::logic_error("comedi protocol: " + std::to_string(steps_.size() - pos_) +
                                   " expected call(s) never made, the first: '" + steps_[pos_].call + "'");
    }
    std::vector<std::string> log() const { return log_; }
    // Total time (s) the device asked to pause (the closing ramp), without sleeping.
    double paused() const noexcept { return paused_; }

    bool open(const std::string& file) override { return expect("open " + file) != "-1"; }
    void close() override { expect("close"); }
    std::string error() override { return last_error_; }
    std::string board_name() override { return expect("board_name"); }
    int find_subdevice_by_type(int type, unsigned start) override {
        return to_int(expect(fmt("find_subdevice_by_type", {double(type), double(start)})));
    }
    int get_subdevice_type(unsigned s) override { return to_int(expect(fmt("get_subdevice_type", {double(s)}))); }
    int get_subdevice_flags(unsigned s) override { return to_int(expect(fmt("get_subdevice_flags", {double(s)}))); }
    int get_n_channels(unsigned s) override { return to_int(expect(fmt("get_n_channels", {double(s)}))); }
    long long get_maxdata(unsigned s, unsigned c) override {
        return std::stoll(expect(fmt("get_maxdata", {double(s), double(c)})));
    }
    int find_range(unsigned s, unsigned c, double lo, double hi) override {
        return to_int(expect(fmt("find_range", {double(s), double(c), lo, hi})));
    }
    bool load_calibration(const std::string& path) override {
        return expect("load_calibration" + (path.empty() ? std::string() : " " + path)) != "0";
    }
    int softcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        return converter("softcal_converter", s, c, r, to, p);
    }
    int hardcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        return converter("hardcal_converter", s, c, r, to, p);
    }
    int data_read(unsigned s, unsigned c, unsigned r, unsigned a, unsigned& data) override {
        std::istringstream out(expect(fmt("data_read", {double(s), double(c), double(r), double(a)})));
        long long rc = -1, d = 0;
        out >> rc >> d;
        data = unsigned(d);
        return int(rc);
    }
    int data_write(unsigned s, unsigned c, unsigned r, unsigned a, unsigned data) override {
        return to_int(expect(fmt("data_write", {double(s), double(c), double(r), double(a), double(data)})));
    }
    double to_physical(unsigned data, const ComediPoly& p) override { return poly_to_physical(data, p); }
    unsigned from_physical(double v, const ComediPoly& p) override { return poly_from_physical(v, p); }
    void pause(double seconds) override { paused_ += seconds; }

private:
    struct Step {
        std::string call, result;
    };
    static std::string trim(const std::string& s) {
        const auto a = s.find_first_not_of(" \t\r");
        const auto b = s.find_last_not_of(" \t\r");
        return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
    }
    static std::string fmt(const char* name, std::initializer_list<double> args) {
        std::string s = name;
        char buf[32];
        for (double a : args) {
            std::snprintf(buf, sizeof buf, " %.17g", a);
            s += buf;
        }
        return s;
    }
    static int to_int(const std::string& s) { return int(std::stol(s)); }
    // The result of the next step, after checking that `call` is what it expects.  A result
    // "-1 : message" sets the error message the device will report.
    std::string expect(const std::string& call) {
        log_.push_back(call);
        if (pos_ >= steps_.size())
            throw std::logic_error("comedi protocol: unexpected call '" + call + "' after the last expected step (" +
                                   std::to_string(steps_.size()) + ")");
        const Step& st = steps_[pos_++];
        if (st.call != call)
            throw std::logic_error("comedi protocol step " + std::to_string(pos_) + ": expected '" + st.call +
                                   "', got '" + call + "'");
        std::string r = st.result;
        const auto colon = r.find(" : ");
        if (colon != std::string::npos && r.rfind("-1", 0) == 0) {
            last_error_ = trim(r.substr(colon + 3));
            r = trim(r.substr(0, colon));
        }
        return r;
    }
    int converter(const char* name, unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) {
        std::string res = expect(fmt(name, {double(s), double(c), double(r)}) + (to ? " to" : " from"));
        const auto colon = res.find(':');
        const int rc = to_int(res.substr(0, colon));
        if (rc >= 0 && colon != std::string::npos) {
            std::istringstream in(res.substr(colon + 1));
            in >> p.order >> p.expansion_origin;
            for (unsigned i = 0; i <= p.order && i < 4; ++i) in >> p.coefficients[i];
        }
        return rc;
    }

    std::vector<Step> steps_;
    std::size_t pos_ = 0;
    std::vector<std::string> log_;
    std::string last_error_ = "protocol error";
    double paused_ = 0.0;
};

struct ComediOptions {
    std::string calibration_file;  // softcal file; "" = comedilib's default path
    // Closing ramp to 0 V: rate in the output channel's physical units per second (V/s at the
    // actuator, converted to connector volts with the channel's calibration gain), and the time
    // between two writes.  The default rate is the trial runner's Safety::ramp_rate.
    double close_ramp_rate = 500.0;   // V/s
    double close_ramp_period = 1e-3;  // s

    void validate() const {
        if (!(std::isfinite(close_ramp_rate) && close_ramp_rate > 0.0))
            throw std::invalid_argument("comedi: close_ramp_rate must be a positive finite number of V/s, got " +
                                        std::to_string(close_ramp_rate));
        if (!(std::isfinite(close_ramp_period) && close_ramp_period > 0.0 && close_ramp_period <= 1.0))
            throw std::invalid_argument("comedi: close_ramp_period must be in (0, 1] s, got " +
                                        std::to_string(close_ramp_period));
    }
};

class ComediDevice final : public Device {
public:
    ComediDevice(std::unique_ptr<ComediApi> api, std::string file, std::vector<Channel> outputs,
                 std::vector<Channel> inputs, ComediOptions options = {})
        : api_(std::move(api)), file_(std::move(file)), opt_(std::move(options)) {
        if (!api_) throw std::invalid_argument("comedi: no comedilib interface");
        if (outputs.empty()) throw std::invalid_argument("comedi: at least one output channel is needed");
        if (inputs.empty()) throw std::invalid_argument("comedi: at least one input channel is needed");
        for (const auto& c : outputs) c.validate("output");
        for (const auto& c : inputs) c.validate("input");
        opt_.validate();
        if (!api_->open(file_)) throw DeviceError("cannot open Comedi device '" + file_ + "': " + api_->error());
        open_ = true;
        try {
            board_ = api_->board_name();
            bool calibration_loaded = false, calibration_tried = false;
            auto configure = [&](std::vector<Channel>& chans, std::vector<Conv>& conv, int type) {
                const char* kind = type == COMEDI_AO ? "analog output" : "analog input";
                for (auto& ch : chans) {
                    const std::string where = "'" + file_ + "' " + kind + " channel '" + ch.name + "'";
                    int sub = ch.subdevice;
                    if (sub < 0) {
                        sub = api_->find_subdevice_by_type(type, 0);
                        if (sub < 0) throw DeviceError("'" + file_ + "' has no " + kind + " subdevice: " + api_->error());
                        ch.subdevice = sub;
                    } else if (api_->get_subdevice_type(unsigned(sub)) != type) {
                        throw DeviceError(where + ": subdevice " + std::to_string(sub) + " is not an " + kind +
                                          " subdevice");
                    }
                    const unsigned s = unsigned(sub);
                    const int n = api_->get_n_channels(s);
                    if (n < 0) throw DeviceError(where + ": cannot query subdevice " + std::to_string(s) + ": " + api_->error());
                    if (ch.channel >= unsigned(n))
                        throw DeviceError(where + ": channel " + std::to_string(ch.channel) + " does not exist (subdevice " +
                                          std::to_string(s) + " has " + std::to_string(n) + " channels)");
                    const int r = api_->find_range(s, ch.channel, ch.range_min, ch.range_max);
                    if (r < 0)
                        throw DeviceError(where + ": no range [" + std::to_string(ch.range_min) + ", " +
                                          std::to_string(ch.range_max) + "] V on channel " + std::to_string(ch.channel));
                    const long long maxdata = api_->get_maxdata(s, ch.channel);
                    if (maxdata <= 0) throw DeviceError(where + ": cannot read maxdata: " + api_->error());
                    Conv c{s, ch.channel, unsigned(r), ch.aref, (unsigned)maxdata, {}, "hardcal"};
                    const int flags = api_->get_subdevice_flags(s);
                    if (flags < 0) throw DeviceError(where + ": cannot read subdevice flags: " + api_->error());
                    const bool to = type == COMEDI_AI;
                    if (flags & COMEDI_SOFT_CAL) {
                        if (!calibration_tried) {
                            calibration_loaded = api_->load_calibration(opt_.calibration_file);
                            calibration_tried = true;
                        }
                        if (!calibration_loaded)
                            throw DeviceError(where + ": the subdevice is software-calibrated but no calibration file " +
                                              (opt_.calibration_file.empty() ? std::string("at comedilib's default path")
                                                                             : "'" + opt_.calibration_file + "'") +
                                              " could be read; run comedi_soft_calibrate first");
                        if (api_->softcal_converter(s, ch.channel, c.range, to, c.poly) < 0)
                            throw DeviceError(where + ": no software calibration for range " + std::to_string(c.range) +
                                              ": " + api_->error());
                        c.kind = "softcal";
                    } else if (api_->hardcal_converter(s, ch.channel, c.range, to, c.poly) < 0) {
                        throw DeviceError(where + ": no hardware-calibrated conversion: " + api_->error());
                    }
                    conv.push_back(c);
                }
            };
            configure(outputs, out_conv_, COMEDI_AO);
            configure(inputs, in_conv_, COMEDI_AI);
        } catch (...) {
            open_ = false;
            try {
                api_->close();
            } catch (...) {  // keep the configuration error, not a failure to close
            }
            throw;
        }
        outs_ = std::move(outputs);
        ins_ = std::move(inputs);
        last_.assign(outs_.size(), 0.0);
    }
    ~ComediDevice() override {
        try {
            close();
        } catch (...) {
        }
    }

    std::string description() const override { return "comedi " + file_ + " (" + board_ + ")"; }
    bool simulated() const override { return false; }
    const std::vector<Channel>& outputs() const override { return outs_; }
    const std::vector<Channel>& inputs() const override { return ins_; }
    void start(double period) override {
        if (!open_) throw DeviceError("Comedi device '" + file_ + "' is closed");
        if (!(period > 0)) throw std::invalid_argument("period must be > 0 s");
    }
    void read(double* volts) override {
        for (std::size_t i = 0; i < in_conv_.size(); ++i) {
            const Conv& c = in_conv_[i];
            unsigned data = 0;
            if (api_->data_read(c.sub, c.chan, c.range, c.aref, data) < 0)
                throw DeviceError("'" + file_ + "': reading input '" + ins_[i].name + "' failed: " + api_->error());
            volts[i] = (data == 0 || data >= c.maxdata) ? std::numeric_limits<double>::quiet_NaN()
                                                        : api_->to_physical(data, c.poly);
        }
    }
    void write(const double* volts) override {
        for (std::size_t i = 0; i < out_conv_.size(); ++i) {
            const Conv& c = out_conv_[i];
            const unsigned data = std::min(api_->from_physical(volts[i], c.poly), c.maxdata);
            if (api_->data_write(c.sub, c.chan, c.range, c.aref, data) < 0)
                throw DeviceError("'" + file_ + "': writing output '" + outs_[i].name + "' failed: " + api_->error());
            last_[i] = volts[i];
        }
    }
    // Ramp every output to 0 V at the connector and close the device file.  Idempotent.
    //
    // All outputs move together, linearly from their last written value to 0 V, in as many
    // steps (one every close_ramp_period, the first at once) as the channel needing the most
    // requires so that none changes faster than close_ramp_rate at the actuator; the last step
    // writes exactly 0 V.  An output already at 0 V gets one write of 0 V.  The device file is
    // closed even if a write throws (the error is rethrown afterwards).
    void close() {
        if (!open_) return;
        open_ = false;
        std::exception_ptr failure;
        try {
            ramp_to_zero();
        } catch (...) {
            failure = std::current_exception();
        }
        try {
            api_->close();
        } catch (...) {
            if (!failure) failure = std::current_exception();
        }
        if (failure) std::rethrow_exception(failure);
    }
    // Writes the closing ramp takes from the current outputs (at least 1).
    std::size_t close_ramp_steps() const {
        std::size_t steps = 1;
        for (std::size_t i = 0; i < outs_.size(); ++i) {
            const double per_step = opt_.close_ramp_rate * opt_.close_ramp_period / std::abs(outs_[i].cal.gain);
            const double need = std::ceil(std::abs(last_[i]) / per_step - 1e-9);
            if (need > double(steps)) steps = std::size_t(need);
        }
        return steps;
    }
    bool is_open() const noexcept { return open_; }
    const std::string& file() const noexcept { return file_; }
    const std::string& board() const noexcept { return board_; }
    // "softcal" or "hardcal" per channel (outputs, then inputs).
    std::vector<std::string> conversions() const {
        std::vector<std::string> k;
        for (const auto& c : out_conv_) k.push_back(c.kind);
        for (const auto& c : in_conv_) k.push_back(c.kind);
        return k;
    }
    ComediApi& api() noexcept { return *api_; }
    const ComediOptions& options() const noexcept { return opt_; }

private:
    void ramp_to_zero() {
        const std::size_t steps = close_ramp_steps();
        const std::vector<double> from = last_;
        for (std::size_t s = 1; s <= steps; ++s) {
            if (s > 1) api_->pause(opt_.close_ramp_period);
            const double frac = s == steps ? 0.0 : 1.0 - double(s) / double(steps);
            for (std::size_t i = 0; i < out_conv_.size(); ++i) {
                const Conv& c = out_conv_[i];
                const double v = from[i] * frac;
                api_->data_write(c.sub, c.chan, c.range, c.aref, std::min(api_->from_physical(v, c.poly), c.maxdata));
                last_[i] = v;
            }
        }
    }

    struct Conv {
        unsigned sub, chan, range, aref, maxdata;
        ComediPoly poly;
        std::string kind;
    };
    std::unique_ptr<ComediApi> api_;
    std::string file_, board_;
    ComediOptions opt_;
    std::vector<Channel> outs_, ins_;
    std::vector<Conv> out_conv_, in_conv_;
    bool open_ = false;
};

}  // namespace preisach::daq

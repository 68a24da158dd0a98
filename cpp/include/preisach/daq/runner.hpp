// The trial runner: a clocked sample loop with safety limits, streaming every sample to a
// recording file.  Pure C++; the Python bindings call run() with the GIL released.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <pthread.h>
#include <sched.h>

#include "controller.hpp"
#include "device.hpp"
#include "recording_file.hpp"

namespace preisach::daq {

// Safety limits, in physical units at the actuator and of the primary measured input.
struct Safety {
    double u_min = -135.0;  // V: lowest output (the SA11 amplifier gives +/-135 V, thesis 3.1)
    double u_max = 135.0;   // V: highest output
    double slew_rate = 1e4;  // V/s: largest output change per second (inf: none)
    double ramp_rate = 500.0;  // V/s: rate of the ramp to 0 V after an abort or a stop request
    double y_min = -std::numeric_limits<double>::infinity();  // primary input limits; a reading
    double y_max = std::numeric_limits<double>::infinity();   // outside aborts the trial
    // Deadline budgets (real-time runs).  A single late sample only holds the previous output
    // one period longer; what endangers a regulated actuator is a stall: many deadlines in a
    // row without a fresh output.  Abort when more than max_consecutive_missed deadlines are
    // missed in a row (default 20: 20 ms at 1 kHz), or more than max_missed_deadlines in total
    // (< 0: no limit, the default; every miss is still counted and recorded).
    long long max_missed_deadlines = -1;
    long long max_consecutive_missed = 20;

    void validate() const {
        if (!(std::isfinite(u_min) && std::isfinite(u_max) && u_min <= 0.0 && 0.0 <= u_max))
            throw std::invalid_argument("safety: output limits [u_min, u_max] = [" + std::to_string(u_min) + ", " +
                                        std::to_string(u_max) + "] V must be finite and contain 0 V");
        if (!(slew_rate > 0.0)) throw std::invalid_argument("safety: slew_rate must be > 0 V/s (inf for none)");
        if (!(std::isfinite(ramp_rate) && ramp_rate > 0.0))
            throw std::invalid_argument("safety: ramp_rate must be a positive finite number of V/s");
        // The ramp to 0 V after an abort is not slew limited itself: it must not be faster.
        if (ramp_rate > slew_rate)
            throw std::invalid_argument("safety: ramp_rate = " + std::to_string(ramp_rate) + " V/s exceeds slew_rate = " +
                                        std::to_string(slew_rate) +
                                        " V/s; the ramp to 0 V must respect the slew limit (use ramp_rate <= slew_rate)");
        if (std::isnan(y_min) || std::isnan(y_max) || !(y_min < y_max))
            throw std::invalid_argument("safety: input limits [y_min, y_max] must satisfy y_min < y_max");
        if (max_consecutive_missed == 0)
            throw std::invalid_argument("safety: max_consecutive_missed must be >= 1 (or < 0 for no limit)");
    }
};

struct TrialOptions {
    double period = 1e-3;          // s
    std::size_t n_samples = 0;     // 0: the controller's length
    bool realtime = false;         // pace against the clock (always, for a device that is not simulated)
    std::size_t output = 0;        // the actuator's output channel
    std::size_t input = 0;         // the primary measured input channel (column y)
    std::string path;              // recording file (.csv)
    bool overwrite = false;        // replace an existing file
    bool fsync = true;             // fsync every chunk
    std::vector<MetaItem> metadata;  // leading metadata; overrides the runner's own keys
    std::size_t buffer_rows = 65536;
    double spin = 2e-4;            // s busy-waited before each deadline (sleep until then)
    double t0 = 0.0;               // time of the first sample in the file (s)
    int priority = 0;              // SCHED_FIFO priority to request for the loop (0: leave alone)
    bool ramp_at_end = false;      // ramp to 0 V after a complete trial as well
};

struct TrialResult {
    std::string path;
    std::string end_status;        // "complete", "interrupted" or "aborted: <reason>"
    std::string reason;            // why it ended early ("" when complete)
    std::size_t planned = 0;       // samples planned
    std::size_t samples = 0;       // samples taken in the trial proper (rows before the ramp)
    std::size_t ramp_samples = 0;  // rows of the ramp to 0 V after an abort or stop
    std::size_t dropped = 0;       // samples not written because a reading was NaN
    std::size_t missed_deadlines = 0;
    std::vector<std::size_t> missed;  // indices of the first 1024 samples that missed
    double max_lateness = 0.0;     // s: latest start of a sample after its deadline
    double mean_lateness = 0.0;    // s
    double elapsed = 0.0;          // s of wall-clock time
    double final_output = 0.0;     // V at the actuator when the runner returned
    bool realtime = false;
    std::string priority;          // what happened to the SCHED_FIFO request
};

namespace detail {

// Raises the calling thread to SCHED_FIFO for its lifetime, if asked and allowed.
class PriorityGuard {
public:
    explicit PriorityGuard(int priority) {
        if (priority <= 0) {
            note = "not requested";
            return;
        }
        pthread_getschedparam(pthread_self(), &old_policy_, &old_);
        sched_param p{};
        p.sched_priority = std::min(priority, sched_get_priority_max(SCHED_FIFO));
        const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
        changed_ = rc == 0;
        note = changed_ ? "SCHED_FIFO " + std::to_string(p.sched_priority)
                        : std::string("SCHED_FIFO refused: ") + std::strerror(rc);
    }
    ~PriorityGuard() {
        if (changed_) pthread_setschedparam(pthread_self(), old_policy_, &old_);
    }
    std::string note;

private:
    bool changed_ = false;
    int old_policy_ = SCHED_OTHER;
    sched_param old_{};
};

struct ClaimGuard {
    Device& d;
    ClaimGuard(Device& dev, const std::string& who) : d(dev) { d.claim(who); }
    ~ClaimGuard() { d.release(); }
};

inline std::string num(double v) {
    char buf[40];
    return std::string(buf, format_double(buf, sizeof buf, v));
}

}  // namespace detail

class TrialRunner {
public:
    // Ask a running trial to stop (thread-safe, async-signal-unsafe): the loop ends at the
    // next sample, ramps the output to 0 V and closes the file with end_status "interrupted".
    void request_stop(const std::string& reason = "stop requested") {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_reason_ = reason;
        }
        stop_.store(true);
    }
    bool stop_requested() const noexcept { return stop_.load(); }
    // Samples taken so far in the current (or last) trial, and the number planned.
    std::size_t progress() const noexcept { return progress_.load(); }
    std::size_t planned() const noexcept { return planned_.load(); }
    bool running() const noexcept { return running_.load(); }

    TrialResult run(Device& dev, Controller& ctl, const TrialOptions& opt, const Safety& safety) {
        using clock = std::chrono::steady_clock;
        safety.validate();
        if (!(std::isfinite(opt.period) && opt.period > 0))
            throw std::invalid_argument("period: must be a positive number of seconds, got " + std::to_string(opt.period));
        if (opt.path.empty()) throw std::invalid_argument("path: the recording file name is empty");
        const auto& outs = dev.outputs();
        const auto& ins = dev.inputs();
        if (opt.output >= outs.size())
            throw std::invalid_argument("output: channel index " + std::to_string(opt.output) + " but the device has " +
                                        std::to_string(outs.size()) + " output channel(s)");
        if (opt.input >= ins.size())
            throw std::invalid_argument("input: channel index " + std::to_string(opt.input) + " but the device has " +
                                        std::to_string(ins.size()) + " input channel(s)");
        for (const auto& c : outs) c.validate("output");
        for (const auto& c : ins) c.validate("input");
        const std::size_t planned = opt.n_samples ? opt.n_samples : ctl.length();
        if (planned == 0)
            throw std::invalid_argument("n_samples: the trial has no length (give n_samples or a controller with one)");
        if (running_.exchange(true)) throw std::runtime_error("this trial runner is already running a trial");
        struct RunningGuard {
            std::atomic<bool>& r;
            ~RunningGuard() { r.store(false); }
        } running_guard{running_};
        progress_.store(0);
        planned_.store(planned);

        // Columns: t, u, y, the command before the limits, the raw connector volts, the other
        // inputs by name, and the lateness of each sample.
        std::vector<std::string> cols{"t", "u", "y", "u_cmd", "u_dac", "y_adc"};
        for (std::size_t i = 0; i < ins.size(); ++i)
            if (i != opt.input) cols.push_back(ins[i].name);
        cols.push_back("lateness");
        const std::size_t width = cols.size();

        const bool rt = opt.realtime || !dev.simulated();
        const Channel& och = outs[opt.output];
        const Channel& ich = ins[opt.input];
        std::vector<MetaItem> meta = opt.metadata;
        auto add = [&](const std::string& k, MetaValue v) {
            for (const auto& m : meta)
                if (m.first == k) return;
            meta.emplace_back(k, std::move(v));
        };
        add("sample_time", opt.period);
        add("input_units", och.unit);
        add("output_units", ich.unit);
        add("device", dev.description());
        add("realtime", (long long)(rt ? 1 : 0));
        add("output_channel", och.name + " (channel " + std::to_string(och.channel) + ")");
        add("output_gain", och.cal.gain);
        add("output_offset", och.cal.offset);
        add("input_channel", ich.name + " (channel " + std::to_string(ich.channel) + ")");
        add("input_gain", ich.cal.gain);
        add("input_offset", ich.cal.offset);
        add("u_min", safety.u_min);
        add("u_max", safety.u_max);
        add("slew_rate", safety.slew_rate);
        add("planned_samples", (long long)planned);

        detail::ClaimGuard claim(dev, "trial runner");
        dev.start(opt.period);
        StreamingCsv writer(opt.path, cols, meta, opt.overwrite, opt.fsync, opt.buffer_rows);

        TrialResult res;
        res.path = opt.path;
        res.planned = planned;
        res.realtime = rt;
        res.missed.reserve(1024);
        const std::size_t nin = ins.size(), nout = outs.size();
        std::vector<double> cin(nin, 0.0), pin(nin, 0.0), cout_(nout, 0.0), row(width, 0.0);
        for (std::size_t i = 0; i < nout; ++i) cout_[i] = dev.last_output(i);
        double u_prev = och.cal.physical(cout_[opt.output]);
        const double slew_step = safety.slew_rate * opt.period;
        const auto period_ns = std::chrono::nanoseconds((long long)std::llround(opt.period * 1e9));
        const auto spin = std::chrono::nanoseconds((long long)std::llround(std::max(0.0, opt.spin) * 1e9));

        enum class End { running, complete, interrupted, aborted } end = End::running;
        std::string reason;
        std::exception_ptr error;
        double late_sum = 0.0;
        std::size_t in_a_row = 0;  // deadlines missed in a row (real-time runs)
        std::size_t rows = 0;
        bool device_ok = true;

        auto abort_with = [&](const std::string& why) {
            end = End::aborted;
            reason = why;
        };
        auto wait_until = [&](clock::time_point deadline) {
            if (clock::now() < deadline - spin) std::this_thread::sleep_until(deadline - spin);
            while (clock::now() < deadline) {
            }
        };
        auto push = [&](double t, double u, double u_cmd, double dac, double late) {
            row[0] = t;
            row[1] = u;
            row[2] = pin[opt.input];
            row[3] = u_cmd;
            row[4] = dac;
            row[5] = cin[opt.input];
            std::size_t c = 6;
            for (std::size_t i = 0; i < nin; ++i)
                if (i != opt.input) row[c++] = pin[i];
            row[c] = late;
            while (!writer.try_push(row.data())) {
                if (writer.failed()) return false;
                std::this_thread::sleep_for(std::chrono::microseconds(50));
            }
            ++rows;
            return true;
        };
        // Read every input; "" when all readings are finite, else the reason.
        auto read_inputs = [&](std::size_t k, double t) -> std::string {
            dev.read(cin.data());
            std::string bad;
            for (std::size_t i = 0; i < nin; ++i) {
                pin[i] = ins[i].cal.physical(cin[i]);
                if (!std::isfinite(pin[i]) && bad.empty())
                    bad = "input channel '" + ins[i].name + "' read " + (std::isnan(cin[i]) ? "NaN" : detail::num(cin[i])) +
                          " (converter out of range [" + detail::num(ins[i].range_min) + ", " +
                          detail::num(ins[i].range_max) + "] V) at sample " + std::to_string(k) + ", t = " +
                          detail::num(t) + " s";
            }
            return bad;
        };
        // Apply the safety limits to a request; returns the connector volts.
        auto limit = [&](double u_req, double& u) {
            u = std::min(std::max(u_req, safety.u_min), safety.u_max);
            if (std::isfinite(slew_step)) u = std::min(std::max(u, u_prev - slew_step), u_prev + slew_step);
            const double c = std::min(std::max(och.cal.connector(u), och.range_min), och.range_max);
            u = och.cal.physical(c);
            return c;
        };

        detail::PriorityGuard prio(opt.priority);
        res.priority = prio.note;
        const auto wall0 = clock::now();
        const auto t_start = wall0 + (rt ? std::chrono::milliseconds(2) : std::chrono::milliseconds(0));
        ctl.reset();
        std::size_t k = 0;
        std::size_t next_slot = 0;  // the first sample slot the ramp may use
        while (k < planned) {
            next_slot = k + 1;
            const auto deadline = t_start + period_ns * (long long)k;
            if (rt) wait_until(deadline);
            const double late = rt ? std::chrono::duration<double>(clock::now() - deadline).count() : 0.0;
            const double t = opt.t0 + double(k) * opt.period;
            std::string bad;
            try {
                bad = read_inputs(k, t);
            } catch (const std::exception& e) {
                abort_with(std::string("device read failed at sample ") + std::to_string(k) + ": " + e.what());
                error = std::current_exception();
                break;
            }
            if (!bad.empty()) {
                ++res.dropped;
                abort_with(bad);
                break;
            }
            const double y = pin[opt.input];
            if (y < safety.y_min || y > safety.y_max) {
                push(t, u_prev, u_prev, cout_[opt.output], late);
                abort_with("input channel '" + ich.name + "' read " + detail::num(y) + " " + ich.unit +
                           ", outside the safety limits [" + detail::num(safety.y_min) + ", " +
                           detail::num(safety.y_max) + "] " + ich.unit + " at sample " + std::to_string(k) + ", t = " + detail::num(t) +
                           " s");
                break;
            }
            if (writer.failed()) {  // the recording cannot be written: stop actuating now
                abort_with(writer.error());
                break;
            }
            if (stop_.load()) {
                push(t, u_prev, u_prev, cout_[opt.output], late);
                end = End::interrupted;
                std::lock_guard<std::mutex> lock(mutex_);
                reason = stop_reason_;
                break;
            }
            double u_cmd;
            try {
                u_cmd = ctl.output(SampleInfo{k, t, y, pin.data(), nin, u_prev});
            } catch (const std::exception& e) {
                push(t, u_prev, u_prev, cout_[opt.output], late);
                abort_with(std::string("controller raised at sample ") + std::to_string(k) + ": " + e.what());
                error = std::current_exception();
                break;
            } catch (...) {
                push(t, u_prev, u_prev, cout_[opt.output], late);
                abort_with("controller raised an unknown exception at sample " + std::to_string(k));
                error = std::current_exception();
                break;
            }
            if (!std::isfinite(u_cmd)) {
                push(t, u_prev, u_prev, cout_[opt.output], late);
                abort_with("controller returned a non-finite output at sample " + std::to_string(k) + ", t = " +
                           detail::num(t) + " s");
                break;
            }
            double u;
            cout_[opt.output] = limit(u_cmd, u);
            try {
                dev.write(cout_.data());
            } catch (const std::exception& e) {
                device_ok = false;
                abort_with(std::string("device write failed at sample ") + std::to_string(k) + ": " + e.what());
                error = std::current_exception();
                break;
            }
            ctl.applied(u);
            u_prev = u;
            if (!push(t, u, u_cmd, cout_[opt.output], late)) {
                abort_with(writer.error());
                break;
            }
            late_sum += late;
            res.max_lateness = std::max(res.max_lateness, late);
            ++k;
            progress_.store(k, std::memory_order_relaxed);
            if (rt && clock::now() > deadline + period_ns) {
                ++res.missed_deadlines;
                ++in_a_row;
                if (res.missed.size() < 1024) res.missed.push_back(k - 1);
                const auto over = [](std::size_t n, long long budget) { return budget >= 0 && (long long)n > budget; };
                if (over(in_a_row, safety.max_consecutive_missed)) {
                    abort_with(std::to_string(in_a_row) + " deadlines missed in a row exceed the budget of " +
                               std::to_string(safety.max_consecutive_missed) + " (stalled at sample " +
                               std::to_string(k - in_a_row) + ")");
                    break;
                }
                if (over(res.missed_deadlines, safety.max_missed_deadlines)) {
                    abort_with(std::to_string(res.missed_deadlines) + " missed deadlines exceed the budget of " +
                               std::to_string(safety.max_missed_deadlines) + " (last at sample " +
                               std::to_string(k - 1) + ")");
                    break;
                }
            } else {
                in_a_row = 0;
            }
        }
        if (end == End::running) {
            end = End::complete;
            next_slot = k;
        }
        res.samples = rows;
        res.mean_lateness = k ? late_sum / double(k) : 0.0;

        // Ramp the output to 0 V at ramp_rate, still sampling and logging.
        const bool ramp = device_ok && (end != End::complete || opt.ramp_at_end) && u_prev != 0.0;
        if (ramp) {
            const double step = safety.ramp_rate * opt.period;
            std::size_t j = next_slot;
            bool reading = true;
            while (u_prev != 0.0) {
                const auto deadline = t_start + period_ns * (long long)j;
                if (rt) wait_until(deadline);
                const double late = rt ? std::chrono::duration<double>(clock::now() - deadline).count() : 0.0;
                const double t = opt.t0 + double(j) * opt.period;
                bool valid = false;
                if (reading) {
                    try {
                        valid = read_inputs(j, t).empty();
                    } catch (...) {
                        reading = false;
                    }
                }
                const double u = std::abs(u_prev) <= step ? 0.0 : u_prev - std::copysign(step, u_prev);
                const double c = std::min(std::max(och.cal.connector(u), och.range_min), och.range_max);
                cout_[opt.output] = c;
                try {
                    dev.write(cout_.data());
                } catch (...) {
                    break;
                }
                u_prev = u;
                if (valid && !writer.failed()) {
                    if (push(t, u, 0.0, c, late)) ++res.ramp_samples;
                } else if (!valid) {
                    ++res.dropped;
                }
                ++j;
            }
        }
        dev.stop();
        res.final_output = u_prev;
        res.elapsed = std::chrono::duration<double>(clock::now() - wall0).count();
        res.reason = reason;
        res.end_status = end == End::complete      ? "complete"
                         : end == End::interrupted ? "interrupted"
                                                   : "aborted: " + reason;

        std::vector<MetaItem> trailer{{"samples", (long long)res.samples},
                                      {"ramp_samples", (long long)res.ramp_samples},
                                      {"dropped_samples", (long long)res.dropped},
                                      {"missed_deadlines", (long long)res.missed_deadlines},
                                      {"max_lateness", res.max_lateness},
                                      {"elapsed", res.elapsed},
                                      {"final_output", res.final_output}};
        if (!reason.empty()) trailer.emplace_back("end_reason", reason);
        trailer.emplace_back("end_status", res.end_status);
        try {
            writer.finish(trailer);
        } catch (...) {
            if (!error) error = std::current_exception();
        }
        stop_.store(false);  // a stop requested before or during this trial was consumed by it
        if (error) std::rethrow_exception(error);
        return res;
    }

private:
    std::atomic<bool> stop_{false};
    std::atomic<bool> running_{false};
    std::atomic<std::size_t> progress_{0};
    std::atomic<std::size_t> planned_{0};
    std::mutex mutex_;
    std::string stop_reason_ = "stop requested";
};

}  // namespace preisach::daq

// DAQ layer (preisach/daq): metadata formatting, the ring buffer, the streaming recording,
// the trial runner on the virtual rig (safety limits, aborts, stop requests, exceptions),
// the PI controller, and the Comedi device against a replayed comedilib protocol.
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <csignal>

#include <sys/resource.h>

#include <doctest/doctest.h>

#include <preisach/blocks.hpp>
#include <preisach/daq.hpp>

// One namespace per file: the unity build of the tests (CMakeLists.txt) compiles several
// files as one unit.
namespace unity_test_daq {

using namespace preisach::daq;
namespace pb = preisach::blocks;
using preisach::EverettTable;
using preisach::State;

namespace {

// A Preisach model on [-100, 100] V with uniform relay weights: output -3 ... 3 V.
std::shared_ptr<const EverettTable> ss15_like() {
    static const auto t = [] {
        const int n = 41;
        Eigen::VectorXd lv(n);
        for (int i = 0; i < n; ++i) lv[i] = -100.0 + 5.0 * i;
        preisach::RowMatrixXd w = preisach::RowMatrixXd::Zero(n - 1, n - 1);
        for (int i = 0; i < n - 1; ++i)
            for (int j = 0; j <= i; ++j) w(i, j) = 3.0 / (40.0 * 41.0 / 2.0);
        return std::make_shared<const EverettTable>(preisach::everett_from_weights(lv, w, -3.0));
    }();
    return t;
}

VirtualRig make_rig(double dt = 1e-3, double noise = 0.0) {
    std::vector<std::unique_ptr<pb::Block>> b;
    b.push_back(std::make_unique<pb::PreisachStage>(dt, ss15_like(), State::negative_saturation(-100, 100)));
    VirtualRigConfig cfg;
    cfg.sample_time = dt;
    cfg.adc_noise = noise;
    Channel out{"V_in", 1, -1, -10.0, 10.0, {-14.12, -0.02}, "V", 0};
    Channel in{"V_out", 1, -1, -5.0, 5.0, {1.0, 0.0}, "V", 0};
    return VirtualRig(pb::Chain(std::move(b)), cfg, out, in);
}

std::string tmpfile(const std::string& name) {
    const std::string p = "/tmp/preisach_test_daq_" + name + "_" + std::to_string(::getpid()) + ".csv";
    std::remove(p.c_str());
    return p;
}

std::vector<std::string> lines_of(const std::string& path) {
    std::ifstream f(path);
    std::vector<std::string> out;
    std::string l;
    while (std::getline(f, l)) out.push_back(l);
    return out;
}

std::size_t data_rows(const std::vector<std::string>& lines) {
    std::size_t n = 0;
    bool header = false;
    for (const auto& l : lines) {
        if (l.empty() || l[0] == '#') continue;
        if (!header) header = true;
        else ++n;
    }
    return n;
}

std::string trailer(const std::vector<std::string>& lines, const std::string& key) {
    for (auto it = lines.rbegin(); it != lines.rend(); ++it)
        if (it->rfind("# " + key + ":", 0) == 0) return it->substr(key.size() + 4);
    return "<missing>";
}

}  // namespace

TEST_CASE("metadata values are formatted like preisach.recording") {
    CHECK(format_meta_value(MetaValue{1e-3}) == "0.001");
    CHECK(format_meta_value(MetaValue{100.0}) == "100.0");
    CHECK(format_meta_value(MetaValue{-0.5}) == "-0.5");
    CHECK(format_meta_value(MetaValue{(long long)7}) == "7");
    CHECK(format_meta_value(MetaValue{std::string("complete")}) == "complete");
    CHECK(format_meta_value(MetaValue{std::string("aborted: x")}) == "aborted: x");
    CHECK(format_meta_value(MetaValue{std::string("007")}) == "\"007\"");
    CHECK(format_meta_value(MetaValue{std::string("nan")}) == "\"nan\"");
    CHECK(format_meta_value(MetaValue{std::string(" pad")}) == "\" pad\"");
    CHECK(format_meta_value(MetaValue{std::string("a\nb")}) == "\"a\\u000ab\"");
    CHECK(meta_lines({{"k", std::string("")}}) == "# k:\n");
    CHECK_THROWS_AS(meta_lines({{"1bad", 1.0}}), std::invalid_argument);
}

TEST_CASE("ring buffer: FIFO order across the wrap, full and empty") {
    RowRing r(4, 2);
    double row[2], out[8];
    for (int round = 0; round < 5; ++round) {
        for (int i = 0; i < 4; ++i) {
            row[0] = round * 10 + i;
            row[1] = -row[0];
            CHECK(r.try_push(row));
        }
        CHECK_FALSE(r.try_push(row));
        CHECK(r.pop(out, 3) == 3);
        CHECK(out[0] == round * 10);
        CHECK(out[5] == -(round * 10 + 2));
        CHECK(r.pop(out, 8) == 1);
        CHECK(out[0] == round * 10 + 3);
        CHECK(r.pop(out, 8) == 0);
    }
}

TEST_CASE("streaming recording: exact text, refuses to clobber") {
    const auto p = tmpfile("stream");
    {
        StreamingCsv w(p, {"t", "u", "y"}, {{"sample_time", 0.001}, {"experiment", std::string("x")}}, false, false, 8);
        for (int k = 0; k < 100; ++k) {
            const double row[3] = {k * 0.001, 0.1 * k, -1.0 / 3.0};
            while (!w.try_push(row)) std::this_thread::sleep_for(std::chrono::microseconds(10));
        }
        w.finish({{"end_status", std::string("complete")}});
        CHECK(w.rows_written() == 100);
    }
    const auto l = lines_of(p);
    REQUIRE(l.size() == 104);
    CHECK(l[0] == "# sample_time: 0.001");
    CHECK(l[1] == "# experiment: x");
    CHECK(l[2] == "t,u,y");
    CHECK(l[3] == "0,0,-0.3333333333333333");
    CHECK(l[5] == "0.002,0.2,-0.3333333333333333");
    CHECK(l.back() == "# end_status: complete");
    try {
        StreamingCsv again(p, {"t", "u", "y"}, {});
        FAIL("an existing file was overwritten");
    } catch (const RecordingIOError& e) {
        CHECK(e.error_code() == EEXIST);
        CHECK(std::string(e.what()).find(p) != std::string::npos);
    }
    std::remove(p.c_str());
}

TEST_CASE("runner on the virtual rig: every sample recorded, calibration applied, one-sample causality") {
    auto rig = make_rig();
    std::vector<double> w(500);
    for (std::size_t k = 0; k < w.size(); ++k) w[k] = 90.0 * std::sin(2 * M_PI * double(k) / 250.0);
    WaveformController ctl(w);
    TrialOptions opt;
    opt.path = tmpfile("run");
    opt.fsync = false;
    TrialRunner runner;
    const auto res = runner.run(rig, ctl, opt, Safety{});
    CHECK(res.end_status == "complete");
    CHECK(res.samples == 500);
    CHECK(res.ramp_samples == 0);
    CHECK(runner.progress() == 500);
    const auto l = lines_of(opt.path);
    CHECK(data_rows(l) == 500);
    CHECK(trailer(l, "end_status") == "complete");
    CHECK(trailer(l, "samples") == "500");
    // the DAC value is the inverse of Eq B.1b, and the rig's amplifier applies Eq B.1b
    CHECK(rig.last_output(0) == doctest::Approx((w.back() + 0.02) / -14.12));
    CHECK(rig.actuator_voltage() == doctest::Approx(w.back()).epsilon(1e-12));
    CHECK(res.final_output == doctest::Approx(w.back()));
    CHECK_FALSE(rig.busy());
    std::remove(opt.path.c_str());
}

TEST_CASE("real-time budget: a stall of many periods aborts, a lone late sample does not") {
    // A controller that blocks for 40 ms at sample 30 stalls the 1 kHz loop: every deadline
    // passed during the stall is missed in a row, exceeding the default budget of 20.
    auto rig = make_rig();
    const auto stall = [](std::size_t at, int ms) {
        return FunctionController(
            [at, ms](const SampleInfo& s) {
                if (s.k == at) std::this_thread::sleep_for(std::chrono::milliseconds(ms));
                return 0.0;
            },
            200);
    };
    TrialOptions opt;
    opt.path = tmpfile("stall");
    opt.fsync = false;
    opt.realtime = true;
    TrialRunner runner;
    auto ctl = stall(30, 40);
    const auto res = runner.run(rig, ctl, opt, Safety{});
    CHECK(res.end_status.rfind("aborted: 21 deadlines missed in a row exceed the budget of 20", 0) == 0);
    CHECK(res.missed_deadlines >= 21);
    CHECK(res.samples < 200);
    std::remove(opt.path.c_str());

    // The same stall with the in-a-row budget off and a total budget of the trial's length
    // completes; every miss is still counted.  (A budget of 100 aborted once on a machine
    // running four other jobs on its two cores: 101 misses, the stall's 40 and the load's.)
    Safety lenient;
    lenient.max_consecutive_missed = -1;
    lenient.max_missed_deadlines = 200;
    auto ctl2 = stall(30, 40);
    const auto res2 = runner.run(rig, ctl2, opt, lenient);
    CHECK(res2.end_status == "complete");
    CHECK(res2.missed_deadlines >= 30);
    std::remove(opt.path.c_str());

    Safety zero;
    zero.max_consecutive_missed = 0;
    CHECK_THROWS_AS(zero.validate(), std::invalid_argument);

    Safety fast_ramp;
    fast_ramp.slew_rate = 1e4;
    fast_ramp.ramp_rate = 2e4;
    CHECK_THROWS_AS(fast_ramp.validate(), std::invalid_argument);
    fast_ramp.ramp_rate = 1e4;  // equal is fine
    CHECK_NOTHROW(fast_ramp.validate());
}

TEST_CASE("runner safety: clamp and slew limit, NaN command aborts and ramps to 0 V") {
    auto rig = make_rig();
    // 300 V, far above the +/-135 V limit, as a step; NaN at sample 150
    FunctionController ctl([](const SampleInfo& s) { return s.k == 150 ? std::nan("") : 300.0; }, 200);
    TrialOptions opt;
    opt.path = tmpfile("safety");
    opt.fsync = false;
    Safety s;
    s.slew_rate = 20000.0;  // 20 V per 1 ms sample
    s.ramp_rate = 10000.0;  // 10 V per sample on the way down (at most the slew rate)
    TrialRunner runner;
    const auto res = runner.run(rig, ctl, opt, s);
    CHECK(res.end_status.rfind("aborted: controller returned a non-finite output at sample 150", 0) == 0);
    CHECK(res.samples == 151);                      // 150 applied + the sample that saw the NaN
    CHECK(res.ramp_samples == 14);                  // 135 V -> 0 V in steps of 10 V
    CHECK(res.final_output == 0.0);
    CHECK(rig.actuator_voltage() == doctest::Approx(0.0).epsilon(1e-12).scale(1.0));
    const auto l = lines_of(opt.path);
    // u column: 20, 40, ... then the 135 V clamp
    CHECK(l[l.size() - 1].rfind("# end_status: aborted:", 0) == 0);
    std::vector<double> u;
    for (const auto& line : l)
        if (!line.empty() && line[0] != '#' && line[0] != 't') u.push_back(std::stod(line.substr(line.find(',') + 1)));
    REQUIRE(u.size() == 165);
    for (std::size_t k = 1; k < u.size(); ++k) CHECK(std::abs(u[k] - u[k - 1]) <= 20.0 + 1e-9);
    CHECK(u[0] == doctest::Approx(-0.02 + 20.0));  // from the DAC at 0 V: V_in = -0.02 V
    for (std::size_t k = 151; k + 1 < u.size(); ++k) CHECK(u[k - 1] - u[k] == doctest::Approx(10.0));
    CHECK(u[149] == doctest::Approx(135.0));
    CHECK(u.back() == 0.0);
    std::remove(opt.path.c_str());
}

TEST_CASE("runner: stop request from another thread, output limits, exceptions rethrown after the file") {
    SUBCASE("stop request -> interrupted, paced in real time") {
        auto rig = make_rig();
        WaveformController ctl(std::vector<double>(100000, 20.0));
        TrialOptions opt;
        opt.path = tmpfile("stop");
        opt.fsync = false;
        opt.realtime = true;
        TrialRunner runner;
        std::atomic<bool> returned{false};  // never wait for progress a run that ended cannot make
        std::thread stopper([&] {
            while (runner.progress() < 50 && !returned.load())
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            runner.request_stop("test stop");
        });
        Safety safety;
        safety.max_consecutive_missed = -1;  // a loaded machine may stall the loop: not this test's point
        TrialResult res;
        try {
            res = runner.run(rig, ctl, opt, safety);
        } catch (...) {
            returned.store(true);
            stopper.join();
            throw;
        }
        returned.store(true);
        stopper.join();
        CHECK(res.end_status == "interrupted");
        CHECK(res.reason == "test stop");
        CHECK(res.samples >= 50);
        CHECK(res.samples < 100000);
        CHECK(res.realtime);
        CHECK(res.final_output == 0.0);
        const auto l = lines_of(opt.path);
        CHECK(data_rows(l) == res.samples + res.ramp_samples);
        CHECK(trailer(l, "end_reason") == "test stop");
        std::remove(opt.path.c_str());
    }
    SUBCASE("reading outside the input limits aborts") {
        auto rig = make_rig();
        WaveformController ctl(std::vector<double>(1000, 100.0));
        TrialOptions opt;
        opt.path = tmpfile("ylim");
        opt.fsync = false;
        Safety s;
        s.y_max = 1.0;
        TrialRunner runner;
        const auto res = runner.run(rig, ctl, opt, s);
        CHECK(res.end_status.find("outside the safety limits") != std::string::npos);
        CHECK(res.samples < 1000);
        std::remove(opt.path.c_str());
    }
    SUBCASE("a throwing controller: file finished, exception rethrown") {
        auto rig = make_rig();
        FunctionController ctl(
            [](const SampleInfo& s) -> double {
                if (s.k == 30) throw std::runtime_error("boom");
                return 10.0;
            },
            100);
        TrialOptions opt;
        opt.path = tmpfile("throw");
        opt.fsync = false;
        TrialRunner runner;
        CHECK_THROWS_WITH_AS(runner.run(rig, ctl, opt, Safety{}), "boom", std::runtime_error);
        const auto l = lines_of(opt.path);
        CHECK(trailer(l, "end_status") == "aborted: controller raised at sample 30: boom");
        CHECK(data_rows(l) >= 31);
        CHECK_FALSE(rig.busy());
        std::remove(opt.path.c_str());
    }
}

TEST_CASE("runner: a failing recording writer stops the loop at once and ramps the output to 0 V") {
    // A file-size limit makes write() fail with EFBIG after a few hundred rows, as a full disk
    // (ENOSPC) or a failing one (EIO) would: the writer thread fails while the loop runs.
    auto rig = make_rig();
    WaveformController ctl(std::vector<double>(100000, 50.0));  // 100 s at 1 kHz
    TrialOptions opt;
    opt.path = tmpfile("full");
    opt.fsync = false;
    opt.realtime = true;
    Safety safety;
    safety.max_consecutive_missed = -1;
    rlimit old{};
    REQUIRE(getrlimit(RLIMIT_FSIZE, &old) == 0);
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit small = old;
    small.rlim_cur = 16384;
    REQUIRE(setrlimit(RLIMIT_FSIZE, &small) == 0);
    TrialRunner runner;
    bool threw = false;
    int err = 0;
    const auto t0 = std::chrono::steady_clock::now();
    try {
        runner.run(rig, ctl, opt, safety);
    } catch (const RecordingIOError& e) {
        threw = true;
        err = e.error_code();
        CHECK(std::string(e.what()).find(opt.path) != std::string::npos);
    }
    const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, old_handler);
    CHECK(threw);
    CHECK(err == EFBIG);
    CHECK(took < 5.0);                             // not the 100 s the waveform asks for
    CHECK(rig.actuator_voltage() == 0.0);          // ramped down although nothing more is logged
    CHECK_FALSE(rig.busy());
    std::remove(opt.path.c_str());
}

TEST_CASE("PI controller regulates the virtual rig to the setpoint") {
    auto rig = make_rig(1e-3, 1e-3);
    std::vector<double> ff(3000, 0.0);
    PIController pi(2.0, 400.0, 1.0, 1e-3, ff, 500, 10);
    TrialOptions opt;
    opt.path = tmpfile("pi");
    opt.fsync = false;
    TrialRunner runner;
    const auto res = runner.run(rig, pi, opt, Safety{});
    CHECK(res.end_status == "complete");
    CHECK(rig.plant_output() == doctest::Approx(1.0).epsilon(0.01));
    CHECK(std::abs(pi.error()) < 0.01);
    std::remove(opt.path.c_str());
}

TEST_CASE("comedi device: replayed protocol of configuration, conversions, I/O and close") {
    // A 16-bit card: AO subdevice 1 (+/-10 V, hardcal), AI subdevice 0 (+/-5 V, softcal).
    const std::string protocol = R"(
        # configuration of the output channel
        open /dev/comedi0 -> 1
        board_name -> pci-multiq
        find_subdevice_by_type 2 0 -> 1
        get_n_channels 1 -> 4
        find_range 1 1 -10 10 -> 0
        get_maxdata 1 1 -> 65535
        get_subdevice_flags 1 -> 0
        hardcal_converter 1 1 0 from -> 0 : 1 -10 0 3276.75
        # configuration of the input channel (software-calibrated)
        find_subdevice_by_type 1 0 -> 0
        get_n_channels 0 -> 8
        find_range 0 1 -5 5 -> 2
        get_maxdata 0 1 -> 65535
        get_subdevice_flags 0 -> 8192
        load_calibration -> 1
        softcal_converter 0 1 2 to -> 0 : 1 32767.5 0.001 0.00015259
        # two samples
        data_read 0 1 2 0 -> 0 39321
        data_write 1 1 0 0 32768 -> 0
        data_read 0 1 2 0 -> 0 0
        data_write 1 1 0 0 36044 -> 0
    )";
    // close: the output ramps from 1 V to 0 V at the connector at the default 500 V/s at the
    // actuator (gain -14.12: 35.41 V/s at the connector, 35.41 mV per 1 ms write), so
    // ceil(1 / 0.035411) = 29 writes of 1 V * (29 - s) / 29, the last exactly 0 V (code 32768).
    std::string closing;
    for (int s = 1; s <= 29; ++s) {
        const double v = 1.0 * (29 - s) / 29.0;
        closing += "data_write 1 1 0 0 " + std::to_string(unsigned(std::nearbyint(3276.75 * (v + 10.0)))) + " -> 0\n";
    }
    closing += "close ->\n";
    auto api = std::make_unique<ComediReplay>(protocol + closing);
    Channel out{"V_in", 1, -1, -10.0, 10.0, {-14.12, -0.02}, "V", 0};
    Channel in{"V_out", 1, -1, -5.0, 5.0, {1.0, 0.0}, "V", 0};
    {
        ComediDevice dev(std::move(api), "/dev/comedi0", {out}, {in});
        CHECK(dev.description() == "comedi /dev/comedi0 (pci-multiq)");
        CHECK(dev.conversions() == std::vector<std::string>{"hardcal", "softcal"});
        CHECK(dev.outputs()[0].subdevice == 1);
        double v = 0;
        dev.read(&v);
        CHECK(v == doctest::Approx(0.001 + 0.00015259 * (39321 - 32767.5)));
        const double zero = 0.0, one = 1.0;
        dev.write(&zero);  // 3276.75 * (0 V + 10) = 32767.5 -> 32768 (round half to even)
        dev.read(&v);
        CHECK(std::isnan(v));  // code 0: out of range
        dev.write(&one);   // 3276.75 * (1 V + 10) = 36044.25 -> 36044
        CHECK(dev.close_ramp_steps() == 29);
        dev.close();
        auto& replay = static_cast<ComediReplay&>(dev.api());
        CHECK_NOTHROW(replay.verify());
        CHECK(replay.paused() == doctest::Approx(28 * 1e-3));  // one period between writes
        CHECK_FALSE(dev.is_open());
        CHECK_NOTHROW(dev.close());  // idempotent: no further calls
    }
}

// Forwards every call to a shared replay, so the protocol can be checked after the device
// (which owns its interface) is destroyed.
struct SpyApi final : ComediApi {
    explicit SpyApi(std::shared_ptr<ComediReplay> r) : r_(std::move(r)) {}
    bool open(const std::string& f) override { return r_->open(f); }
    void close() override { r_->close(); }
    std::string error() override { return r_->error(); }
    std::string board_name() override { return r_->board_name(); }
    int find_subdevice_by_type(int t, unsigned s) override { return r_->find_subdevice_by_type(t, s); }
    int get_subdevice_type(unsigned s) override { return r_->get_subdevice_type(s); }
    int get_subdevice_flags(unsigned s) override { return r_->get_subdevice_flags(s); }
    int get_n_channels(unsigned s) override { return r_->get_n_channels(s); }
    long long get_maxdata(unsigned s, unsigned c) override { return r_->get_maxdata(s, c); }
    int find_range(unsigned s, unsigned c, double lo, double hi) override { return r_->find_range(s, c, lo, hi); }
    bool load_calibration(const std::string& p) override { return r_->load_calibration(p); }
    int softcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        return r_->softcal_converter(s, c, r, to, p);
    }
    int hardcal_converter(unsigned s, unsigned c, unsigned r, bool to, ComediPoly& p) override {
        return r_->hardcal_converter(s, c, r, to, p);
    }
    int data_read(unsigned s, unsigned c, unsigned r, unsigned a, unsigned& d) override {
        return r_->data_read(s, c, r, a, d);
    }
    int data_write(unsigned s, unsigned c, unsigned r, unsigned a, unsigned d) override {
        return r_->data_write(s, c, r, a, d);
    }
    double to_physical(unsigned d, const ComediPoly& p) override { return r_->to_physical(d, p); }
    unsigned from_physical(double v, const ComediPoly& p) override { return r_->from_physical(v, p); }
    void pause(double seconds) override { r_->pause(seconds); }

private:
    std::shared_ptr<ComediReplay> r_;
};

TEST_CASE("comedi device: close ramps every output to 0 V no faster than the ramp rate") {
    // Two outputs on a 12-bit AO subdevice (+/-10 V, 204.75 codes per volt), one input.
    // One channel's configuration: subdevice of `type` (2 AO, 1 AI), hardware calibration.
    auto channel = [](int type, int sub, int chan, int n_chan, int lo, int hi, int maxdata,
                      const std::string& conversion) {
        const std::string sc = std::to_string(sub) + " " + std::to_string(chan);
        return "find_subdevice_by_type " + std::to_string(type) + " 0 -> " + std::to_string(sub) + "\n" +
               "get_n_channels " + std::to_string(sub) + " -> " + std::to_string(n_chan) + "\n" +
               "find_range " + sc + " " + std::to_string(lo) + " " + std::to_string(hi) + " -> 0\n" +
               "get_maxdata " + sc + " -> " + std::to_string(maxdata) + "\n" +
               "get_subdevice_flags " + std::to_string(sub) + " -> 0\n" +
               "hardcal_converter " + sc + " 0 " + conversion + "\n";
    };
    const std::string setup = "open /dev/comedi0 -> 1\nboard_name -> b\n" +
                              channel(2, 1, 0, 4, -10, 10, 4095, "from -> 0 : 1 -10 0 204.75") +
                              channel(2, 1, 1, 4, -10, 10, 4095, "from -> 0 : 1 -10 0 204.75") +
                              channel(1, 0, 0, 8, -5, 5, 8191, "to -> 0 : 1 0 -5 0.001220703125");
    Channel a{"A", 0, -1, -10.0, 10.0, {-14.12, -0.02}, "V", 0};  // the SS15 amplifier
    Channel b{"B", 1, -1, -10.0, 10.0, {1.0, 0.0}, "V", 0};       // unit gain
    Channel in{"y", 0, -1, -5.0, 5.0, {1.0, 0.0}, "V", 0};
    auto code = [](double v) { return unsigned(std::nearbyint(204.75 * (v + 10.0))); };
    // One write of both outputs (connector volts), as the device issues it.
    auto writes = [&](double va, double vb) {
        return "data_write 1 0 0 0 " + std::to_string(code(va)) + " -> 0\ndata_write 1 1 0 0 " +
               std::to_string(code(vb)) + " -> 0\n";
    };
    // A at -2 V and B at +0.5 V (connector); 100 V/s at the actuator, a write every 2 ms:
    // A may move 0.2 / 14.12 = 14.2 mV per write -> ceil(2 / 0.014164) = 142 writes; B (0.2 V per
    // write) alone would need 3, but both move together in A's 142 steps.
    const int n = 142;
    std::string protocol = setup + writes(-2.0, 0.5);
    for (int s = 1; s <= n; ++s) protocol += writes(-2.0 * (n - s) / n, 0.5 * (n - s) / n);
    protocol += "close ->\n";
    ComediOptions opt;
    opt.close_ramp_rate = 100.0;
    opt.close_ramp_period = 2e-3;
    {
        ComediDevice dev(std::make_unique<ComediReplay>(protocol), "/dev/comedi0", {a, b}, {in}, opt);
        const double v[2] = {-2.0, 0.5};
        dev.write(v);
        CHECK(dev.close_ramp_steps() == n);
        dev.close();
        auto& replay = static_cast<ComediReplay&>(dev.api());
        CHECK_NOTHROW(replay.verify());
        CHECK(replay.paused() == doctest::Approx((n - 1) * 2e-3));
        // The codes written after the trial: monotone to 0 V, no step above the rate (+1 code of
        // rounding), the last one exactly 0 V.
        const auto calls = replay.log();
        std::vector<long> codes_a;
        for (std::size_t i = calls.size() - 1 - 2 * n; i + 1 < calls.size(); i += 2)
            codes_a.push_back(std::stol(calls[i].substr(calls[i].rfind(' '))));
        REQUIRE(codes_a.size() == std::size_t(n));
        long prev = long(code(-2.0));
        const double max_codes = 100.0 * 2e-3 / 14.12 * 204.75 + 1.0;
        for (long c : codes_a) {
            CHECK(c >= prev);
            CHECK(double(c - prev) <= max_codes);
            prev = c;
        }
        CHECK(codes_a.back() == long(code(0.0)));
    }
    // The destructor ramps too: 0.1 V at A with 1000 V/s and 1 ms is 1 / 14.12 = 70.8 mV per
    // write -> 2 writes.  A spy keeps the replay alive after the device is gone.
    {
        const std::string p = setup + writes(0.1, 0.0) + writes(0.05, 0.0) + writes(0.0, 0.0) + "close ->\n";
        auto replay = std::make_shared<ComediReplay>(p);
        ComediOptions fast;
        fast.close_ramp_rate = 1000.0;
        {
            ComediDevice dev(std::make_unique<SpyApi>(replay), "/dev/comedi0", {a, b}, {in}, fast);
            const double v[2] = {0.1, 0.0};
            dev.write(v);
            CHECK(replay->consumed() == replay->size() - 5);
        }
        CHECK_NOTHROW(replay->verify());
        CHECK(replay->paused() == doctest::Approx(1e-3));
    }
    ComediOptions bad;
    bad.close_ramp_rate = 0.0;
    CHECK_THROWS_WITH_AS(ComediDevice(std::make_unique<ComediReplay>(setup), "/dev/comedi0", {a, b}, {in}, bad),
                         "comedi: close_ramp_rate must be a positive finite number of V/s, got 0.000000",
                         std::invalid_argument);
}

TEST_CASE("comedi device: protocol mismatch and a missing device file are clear errors") {
    Channel out{"V_in", 1, -1, -10.0, 10.0, {-14.12, -0.02}, "V", 0};
    Channel in{"V_out", 1, -1, -5.0, 5.0, {1.0, 0.0}, "V", 0};
    auto missing = std::make_unique<ComediReplay>("open /dev/comedi7 -> -1 : No such file or directory\n");
    try {
        ComediDevice dev(std::move(missing), "/dev/comedi7", {out}, {in});
        FAIL("no error");
    } catch (const DeviceError& e) {
        CHECK(std::string(e.what()) == "cannot open Comedi device '/dev/comedi7': No such file or directory");
    }
    auto wrong = std::make_unique<ComediReplay>("open /dev/comedi0 -> 1\nboard_name -> b\nget_n_channels 1 -> 4\n");
    CHECK_THROWS_WITH_AS(ComediDevice(std::move(wrong), "/dev/comedi0", {out}, {in}),
                         "comedi protocol step 3: expected 'get_n_channels 1', got 'find_subdevice_by_type 2 0'",
                         std::logic_error);
    auto nochan = std::make_unique<ComediReplay>(
        "open /dev/comedi0 -> 1\nboard_name -> b\nfind_subdevice_by_type 2 0 -> 1\nget_n_channels 1 -> 1\nclose ->\n");
    CHECK_THROWS_WITH_AS(ComediDevice(std::move(nochan), "/dev/comedi0", {out}, {in}),
                         "'/dev/comedi0' analog output channel 'V_in': channel 1 does not exist (subdevice 1 has 1 "
                         "channels)",
                         DeviceError);
    if (comedi_available()) {
        try {
            ComediDevice dev(make_comedilib_api("/nonexistent/comedi9"), "/nonexistent/comedi9", {out}, {in});
            FAIL("no error");
        } catch (const DeviceError& e) {
            CHECK(std::string(e.what()).find("'/nonexistent/comedi9'") != std::string::npos);
        }
    } else {
        CHECK_THROWS_AS(make_comedilib_api("/dev/comedi0"), DeviceError);
    }
}

}  // namespace unity_test_daq

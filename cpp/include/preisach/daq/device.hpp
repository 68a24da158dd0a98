// The device interface of the DAQ layer: analog outputs and inputs in connector volts.
#pragma once

#include <atomic>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "channel.hpp"

namespace preisach::daq {

// Errors talking to hardware (device file missing, driver call failed); Python sees them as
// preisach.errors.DeviceError (an OSError).
class DeviceError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// A DAQ device sampled by the trial runner.  All values are connector volts; the channels
// carry the calibrations to physical units, which the runner applies.  The runner calls,
// for every sample k: read() (the inputs at t_k), then write() (the outputs from t_k on).
// A simulated device advances its model in write(), over one sample period with the output
// held, so read() at t_{k+1} sees the response to the output written at t_k -- exactly the
// one-sample causality of a real clocked loop.
class Device {
public:
    virtual ~Device() = default;

    // Human-readable identity ("virtual SS15 ...", "comedi /dev/comedi0 (board ...)").
    virtual std::string description() const = 0;
    // True when the device is a simulation that may run faster than real time.
    virtual bool simulated() const = 0;
    virtual const std::vector<Channel>& outputs() const = 0;
    virtual const std::vector<Channel>& inputs() const = 0;
    // Prepare to sample every `period` seconds (throws std::invalid_argument if the device
    // cannot, e.g. a simulation built for another sample time).
    virtual void start(double period) = 0;
    // Read every input channel into volts[0 .. inputs().size()); a converter reading at the
    // end of its range (saturated) is reported as NaN.
    virtual void read(double* volts) = 0;
    // Set every output channel from volts[0 .. outputs().size()).
    virtual void write(const double* volts) = 0;
    // Called after the last sample; outputs keep their last value.
    virtual void stop() {}
    // The connector volts last written to output i (0 before any write).
    double last_output(std::size_t i) const { return i < last_.size() ? last_[i] : 0.0; }

    // A device serves one trial at a time; the runner claims it for the duration.
    bool busy() const noexcept { return busy_.load(); }
    void claim(const std::string& who) {
        bool expected = false;
        if (!busy_.compare_exchange_strong(expected, true))
            throw std::runtime_error(description() + " is already in use by a running trial (" + who + ")");
    }
    void release() noexcept { busy_.store(false); }

protected:
    std::vector<double> last_;  // subclasses keep it sized to outputs()

private:
    std::atomic<bool> busy_{false};
};

}  // namespace preisach::daq

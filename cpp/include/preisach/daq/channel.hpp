// Analog channels of a DAQ device: connector-volt range and linear calibration.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace preisach::daq {

// Linear calibration of a channel: physical = gain * connector + offset (the
// preisach.calibration.LinearCalibration of Python; e.g. the SS15's channel B amplifier,
// Eq B.1b: V_in = -14.12 V_bin - 0.02).  "Connector" volts are what the card sets or reads;
// "physical" units are what is really applied or measured (volts at the actuator, volts
// out of the strain-gauge amplifier).
struct LinearCal {
    double gain = 1.0;
    double offset = 0.0;

    double physical(double connector) const noexcept { return gain * connector + offset; }
    double connector(double physical) const noexcept { return (physical - offset) / gain; }
    void validate(const std::string& where) const {
        if (!std::isfinite(gain) || gain == 0.0)
            throw std::invalid_argument(where + ": calibration gain must be finite and non-zero, got " +
                                        std::to_string(gain));
        if (!std::isfinite(offset))
            throw std::invalid_argument(where + ": calibration offset must be finite, got " + std::to_string(offset));
    }
};

// One analog channel.  `channel` is the card's channel number, `subdevice` the Comedi
// subdevice (-1: the first analog input/output subdevice), `range_min/range_max` the
// connector-volt range the converter is set to, `aref` the Comedi analog reference
// (0 ground, 1 common, 2 differential).
struct Channel {
    std::string name;
    unsigned channel = 0;
    int subdevice = -1;
    double range_min = -10.0;
    double range_max = 10.0;
    LinearCal cal{};
    std::string unit = "V";
    unsigned aref = 0;

    void validate(const std::string& kind) const {
        const std::string where = kind + " channel '" + name + "'";
        if (name.empty()) throw std::invalid_argument(kind + " channel " + std::to_string(channel) + ": name is empty");
        if (!(std::isfinite(range_min) && std::isfinite(range_max) && range_min < range_max))
            throw std::invalid_argument(where + ": range [" + std::to_string(range_min) + ", " +
                                        std::to_string(range_max) + "] V must be finite with min < max");
        if (aref > 3) throw std::invalid_argument(where + ": aref must be 0..3, got " + std::to_string(aref));
        cal.validate(where);
    }
    // Physical values at the two ends of the connector range (ordered low, high).
    double physical_low() const noexcept { return std::min(cal.physical(range_min), cal.physical(range_max)); }
    double physical_high() const noexcept { return std::max(cal.physical(range_min), cal.physical(range_max)); }
};

}  // namespace preisach::daq

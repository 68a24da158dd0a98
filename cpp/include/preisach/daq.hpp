// Umbrella header of the DAQ layer (pure C++, no Python).
#pragma once

#include "daq/channel.hpp"
#include "daq/comedi.hpp"
#include "daq/comedi_lib.hpp"
#include "daq/controller.hpp"
#include "daq/device.hpp"
#include "daq/recording_file.hpp"
#include "daq/ring_buffer.hpp"
#include "daq/runner.hpp"
#include "daq/virtual_rig.hpp"

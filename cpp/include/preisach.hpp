// Umbrella header of the preisach C++ core.
#pragma once

#include "preisach/batch.hpp"
#include "preisach/everett.hpp"
#include "preisach/memory.hpp"
#include "preisach/simulator.hpp"
#include "preisach/types.hpp"

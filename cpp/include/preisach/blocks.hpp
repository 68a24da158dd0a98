// Umbrella header of the physics blocks (pure C++, no Python).
#pragma once

#include "blocks/block.hpp"
#include "blocks/chain.hpp"
#include "blocks/creep.hpp"
#include "blocks/drift.hpp"
#include "blocks/filters.hpp"
#include "blocks/linear.hpp"
#include "blocks/preisach_stage.hpp"
#include "blocks/rate_stage.hpp"
#include "blocks/rng.hpp"

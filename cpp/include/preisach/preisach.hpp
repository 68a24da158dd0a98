// Umbrella header of the preisach C++ core (pure C++17 + Eigen, no Python).
//
// Conventions everywhere: volts in, volts out, seconds; a relay gamma(alpha, beta) switches up
// at alpha and down at beta, alpha >= beta; r = (alpha - beta)/2, s = (alpha + beta)/2.
//
//   everett.hpp    Everett function E(alpha, beta) tabulated on a triangular grid
//   memory.hpp     State: the Preisach boundary psi (reduced memory sequence)
//   simulator.hpp  boundary-tracking simulator, read-out Gamma, slopes (Appendix A)
//   batch.hpp      many simulations on all cores
//   identify.hpp   Mayergoyz identification (FOD grid -> Everett table, weights mu, kappa)
//   regressor.hpp  the output as a linear function of the Everett table (least squares)
//   neutral.hpp    locus of neutral states N(l) and its inverse (Eq 2.18-2.20)
//   inverse.hpp    exact inverse: the input that drives the output to a target (feedforward)
//   control.hpp    discrete PI regulation of a model (chapter 5)
//   play.hpp, moving.hpp   rate-dependent play and output-feedback (moving) models, for diagnosis
//   rate_dependent.hpp  K Everett tables blended by a filtered input rate, one shared boundary
//   blocks.hpp     physics blocks of the virtual rig (structural mode, creep, delay, ...)
//   daq.hpp        DAQ layer: devices, calibration, virtual SS15, Comedi, trial runner
#pragma once

#include "batch.hpp"
#include "blocks.hpp"
#include "control.hpp"
#include "daq.hpp"
#include "everett.hpp"
#include "feedback_scan.hpp"
#include "identify.hpp"
#include "inverse.hpp"
#include "memory.hpp"
#include "moving.hpp"
#include "neutral.hpp"
#include "play.hpp"
#include "rate_dependent.hpp"
#include "regressor.hpp"
#include "simulator.hpp"
#include "types.hpp"

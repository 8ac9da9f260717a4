// A/B mode (BLOCKSTEP_AB=file.csv under LD_PRELOAD): every step of every
// world of an unmodified ODE program is taken by ODE's quickstep and by
// blockstep from the same saved state, then once more by the stepper the
// program chose (unless that was the last of the two), so the program
// goes on exactly as without A/B mode, and a CSV row per step gives both
// steppers' solve time, joint separation and kinetic energy, and how far
// their velocities ended apart. `blockstep-compare --ab file.csv` turns
// the file into the comparison's summary and report.
#pragma once

#include <ode/ode.h>

#include "adapters/ode/world_bridge.h"

namespace blockstep::plugin {

// What the program asked for: its step is the one whose result it keeps.
enum class AbChoice { QuickStep, Step, Blockstep };

// BLOCKSTEP_AB names a file that could be opened for writing.
bool abMode();

// One A/B step of w (see above). `odeStepper` is the ODE stepper the
// program called (blockstep follows its settings, as in blockStep()).
int abStep(dWorldID w, dReal h, AbChoice chosen, ode::OdeStepper odeStepper);

}  // namespace blockstep::plugin

// The rows an ODE program wrote under BLOCKSTEP_AB (plugin/ab_mode.h),
// read back as one quickstep run and one blockstep run per world of the
// program, each step a frame: what blockstep-compare --ab reports.
#pragma once

#include <string>
#include <vector>

#include "compare/ode/runner.h"

namespace blockstep::compare {

struct AbWorld {
  int world = 0;        // the program's world, numbered by its first step
  std::string kept;     // the stepper the program ran (quickstep, blockstep, dWorldStep)
  double dt = 0.0;      // the program's step (the first row's)
  RunResult quickstep;  // scene "<name>_world<N>"
  RunResult blockstep;
  double maxSpeedDifference = 0.0;  // m/s, the largest body's, over the steps
};

// Throws std::invalid_argument naming the line and column that is wrong.
std::vector<AbWorld> readAbFile(const std::string& path, const std::string& name);

}  // namespace blockstep::compare

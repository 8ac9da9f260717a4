// Convergence from one saved state: how a scene's constraint error falls
// with the sweeps (iterations) one step is given, every solver starting
// from the same bodies, velocities and contacts.
#pragma once

#include <string>
#include <vector>

#include "compare/ode/scene.h"

namespace blockstep::compare {

struct ConvergenceOptions {
  int atFrame = 60;        // the saved state: this many frames of quickstep 20 x 10
  int maxSweeps = 50;      // n = 1..maxSweeps
  double dt = 1.0 / 60.0;  // the one step taken from the saved state
  // The converged step is dWorldStep's up to this many joint rows in an
  // island, else blockstep's block solver given 20 x maxSweeps sweeps.
  int directRowLimit = 3000;
};

// Per sweep count n (index n - 1): how far the velocities one step of dt
// with n sweeps gives are from the converged step's (the largest body's
// speed difference, m/s), and blockstep's own residual after sweep n of
// one step given maxSweeps. Every solver solves the same rows (ODE's ERP
// and CFM; blockstep's paper solver), so all converge to the same step.
struct ConvergenceResult {
  std::string scene;
  std::string reference;              // what the converged step is
  std::vector<double> quickstep;      // dWorldQuickStep, n iterations
  std::vector<double> blockstep;      // blockstep's paper solver, n block sweeps
  std::vector<double> blockstepRows;  // the same, row by row
  // The same with island blocks (an island's joint equality rows up to
  // 192 solved as one exact block, as the sub-stepped solver does).
  std::vector<double> blockstepIsland;
  std::vector<double> residualMax;  // blockstep's residual after sweep n, m/s
  std::vector<double> residualRms;
  double startSeparation = 0.0;  // the saved state's largest joint separation, m
  int contacts = 0;              // contacts in the step
};

// Steps the scene to the saved state with quickstep 20 x 10 (collision
// each sub-step), then takes the one step from it again and again.
// Warm starting is off for blockstep (quickstep has none), so every
// solve starts from zero impulses. Throws std::invalid_argument for bad
// options.
ConvergenceResult convergence(Scene& scene, const ConvergenceOptions& options);

}  // namespace blockstep::compare

// Convergence from one saved state (convergence.h).
#include "compare/ode/convergence.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "adapters/ode/body_state.h"
#include "blockstep/blockstep_ode.h"
#include "compare/ode/runner.h"

namespace blockstep::compare {

namespace {

std::vector<ode::OdeBodyState> save(const Scene& scene) {
  std::vector<ode::OdeBodyState> state;
  for (dBodyID b : scene.bodies())
    state.push_back(ode::OdeBodyState::of(b));
  return state;
}

// Back to the saved state, forces cleared and every body awake.
void restore(const std::vector<ode::OdeBodyState>& state) {
  for (const ode::OdeBodyState& s : state) {
    s.putBack();
    dBodySetForce(s.body, 0, 0, 0);
    dBodySetTorque(s.body, 0, 0, 0);
    dBodyEnable(s.body);
  }
}

enum class Solve { Quick, Block, BlockRows, BlockIsland, Direct };

// The bodies' linear velocities after one step of dt from the saved state
// with n sweeps.
std::vector<double> stepFrom(Scene& scene, const std::vector<ode::OdeBodyState>& state, Solve solve,
                             int n, double dt, bool recordResiduals = false) {
  restore(state);
  const dWorldID w = scene.world();
  scene.collide();
  if (solve == Solve::Quick) {
    dWorldSetQuickStepNumIterations(w, n);
    dRandSetSeed(0);  // quickstep shuffles its rows with ODE's random numbers
    dWorldQuickStep(w, dt);
  } else if (solve == Solve::Direct) {
    dWorldStep(w, dt);
  } else {
    dWorldSetBlockPaperSolver(w, n);
    dWorldSetBlockWarmStarting(w, 0);
    dWorldSetBlockContactPersistence(w, 0.0);
    dWorldSetBlockMode(w, solve == Solve::BlockRows ? dBlockModeRowByRow : dBlockModeBlock);
    // The sub-stepped solver's island blocks (192 rows), or none as the
    // paper has it.
    dWorldSetBlockIslandBlockRows(w, solve == Solve::BlockIsland ? 192 : 0);
    dWorldSetBlockRecordResiduals(w, recordResiduals ? 1 : 0);
    dWorldBlockStep(w, dt);
  }
  scene.clearContacts();
  std::vector<double> v;
  for (dBodyID b : scene.bodies())
    for (int k = 0; k < 3; ++k)
      v.push_back(dBodyGetLinearVel(b)[k]);
  return v;
}

// The largest body's speed difference between two results.
double farthest(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i + 2 < a.size(); i += 3)
    worst = std::max(worst, std::hypot(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]));
  return worst;
}

}  // namespace

ConvergenceResult convergence(Scene& scene, const ConvergenceOptions& options) {
  if (options.atFrame < 0 || options.maxSweeps < 1 || options.maxSweeps > 10000 ||
      !(options.dt > 0.0) || options.dt > 1.0)
    throw std::invalid_argument(
        "a convergence study needs a frame >= 0, 1 to 10000 sweeps and 0 < dt <= 1 s");
  const dWorldID w = scene.world();
  ConvergenceResult r;
  r.scene = scene.name();
  // The saved state: quickstep 20 with 10 sub-steps, each colliding.
  dWorldSetQuickStepNumIterations(w, 20);
  dRandSetSeed(0);
  for (int f = 0; f < options.atFrame; ++f) {
    for (int k = 0; k < 10; ++k) {
      scene.collide();
      dWorldQuickStep(w, options.dt / 10);
      scene.clearContacts();
    }
  }
  const std::vector<ode::OdeBodyState> state = save(scene);
  r.startSeparation = scene.jointError().separation;
  scene.collide();
  r.contacts = scene.contactCount();
  scene.clearContacts();

  // The converged step: ODE's exact LCP where its dense solve is quick,
  // else blockstep's block solver given 20 times the sweeps.
  std::vector<double> exact;
  // Contacts count three rows each (normal, two friction directions): a
  // settled pyramid's 1660 contacts took dWorldStep over three minutes.
  if (largestIslandRows(scene) + 3 * r.contacts <= options.directRowLimit) {
    exact = stepFrom(scene, state, Solve::Direct, 0, options.dt);
    r.reference = "dWorldStep";
  } else {
    exact = stepFrom(scene, state, Solve::Block, 20 * options.maxSweeps, options.dt);
    r.reference = "blockstep, " + std::to_string(20 * options.maxSweeps) + " block sweeps";
  }
  for (int n = 1; n <= options.maxSweeps; ++n) {
    r.quickstep.push_back(farthest(stepFrom(scene, state, Solve::Quick, n, options.dt), exact));
    r.blockstep.push_back(farthest(stepFrom(scene, state, Solve::Block, n, options.dt), exact));
    r.blockstepRows.push_back(
        farthest(stepFrom(scene, state, Solve::BlockRows, n, options.dt), exact));
    r.blockstepIsland.push_back(
        farthest(stepFrom(scene, state, Solve::BlockIsland, n, options.dt), exact));
  }
  // blockstep's own residual, sweep by sweep, in one step given them all.
  stepFrom(scene, state, Solve::Block, options.maxSweeps, options.dt, true);
  dWorldSetBlockRecordResiduals(w, 0);
  r.residualMax.resize(options.maxSweeps);
  r.residualRms.resize(options.maxSweeps);
  const int recorded = dWorldGetBlockResidualHistory(w, r.residualMax.data(), r.residualRms.data(),
                                                     options.maxSweeps);
  r.residualMax.resize(std::min(recorded, options.maxSweeps));
  r.residualRms.resize(r.residualMax.size());
  restore(state);
  return r;
}

}  // namespace blockstep::compare

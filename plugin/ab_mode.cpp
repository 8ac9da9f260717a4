// A/B mode (ab_mode.h).
#include "plugin/ab_mode.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <mutex>
#include <vector>

#include "adapters/ode/body_state.h"
#include "adapters/ode/registry.h"
#include "plugin/plugin_state.h"

namespace blockstep::plugin {

namespace {

using Clock = std::chrono::steady_clock;

// A body as a step found it: pose, velocities, the forces the program
// added for this step (ODE clears them when it steps) and whether it was
// enabled (ODE's auto-disable may change that).
struct SavedBody {
  ode::OdeBodyState state;
  dVector3 force{}, torque{};
  bool enabled = true;
};

// What one stepper's step gave.
struct Outcome {
  double seconds = 0.0;
  double maxSeparation = 0.0, rmsSeparation = 0.0;
  double kineticEnergy = 0.0;
  int stepped = 0;  // the stepper's return value
};

struct AbFile {
  std::FILE* file = nullptr;
  bool failed = false;
  std::mutex mutex;
  // Worlds by first step (their number in the file) and steps so far.
  std::vector<dWorldID> worlds;
  std::vector<long> steps;
};

AbFile& abFile() {
  static AbFile* f = [] {
    auto* made = new AbFile();
    const char* path = std::getenv("BLOCKSTEP_AB");
    if (!path || !*path) return made;
    made->file = std::fopen(path, "w");
    if (!made->file) {
      say("BLOCKSTEP_AB=%s: cannot write the file; A/B mode off", path);
      made->failed = true;
      return made;
    }
    std::fprintf(made->file,
                 "world,step,h,kept,quickstep_ms,quickstep_max_separation_m,"
                 "quickstep_rms_separation_m,quickstep_kinetic_j,blockstep_ms,"
                 "blockstep_max_separation_m,blockstep_rms_separation_m,blockstep_kinetic_j,"
                 "speed_difference_m_s,bodies,joints,contacts\n");
    std::atexit([] {
      if (abFile().file) std::fflush(abFile().file);
    });
    return made;
  }();
  return *f;
}

// The world's bodies and joints, copied from the registry (the steps
// below call into the plugin, which takes the world's lock itself).
void listWorld(dWorldID w, std::vector<dBodyID>& bodies, std::vector<dJointID>& joints) {
  bodies.clear();
  joints.clear();
  if (const std::shared_ptr<ode::WorldRecord> record = ode::Registry::instance().world(w)) {
    std::lock_guard lock(record->mutex);
    bodies.assign(record->bodies.begin(), record->bodies.end());
    joints.assign(record->joints.begin(), record->joints.end());
  }
}

void save(const std::vector<dBodyID>& bodies, std::vector<SavedBody>& saved) {
  saved.clear();
  for (dBodyID b : bodies) {
    SavedBody s;
    s.state = ode::OdeBodyState::of(b);
    for (int k = 0; k < 3; ++k) {
      s.force[k] = dBodyGetForce(b)[k];
      s.torque[k] = dBodyGetTorque(b)[k];
    }
    s.enabled = dBodyIsEnabled(b) != 0;
    saved.push_back(s);
  }
}

// Put back through ODE's setters: ODE normalizes the orientation it is
// given, which can move the last bits of a quaternion it had normalized
// itself, so the kept step starts from the saved state to rounding. A
// stable scene agrees with a run without A/B mode to rounding; a chaotic
// one (a chain flying apart under quickstep) drifts from it in time.
void restore(const std::vector<SavedBody>& saved) {
  for (const SavedBody& s : saved) {
    s.state.putBack();
    dBodySetForce(s.state.body, s.force[0], s.force[1], s.force[2]);
    dBodySetTorque(s.state.body, s.torque[0], s.torque[1], s.torque[2]);
    if (s.enabled)
      dBodyEnable(s.state.body);
    else
      dBodyDisable(s.state.body);
  }
}

// The gap between a joint's two anchors (each body's own), for the joint
// kinds ODE gives both of; false for the others.
bool anchorGap(dJointID j, double& gap) {
  dVector3 a1, a2;
  switch (dJointGetType(j)) {
    case dJointTypeBall:
      dJointGetBallAnchor(j, a1);
      dJointGetBallAnchor2(j, a2);
      break;
    case dJointTypeHinge:
      dJointGetHingeAnchor(j, a1);
      dJointGetHingeAnchor2(j, a2);
      break;
    case dJointTypeUniversal:
      dJointGetUniversalAnchor(j, a1);
      dJointGetUniversalAnchor2(j, a2);
      break;
    case dJointTypeHinge2:
      dJointGetHinge2Anchor(j, a1);
      dJointGetHinge2Anchor2(j, a2);
      break;
    default:
      return false;
  }
  gap = std::sqrt((a1[0] - a2[0]) * (a1[0] - a2[0]) + (a1[1] - a2[1]) * (a1[1] - a2[1]) +
                  (a1[2] - a2[2]) * (a1[2] - a2[2]));
  return true;
}

void measure(const std::vector<dBodyID>& bodies, const std::vector<dJointID>& joints, Outcome& out,
             int& measuredJoints, int& contacts) {
  double sumSq = 0.0;
  measuredJoints = contacts = 0;
  out.maxSeparation = 0.0;
  for (dJointID j : joints) {
    if (dJointGetType(j) == dJointTypeContact) {
      ++contacts;
      continue;
    }
    double gap = 0.0;
    if (!dJointIsEnabled(j) || !anchorGap(j, gap)) continue;
    out.maxSeparation = std::max(out.maxSeparation, gap);
    sumSq += gap * gap;
    ++measuredJoints;
  }
  out.rmsSeparation = measuredJoints ? std::sqrt(sumSq / measuredJoints) : 0.0;
  out.kineticEnergy = 0.0;
  for (dBodyID b : bodies)
    out.kineticEnergy += ode::kineticEnergy(b);
}

}  // namespace

bool abMode() {
  const AbFile& f = abFile();
  return f.file != nullptr;
}

int abStep(dWorldID w, dReal h, AbChoice chosen, ode::OdeStepper odeStepper) {
  BLOCKSTEP_REAL(dWorldQuickStep);
  BLOCKSTEP_REAL(dWorldStep);
  auto* fallback = odeStepper == ode::OdeStepper::Step ? real_dWorldStep : real_dWorldQuickStep;
  // Kept between steps so that a warmed-up program allocates nothing here,
  // one set per nesting level: a moved callback may step another world.
  struct Scratch {
    std::vector<dBodyID> bodies;
    std::vector<dJointID> joints;
    std::vector<SavedBody> saved;
    std::vector<double> firstVelocity;  // after the first of the two
  };
  static thread_local std::deque<Scratch> levels;  // a deque keeps references valid
  static thread_local std::size_t depth = 0;
  if (depth == levels.size()) levels.emplace_back();
  Scratch& scratch = levels[depth];
  struct Nested {
    Nested() { ++depth; }
    ~Nested() { --depth; }
  } nested;
  std::vector<dBodyID>& bodies = scratch.bodies;
  std::vector<dJointID>& joints = scratch.joints;
  std::vector<SavedBody>& saved = scratch.saved;
  std::vector<double>& firstVelocity = scratch.firstVelocity;
  listWorld(w, bodies, joints);
  save(bodies, saved);
  // Quickstep shuffles its rows with ODE's random numbers: each step
  // starts from the program's own sequence, so the kept step is the one
  // it would have had.
  const unsigned long seed = dRandGetSeed();

  Outcome quick, block;
  int measuredJoints = 0, contacts = 0;
  auto stepQuick = [&] {
    dRandSetSeed(seed);
    const auto t0 = Clock::now();
    quick.stepped = real_dWorldQuickStep(w, h);
    quick.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    measure(bodies, joints, quick, measuredJoints, contacts);
  };
  auto stepBlock = [&] {
    dRandSetSeed(seed);
    const auto t0 = Clock::now();
    block.stepped = blockStep(w, h, fallback, odeStepper);
    block.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    measure(bodies, joints, block, measuredJoints, contacts);
  };
  // How far the two steps' velocities ended apart (the largest body's).
  auto keepVelocities = [&] {
    firstVelocity.clear();
    for (dBodyID b : bodies)
      firstVelocity.insert(firstVelocity.end(), dBodyGetLinearVel(b), dBodyGetLinearVel(b) + 3);
  };
  double speedDifference = 0.0;
  auto compareVelocities = [&] {
    for (std::size_t i = 0; i < bodies.size(); ++i) {
      const dReal* v = dBodyGetLinearVel(bodies[i]);
      const double* q = &firstVelocity[3 * i];
      speedDifference =
          std::max(speedDifference, std::hypot(v[0] - q[0], v[1] - q[1], v[2] - q[2]));
    }
  };
  // The kept step comes last.
  const bool blockFirst = chosen == AbChoice::QuickStep;
  blockFirst ? stepBlock() : stepQuick();
  keepVelocities();
  restore(saved);
  blockFirst ? stepQuick() : stepBlock();
  compareVelocities();
  int result = chosen == AbChoice::QuickStep ? quick.stepped : block.stepped;
  if (chosen == AbChoice::Step) {
    restore(saved);
    dRandSetSeed(seed);
    result = real_dWorldStep(w, h);
  }

  AbFile& f = abFile();
  std::lock_guard lock(f.mutex);
  std::size_t index = 0;
  while (index < f.worlds.size() && f.worlds[index] != w)
    ++index;
  if (index == f.worlds.size()) {
    f.worlds.push_back(w);
    f.steps.push_back(0);
  }
  const char* kept = chosen == AbChoice::QuickStep   ? "quickstep"
                     : chosen == AbChoice::Blockstep ? "blockstep"
                                                     : "dWorldStep";
  std::fprintf(f.file, "%zu,%ld,%.9g,%s,%.6g,%.9g,%.9g,%.9g,%.6g,%.9g,%.9g,%.9g,%.9g,%zu,%d,%d\n",
               index + 1, f.steps[index]++, double(h), kept, quick.seconds * 1e3,
               quick.maxSeparation, quick.rmsSeparation, quick.kineticEnergy, block.seconds * 1e3,
               block.maxSeparation, block.rmsSeparation, block.kineticEnergy, speedDifference,
               bodies.size(), measuredJoints, contacts);
  return result;
}

}  // namespace blockstep::plugin

// The plugin's C API (blockstep_ode.h) and its configuration from the
// BLOCKSTEP_* environment variables.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "adapters/ode/body_state.h"
#include "adapters/ode/registry.h"
#include "adapters/ode/world_bridge.h"

#include "blockstep/blockstep_ode.h"
#include "plugin/ab_mode.h"
#include "plugin/plugin_state.h"

namespace blockstep::plugin {
namespace {

using ode::BridgeSettings;
using ode::Registry;
using ode::StepOutcome;
using ode::WorldBridge;

struct Config {
  Replace replace;
  bool quiet = false;
  BridgeSettings defaults;
};

// A body ODE's stepper must leave alone while it steps the islands
// blockstep handed back.
using HeldBody = ode::OdeBodyState;

// What the API remembers of a world besides its bridge; read and changed
// under the world's lock.
struct WorldState {
  int stepper = dBlockStepperNone;
  int handedToOde = 0;       // bodies of runaway islands ODE stepped in the last step
  bool saidRunaway = false;  // the runaway message is printed once per world
  unsigned saidClamped = 0;  // ode::ClampedInput kinds said for this world
  std::string message;
  std::vector<std::string> said;  // messages already printed for this world
  // Per step, reused. A moved callback may step this world again, so a
  // step takes these out while it uses them and puts them back after.
  std::vector<dBodyID> moved, runaway;
  std::vector<HeldBody> held;
};

Config& config() {
  static Config c;
  return c;
}

// The worlds' WorldStates. Shared pointers: a step keeps its world's while
// the program's callbacks run, which may destroy the world.
struct WorldStates {
  std::mutex mutex;
  ode::PointerMap<dWorldID, std::shared_ptr<WorldState>> map;
};

WorldStates& worldStates() {
  static auto* states = new WorldStates();
  return *states;
}

std::shared_ptr<WorldState> stateOf(dWorldID w) {
  WorldStates& states = worldStates();
  std::lock_guard lock(states.mutex);
  std::shared_ptr<WorldState>& s = states.map[w];
  if (!s) s = std::make_shared<WorldState>();
  return s;
}

std::shared_ptr<WorldState> findState(dWorldID w) {
  WorldStates& states = worldStates();
  std::lock_guard lock(states.mutex);
  const std::shared_ptr<WorldState>* s = states.map.find(w);
  return s ? *s : nullptr;
}

bool parseInt(const char* name, const char* text, int lo, int& out, int hi = 100000) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (errno || end == text || *end || v < lo || v > hi) {
    say("ignoring %s=%s: expected a whole number from %d to %d", name, text, lo, hi);
    return false;
  }
  out = static_cast<int>(v);
  return true;
}

bool parseReal(const char* name, const char* text, double& out) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text, &end);
  if (errno || end == text || *end || !(v >= 0.0) || v > 1e9) {
    say("ignoring %s=%s: expected a number >= 0", name, text);
    return false;
  }
  out = v;
  return true;
}

bool parseReplace(const char* text, Replace& out) {
  if (!std::strcmp(text, "all"))
    out = {true, true};
  else if (!std::strcmp(text, "quickstep"))
    out = {true, false};
  else if (!std::strcmp(text, "step"))
    out = {false, true};
  else if (!std::strcmp(text, "none"))
    out = {false, false};
  else
    return false;
  return true;
}

const char* replaceName(const Replace& r) {
  if (r.quickStep && r.step) return "dWorldQuickStep and dWorldStep";
  if (r.quickStep) return "dWorldQuickStep";
  if (r.step) return "dWorldStep";
  return "nothing (ODE steps; call dWorldBlockStep to use blockstep)";
}

// Reads BLOCKSTEP_* once, when the library is loaded.
void readEnvironment() {
  Config& c = config();
  const char* preload = std::getenv("LD_PRELOAD");
  const bool preloaded = preload && std::strstr(preload, "blockstep_ode");
  c.replace = preloaded ? Replace{true, true} : Replace{false, false};
  if (const char* q = std::getenv("BLOCKSTEP_QUIET")) c.quiet = *q && std::strcmp(q, "0") != 0;
  if (const char* r = std::getenv("BLOCKSTEP_REPLACE")) {
    if (!parseReplace(r, c.replace)) {
      say("ignoring BLOCKSTEP_REPLACE=%s: expected all, quickstep, step or none", r);
    }
  }

  BridgeSettings& s = c.defaults;
  if (const char* v = std::getenv("BLOCKSTEP_SOLVER")) {
    if (!std::strcmp(v, "substep")) {
      s.followQuickStepIterations = false;
      s.solver = SolverSettings::subStepped(10);
    } else if (!std::strcmp(v, "paper")) {
      s.followQuickStepIterations = false;
      s.solver = SolverSettings::paper(20);
    } else if (std::strcmp(v, "follow") != 0) {
      say("ignoring BLOCKSTEP_SOLVER=%s: expected follow, substep or paper", v);
    }
  }
  int n = 0;
  double x = 0.0;
  auto explicitly = [&s] { s.followQuickStepIterations = false; };
  if (const char* v = std::getenv("BLOCKSTEP_SUBSTEPS");
      v && parseInt("BLOCKSTEP_SUBSTEPS", v, 1, n, SolverSettings::kMaxSubsteps)) {
    if (s.followQuickStepIterations) s.solver = SolverSettings::subStepped(n);
    s.solver.substeps = n;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_ITERATIONS");
      v && parseInt("BLOCKSTEP_ITERATIONS", v, 1, n)) {
    s.solver.iterations = n;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_RELAX"); v && parseInt("BLOCKSTEP_RELAX", v, 0, n)) {
    s.solver.relaxIterations = n;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_WARM"); v && parseInt("BLOCKSTEP_WARM", v, 0, n)) {
    s.solver.warmStarting = n != 0;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_TOLERANCE");
      v && parseReal("BLOCKSTEP_TOLERANCE", v, x)) {
    s.solver.tolerance = x;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_TIME_BUDGET");
      v && parseReal("BLOCKSTEP_TIME_BUDGET", v, x)) {
    s.solver.timeBudget = x;
    explicitly();
  }
  if (const char* v = std::getenv("BLOCKSTEP_ISLAND_BLOCK_ROWS");
      v && parseInt("BLOCKSTEP_ISLAND_BLOCK_ROWS", v, 0, n)) {
    s.islandBlockRows = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_CONTACT_ISLAND_ROWS");
      v && parseInt("BLOCKSTEP_CONTACT_ISLAND_ROWS", v, 0, n)) {
    s.contactIslandRows = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_LIGHT_BODY_GROUPS");
      v && parseInt("BLOCKSTEP_LIGHT_BODY_GROUPS", v, 0, n, 1)) {
    s.lightBodyGroups = n != 0;
  }
  if (const char* v = std::getenv("BLOCKSTEP_LOAD_RELATIVE_CONTACTS");
      v && parseInt("BLOCKSTEP_LOAD_RELATIVE_CONTACTS", v, 0, n, 1)) {
    s.loadRelativeContacts = n != 0;
  }
  if (const char* v = std::getenv("BLOCKSTEP_RETAKE_TURNS");
      v && parseInt("BLOCKSTEP_RETAKE_TURNS", v, 0, n, 1)) {
    s.retakeTurningParts = n != 0;
  }
  if (const char* v = std::getenv("BLOCKSTEP_IMPACT_DEPTH");
      v && parseReal("BLOCKSTEP_IMPACT_DEPTH", v, x)) {
    s.impactDepth = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_SINKING_DEPTH");
      v && parseReal("BLOCKSTEP_SINKING_DEPTH", v, x)) {
    s.sinkingDepth = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_MAX_TRAVEL");
      v && parseReal("BLOCKSTEP_MAX_TRAVEL", v, x)) {
    s.maxSurfaceTravelPerSubstep = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_CHAIN_BLOCKS");
      v && parseInt("BLOCKSTEP_CHAIN_BLOCKS", v, 0, n, 1)) {
    s.chainBlocks = n != 0;
  }
  if (const char* v = std::getenv("BLOCKSTEP_ISLAND_CONTACTS");
      v && parseInt("BLOCKSTEP_ISLAND_CONTACTS", v, 0, n, 2)) {
    s.islandBlockContacts = n;
  }
  // Angles, rad (parseReal takes finite numbers >= 0 only; 0: off).
  if (const char* v = std::getenv("BLOCKSTEP_MAX_TURN");
      v && parseReal("BLOCKSTEP_MAX_TURN", v, x)) {
    s.maxTurnPerSubstep = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_REFRESH_TURN");
      v && parseReal("BLOCKSTEP_REFRESH_TURN", v, x)) {
    s.maxTurnPerRefresh = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_RELAX_DRIFT")) {
    if (std::strcmp(v, "0") == 0 || std::strcmp(v, "1") == 0)
      s.relaxCancelsDrift = std::strcmp(v, "1") == 0;
    else
      say("ignoring BLOCKSTEP_RELAX_DRIFT=%s: expected 0 or 1", v);
  }
  if (const char* v = std::getenv("BLOCKSTEP_PROJECTIONS");
      v && parseInt("BLOCKSTEP_PROJECTIONS", v, 0, n, SolverSettings::kMaxProjections)) {
    s.positionProjections = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_PROJECTION_TOLERANCE");
      v && parseReal("BLOCKSTEP_PROJECTION_TOLERANCE", v, x)) {
    s.projectionTolerance = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_THREADS");
      v && parseInt("BLOCKSTEP_THREADS", v, 0, n)) {
    if (n <= SolverSettings::kMaxThreads)
      s.threads = n;
    else
      say("ignoring BLOCKSTEP_THREADS=%s: expected 0 (one per core) to %d", v,
          SolverSettings::kMaxThreads);
  }
  if (const char* v = std::getenv("BLOCKSTEP_EXACT_JOINT_SUBSTEPS");
      v && parseInt("BLOCKSTEP_EXACT_JOINT_SUBSTEPS", v, 0, n, SolverSettings::kMaxSubsteps)) {
    s.exactJointIslandSubsteps = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_EXACT_CONTACT_SUBSTEPS");
      v && parseInt("BLOCKSTEP_EXACT_CONTACT_SUBSTEPS", v, 0, n, SolverSettings::kMaxSubsteps)) {
    s.exactContactIslandSubsteps = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_CALM_SUBSTEPS");
      v && parseInt("BLOCKSTEP_CALM_SUBSTEPS", v, 0, n, SolverSettings::kMaxSubsteps)) {
    s.calmTouchedIslandSubsteps = n;
  }
  if (const char* v = std::getenv("BLOCKSTEP_CALM_SPEED");
      v && parseReal("BLOCKSTEP_CALM_SPEED", v, x)) {
    s.calmApproachSpeed = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_RUNAWAY_GAIN");
      v && parseReal("BLOCKSTEP_RUNAWAY_GAIN", v, x)) {
    s.runawayEnergyGain = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_RUNAWAY_SPEED");
      v && parseReal("BLOCKSTEP_RUNAWAY_SPEED", v, x)) {
    s.runawaySpeed = x > 0.0 ? x : kInf;
  }
  if (const char* v = std::getenv("BLOCKSTEP_CONTACT_PERSISTENCE");
      v && parseReal("BLOCKSTEP_CONTACT_PERSISTENCE", v, x)) {
    s.contactPersistence = x;
  }
  if (const char* v = std::getenv("BLOCKSTEP_COLLIDERS")) {
    if (!std::strcmp(v, "1"))
      setCollidersFromEnvironment(true);
    else if (std::strcmp(v, "0"))
      say("ignoring BLOCKSTEP_COLLIDERS=%s: expected 0 or 1", v);
  }
  if (const char* v = std::getenv("BLOCKSTEP_MODE")) {
    if (!std::strcmp(v, "block"))
      s.solver.blockMode = BlockMode::Block;
    else if (!std::strcmp(v, "row"))
      s.solver.blockMode = BlockMode::RowByRow;
    else
      say("ignoring BLOCKSTEP_MODE=%s: expected block or row", v);
  }
}

__attribute__((constructor)) void announce() {
  readEnvironment();
  const Config& c = config();
  if (c.quiet) return;
  const char* solver = c.defaults.followQuickStepIterations ? "sub-steps = quickstep iterations / 2"
                                                            : "solver from BLOCKSTEP_* settings";
  std::fprintf(stderr, "blockstep: active, replacing %s (%s)\n", replaceName(c.replace), solver);
  if (abMode())
    std::fprintf(stderr,
                 "blockstep: A/B mode: each step taken by quickstep and blockstep from the same "
                 "state, the program's own kept, rows written to %s\n",
                 std::getenv("BLOCKSTEP_AB"));
}

// A world's record and bridge (made at first use), its lock held for the
// holder's life: other threads' worlds go on meanwhile.
class LockedWorld {
 public:
  explicit LockedWorld(dWorldID w)
      : record_(Registry::instance().ensureWorld(w)), lock_(record_->mutex) {
    if (!record_->bridge) {
      record_->bridge = std::make_unique<WorldBridge>(w);
      record_->bridge->settings() = config().defaults;
    }
  }
  ode::WorldRecord& record() { return *record_; }
  const std::shared_ptr<ode::WorldRecord>& shared() const { return record_; }
  WorldBridge& bridge() { return *record_->bridge; }
  BridgeSettings& settings() { return record_->bridge->settings(); }
  void unlock() { lock_.unlock(); }
  void lock() { lock_.lock(); }

 private:
  std::shared_ptr<ode::WorldRecord> record_;
  std::unique_lock<std::recursive_mutex> lock_;
};

// Explicit settings, starting from what the world runs now. The reference
// is for the caller's own full expression, while the lock is held.
SolverSettings& explicitSettings(LockedWorld&& world) {
  BridgeSettings& s = world.settings();
  if (s.followQuickStepIterations) {
    s.solver = BridgeSettings::fromQuickStepIterations(
        dWorldGetQuickStepNumIterations(world.record().world));
    s.followQuickStepIterations = false;
  }
  return s.solver;
}

SolverSettings currentSettings(dWorldID w) {
  LockedWorld world(w);
  const BridgeSettings& s = world.settings();
  if (s.followQuickStepIterations)
    return BridgeSettings::fromQuickStepIterations(dWorldGetQuickStepNumIterations(w));
  return s.solver;
}

// A setting the world holds apart from its solver (ode::BridgeSettings:
// it holds under every solver), or unset, the current solver's own.
template <class T>
T heldOrSolvers(dWorldID w, std::optional<T> ode::BridgeSettings::*held,
                T SolverSettings::*solverOwn) {
  const std::optional<T> value = LockedWorld(w).settings().*held;
  return value ? *value : currentSettings(w).*solverOwn;
}

// A world's on/off setting held apart from its solver (1 or 0 through the
// C API); unset, the solver's own is reported.
using FlagSetting = std::optional<bool> ode::BridgeSettings::*;
void setWorldFlag(const char* call, dWorldID w, int on, FlagSetting setting) {
  guarded(call, [&] { LockedWorld(w).settings().*setting = on != 0; });
}
int worldFlag(const char* call, dWorldID w, FlagSetting setting, bool SolverSettings::*solverOwn) {
  return guarded(call, 0, [&] { return heldOrSolvers(w, setting, solverOwn) ? 1 : 0; });
}

void sayOnce(WorldState& state, dWorldID w, const std::string& text, const char* consequence) {
  for (const std::string& s : state.said) {
    if (s == text) return;
  }
  state.said.push_back(text);
  say("world %p: %s; %s", static_cast<void*>(w), text.c_str(), consequence);
}

}  // namespace

Replace& replace() {
  return config().replace;
}
bool quiet() {
  return config().quiet;
}

void say(const char* format, ...) {
  char text[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(text, sizeof text, format, args);
  va_end(args);
  std::fprintf(stderr, "blockstep: %s\n", text);
}

namespace {

// Steps only the handed-back islands with ODE's stepper: every other
// enabled body is disabled for the call (ODE steps enabled islands only)
// and enabled again after; one ODE joined to a stepped island anyway is
// put back as blockstep left it.
int stepWithOde(dWorldID w, dReal h, int (*odeStep)(dWorldID, dReal), std::vector<HeldBody>& held) {
  for (const HeldBody& k : held)
    dBodyDisable(k.body);
  const int result = odeStep(w, h);
  for (const HeldBody& k : held) {
    if (dBodyIsEnabled(k.body)) k.putBack();
    dBodyEnable(k.body);
  }
  return result;
}

}  // namespace

namespace {

// The program's moved callbacks for the bodies the step moved, called
// outside the world's lock: they may call ODE, destroy bodies or the world,
// or step this world or another one. Each is looked up again before its
// call.
void callMovedCallbacks(LockedWorld& world, const std::vector<dBodyID>& moved) {
  ode::WorldRecord& record = world.record();
  for (dBodyID b : moved) {
    world.lock();
    const ode::MovedCallback callback = record.destroyed ? nullptr : record.movedCallback(b);
    const bool destroyed = record.destroyed;
    world.unlock();
    if (destroyed) return;
    if (callback) callback(b);
  }
}

int blockStepLocked(LockedWorld& world, WorldState& state, dReal h,
                    int (*fallback)(dWorldID, dReal), ode::OdeStepper stepper) {
  const dWorldID w = world.record().world;
  WorldBridge& bridge = world.bridge();
  const StepOutcome outcome = bridge.step(world.record(), h, stepper);
  state.message = bridge.message();
  state.handedToOde = 0;
  switch (outcome) {
    case StepOutcome::Stepped: {
      state.stepper = dBlockStepperBlockstep;
      if (!bridge.collisionNote().empty())
        sayOnce(state, w, bridge.collisionNote(), "those geoms are left out of it");
      if (const unsigned fresh = bridge.clampedInputs() & ~state.saidClamped) {
        state.saidClamped |= fresh;
        for (int k = 0; k < ode::kClampedInputKinds; ++k) {
          if (fresh & (1u << k))
            say("world %p: %s (said once per world)", static_cast<void*>(w),
                ode::clampedInputText(1u << k));
        }
      }
      std::vector<dBodyID> moved = std::move(state.moved), runaway = std::move(state.runaway);
      std::vector<HeldBody> held = std::move(state.held);
      moved.assign(bridge.movedWithCallback().begin(), bridge.movedWithCallback().end());
      // Islands the runaway guard put back go to ODE's own stepper.
      runaway.assign(bridge.runawayBodies().begin(), bridge.runawayBodies().end());
      held.clear();
      if (!runaway.empty()) {
        std::sort(runaway.begin(), runaway.end());
        for (dBodyID b : world.record().bodies) {
          if (!dBodyIsEnabled(b) || std::binary_search(runaway.begin(), runaway.end(), b)) continue;
          held.push_back(HeldBody::of(b));
        }
        state.handedToOde = static_cast<int>(runaway.size());
        if (!state.saidRunaway) {
          state.saidRunaway = true;
          say("world %p: %s; put back as before the step and stepped by ODE's %s instead (said "
              "once per world; dBlockStepStats.handedToOde counts such bodies per step)",
              static_cast<void*>(w), bridge.message().c_str(),
              stepper == ode::OdeStepper::Step ? "dWorldStep" : "dWorldQuickStep");
        }
      }
      world.unlock();
      if (!runaway.empty()) stepWithOde(w, h, fallback, held);
      callMovedCallbacks(world, moved);
      world.lock();
      // Their capacity, for the next step.
      state.moved = std::move(moved);
      state.runaway = std::move(runaway);
      state.held = std::move(held);
      return 1;
    }
    case StepOutcome::Unsupported:
      sayOnce(state, w, bridge.message(), "this world is stepped by ODE");
      state.stepper = dBlockStepperOde;
      world.unlock();
      return fallback(w, h);
    case StepOutcome::Invalid:
      break;
  }
  sayOnce(state, w, bridge.message(), "the step was refused and the world left as it was");
  state.stepper = dBlockStepperNone;
  return 0;
}

}  // namespace

int blockStep(dWorldID w, dReal h, int (*fallback)(dWorldID, dReal), ode::OdeStepper stepper) {
  if (!w) {
    say("dWorldBlockStep: null world");
    return 0;
  }
  return guarded("blockstep's step", 0, [&] {
    LockedWorld world(w);
    const std::shared_ptr<WorldState> state = stateOf(w);
    return blockStepLocked(world, *state, h, fallback, stepper);
  });
}

const JointState* steppedJointState(dJointID j) {
  const std::shared_ptr<ode::WorldRecord> world = Registry::instance().worldOfJoint(j);
  if (!world) return nullptr;
  std::lock_guard lock(world->mutex);
  const std::shared_ptr<WorldState> state = findState(world->world);
  if (!state || state->stepper != dBlockStepperBlockstep || !world->bridge || world->destroyed)
    return nullptr;
  return world->bridge->jointState(j);
}

void forgetWorld(dWorldID w) {
  WorldStates& states = worldStates();
  std::lock_guard lock(states.mutex);
  states.map.erase(w);
}

namespace {

// A count setting within [lo, hi], or said and refused.
bool inRange(const char* function, int n, int lo, int hi) {
  if (n >= lo && n <= hi) return true;
  say("%s(%d): expected %d to %d; call ignored", function, n, lo, hi);
  return false;
}

}  // namespace

}  // namespace blockstep::plugin

using namespace blockstep;
using namespace blockstep::plugin;

extern "C" {

int dWorldBlockStep(dWorldID w, dReal stepsize) {
  return guarded("dWorldBlockStep", 0, [&] {
    BLOCKSTEP_REAL(dWorldQuickStep);
    if (abMode()) return abStep(w, stepsize, AbChoice::Blockstep, ode::OdeStepper::QuickStep);
    return blockStep(w, stepsize, real_dWorldQuickStep);
  });
}

void dWorldSetBlockFollowQuickStep(dWorldID w) {
  guarded(__func__, [&] { LockedWorld(w).settings().followQuickStepIterations = true; });
}
void dWorldSetBlockSubsteppedSolver(dWorldID w, int substeps) {
  if (!inRange(__func__, substeps, 1, SolverSettings::kMaxSubsteps)) return;
  guarded(__func__,
          [&] { explicitSettings(LockedWorld(w)) = SolverSettings::subStepped(substeps); });
}
void dWorldSetBlockPaperSolver(dWorldID w, int iterations) {
  if (!inRange(__func__, iterations, 1, SolverSettings::kMaxIterations)) return;
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)) = SolverSettings::paper(iterations); });
}

void dWorldSetBlockIterations(dWorldID w, int n) {
  if (!inRange(__func__, n, 1, SolverSettings::kMaxIterations)) return;
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)).iterations = n; });
}
int dWorldGetBlockIterations(dWorldID w) {
  return guarded(__func__, 0, [&] { return currentSettings(w).iterations; });
}
void dWorldSetBlockSubsteps(dWorldID w, int n) {
  if (!inRange(__func__, n, 1, SolverSettings::kMaxSubsteps)) return;
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)).substeps = n; });
}
int dWorldGetBlockSubsteps(dWorldID w) {
  return guarded(__func__, 0, [&] { return currentSettings(w).substeps; });
}
void dWorldSetBlockRelaxIterations(dWorldID w, int n) {
  if (!inRange(__func__, n, 0, SolverSettings::kMaxIterations)) return;
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)).relaxIterations = n; });
}
int dWorldGetBlockRelaxIterations(dWorldID w) {
  return guarded(__func__, 0, [&] { return currentSettings(w).relaxIterations; });
}
void dWorldSetBlockIslandBlockRows(dWorldID w, int rows) {
  if (!inRange(__func__, rows, 0, 4096)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().islandBlockRows = rows; });
}
int dWorldGetBlockIslandBlockRows(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::islandBlockRows,
                         &SolverSettings::islandBlockRows);
  });
}
void dWorldSetBlockContactIslandRows(dWorldID w, int rows) {
  if (!inRange(__func__, rows, 0, 4096)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().contactIslandRows = rows; });
}
int dWorldGetBlockContactIslandRows(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::contactIslandRows,
                         &SolverSettings::contactIslandRows);
  });
}
void dWorldSetBlockLightBodyGroups(dWorldID w, int on) {
  setWorldFlag(__func__, w, on, &ode::BridgeSettings::lightBodyGroups);
}
int dWorldGetBlockLightBodyGroups(dWorldID w) {
  return worldFlag(__func__, w, &ode::BridgeSettings::lightBodyGroups,
                   &SolverSettings::lightBodyGroups);
}
void dWorldSetBlockLoadRelativeContacts(dWorldID w, int on) {
  setWorldFlag(__func__, w, on, &ode::BridgeSettings::loadRelativeContacts);
}
int dWorldGetBlockLoadRelativeContacts(dWorldID w) {
  return worldFlag(__func__, w, &ode::BridgeSettings::loadRelativeContacts,
                   &SolverSettings::loadRelativeContacts);
}
void dWorldSetBlockRetakeTurns(dWorldID w, int on) {
  setWorldFlag(__func__, w, on, &ode::BridgeSettings::retakeTurningParts);
}
int dWorldGetBlockRetakeTurns(dWorldID w) {
  return worldFlag(__func__, w, &ode::BridgeSettings::retakeTurningParts,
                   &SolverSettings::retakeTurningParts);
}
void dWorldSetBlockChainBlocks(dWorldID w, int on) {
  setWorldFlag(__func__, w, on, &ode::BridgeSettings::chainBlocks);
}
int dWorldGetBlockChainBlocks(dWorldID w) {
  return worldFlag(__func__, w, &ode::BridgeSettings::chainBlocks, &SolverSettings::chainBlocks);
}
void dWorldSetBlockIslandContacts(dWorldID w, int mode) {
  if (!inRange(__func__, mode, 0, 2)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().islandBlockContacts = mode; });
}
int dWorldGetBlockIslandContacts(dWorldID w) {
  return guarded(__func__, 0, [&] {
    const std::optional<int> held = LockedWorld(w).settings().islandBlockContacts;
    if (held) return *held;
    const SolverSettings s = currentSettings(w);
    return s.islandBlockContacts ? 1 : s.islandBlockImpacts ? 2 : 0;
  });
}
// A world's setting of a quantity >= 0 (0: off) held apart from its
// solver: a bad value is said ("expected <what>") and ignored; unset, the
// solver's own is reported.
using QuantitySetting = std::optional<double> ode::BridgeSettings::*;
void setWorldQuantity(const char* call, dWorldID w, dReal value, QuantitySetting setting,
                      const char* what) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    say("%s(%g): expected %s; call ignored", call, double(value), what);
    return;
  }
  guarded(call, [&] { LockedWorld(w).settings().*setting = value; });
}
dReal worldQuantity(const char* call, dWorldID w, QuantitySetting setting,
                    double SolverSettings::*solverOwn) {
  return guarded(call, dReal(0), [&] { return dReal(heldOrSolvers(w, setting, solverOwn)); });
}
constexpr const char* kAngle = "an angle >= 0 (rad; 0: off)";
constexpr const char* kDepth = "a depth >= 0 (m; 0: off)";
constexpr const char* kDistance = "a distance >= 0 (m; 0: off)";
void dWorldSetBlockImpactDepth(dWorldID w, dReal metres) {
  setWorldQuantity(__func__, w, metres, &ode::BridgeSettings::impactDepth, kDepth);
}
dReal dWorldGetBlockImpactDepth(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::impactDepth,
                       &SolverSettings::impactDepth);
}
void dWorldSetBlockSinkingDepth(dWorldID w, dReal metres) {
  setWorldQuantity(__func__, w, metres, &ode::BridgeSettings::sinkingDepth, kDepth);
}
dReal dWorldGetBlockSinkingDepth(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::sinkingDepth,
                       &SolverSettings::sinkingDepth);
}
void dWorldSetBlockMaxTravel(dWorldID w, dReal metres) {
  setWorldQuantity(__func__, w, metres, &ode::BridgeSettings::maxSurfaceTravelPerSubstep,
                   kDistance);
}
dReal dWorldGetBlockMaxTravel(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::maxSurfaceTravelPerSubstep,
                       &SolverSettings::maxSurfaceTravelPerSubstep);
}
void dWorldSetBlockMaxTurn(dWorldID w, dReal radians) {
  setWorldQuantity(__func__, w, radians, &ode::BridgeSettings::maxTurnPerSubstep, kAngle);
}
dReal dWorldGetBlockMaxTurn(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::maxTurnPerSubstep,
                       &SolverSettings::maxTurnPerSubstep);
}
void dWorldSetBlockRefreshTurn(dWorldID w, dReal radians) {
  setWorldQuantity(__func__, w, radians, &ode::BridgeSettings::maxTurnPerRefresh, kAngle);
}
dReal dWorldGetBlockRefreshTurn(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::maxTurnPerRefresh,
                       &SolverSettings::maxTurnPerRefresh);
}
void dWorldSetBlockRelaxDrift(dWorldID w, int on) {
  if (on != 0 && on != 1) {
    say("dWorldSetBlockRelaxDrift(%d): expected 0 or 1; call ignored", on);
    return;
  }
  guarded(__func__, [&] { LockedWorld(w).settings().relaxCancelsDrift = on == 1; });
}
void dWorldSetBlockThreads(dWorldID w, int threads) {
  if (threads < 0 || threads > SolverSettings::kMaxThreads) {
    say("dWorldSetBlockThreads(%d): expected 0 (one per core) to %d; call ignored", threads,
        SolverSettings::kMaxThreads);
    return;
  }
  guarded(__func__, [&] { LockedWorld(w).settings().threads = threads; });
}

void dWorldSetBlockExactJointSubsteps(dWorldID w, int substeps) {
  if (!inRange(__func__, substeps, 0, SolverSettings::kMaxSubsteps)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().exactJointIslandSubsteps = substeps; });
}
int dWorldGetBlockExactJointSubsteps(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::exactJointIslandSubsteps,
                         &SolverSettings::exactJointIslandSubsteps);
  });
}
void dWorldSetBlockCalmSubsteps(dWorldID w, int substeps) {
  if (!inRange(__func__, substeps, 0, SolverSettings::kMaxSubsteps)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().calmTouchedIslandSubsteps = substeps; });
}
int dWorldGetBlockCalmSubsteps(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::calmTouchedIslandSubsteps,
                         &SolverSettings::calmTouchedIslandSubsteps);
  });
}
void dWorldSetBlockCalmSpeed(dWorldID w, dReal metresPerSecond) {
  setWorldQuantity(__func__, w, metresPerSecond, &ode::BridgeSettings::calmApproachSpeed,
                   "a speed >= 0 (m/s)");
}
dReal dWorldGetBlockCalmSpeed(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::calmApproachSpeed,
                       &SolverSettings::calmApproachSpeed);
}
void dWorldSetBlockExactContactSubsteps(dWorldID w, int substeps) {
  if (!inRange(__func__, substeps, 0, SolverSettings::kMaxSubsteps)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().exactContactIslandSubsteps = substeps; });
}
int dWorldGetBlockExactContactSubsteps(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::exactContactIslandSubsteps,
                         &SolverSettings::exactContactIslandSubsteps);
  });
}

int dWorldGetBlockThreads(dWorldID w) {
  return guarded(__func__, 1, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::threads, &SolverSettings::threads);
  });
}

void dWorldSetBlockProjections(dWorldID w, int projections) {
  if (!inRange(__func__, projections, 0, SolverSettings::kMaxProjections)) return;
  guarded(__func__, [&] { LockedWorld(w).settings().positionProjections = projections; });
}
void dWorldSetBlockProjectionTolerance(dWorldID w, dReal error) {
  setWorldQuantity(__func__, w, error, &ode::BridgeSettings::projectionTolerance,
                   "an error >= 0 (m, or rad for angular rows; 0: always project)");
}
dReal dWorldGetBlockProjectionTolerance(dWorldID w) {
  return worldQuantity(__func__, w, &ode::BridgeSettings::projectionTolerance,
                       &SolverSettings::projectionTolerance);
}
int dWorldGetBlockProjections(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return heldOrSolvers(w, &ode::BridgeSettings::positionProjections,
                         &SolverSettings::positionProjections);
  });
}
int dWorldGetBlockRelaxDrift(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return int(heldOrSolvers(w, &ode::BridgeSettings::relaxCancelsDrift,
                             &SolverSettings::relaxCancelsDrift));
  });
}
void dWorldSetBlockRunawayLimits(dWorldID w, dReal energyGain, dReal maxSpeed) {
  if (std::isnan(energyGain) || std::isnan(maxSpeed)) {
    say("dWorldSetBlockRunawayLimits(%g, %g): NaN limit; call ignored", double(energyGain),
        double(maxSpeed));
    return;
  }
  guarded(__func__, [&] {
    BridgeSettings& s = LockedWorld(w).settings();
    s.runawayEnergyGain = energyGain > 0 ? energyGain : 0.0;
    s.runawaySpeed = maxSpeed > 0 ? maxSpeed : kInf;
  });
}
void dWorldGetBlockRunawayLimits(dWorldID w, dReal* energyGain, dReal* maxSpeed) {
  guarded(__func__, [&] {
    LockedWorld world(w);
    if (energyGain) *energyGain = world.settings().runawayEnergyGain;
    if (maxSpeed) *maxSpeed = world.settings().runawaySpeed;
  });
}
void dWorldSetBlockContactPersistence(dWorldID w, dReal distance) {
  if (!(distance >= 0) || !std::isfinite(distance)) {
    say("dWorldSetBlockContactPersistence(%g): expected a finite distance >= 0 m; call ignored",
        double(distance));
    return;
  }
  guarded(__func__, [&] { LockedWorld(w).settings().contactPersistence = distance; });
}
dReal dWorldGetBlockContactPersistence(dWorldID w) {
  return guarded(__func__, dReal(0),
                 [&] { return dReal(LockedWorld(w).settings().contactPersistence); });
}
void dWorldSetBlockTolerance(dWorldID w, dReal t) {
  guarded(__func__,
          [&] { explicitSettings(LockedWorld(w)).tolerance = t > 0 && t < dInfinity ? t : 0; });
}
dReal dWorldGetBlockTolerance(dWorldID w) {
  return guarded(__func__, dReal(0), [&] { return dReal(currentSettings(w).tolerance); });
}
void dWorldSetBlockTimeBudget(dWorldID w, dReal s) {
  guarded(__func__,
          [&] { explicitSettings(LockedWorld(w)).timeBudget = s > 0 && s < dInfinity ? s : 0; });
}
dReal dWorldGetBlockTimeBudget(dWorldID w) {
  return guarded(__func__, dReal(0), [&] { return dReal(currentSettings(w).timeBudget); });
}
void dWorldSetBlockWarmStarting(dWorldID w, int on) {
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)).warmStarting = on != 0; });
}
int dWorldGetBlockWarmStarting(dWorldID w) {
  return guarded(__func__, 0, [&] { return currentSettings(w).warmStarting ? 1 : 0; });
}
void dWorldSetBlockMode(dWorldID w, int mode) {
  guarded(__func__, [&] {
    explicitSettings(LockedWorld(w)).blockMode =
        mode == dBlockModeRowByRow ? BlockMode::RowByRow : BlockMode::Block;
  });
}
int dWorldGetBlockMode(dWorldID w) {
  return guarded(__func__, 0, [&] {
    return currentSettings(w).blockMode == BlockMode::RowByRow ? dBlockModeRowByRow
                                                               : dBlockModeBlock;
  });
}
void dWorldSetBlockRecordResiduals(dWorldID w, int on) {
  guarded(__func__, [&] { explicitSettings(LockedWorld(w)).recordResiduals = on != 0; });
}

void dWorldSetBlockCollision(dWorldID w, dSpaceID space, const dSurfaceParameters* surface,
                             int flags) {
  if (space && !surface) {
    say("dWorldSetBlockCollision: a space needs a contact surface; call ignored");
    return;
  }
  if (flags & ~dBlockCollideEverySubstep) {
    say("dWorldSetBlockCollision: unknown flags %#x; call ignored", unsigned(flags));
    return;
  }
  guarded(__func__, [&] {
    BridgeSettings& s = LockedWorld(w).settings();
    s.collisionSpace = space;
    s.collisionSurface = space ? *surface : dSurfaceParameters{};
    s.collideEverySubstep = (flags & dBlockCollideEverySubstep) != 0;
  });
}

int dWorldGetBlockStepStats(dWorldID w, dBlockStepStats* out) {
  return guarded(__func__, 0, [&] {
    const std::shared_ptr<ode::WorldRecord> record = Registry::instance().world(w);
    const std::shared_ptr<WorldState> state = findState(w);
    if (!out || !state || !record) return 0;
    std::lock_guard lock(record->mutex);
    if (!record->bridge) return 0;
    const StepStats& s = record->bridge->stats();
    *out = dBlockStepStats{};
    out->stepper = state->stepper;
    if (state->stepper == dBlockStepperBlockstep) {
      out->substeps = s.substeps;
      out->iterations = s.iterations;
      out->islands = s.islands;
      out->blocks = s.blocks;
      out->rows = s.rows;
      out->residualCount = static_cast<int>(s.residuals.size());
      out->solveSeconds = s.solveSeconds;
      out->stepSeconds = s.stepSeconds;
      out->collideSeconds = s.collideSeconds;
      out->handedToOde = state->handedToOde;
      out->preparedSubsteps = s.preparedSubsteps;
    }
    return 1;
  });
}

dReal dWorldGetBlockDeepestContact(dWorldID w) {
  return guarded(__func__, dReal(0), [&]() -> dReal {
    const std::shared_ptr<ode::WorldRecord> record = Registry::instance().world(w);
    const std::shared_ptr<WorldState> state = findState(w);
    if (!state || !record) return 0;
    std::lock_guard lock(record->mutex);
    if (!record->bridge || state->stepper != dBlockStepperBlockstep) return 0;
    return static_cast<dReal>(record->bridge->stats().deepestFound);
  });
}

int dWorldGetBlockResidualHistory(dWorldID w, dReal* maxima, dReal* rms, int capacity) {
  return guarded(__func__, 0, [&] {
    const std::shared_ptr<ode::WorldRecord> record = Registry::instance().world(w);
    if (!record) return 0;
    std::lock_guard lock(record->mutex);
    if (!record->bridge) return 0;
    const auto& r = record->bridge->stats().residuals;
    for (int i = 0; i < capacity && i < static_cast<int>(r.size()); ++i) {
      if (maxima) maxima[i] = r[i].max;
      if (rms) rms[i] = r[i].rms;
    }
    return static_cast<int>(r.size());
  });
}

void dWorldSetBlockRecordStageEnergy(dWorldID w, int on) {
  guarded(__func__, [&] { LockedWorld(w).settings().recordStageEnergy = on != 0; });
}

int dWorldGetBlockStageEnergy(dWorldID w, int* substep, int* stage, dReal* kinetic,
                              dReal* potential, int capacity) {
  return guarded(__func__, 0, [&] {
    const std::shared_ptr<ode::WorldRecord> record = Registry::instance().world(w);
    const std::shared_ptr<WorldState> state = findState(w);
    if (!state || !record) return 0;
    std::lock_guard lock(record->mutex);
    if (!record->bridge || state->stepper != dBlockStepperBlockstep) return 0;
    const auto& samples = record->bridge->stats().stageEnergy;
    for (int i = 0; i < capacity && i < static_cast<int>(samples.size()); ++i) {
      const StageEnergySample& e = samples[static_cast<std::size_t>(i)];
      if (substep) substep[i] = e.substep;
      if (stage) stage[i] = static_cast<int>(e.after);
      if (kinetic) kinetic[i] = static_cast<dReal>(e.kinetic);
      if (potential) potential[i] = static_cast<dReal>(e.potential);
    }
    return static_cast<int>(samples.size());
  });
}

// The text lives in the world's state until its next step (or the world's
// destruction), as before.
const char* dWorldGetBlockStepMessage(dWorldID w) {
  const std::shared_ptr<WorldState> state = findState(w);
  return state ? state->message.c_str() : "";
}

int dBlockStepSetReplace(const char* mode) {
  return mode && parseReplace(mode, config().replace) ? 1 : 0;
}

}  // extern "C"

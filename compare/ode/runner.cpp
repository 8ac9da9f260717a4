// Stepping a scene with one stepper, frame by frame.
#include "compare/ode/runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <stdexcept>

#include "blockstep/blockstep_ode.h"

namespace blockstep::compare {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

[[noreturn]] void reject(const std::string& text, const std::string& why) {
  throw std::invalid_argument(
      "stepper '" + text + "': " + why +
      " (accepted: quickstep:IT[xSUB], direct, blockstep, blockstep:substep:N, "
      "blockstep:paper:IT, pbd:IT[xSUB], xpbd:IT[xSUB]; IT 1..10000, N and SUB 1..1000)");
}

int number(const std::string& text, const std::string& digits, int lo, int hi) {
  if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos ||
      digits.size() > 6)
    reject(text, "'" + digits + "' is not a whole number");
  const int n = std::stoi(digits);
  if (n < lo || n > hi) reject(text, std::to_string(n) + " is out of range");
  return n;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

void configure(dWorldID w, const Stepper& s) {
  dWorldSetQuickStepNumIterations(w, s.kind == Stepper::Kind::Quick ? s.iterations : 20);
  if (s.kind != Stepper::Kind::Block) return;
  switch (s.preset) {
    case Stepper::Preset::FollowQuickStep:
      dWorldSetBlockFollowQuickStep(w);
      break;
    case Stepper::Preset::Substepped:
      dWorldSetBlockSubsteppedSolver(w, s.substeps);
      break;
    case Stepper::Preset::Paper:
      dWorldSetBlockPaperSolver(w, s.iterations);
      break;
  }
}

// ODE's own messages (dWorldStep's "LCP internal error" on stacks) are
// counted per run instead of printed.
int odeMessages = 0;

void countMessage(int, const char*, va_list) {
  ++odeMessages;
}

bool finiteState(const Scene& scene) {
  for (dBodyID b : scene.bodies()) {
    const dReal* p = dBodyGetPosition(b);
    const dReal* v = dBodyGetLinearVel(b);
    const dReal* w = dBodyGetAngularVel(b);
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(p[k]) || !std::isfinite(v[k]) || !std::isfinite(w[k])) return false;
  }
  return true;
}

// The joint rows of the scene's largest island (bodies joined by joints;
// a joint to the world joins nothing): what dWorldStep factors at once.
int largestIslandRows(const Scene& scene) {
  const auto& bodies = scene.bodies();
  std::vector<int> parent(bodies.size()), rows(bodies.size(), 0);
  for (std::size_t i = 0; i < parent.size(); ++i)
    parent[i] = static_cast<int>(i);
  auto find = [&](int i) {
    while (parent[i] != i)
      i = parent[i] = parent[parent[i]];
    return i;
  };
  auto index = [&](dBodyID b) {
    return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin());
  };
  for (const JointRecord& j : scene.joints()) {
    const int n = j.kind == JointKind::Ball ? 3 : j.kind == JointKind::Hinge ? 5 : 6;
    const int a = find(index(j.body1));
    if (j.body2) {
      const int b = find(index(j.body2));
      if (a != b) {
        parent[b] = a;
        rows[a] += rows[b];
      }
    }
    rows[a] += n;
  }
  int largest = 0;
  for (std::size_t i = 0; i < parent.size(); ++i)
    if (parent[i] == static_cast<int>(i)) largest = std::max(largest, rows[i]);
  return largest;
}

}  // namespace

Stepper parseStepper(const std::string& text) {
  Stepper s;
  s.label = text;
  if (text == "direct") {
    s.kind = Stepper::Kind::Direct;
    return s;
  }
  if (text == "blockstep") {
    s.kind = Stepper::Kind::Block;
    return s;
  }
  // IT[xSUB] after a prefix: quickstep's and the particle steppers'.
  auto iterationsBySubsteps = [&](const std::string& prefix) {
    const std::string rest = text.substr(prefix.size());
    const std::size_t x = rest.find('x');
    s.iterations = number(text, rest.substr(0, x), 1, 10000);
    if (x != std::string::npos) s.substeps = number(text, rest.substr(x + 1), 1, 1000);
  };
  for (const char* prefix : {"quickstep:", "pbd:", "xpbd:"}) {
    if (text.rfind(prefix, 0) != 0) continue;
    iterationsBySubsteps(prefix);
    if (prefix[0] != 'q') {
      s.kind = Stepper::Kind::Particles;
      s.xpbd = prefix[0] == 'x';
    }
    return s;
  }
  s.kind = Stepper::Kind::Block;
  const std::string substep = "blockstep:substep:", paper = "blockstep:paper:";
  if (text.rfind(substep, 0) == 0) {
    s.preset = Stepper::Preset::Substepped;
    s.substeps = number(text, text.substr(substep.size()), 1, 1000);
    return s;
  }
  if (text.rfind(paper, 0) == 0) {
    s.preset = Stepper::Preset::Paper;
    s.iterations = number(text, text.substr(paper.size()), 1, 10000);
    return s;
  }
  reject(text, "unknown stepper");
}

void summarize(RunResult& r, const Scene& scene, const RunOptions& options) {
  std::vector<double> solve, collide;
  double sumSq = 0.0;
  long samples = 0;
  const int lastSecond = std::max(1, static_cast<int>(std::lround(1.0 / options.dt)));
  double lastPen = 0.0;
  int lastCount = 0;
  for (std::size_t f = 0; f < r.frames.size(); ++f) {
    const FrameRecord& rec = r.frames[f];
    solve.push_back(rec.solveSeconds * 1e3);
    collide.push_back(rec.collideSeconds * 1e3);
    r.maxSeparation = std::max(r.maxSeparation, rec.joints.separation);
    r.maxAngle = std::max(r.maxAngle, rec.joints.angle);
    r.maxPenetration = std::max(r.maxPenetration, rec.penetration);
    sumSq += rec.joints.separationSumSq;
    r.runawayFrames += rec.handedToOde > 0;
    r.odeSteppedFrames += rec.steppedByOde;
    samples += rec.joints.joints;
    if (f + lastSecond >= r.frames.size()) {
      lastPen += rec.penetration;
      ++lastCount;
    }
  }
  r.framesRun = static_cast<int>(r.frames.size());
  r.medianSolveMs = median(solve);
  r.medianCollideMs = median(collide);
  r.rmsSeparation = samples > 0 ? std::sqrt(sumSq / samples) : 0.0;
  r.lastSecondPenetration = lastCount > 0 ? lastPen / lastCount : 0.0;
  if (dBodyID p = scene.probe()) {
    const dReal* now = dBodyGetPosition(p);
    const dReal* s = scene.probeStart();
    r.drift = std::sqrt((now[0] - s[0]) * (now[0] - s[0]) + (now[1] - s[1]) * (now[1] - s[1]) +
                        (now[2] - s[2]) * (now[2] - s[2]));
  }
}

RunResult run(Scene& scene, const Stepper& stepper, const RunOptions& options) {
  if (!(options.dt > 0.0) || options.dt > 1.0 || options.frames < 1)
    throw std::invalid_argument("a run needs frames >= 1 and 0 < dt <= 1 s");
  RunResult r;
  r.scene = scene.name();
  r.stepper = stepper.label;
  r.framesAsked = options.frames;
  r.frames.reserve(options.frames);
  if (stepper.kind == Stepper::Kind::Particles) return runParticles(scene, stepper, options);
  const dWorldID w = scene.world();
  if (stepper.kind == Stepper::Kind::Direct) {
    const int rows = largestIslandRows(scene);
    if (rows > options.directRowLimit) {
      r.stoppedBecause = "not run: an island of " + std::to_string(rows) +
                         " joint rows (dWorldStep takes 15-18 s a frame at 5952)";
      return r;
    }
  }
  configure(w, stepper);
  odeMessages = 0;
  // Quickstep shuffles its rows with ODE's random numbers: every run
  // starts them alike, so a run repeats whatever ran before it.
  dRandSetSeed(0);
  dMessageFunction* previousHandler = dGetMessageHandler();
  dSetMessageHandler(&countMessage);
  const auto start = Clock::now();
  for (int f = 0; f < options.frames; ++f) {
    FrameRecord rec;
    // Quickstep's sub-steps are whole steps of dt / SUB, each with its own
    // collision, as an ODE program sub-stepping does (contacts kept over
    // the sub-steps would push out their depth SUB times over).
    const int steps = stepper.kind == Stepper::Kind::Quick ? stepper.substeps : 1;
    const double h = options.dt / steps;
    int ok = 1;
    for (int k = 0; k < steps && ok; ++k) {
      const auto t0 = Clock::now();
      rec.penetration = std::max(rec.penetration, scene.collide());
      rec.contacts = scene.contactCount();
      const auto t1 = Clock::now();
      switch (stepper.kind) {
        case Stepper::Kind::Quick:
          ok = dWorldQuickStep(w, h);
          break;
        case Stepper::Kind::Direct:
          ok = dWorldStep(w, h);
          break;
        case Stepper::Kind::Block: {
          ok = dWorldBlockStep(w, h);
          dBlockStepStats stats;
          if (dWorldGetBlockStepStats(w, &stats)) {
            rec.handedToOde += stats.handedToOde;
            rec.steppedByOde |= stats.stepper == dBlockStepperOde;
          }
          break;
        }
        case Stepper::Kind::Particles:  // runParticles() steps these
          break;
      }
      const auto t2 = Clock::now();
      scene.clearContacts();
      rec.collideSeconds += seconds(t0, t1);
      rec.solveSeconds += seconds(t1, t2);
    }
    rec.joints = scene.jointError();
    rec.kineticEnergy = scene.kineticEnergy();
    r.frames.push_back(rec);
    if (options.onFrame) options.onFrame(f + 1, seconds(start, Clock::now()));
    if (!ok) {
      r.stoppedBecause =
          "the stepper refused frame " + std::to_string(f) +
          (stepper.kind == Stepper::Kind::Block ? std::string(": ") + dWorldGetBlockStepMessage(w)
                                                : std::string());
      break;
    }
    if (!finiteState(scene)) {
      r.exploded = true;
      r.stoppedBecause = "non-finite state at frame " + std::to_string(f);
      break;
    }
    // The cap is for dWorldStep, whose exact LCP takes seconds to minutes
    // a frame on cloth and lattices; the other steppers run every frame.
    if (stepper.kind == Stepper::Kind::Direct &&
        seconds(start, Clock::now()) > options.capSeconds && f + 1 < options.frames) {
      char text[120];
      std::snprintf(text, sizeof text, "wall-time cap of %g s reached after %d frames",
                    options.capSeconds, f + 1);
      r.stoppedBecause = text;
      break;
    }
  }

  dSetMessageHandler(previousHandler);
  r.odeMessages = odeMessages;
  summarize(r, scene, options);
  return r;
}

}  // namespace blockstep::compare

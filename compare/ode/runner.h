// Steps a comparison scene with one stepper and records, per frame, the
// time of collision and solve apart, the joint error measured from the
// joint geometry, the deepest contact and the kinetic energy.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "compare/ode/scene.h"

namespace blockstep::compare {

// The runs' clock, and seconds between two of its readings.
using Clock = std::chrono::steady_clock;
inline double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// A stepper and its settings, as written on the command line:
//   quickstep:IT[xSUB]     ODE's dWorldQuickStep, IT iterations, SUB steps
//                          of dt / SUB per frame, each with its collision
//   direct                 ODE's dWorldStep (exact LCP), under a wall-time cap
//   blockstep              dWorldBlockStep as a drop-in: sub-steps follow the
//                          quickstep iterations (20: 10 sub-steps)
//   blockstep:substep:N    the sub-stepped solver with N sub-steps
//   blockstep:paper:IT     the paper's solver, one step, IT sweeps
//   pbd:IT[xSUB]           the paper's position-based baseline on the same
//   xpbd:IT[xSUB]          layout (compare/pbd): a particle per body, a
//                          distance constraint per ball joint
// Settings a run changes from its stepper's own, written after it as
// ",key=value" (or swept with --sweep key=v1,v2,...); unset ones keep the
// scene's and the stepper's defaults. settingKeys() lists them.
struct Overrides {
  std::optional<double> erp, cfm;  // the world's ERP and CFM (every stepper)
  std::optional<double> dt;        // the frame step, s
  // blockstep only.
  std::optional<int> sweeps;           // velocity sweeps per sub-step
  std::optional<int> relax;            // relax sweeps per sub-step
  std::optional<bool> warm;            // warm starting
  std::optional<bool> rowByRow;        // mode=row: one row at a time, not one block per joint
  std::optional<int> islandRows;       // island blocks up to this many joint rows (0: off)
  std::optional<bool> lightGroups;     // light bodies' contacts as exact groups in larger islands
  std::optional<bool> loadContacts;    // fresh contacts on jointed bodies relative to their load
  std::optional<double> impactDepth;   // fast-closing contacts' neighbourhoods as exact groups, m
  std::optional<double> maxTravel;     // a touching body's surface travel per part, m
  std::optional<double> sinkingDepth;  // contacts still sinking after the sweeps: exact groups, m
  std::optional<bool> retakeTurns;     // parts that spin a touching body up taken again, shorter
  std::optional<bool> chains;          // larger islands cut into chains of that many rows
  std::optional<int> islandContacts;   // island blocks' contacts in their joints' null space
  std::optional<int> contactRows;      // contact islands as one block up to this many points
  std::optional<double> maxTurn;       // rad per sub-step before more sub-steps (0: off)
  std::optional<double> refreshTurn;   // rad before sub-steps prepare rows again (0: always)
  std::optional<bool> relaxDrift;      // relax closes the joints' linearization drift
  std::optional<int> projections;      // position projections at each step's end (0: off)
  std::optional<double> projectionTolerance;  // islands closed within this are not projected
  std::optional<int> threads;                 // threads sweeping independent islands (0: per core)
  // Sub-steps of joint islands and of contact islands solved exactly (0: the step's count).
  std::optional<int> exactJointSubsteps, exactContactSubsteps, calmSubsteps;
  std::optional<double> calmSpeed;
  std::optional<double> persistence;  // contact persistence, m (0: off)
  std::optional<double> tolerance;    // stop sweeping below this residual, m/s (0: off)
  // Who collides: the scene's dSpaceCollide once a frame (unset), or
  // blockstep's own collision (dWorldSetBlockCollision) once a frame or
  // before every sub-step.
  enum class Collision { Ode, Core, CoreEverySubstep };
  std::optional<Collision> collision;
};

struct Stepper {
  enum class Kind { Quick, Direct, Block, Particles } kind = Kind::Quick;
  bool xpbd = false;  // Particles: XPBD (compliance from the world's ERP and CFM), else PBD
  enum class Preset { FollowQuickStep, Substepped, Paper } preset = Preset::FollowQuickStep;
  int iterations = 20;  // quickstep iterations; the paper solver's sweeps
  int substeps = 1;     // per frame (quickstep); the sub-stepped solver's
  Overrides overrides;
  std::string label;  // as given
};

// Throws std::invalid_argument saying what is accepted. After the
// stepper's name, ",key=value" items set Overrides or, as iterations=IT
// and substeps=SUB, the numbers of the name itself.
Stepper parseStepper(const std::string& text);

// The keys a ",key=value" item or --sweep accepts, with a line each.
std::vector<std::pair<std::string, std::string>> settingKeys();

// --sweep's "key=v1,v2,...": each stepper label once per value, with
// ",key=value" added (checked later by parseStepper). Throws
// std::invalid_argument for a malformed sweep.
std::vector<std::string> sweepLabels(const std::vector<std::string>& labels,
                                     const std::string& sweep);

struct FrameRecord {
  double collideSeconds = 0.0;
  double solveSeconds = 0.0;
  JointError joints;
  double penetration = 0.0;  // deepest contact, m
  // Deepest contact whose pair touched at the collision before (Scene::deepestHeldContact), m.
  double heldPenetration = 0.0;
  // blockstep colliding itself: the deepest point its own collision found
  // within the frame, at any sub-step (dWorldGetBlockDeepestContact), m.
  // The measure above sees only the frame's end; 0 for the others.
  double foundPenetration = 0.0;
  int contacts = 0;
  double kineticEnergy = 0.0;
  double potentialEnergy = 0.0;  // of gravity, from the world's origin
  // blockstep: bodies its runaway guard handed to ODE's stepper this
  // frame; whole frames ODE stepped because blockstep does not cover the
  // content.
  int handedToOde = 0;
  bool steppedByOde = false;
};

struct RunResult {
  std::string scene, stepper;
  std::vector<FrameRecord> frames;
  int framesAsked = 0;
  int framesRun = 0;           // frames stepped (kept when the records are not: --jobs)
  bool exploded = false;       // a non-finite state
  int runawayFrames = 0;       // blockstep: frames its guard handed an island to ODE
  int odeSteppedFrames = 0;    // blockstep: frames ODE stepped instead (unsupported content)
  std::string stoppedBecause;  // empty when every frame ran
  int odeMessages = 0;         // ODE's messages during the run (e.g. "LCP internal error")
  // Summary.
  double medianSolveMs = 0.0, medianCollideMs = 0.0;
  double maxSeparation = 0.0, rmsSeparation = 0.0, maxAngle = 0.0;
  double maxPenetration = 0.0;
  double maxHeldPenetration = 0.0;     // the deepest contact the stepper had a step to act on
  double maxFoundPenetration = 0.0;    // FrameRecord::foundPenetration's largest
  double lastSecondPenetration = 0.0;  // mean deepest contact over the last second
  double drift = 0.0;                  // the probe body's distance from its start, m
  // Mechanical energy (kinetic plus gravity's potential) before the first
  // frame, and its largest excess over that during the run, J: what a
  // stepper gave the scene that nothing in it supplies (motors and
  // kinematic bodies aside).
  double startEnergy = 0.0;
  double maxEnergyGain = 0.0;
  // The most it gained since its lowest so far (the start included): a
  // stepper that gives energy back after the scene lost some (a ragdoll's
  // head spun up on the ground after the landing took 480 J) shows here
  // and not in the gain over the start.
  double maxEnergyRise = 0.0;
  // Recorded when RunOptions::poseStride > 0: every body's pose (x, y, z,
  // qw, qx, qy, qz) at the start and after every poseStride-th frame, body
  // after body, frame after frame (the report's 3D replay).
  std::vector<float> poses;
  int poseStride = 0;
};

// The error a scene is judged by: joint separation; for a stack of boxes
// (no joints) how far its probe, the top box, drifted; for a scene of
// loose bodies with no probe (a pile) the deepest contact held from one
// frame's collision to the next.
enum class SceneError { JointSeparation, ProbeDrift, HeldPenetration };
SceneError sceneErrorOf(const Scene& scene);
const char* describe(SceneError e);
double sceneError(const RunResult& r, SceneError e);

// How many quickstep runs some blockstep run beats at no more cost: lower
// error (sceneError) and settled contact no deeper (the last second's mean deepest
// contact, 0.1 mm slack). Cost is the median solve time, or with
// `withCollision` the solve and collision times together, the frame's
// whole physics: a program that sub-steps quickstep collides every
// sub-step, and blockstep colliding by itself every sub-step
// (collision=substep) counts its collision apart from its solve too.
// Runs that stopped early take no part.
struct Standing {
  int quick = 0;   // quickstep runs judged
  int beaten = 0;  // of those, beaten by some blockstep run
};
Standing standing(const std::vector<RunResult>& results, const std::vector<Stepper>& steppers,
                  SceneError measure, bool withCollision);

struct RunOptions {
  int frames = 300;
  double dt = 1.0 / 60.0;
  double capSeconds = 60.0;  // wall time a dWorldStep run may take (minutes on cloth)
  // dWorldStep is not run on an island of more joint rows than this: its
  // dense factorization took 15-18 s for one frame of cloth32 (5952 rows).
  int directRowLimit = 3000;
  // Called after each frame with the frames done and the seconds spent
  // (the command line's progress line); may be empty.
  std::function<void(int, double)> onFrame;
  // Record the bodies' poses every this many frames (0: not at all).
  int poseStride = 0;
  // Print every contact deeper than this (m) at each measured collision,
  // with both bodies' mass and motion, to stderr (0: none): where a run's
  // deepest contact came from.
  double traceDepth = 0.0;
  // Print blockstep's kinetic and potential energy after each stage of
  // every sub-step (dWorldGetBlockStageEnergy) of frames [from, to] to
  // stderr (from < 0: none): which stage of a step gains energy.
  int traceEnergyFrom = -1;
  int traceEnergyTo = -1;
  // 0: the scene as built. s > 0: before the first frame, every body's
  // velocity is moved by kPerturbSpeed in a direction drawn from seed s
  // (perturbStart): runs of a scene whose outcome is chaotic (a ragdoll's
  // landings, a pile) then show the spread of what a stepper gives, not
  // one draw of it.
  int perturbSeed = 0;
};

// The speed each body's start is moved by under RunOptions::perturbSeed,
// m/s: far below what any measure reads in one frame, and enough for a
// chaotic scene to go its own way within a second.
constexpr double kPerturbSpeed = 1e-4;
// Moves every body's linear velocity by kPerturbSpeed in a direction
// drawn from seed (> 0; the same seed, the same moves).
void perturbStart(Scene& scene, int seed);

// Appends the scene's body poses to r.poses when frame `done` (frames
// stepped so far) is one to record.
void recordPoses(const Scene& scene, int done, const RunOptions& options, RunResult& r);

RunResult run(Scene& scene, const Stepper& stepper, const RunOptions& options);

// The particle steppers' run (particle_run.cpp): the scene turned into
// particles once, stepped by compare/pbd, written back to the bodies each
// frame. A scene it cannot stand for (joints other than balls, bodies that
// collide with one another, shapes it has no particle for) is not run,
// and stoppedBecause says why.
RunResult runParticles(Scene& scene, const Stepper& stepper, const RunOptions& options);

// The joint rows of the scene's largest island (bodies joined by joints;
// a joint to the world joins nothing): what dWorldStep factors at once.
int largestIslandRows(const Scene& scene);

// A run's summary (medians, maxima, drift) from its frames.
void summarize(RunResult& r, const Scene& scene, const RunOptions& options);
// The same from the frames alone (frames of dt seconds), drift left as it is.
void summarizeFrames(RunResult& r, double dt);

}  // namespace blockstep::compare

// One ODE world stepped by blockstep. The bridge keeps a core World that
// mirrors the ODE world's bodies and joints (so warm-start impulses and
// joint frames live on between steps) and at each step:
//   1. reads every joint and contact (nothing is changed yet: a kind or
//      mode the core cannot model, or bad input, returns before any write,
//      so the caller can step that world with ODE instead);
//   2. runs ODE's auto-disable and island wake-up rules;
//   3. copies bodies (pose, velocity, mass, force and torque accumulators,
//      gravity mode, kinematic, max angular speed) into the core;
//   4. makes, remakes (when the program moved an anchor or axis) or
//      updates (limits, motors, ERP/CFM) the core joints, and hands over
//      the contacts grouped into manifolds;
//   5. steps the core and writes poses, velocities, cleared accumulators,
//      ODE-style damping and dJointFeedback back.
//
// ERP and CFM: in ODE a pair (ERP, CFM) chosen for step h is a spring
// k = ERP / (h CFM) and damper d = (1 - ERP) / CFM (ODE manual, "How to use
// ERP and CFM"). A row whose CFM is above ODE's default 1e-5 is the program
// asking for a soft joint or contact (soft_cfm): it becomes that spring,
// the same stiffness whatever the sub-step. Rows at or below 1e-5 count as
// rigid: under sub-stepping they take the solver's rigid-row softness
// (SolverSettings::rigidJointSoftness), otherwise they keep (ERP, CFM).
#pragma once

#include <ode/ode.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "adapters/ode/contact_mapping.h"
#include "adapters/ode/joint_mapping.h"
#include "adapters/ode/pointer_map.h"
#include "core/world/world.h"

namespace blockstep::ode {

struct WorldRecord;

// Which of ODE's steppers the program called.
enum class OdeStepper { QuickStep, Step };

struct BridgeSettings {
  // Follow what the program asked of ODE. dWorldQuickStep: derive the
  // solver from the world's quickstep iteration count
  // (dWorldGetQuickStepNumIterations): n iterations become n / 2 sub-steps
  // of one solve sweep and one relax sweep (SolverSettings::subStepped),
  // so an A/B run against quickstep spends the same number of sweeps.
  // dWorldStep, ODE's exact solver: SolverSettings::direct().
  bool followQuickStepIterations = true;
  SolverSettings solver = SolverSettings::subStepped(10);

  // Whatever the solver above (followed or explicit): island blocks up to
  // this many rows (unset: the solver's own choice), and the runaway
  // guard's limits (SolverSettings::runawayEnergyGain, runawaySpeed).
  std::optional<int> islandBlockRows;
  // Islands larger than that cut into chains (SolverSettings::chainBlocks;
  // unset: the solver's own).
  std::optional<bool> chainBlocks;
  // Contacts of island blocks in their joints' null space: 0 never, 1
  // always (SolverSettings::islandBlockContacts), 2 in steps where one is
  // an impact (SolverSettings::islandBlockImpacts); unset: the solver's own.
  std::optional<int> islandBlockContacts;
  // Contact islands as one exact block up to this many normal rows
  // (SolverSettings::contactIslandRows; unset: the solver's own).
  std::optional<int> contactIslandRows;
  // In larger contact islands, each light body's manifolds as one exact
  // group (SolverSettings::lightBodyGroups; unset: the solver's own).
  std::optional<bool> lightBodyGroups;
  // Fresh contacts on jointed bodies give no more under their load than
  // under their own weight (SolverSettings::loadRelativeContacts; unset:
  // the solver's own).
  std::optional<bool> loadRelativeContacts;
  // In larger contact islands, the manifolds around each fast-closing
  // fresh contact as one exact group (SolverSettings::impactDepth, m;
  // unset: the solver's own).
  std::optional<double> impactDepth;
  // In larger contact islands, the manifolds around each contact still
  // sinking after the sweeps as one exact group (SolverSettings::
  // sinkingDepth, m; unset: the solver's own).
  std::optional<double> sinkingDepth;
  // Colliding every sub-step, a part that spins a touching body past the
  // turn per sub-step is taken again, shorter
  // (SolverSettings::retakeTurningParts; unset: the solver's own).
  std::optional<bool> retakeTurningParts;
  // The turn per sub-step above which a step runs more sub-steps
  // (SolverSettings::maxTurnPerSubstep; unset: the solver's own).
  std::optional<double> maxTurnPerSubstep;
  // Colliding every sub-step, the farthest a touching body's turn may move
  // its surface within a part (SolverSettings::maxSurfaceTravelPerSubstep,
  // m; unset: the solver's own).
  std::optional<double> maxSurfaceTravelPerSubstep;
  // The turn before sub-steps prepare their rows again
  // (SolverSettings::maxTurnPerRefresh; unset: the solver's own).
  std::optional<double> maxTurnPerRefresh;
  // Relax closes the joints' linearization drift
  // (SolverSettings::relaxCancelsDrift; unset: the solver's own).
  std::optional<bool> relaxCancelsDrift;
  // Position projections after each sub-step's position update
  // (SolverSettings::positionProjections; unset: the solver's own).
  std::optional<int> positionProjections;
  // Islands closed within this are not projected
  // (SolverSettings::projectionTolerance; unset: the solver's own).
  std::optional<double> projectionTolerance;
  // Threads sweeping independent islands (SolverSettings::threads; unset:
  // the solver's own, 1).
  std::optional<int> threads;
  // Sub-steps of joint and of contact islands solved exactly
  // (SolverSettings::exactJointIslandSubsteps, exactContactIslandSubsteps;
  // 0: the nominal count; unset: the solver's own).
  std::optional<int> exactJointIslandSubsteps, exactContactIslandSubsteps;
  // Sub-steps of a calm island and its largest closing speed, m/s
  // (SolverSettings::calmTouchedIslandSubsteps, calmApproachSpeed; unset:
  // the solver's own).
  std::optional<int> calmTouchedIslandSubsteps;
  std::optional<double> calmApproachSpeed;
  // Record each sub-step's energy after every stage
  // (SolverSettings::recordStageEnergy), whatever the solver.
  bool recordStageEnergy = false;
  double runawayEnergyGain = SolverSettings{}.runawayEnergyGain;
  double runawaySpeed = SolverSettings{}.runawaySpeed;
  // World::setContactPersistence: a pair ODE's collider gives one or two
  // points that tip a body keeps its recent points within this distance
  // (m; 0: off). 5 mm lays demo_moving_convex's coin flat; at 20 mm a
  // box landing on a corner came to rest propped 3.3 degrees on an edge
  // with two carried corners 13.6 mm above the ground (cause not found).
  double contactPersistence = 0.005;

  // blockstep's own collision (dWorldSetBlockCollision): the geoms of this
  // space, and of the spaces inside it, become core shapes that the core
  // collides (GJK/EPA, manifolds of up to four points, speculative
  // contacts within CollisionSettings::margin) each step, or each
  // sub-step, with `collisionSurface` as ODE would read it from a contact.
  // The contact joints the program makes are solved as well. nullptr: off.
  dSpaceID collisionSpace = nullptr;
  dSurfaceParameters collisionSurface{};
  bool collideEverySubstep = false;

  // The drop-in's solver for quickstep's iteration count: iterations / 2
  // sub-steps, and one for an island of contacts solved as one exact group
  // (a stack stands as still at one as at ten, for a third of the time)
  // and for an island of joints solved exactly that nothing touches (its
  // joints hold at any step and SHAKE's projection keeps its energy:
  // chains at quickstep 20's cost hold to 0.001 mm where quickstep's
  // open 204 mm; README "Fewer sub-steps for exact islands").
  static SolverSettings fromQuickStepIterations(int iterations);
  static constexpr int kExactContactIslandSubsteps = 1;
  static constexpr int kExactJointIslandSubsteps = 1;
};

enum class StepOutcome {
  Stepped,
  Unsupported,  // a joint kind or mode without a mapping; the world is untouched
  Invalid,      // bad input (non-finite state, bad mass, bad step); the world is untouched
};

class WorldBridge {
 public:
  explicit WorldBridge(dWorldID world);

  StepOutcome step(const WorldRecord& record, double h, OdeStepper stepper = OdeStepper::QuickStep);
  // Why the last step was not Stepped, or which islands it handed back.
  const std::string& message() const { return message_; }

  // Called by the registry when ODE destroys these.
  void forgetBody(dBodyID body);
  void forgetJoint(dJointID joint);

  // The core joint's carried state (a transmission's wheel angles and
  // contact points), or nullptr when the joint has no core joint yet.
  const JointState* jointState(dJointID joint) const;

  // The bodies the last step moved that have a dBodySetMovedCallback; the
  // caller calls them once the step is over (ODE calls them as it moves
  // each body, after the solve).
  const std::vector<dBodyID>& movedWithCallback() const { return movedWithCallback_; }

  // The bodies of the islands the last step handed back (the runaway
  // guard caught them: message() says why): they are as they were before
  // the step, forces kept, for the caller to step with ODE's stepper.
  const std::vector<dBodyID>& runawayBodies() const { return runawayBodies_; }

  BridgeSettings& settings() { return settings_; }
  const StepStats& stats() const { return core_.lastStepStats(); }
  const World& core() const { return core_; }
  // Geoms of the collision space blockstep leaves out of its collision
  // (no core shape for their class), or "".
  const std::string& collisionNote() const { return collisionNote_; }
  // The ClampedInput kinds the last step brought into range.
  unsigned clampedInputs() const { return clamped_; }

 private:
  struct BodySleep {  // ODE's auto-disable state of one body
    int stepsLeft = 0;
    double timeLeft = 0.0;
    int sampleCount = 0;  // samples wanted (dBodyGetAutoDisableAverageSamplesCount)
    int next = 0;
    bool ready = false;
    bool wasDisabled = false;
    bool initialized = false;
    bool moved = false;  // lastX / lastQ hold the pose after our last step
    Vec3 lastX = Vec3::Zero();
    Quat lastQ = Quat::Identity();
    Vec3 linearSample = Vec3::Zero();  // the motion over our last step, per second
    Vec3 angularSample = Vec3::Zero();
    double lastStep = 0.0;
    std::vector<Vec3> linear, angular;
  };
  struct MappedBody {
    BodyId id = -1;
    int heldSteps = 0;  // ODE steps its island for this many more steps (runaway)
    BodySleep sleep;
  };
  // The ODE joint of each core joint id (set when made; forgetBody reads
  // it for the core's joints of a body).
  std::vector<dJointID> odeJointOf_;
  struct MappedJoint {
    JointId id = -1;
    int type = -1;
    dBodyID body1 = nullptr, body2 = nullptr;
    JointGeometry local;  // geometry in its body's frame at creation
    double offset[3] = {0.0, 0.0, 0.0};
    bool seen = false;
    // What the core joint was last made or updated from: the joint's
    // setter count (JointRecord::changes) and the world's rows' settings
    // then, and the ClampedInput kinds its read brought into range. While
    // they hold, the joint is not read again (readAll).
    bool readValid = false;
    std::uint32_t readChanges = 0;
    struct ReadKey {
      double erp = 0.0, cfm = 0.0, step = 0.0;
      bool operator==(const ReadKey&) const = default;
    } readKey;
    unsigned readClamped = 0;
  };

  bool readAll(const WorldRecord& record);
  void autoDisable(const WorldRecord& record, double h);
  void wakeIslands(const WorldRecord& record);
  void syncBodies(const WorldRecord& record);
  void syncJoints(const WorldRecord& record);
  void syncShapes();
  void syncSpace(dSpaceID space);
  void handBackRunaways(const WorldRecord& record);
  bool handedBack(dBodyID body);
  dBodyID odeBody(const WorldRecord& record, BodyId id);
  dJointID odeJoint(const WorldRecord& record, JointId id) const;
  void writeBack(const WorldRecord& record);
  void writeFeedback(const WorldRecord& record);
  void writeContactFeedback();
  BodyId coreBody(dBodyID body);
  MappedBody& mapBody(dBodyID body);
  JointGeometry toLocal(const JointGeometry& g, dBodyID body1, dBodyID body2) const;
  bool sameGeometry(const MappedJoint& m, const JointGeometry& now) const;
  void makeJoint(MappedJoint& m, dJointID j, JointRead& read);
  SolverSettings solverFor(OdeStepper stepper) const;
  static Softness jointSoftness(double erp, double cfm, const void* bridge);
  Softness contactSoftness(double erp, double cfm) const;

  dWorldID world_;
  World core_;
  BridgeSettings settings_;
  PointerMap<dBodyID, MappedBody> bodies_;
  PointerMap<dJointID, MappedJoint> joints_;
  struct MappedGeom {
    ShapeId id = -1;  // -1: no core shape (its class has none)
    bool seen = false;
  };
  PointerMap<dGeomID, MappedGeom> geoms_;
  std::vector<dGeomID> goneGeoms_;
  std::string collisionNote_;
  // Per step, reused.
  std::vector<JointRead> reads_;  // one per record.joints entry (contacts: unused)
  // Per entry of reads_: the joint is as the core has it (not read again),
  // its setter count at the read, the ClampedInput kinds the read set.
  struct ReadState {
    bool unchanged = false;
    std::uint32_t changes = 0;
    bool counted = false;  // the registry counts its setters (a record)
    unsigned clamped = 0;
  };
  std::vector<ReadState> readStates_;
  MappedJoint::ReadKey readKey_;  // this step's
  std::vector<ContactManifold> pointContacts_, manifolds_;
  ContactGrouping grouping_;                                // groupContacts' scratch
  std::vector<std::pair<dBodyID, dBodyID>> contactBodies_;  // ODE body1, body2 of each point
  struct ContactFeedback {  // a contact joint whose dJointFeedback the program reads
    dJointFeedback* out;
    dBodyID body1, body2;
    BodyId core1, core2;
    Vec3 position;
  };
  std::vector<ContactFeedback> contactFeedback_;
  std::vector<dBodyID> movedWithCallback_;
  std::vector<dBodyID> runawayBodies_;
  std::vector<std::uint8_t> handedBack_;  // by core body: in runawayBodies_
  std::vector<BodyId> heldIds_, islandParent_;
  // Steps a caught island stays with ODE's stepper before blockstep tries
  // it again: a second at 60 Hz.
  static constexpr int kHoldSteps = 60;
  WorldContactParams contactParams_;
  double step_ = 0.0;
  std::string message_;
  mutable unsigned clamped_ = 0;  // ClampedInput kinds, this step
};

}  // namespace blockstep::ode

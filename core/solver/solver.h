// The block Sequential-Impulses step (section 4.3), as a list of stages.
// The World owns bodies and joints; the Solver owns only per-step
// workspace, sized on the first step and reused (no allocation per step
// once a scene has warmed up).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "core/body/body.h"
#include "core/constraints/contact.h"
#include "core/constraints/joint.h"
#include "core/constraints/parts/row_writer.h"
#include "core/constraints/row.h"
#include "core/solver/contact_island.h"
#include "core/solver/island_block.h"
#include "core/solver/runaway_guard.h"
#include "core/solver/settings.h"
#include "core/solver/solver_body.h"

namespace blockstep {

struct StepInput {
  std::vector<Body>& bodies;
  std::vector<Joint>& joints;
  std::vector<ContactManifold>& contacts;  // this step's; impulses are written back
  const Body& worldBody;                   // the static frame behind kWorldBody
  Vec3 gravity;
  double h;  // the whole step, s
  // The step whose rate caps how fast contacts push out of penetration
  // (Solver::penetrationRate): the caller's whole step when it steps in
  // parts (collision every sub-step); 0: h.
  double penetrationStep = 0.0;
  // Contacts from this index on were found where the bodies are at this
  // step's start (collision every sub-step): their depth is measured, not
  // carried from an earlier collision, and deep ones push out faster
  // (Solver::penetrationRate). The caller's own contacts come before them.
  std::int32_t firstFreshContact = std::numeric_limits<std::int32_t>::max();
  // Clear the bodies' force and torque accumulators after the step; a
  // caller stepping in parts keeps them until its last part.
  bool clearForces = true;
  // The sub-step that step-relative springs (Softness::stepSpring) are
  // stiff for: the caller's nominal sub-step when it steps in more parts
  // than its settings' sub-steps; 0: h over the settings' sub-steps.
  double nominalSubstep = 0.0;
};

class Solver {
 public:
  // The stages of one step, in order. Each sub-step runs
  // IntegrateVelocities .. StoreImpulses; BuildIslands runs once per step
  // and Finish after the last sub-step.
  enum class Stage {
    BuildIslands,         // union-find over enabled joints between dynamic bodies
    IntegrateVelocities,  // forces, gravity, damping, gyroscopic term
    Prepare,              // rows, bias, CFM, K and its LDL^T per block
    WarmStart,            // apply last solve's impulses, scaled to the step size
    Solve,                // block Gauss-Seidel sweeps until a stop criterion
    IntegratePositions,   // x += h v, q += h/2 (0, w) q, renormalize
    Relax,                // bias-free sweeps
    StoreImpulses,        // keep impulses for warm starting and feedback
    Finish,               // breakable joints, clear forces, statistics
  };

  void step(const StepInput& in, const SolverSettings& settings, StepStats& stats);

  // Feedback and errors read the rows of the last step.
  JointFeedback feedback(const Joint& joint, double h) const;

  // The most sub-steps a step with these settings runs (maxTurnPerSubstep).
  static int mostSubsteps(const SolverSettings& s);
  // The sub-steps of a step of h turning at turnRate rad/s: the nominal
  // count, or more past maxTurnPerSubstep a sub-step (an island that
  // turned fast in the last step; the world's collision parts).
  static int substepsAt(const SolverSettings& s, double h, double turnRate);
  // The same from another nominal count (SolverSettings::
  // exactJointIslandSubsteps, exactContactIslandSubsteps).
  static int substepsAt(const SolverSettings& s, double h, double turnRate, int nominal);

 private:
  void buildIslands(const StepInput& in, const SolverSettings& s);
  template <class IslandOf>
  void chooseClasses(const StepInput& in, const SolverSettings& s, IslandOf islandOf);
  template <class IslandOf>
  void noteCalmIslands(const StepInput& in, const SolverSettings& s, IslandOf islandOf);
  static constexpr std::size_t kEveryClass = static_cast<std::size_t>(-1);
  void useClass(std::size_t c);
  using Clock = std::chrono::steady_clock;
  void runSubsteps(const StepInput& in, const SolverSettings& s, int substeps,
                   Clock::time_point start, StepStats& stats);
  // The fastest turn of a body in a constrained island, after a sweep:
  // the whole turn (carried rows) and the turn its joint anchors see
  // (sub-step counts).
  void notePeakTurnRate(const StepInput& in, const SolverSettings& s);
  void noteLeverArms(const StepInput& in);
  // Which turn of a body its rows see (noteLeverArms): none, all but
  // the turn about one line through its centre of mass (leverAxis_, body
  // frame), or all.
  enum class LeverArms : std::uint8_t { None, OnAxis, Any };
  // A row's softness as this step uses it (a StepSpring at the nominal
  // sub-step when the step runs more).
  Softness softnessOf(const Softness& soft, double h) const;
  // The rates of the softness last asked for, kept while the next row
  // asks for the same one (finishBlock).
  struct SoftnessCache {
    const Softness* of = nullptr;
    SoftnessAtStep rates;
  };
  const SoftnessAtStep& ratesOf(const Softness& soft, double h, SoftnessCache& cache) const;
  void integrateVelocities(const StepInput& in, const SolverSettings& s, double h);
  void recordStageEnergy(const StepInput& in, const SolverSettings& s,
                         StageEnergySample::After after, int sub, int substeps, StepStats& stats);
  void prepare(const StepInput& in, const SolverSettings& s, double h);
  bool carriesRows(const SolverSettings& s, int sub, double h);
  void carryRows(const StepInput& in, const SolverSettings& s, double h);
  void buildJointBlock(const StepInput& in, const SolverSettings& s, double h, std::int32_t j,
                       ConstraintBlock& blk);
  const Vec3& turnSinceStart(const StepInput& in, BodyId i);
  struct ContactSide {
    Vec3 lever;  // from the body's centre to the contact point, now
    Vec3 moved;  // how far the body's surface there moved since the step's start
  };
  static ContactSide contactSide(const Vec3& local, double radius, const Vec3& outward,
                                 const Vec3& x, const Quat& q, const Vec3& x0, const Quat& q0,
                                 const Vec3& turn);
  void buildContactBlock(const StepInput& in, const SolverSettings& s, double h, std::int32_t c,
                         ConstraintBlock& blk);
  double penetrationRate(const ConstraintRow& row, const ConstraintBlock& blk, double h) const;
  // Depth past which fresh contacts push out faster (penetrationRate), m.
  static constexpr double kDeepPenetration = 0.002;
  // A contact row's residual (m/s) its block solution may leave: far
  // below anything a step moves, far above the factor's rounding.
  static constexpr double kUnmetResidual = 1e-3;
  double blockSpringShare(const SolverSettings& s, double h, const ConstraintBlock& blk,
                          bool inIslandBlock, SoftnessCache& cache) const;
  void selectContactIslands(const StepInput& in, const SolverSettings& s, double h);
  bool groupableContact(const StepInput& in, const ConstraintBlock& blk) const;
  bool closesPast(const ConstraintBlock& blk, double h, double depth) const;
  bool closesBy(const ConstraintBlock& blk, double h, double depth) const;
  void markImpactIslands(double h);
  void solveSinkingContacts(const StepInput& in, const SolverSettings& s, double h,
                            StepStats& stats);
  bool carriesLoadThroughJoint(const SolverSettings& s, const ConstraintBlock& blk) const;
  void finishBlock(const SolverSettings& s, double h, ConstraintBlock& blk, bool inIslandBlock,
                   bool inGroup, bool islandSolvesAll);
  // J v with the velocities the (sub-)step started from.
  double startVelocity(const ConstraintRow& row, const ConstraintBlock& blk) const;
  void solveEqualityBlock(ConstraintBlock& blk, bool useBias, SolverBody& a, SolverBody& b);
  void projectedContactSweeps(ConstraintBlock& blk, bool useBias, SolverBody& a, SolverBody& b);
  void solveFriction(ConstraintBlock& blk, bool useBias, SolverBody& a, SolverBody& b);
  void solveNormals(ConstraintBlock& blk, bool useBias, BlockMode mode, SolverBody& a,
                    SolverBody& b);
  void solveContact(ConstraintBlock& blk, bool useBias, BlockMode mode, SolverBody& a,
                    SolverBody& b);
  static void storeContactImpulses(ContactManifold& m, const ConstraintRow* rows, int n, double h);
  void warmStart();
  int solve(const SolverSettings& s, int substep, double deadline, StepStats& stats);
  void integratePositions(const StepInput& in, const SolverSettings& s, double h);
  static Quat turn(const Quat& q, const RotationUpdate& r, const Vec3& w, double h);
  bool projectPositions(const StepInput& in, const SolverSettings& s, double h, int sub);
  // Position projection keeps the prepared factor while an island turned
  // less than this since its rows were prepared (rad), and checks a pass
  // that turned a body farther than kLinearProjectionTurn (rad).
  static constexpr double kStaleProjectionTurn = 0.05;
  // An island at the exact joint islands' own count (exactJointIslandSubsteps)
  // that turned less than this since its rows were prepared is projected
  // as SHAKE (Ryckaert, Ciccotti and Berendsen 1977) projects: at any
  // error, along the prepared rows (M^-1 J^T of the sub-step's start, with
  // its factor), and its moved bodies take the velocity of their moves
  // (alpha = 1 in payForProjection). The next step's solve then takes out
  // the part along the new rows, as RATTLE does, and for a pendulum the
  // two leave its speed as it was: the velocity the solve made tangent at
  // the old pose loses nothing turning to the new one. At one sub-step
  // relax, and the bare projection, took about (w h)^2 of a turning
  // joint's kinetic energy a step: the star of ODE's demo_I lost 13% of
  // it in 600 frames (now 0.0%) and PyODE's tutorial2 double pendulum
  // (h = 1/50 s) kept 56.8% over 10 s (now 99.9%; dWorldStep 75.3%).
  // Past this turn the prepared rows miss the pose and the projection
  // works at the pose as in other islands: at 0.3 rad the thin links of
  // chain_swing opened 4.3 mm, at 0.5 rad 11.7 mm (1.2 mm at 0.2, 0.2 mm
  // at 0.1, where the double pendulum kept only 71.6%).
  static constexpr double kShakeTurn = 0.2;
  // SHAKE's pass is kept if it closed the errors to this part of what they
  // were, or within the projection tolerance; else the island is projected
  // at its pose (a 100:1 chain turning 0.15 rad a step from quickstep's
  // pose closed 2.2 mm to 2.1 with the prepared rows).
  static constexpr double kShakeContraction = 0.5;
  // An island block's motors hold its joints as equality rows do while
  // within their force (a motor-held beam is rigid), and couple among
  // themselves through the island as those rows do (in a beam of
  // motor-held hinges each motor's moment leans on its neighbours'); one
  // Gauss-Seidel pass over them a sweep lags behind that: at one or two
  // sub-steps ODE's demo_feedback bridge (15 motors between two sliders)
  // swung up to 0.07 J and the runaway guard caught it. A step at fewer
  // sub-steps than this gives them this many passes a step in all (16 /
  // substeps a sweep), what more sub-steps would give: cheap, as a pass
  // moves the island's bodies by each row's precomputed velocity changes
  // and does not use the island's factor. Limits keep one pass: converged
  // in the air, the thrown ragdoll's stops carried more into its landing,
  // and at one sub-step its energy rose 42 J after it instead of 15
  // (ragdoll_pile 159 J instead of 79; medians of 7 starts).
  static constexpr int kMotorPassesPerStep = 16;
  static constexpr double kLinearProjectionTurn = 0.05;
  // How far from a body its mass counts against turning it in position
  // projection's metric at the pose, in sizes of its island (the extent of
  // its bodies' centres). At 1 chain_heavy_swing (a 100 kg end on 0.1 kg
  // links) still opened 99 mm at one sub-step, at 2 6.7 mm, at 4 0.55 mm;
  // chain_swing, hair, the bridge and the ragdolls held alike from 1 to 8.
  static constexpr double kProjectionReach = 2.0;
  using JointRowScratch = std::array<ConstraintRow, kMaxJointSlots>;
  // shake: SHAKE's velocity (alpha = 1), whatever the work.
  void payForProjection(const StepInput& in, int island, bool shake);
  bool projectIsland(const StepInput& in, const SolverSettings& s, int island, double sincePrepared,
                     JointRowScratch& scratch);
  void relaxAgainstDrift(const StepInput& in, double h);
  void relax(const SolverSettings& s, double h);
  void storeImpulses(const StepInput& in, double h);
  void finish(const StepInput& in, StepStats& stats);

  void sweep(int island, bool useBias, BlockMode mode);
  // One sweep of every island: on the calling thread, or spread over the
  // pool's threads (islands share no movable body, so any order gives the
  // same bits).
  void sweepIslands(bool useBias, BlockMode mode);
  void usePool(const SolverSettings& s);
  // f(i) for every i in [0, n): on the pool's threads when there is one
  // and n is worth it. Every f(i) must write only what is its own.
  // grain: the fewest items worth handing to a thread.
  template <class F>
  void forEachIndex(int n, F&& f, int grain = 256) {
    using Fn = std::remove_reference_t<F>;
    forRanges(n, grain, &f, [](void* fn, int begin, int end) {
      for (int i = begin; i < end; ++i)
        (*static_cast<Fn*>(fn))(i);
    });
  }
  void forRanges(int n, int grain, void* fn, void (*range)(void*, int, int));
  // f(i) for each body the class being stepped moves (useClass): every
  // body, or the class's own; on the pool's threads unless `serial`.
  template <class F>
  void forEachBody(int bodyCount, F&& f, bool serial = false) {
    const std::int32_t* list = everyBody_ ? nullptr : classBodies_.data() + classBodyBegin_;
    const int n = everyBody_ ? bodyCount : classBodyEnd_ - classBodyBegin_;
    auto body = [&](int k) { f(list ? list[k] : static_cast<std::int32_t>(k)); };
    if (!serial) {
      forEachIndex(n, body);
      return;
    }
    for (int k = 0; k < n; ++k)
      body(k);
  }
  struct ThreadPool;
  std::shared_ptr<ThreadPool> pool_;   // kept while the thread count stays
  bool pooled_ = false;                // this step has more than one thread
  bool useIslandBlock_ = false;        // this step's settings ask for island blocks
  bool islandBlocksSelected_ = false;  // chosen on the step's first sub-step
  // The rigid-row softness inside island blocks (prepare() says why).
  Softness islandRigid_;
  // The fastest whole turn of a body in the class being stepped
  // ((rad/s)^2, this step's so far) and of its bodies' islands in the
  // last step (rad/s).
  double peakTurnRate_ = 0.0;
  double lastTurnRate_ = 0.0;
  // Per island, this step's fastest turn its joint anchors see
  // ((rad/s)^2, noteLeverArms); per body, its island's in the last step
  // (rad/s), and per island, the largest of its bodies' (rad/s).
  std::vector<double> islandTurn_, bodyTurn_, islandLastTurn_;
  // The same for the whole turn (carried rows).
  std::vector<double> islandFullTurn_, bodyFullTurn_, islandLastFullTurn_;
  std::vector<LeverArms> leverArms_;
  std::vector<std::uint8_t> islandTouched_;  // per island: a contact holds it, this step
  // Per body: its island was solved exactly in the last step (an island
  // block, projected, touching nothing; or contacts only, one exact group);
  // per island (chooseClasses, before it numbers them by class), the least
  // of its bodies' (a joint island: unless a contact holds it now).
  std::vector<std::uint8_t> bodySolvedExactly_, islandSolvedExactly_;
  // Per body: its island's joints were one projected island block in the
  // last step, touched or not; per island (chooseClasses): all of its
  // bodies' were, and no point of its contacts closes faster than
  // calmApproachSpeed (calmTouchedIslandSubsteps).
  std::vector<std::uint8_t> bodyInIslandBlock_, islandCalm_, calmScratch_;
  std::vector<std::uint64_t> exactSerial_;  // per body: Body::serial when its flag was set
  // Their values, ordered so that an island takes the least of its bodies'.
  static constexpr std::uint8_t kNotExact = 0, kExactJoints = 1, kExactContacts = 2;
  // Per island (final numbering): it takes exactJointIslandSubsteps.
  std::vector<std::uint8_t> islandAtExactJointCount_, exactJointCountScratch_;
  bool contactsExactlyOnce(std::int32_t island) const;
  std::vector<std::uint8_t> islandImpact_;  // per island: a contact of it is an impact (prepare)
  std::vector<std::uint8_t>
      impactJointed_;  // per solver body: a joint holds it (markImpactIslands)
  std::vector<Vec3> leverAxis_;
  bool turnRateSeen_ = false;    // a step has measured it (a first step has no history)
  double nominalSubstep_ = 0.0;  // s: the step over the settings' sub-steps
  void coupleBoundedRows(const ConstraintBlock& blk);
  void solveCoupledRow(int rowIndex, bool useBias, ConstraintRow* eq, int ne, SolverBody& a,
                       SolverBody& b);
  // Residual of one island after a sweep: max and sum of squares, rows counted.
  void islandResidual(int island, double& max, double& sumSq, int& count) const;
  std::int32_t solverIndex(BodyId id) const;

  std::vector<SolverBody> bodies_;     // one per world body, then the static dummy
  std::vector<Vec3> startV_, startW_;  // velocities before the step (explicit Euler)
  std::vector<Vec3> startX_;           // poses at the step's start: contacts stay there
  std::vector<Quat> startQ_;
  std::vector<Vec3> gyroOffset_;          // midpoint minus end angular velocity (gyroscopic)
  std::vector<std::uint8_t> heldByRows_;  // per body: a joint or contact acts on it this step
  std::vector<ConstraintBlock> blocks_;
  std::vector<ConstraintRow> rows_;
  // Each joint's warm-start impulses and their sum over the step, side by
  // side while the step runs: taken from the joints at its start, kept
  // here after every sub-step, written back before finish(). The Joint
  // objects are large and scattered; written after every sub-step they
  // cost cloth32 7.6% of its step in cache misses.
  struct JointImpulses {
    std::array<double, kMaxJointSlots> warm{}, step{};
    std::uint32_t slots = 0;  // Joint::warmSlots
    double stepSize = 0.0;    // Joint::warmStepSize
  };
  std::vector<JointImpulses> jointImpulses_;
  // Each block's equality matrix (K, its factor or inverse), packed one
  // after another (ConstraintBlock::matrix).
  std::vector<double> blockMatrices_;
  double* matrixOf(const ConstraintBlock& blk) { return blockMatrices_.data() + blk.matrix; }
  std::array<ConstraintRow, kMaxJointSlots> movedRows_;  // a joint's rows at the new pose
  // Position projection (projectPositions): per row, its error at the new
  // pose and its position impulse; per solver body, its move and turn.
  std::vector<double> projectionError_, projectionImpulse_;
  std::vector<ConstraintRow> projectionRows_;  // Jacobians and M^-1 J^T at the new pose
  std::vector<Vec3> projectionMove_, projectionTurn_;
  std::vector<Mat3> projectionInvI_;  // per solver body: its inverse inertia at the new pose
  std::vector<Vec3> projectionX_;     // per solver body: its pose before the last pass
  std::vector<Quat> projectionQ_;
  std::vector<Vec3> projectionStartX_;  // per solver body: its pose before the first pass
  std::vector<Quat> projectionStartQ_;
  std::vector<std::uint8_t> projectionMark_;        // per solver body: counted once (projectIsland)
  std::vector<JointRowScratch> projectionScratch_;  // a joint's rows at the pose, per thread
  // Islands whose joint equality rows are one block: a selection per
  // class (each keeps its choice while its structure stays), and the
  // class whose selection is in use.
  std::vector<IslandBlocks> islandBlocksOf_ = std::vector<IslandBlocks>(1);
  std::size_t islandBlocksInUse_ = 0;
  // Islands whose contact normals are one exact block (contact_island.h)
  // in the class being stepped, and the settings' bound (0: none).
  ContactIslands contactIslands_;
  int contactIslandRows_ = 0;
  int islandFrictionPasses_ = 1;  // friction passes a sweep in contact islands (runSubsteps)
  // Passes over an island block's motors a sweep (runSubsteps,
  // kMotorPassesPerStep).
  int islandMotorPasses_ = 1;
  IslandBlocks& islandBlocks() { return islandBlocksOf_[islandBlocksInUse_]; }
  const IslandBlocks& islandBlocks() const { return islandBlocksOf_[islandBlocksInUse_]; }
  // How a bounded row's impulse moves the bodies and its joint's equality
  // impulses when solved in the equality block's null space (solver.cpp,
  // coupleBoundedRows). Indexed like rows_; only bounded rows use it.
  struct BoundedCoupling {
    Vec3 dvA, dwA, dvB, dwB;  // body velocity change per unit impulse
    double w[6];              // equality impulse per unit impulse
    double effMass;
  };
  std::vector<BoundedCoupling> coupling_;
  // A block's source: a joint index (>= 0) or a contact manifold, encoded
  // as -(index + 1).
  static std::int32_t contactSource(std::int32_t c) { return -(c + 1); }
  static std::int32_t contactIndex(std::int32_t source) { return -source - 1; }
  std::vector<std::int32_t> sourceOfBlock_;
  // Islands: blocks are ordered by island, island i owning blocks
  // [islandStart_[i], islandStart_[i + 1]).
  std::vector<std::int32_t> parent_;
  std::vector<std::int32_t> islandOfRoot_;
  std::vector<std::int32_t> sourceIsland_;
  std::vector<std::int32_t> fill_;
  std::vector<std::int32_t> islandOfBlock_;
  std::vector<std::int32_t> islandStart_;
  std::vector<std::uint8_t> islandActive_;
  std::vector<std::int32_t> active_;
  int islandCount_ = 0;
  // Classes of islands that take the same sub-steps (chooseClasses):
  // class c owns islands [islandBegin, islandEnd) and bodies
  // classBodies_[classBodyStart_[c], classBodyStart_[c + 1]).
  struct SubstepClass {
    int substeps = 1;
    int islandBegin = 0, islandEnd = 0;
  };
  std::vector<SubstepClass> classes_;
  // The least share of the step's block sub-steps classes must save.
  static constexpr double kClassSaving = 0.2;
  std::vector<std::int32_t> classOfIsland_, countOfClass_, renumbered_;
  std::vector<std::int32_t> classBodies_, classBodyStart_;
  // The class being stepped (useClass): its islands, blocks and bodies,
  // and where its rows and block matrices start.
  int islandBegin_ = 0, islandEnd_ = 0;
  std::int32_t blockBegin_ = 0, blockEnd_ = 0;
  bool everyBody_ = true;
  std::int32_t classBodyBegin_ = 0, classBodyEnd_ = 0;
  int rowBase_ = 0;
  std::size_t matrixBase_ = 0, matrixCount_ = 0;
  // The runaway guard's groups: each body's island, or a group of its own
  // for a dynamic body in no island (-1: not dynamic).
  std::vector<std::int32_t> groupOfBody_;
  int groupCount_ = 0;
  RunawayGuard guard_;
  int rowCount_ = 0;
  std::int32_t dummy_ = 0;
  double stepSize_ = 0.0;               // the whole step being taken (sub-steps divide it)
  std::int32_t firstFreshContact_ = 0;  // StepInput::firstFreshContact (penetrationRate)
  double weightPerMass_ = 0.0;          // |gravity| (loadRelativeGamma)
  // Per solver body, this prepare: whether some joint block holds it.
  std::vector<std::uint8_t> heldByJoint_;
  double sinceStepStart_ = 0.0;  // when the current sub-step starts, s into the step
  // Carried rows (SolverSettings::maxTurnPerRefresh): per row, its bias
  // rate and its error when prepared; per body, where it was then.
  std::vector<double> carriedBiasRate_, preparedC_;
  std::vector<Vec3> preparedX_;
  std::vector<Quat> preparedQ_;
  std::vector<Vec3> movedX_, movedQ_;
  // Per body, its turn since the step's start and the prepare that worked
  // it out (turnSinceStart).
  std::vector<Vec3> turnSinceStart_;
  std::vector<std::uint32_t> turnStamp_;
  std::uint32_t prepareStamp_ = 0;  // per solver body: moved and turned since
  bool factorsInverted_ = false;    // the kept factors are inverses (carryRows)
  bool rowsCarriable_ = false;      // no row of the last prepare can change kind
  double kinematicTurnRate_ = 0.0;  // (rad/s)^2: the fastest kinematic body in a block
  int preparedAt_ = 0;              // the sub-step the rows were prepared in
};

}  // namespace blockstep

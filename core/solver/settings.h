// Solver settings and per-step statistics.
#pragma once

#include <cstdint>
#include <vector>

#include <optional>

#include "core/constraints/joint_desc.h"
#include "core/constraints/softness.h"

namespace blockstep {

enum class Integrator : std::uint8_t {
  SemiImplicitEuler,  // v += h a; x += h v_new (section 3: symplectic, the default)
  ExplicitEuler,      // x += h v_old; v += h a (kept for studies: gains energy)
};

enum class BlockMode : std::uint8_t {
  Block,     // each joint's equality rows as one LDL^T block (section 4.3)
  RowByRow,  // every row its own 1x1 block, for comparison studies
};

struct SolverSettings {
  // Island blocks up to this many rows in the presets that use them: a
  // 64-link ball chain, a few ragdolls joined by contacts. The factor's
  // memory is rows^2 doubles (300 KB here).
  static constexpr int kIslandBlockRows = 192;
  // Contact island blocks up to this many normal rows in the presets that
  // use them: a stack of 32 boxes on four points each. ODE gives a 10-box
  // stack 40 to 68 points (some pairs more than four); at 64 the island
  // fell back to Gauss-Seidel when it had more, and at one or two
  // sub-steps the stack fell. The block is dense (3 rows^2 doubles, 384 KB
  // here); its factor keeps within the rows' profile (a stack's K is
  // banded).
  static constexpr int kContactIslandRows = 128;
  // Most sweeps of the direct preset: the bounded rows of a resting stack
  // or a limit pressed by a chain converge within this many.
  static constexpr int kDirectSweeps = 200;
  // The most sweeps and sub-steps a step may ask for: beyond these a step
  // of a small scene takes seconds, and the numbers are typing mistakes.
  static constexpr int kMaxIterations = 100000;
  static constexpr int kMaxSubsteps = 1000;
  static constexpr int kMaxThreads = 256;
  // The most position projections a sub-step may ask for: each takes out
  // all but about the sub-step's turn of what is left, so a few suffice.
  static constexpr int kMaxProjections = 16;
  // The sub-stepped preset's turn per sub-step (maxTurnPerSubstep).
  static constexpr double kMaxTurnPerSubstep = 0.1;
  // The sub-stepped preset's turn before rows are prepared again
  // (maxTurnPerRefresh). At 0.02 hair (64 strands whipping at their
  // tips) ran into more sub-steps and took 40% longer; at 0.005 a slow
  // double pendulum (demo_dhinge) lost accuracy against ODE's converged
  // answer; at 0.001 both are as before and a stack, a pyramid and
  // softcube keep their gain (at rest or turning slowly, a whole step's
  // sub-steps share one prepare).
  static constexpr double kMaxTurnPerRefresh = 0.001;
  // The sub-stepped preset's surface travel per sub-step
  // (maxSurfaceTravelPerSubstep).
  static constexpr double kMaxSurfaceTravelPerSubstep = 0.005;
  // The sub-stepped preset's impact depth (impactDepth): 1 mm a sub-step
  // is 0.6 m/s at 600 Hz, well above a resting contact's closing under
  // gravity (g h^2, 0.03 mm); 0.5 mm gave the pile no less depth and cost
  // more.
  static constexpr double kImpactDepth = 0.001;
  // The sub-stepped preset's projection tolerance (projectionTolerance).
  // At 1 mm the drop-in's 10 sub-steps hold chain_swing to 0.9 mm (7.4
  // without), chain_heavy_swing to 5.4 mm (torn, 4.5 m), the bridge to
  // 1.7 mm (5.8) and gain it half the energy, for 0-15% more time; trees
  // and slow pendulums (demo_dhinge) stay within it and step as without.
  static constexpr double kProjectionTolerance = 0.001;
  // The sub-stepped preset's sinking depth (sinkingDepth): at the impact
  // depth (1 mm a sub-step) a hull in the pile sank 0.7-0.8 mm a sub-step
  // unseen and went 5.1-5.2 mm deep on two frame steps of ten; at a
  // quarter of it every run stayed at the depth the scene starts with.
  static constexpr double kSinkingDepth = 0.00025;
  // A calm island's largest closing speed (calmApproachSpeed, m/s): above
  // a resting contact's, which closes at most at g h within a step (0.16
  // m/s at 60 Hz) and is stopped by its solve, below a landing's (the
  // ragdoll lands at 3.4 m/s).
  static constexpr double kCalmApproachSpeed = 0.3;

  // Velocity sweeps per (sub-)step: the upper bound when a tolerance or a
  // time budget is set too.
  int iterations = 10;
  // Stop a (sub-)step's sweeps once every island's largest row residual
  // |J v + b + gamma P| (m/s or rad/s) is below this. 0: off.
  double tolerance = 0.0;
  // Wall-time budget for the sweeps of one whole step, seconds. 0: off.
  double timeBudget = 0.0;
  // Sub-steps per step: each integrates velocities, prepares and factors
  // the blocks, warm starts, sweeps, integrates positions and relaxes.
  int substeps = 1;
  // More sub-steps while a jointed body turns fast: each island runs as
  // many as keep the fastest turn of any of its bodies (its island's peak
  // over the last step's sub-steps) to at most this angle per sub-step,
  // up to maxSubstepFactor times `substeps` (islands share no movable
  // body and step apart, Solver::chooseClasses). A body held only by ball
  // joints with anchors on one line through its centre of mass (a capsule
  // chain's link), or by hinges about an axis through it (a flywheel),
  // counts only its turn across that line: its spin about it moves no
  // row (Solver::noteLeverArms). The rows are linear in the turn: a
  // light link whipping at 240 rad/s turns 0.4 rad in a 1/600 s sub-step
  // and its joints open by r (1 - cos 0.4), 4 mm at once. An island
  // whose joints the step's end projects (positionProjections) and that
  // touches nothing takes no more sub-steps for its turns: the projection
  // closes what they open. Rigid-row springs keep the
  // stiffness of the nominal sub-step. 0: off (a fixed count).
  double maxTurnPerSubstep = 0.0;
  int maxSubstepFactor = 4;
  // Sub-steps of an island of joints solved exactly in the last step: its
  // joints' equality rows were one island block, the step's end projected
  // them (positionProjections) and no contact touched it, nor does one
  // now. Its joints then hold at any step, and at this count it is
  // projected as SHAKE projects, keeping a turning joint's energy
  // (Solver::kShakeTurn; README "Fewer sub-steps for exact islands"). The
  // drop-in's is 1 (BridgeSettings::fromQuickStepIterations). 0: the
  // nominal `substeps`. Both need maxTurnPerSubstep (the islands'
  // classes, Solver::chooseClasses).
  int exactJointIslandSubsteps = 0;
  // The same for an island of contacts only whose normals were one exact
  // group (contact_island.h: a stack, a plank under a load). Its load is
  // carried at once whatever the sub-steps; its fast turns still ask for
  // more (a contact's point turns with its body). The drop-in's default
  // is 1 (BridgeSettings::fromQuickStepIterations).
  int exactContactIslandSubsteps = 0;
  // Sub-steps of a calm island: one of joints that a contact holds, whose
  // joints were one projected island block in the last step (a ragdoll, a
  // car, a hair strand on the head: not a cloth cut into chains) and that
  // no contact strikes now: no point of its contacts closes faster than
  // calmApproachSpeed (m/s) at the step's start. One that turns too fast
  // for this count takes the nominal one. 0: the nominal `substeps`. It
  // needs maxTurnPerSubstep (the islands' classes, Solver::chooseClasses).
  // Off by default: it trades settled depth for time (README, "Fewer
  // sub-steps for calm islands").
  int calmTouchedIslandSubsteps = 0;
  double calmApproachSpeed = kCalmApproachSpeed;
  // Colliding every sub-step (World), a part whose own solve spins a
  // touching body's surface past maxTurnPerSubstep within it is taken
  // again from its start, shorter (once): its contacts were linearized
  // where the body was. In the 1,000-shape pile an 87 g cylinder squeezed
  // by a 7.3 kg ball landing at 4.4 m/s spun to about 200 rad/s (0.33 rad
  // in that part) and was 27-29 mm deep at the next collision. So is a
  // part (at its length) whose solve sent a shape farther than the part's
  // collision reached for it (Collider::outranReach), colliding again with
  // the reach of its solved speed: a light ball struck at 12 m/s toward
  // another 8 mm away, with no contact yet, went 9.6 mm into it.
  bool retakeTurningParts = false;
  // Colliding every sub-step (World), parts are also short enough that a
  // touching body's turn moves its shape's features (a box's corners, a
  // capsule's segment ends, a cylinder's rims: turningGeometrySpeed) no
  // farther than this (m) within one: a contact is linearized where the
  // part starts, and what the turn brings in is met only at the next
  // collision. An angle alone lets a large shape's rim travel far (0.1
  // rad is 10 mm at the end of a 0.2 m cylinder) while holding back small
  // ones whose surface barely moves (a 2 cm hair segment: 1.4 mm). At 5 mm no
  // contact of the 1,000-shape pile passed 5 mm at 20 frame steps' frame
  // collisions (two did with the turn only), the 100 hulls went 1.0 mm
  // deep rather than 2.5, at the same solve time. 0: the turn only. It
  // counts only with maxTurnPerSubstep set: without, parts keep the count.
  double maxSurfaceTravelPerSubstep = 0.0;
  // Sub-steps keep the rows, K and factors the step prepared while every
  // body in a constrained island turns less than this angle (rad) since
  // they were prepared, at the fastest rate seen over this step and the
  // last: a row's error then follows the bodies to first order (C = C0 +
  // J dx) and the bias is formed again. Preparing is most of a sub-step's
  // cost (a stack: 34%, softcube 39%), and a resting or slowly moving
  // scene gains nothing from it. Steps whose joints have limits or motors
  // (which may engage within the step) or whose contacts bounce or move
  // (ODE bounce, motionN) prepare every sub-step. 0: every sub-step
  // prepares.
  double maxTurnPerRefresh = 0.0;
  // Bias-free sweeps after each sub-step's position update: they remove
  // the velocity the position correction added, so it does not turn into
  // motion (Box2D v3's relax stage, PhysX TGS). 0: off (the paper's solver).
  int relaxIterations = 0;
  // Relax leaves each joint equality row the velocity that closes the
  // drift of the rows' linearization over the next sub-step
  // (Solver::relaxAgainstDrift says why). Off (relax targets J v = 0), a
  // turning chain loses about (w h)^2 of its kinetic energy a sub-step;
  // on, it keeps it, but a whipping chain's joints open wider and it can
  // gain energy (the drift is measured one sub-step late). Off by default.
  bool relaxCancelsDrift = false;
  // Position projections at the end of the step (post-stabilization,
  // Cline and Pai 2003, "Post-stabilization for rigid body simulation
  // with contact and constraints"): after the last sub-step's relax, an
  // island whose joint equality rows are one island block moves its
  // bodies by dx = M^-1 J^T lambda with K lambda = -C(x), C measured at
  // that pose (J and K too once the island has turned since its rows were
  // prepared), this many times (Solver::projectPositions). The
  // velocity solve is linear in the bodies' motion, so a joint turning
  // at w opens by about r (w h)^2 / 2 a sub-step (relaxAgainstDrift's
  // comment) and the push-back leaves errors of that size: the ragdoll of
  // ../shared/SCENES.md at one 1/60 s sub-step opened 5.4 mm, projected
  // once 0.005 mm. It moves positions; in an island that touches
  // nothing, velocities change only where the moves lifted bodies against
  // gravity or the applied forces, by the share of the moves' own
  // velocity that pays for it (Solver::payForProjection). Only the rows made rigid in an
  // island block (rigidJointSoftness) are projected: a spring keeps its
  // stretch. The sub-stepped preset projects once past
  // kProjectionTolerance (below). Projecting every step, a slow double
  // pendulum (ODE's demo_dhinge) ended 0.2 mm farther from ODE's converged
  // answer, which its check cannot tell from ODE's own. 0: off.
  int positionProjections = 0;
  // With projections, an island whose rigid joint rows are all within
  // this of closing at the step's pose (m, or rad for angular rows) is
  // left as it is: its projection would cost a factor of its rows at the
  // pose to take out errors already this small. The ragdoll at one
  // sub-step, whose joints open more than a millimetre only as it lands,
  // then pays for few projections. 0: every step projects.
  double projectionTolerance = 0.0;
  // Start each solve from the last one's impulses, scaled by the step
  // ratio. Off in the paper preset: with plain Baumgarte (ERP) rows and
  // sweeps that have not converged (high mass ratios, stiff lattices) the
  // carried impulse and the position correction feed each other and grow
  // (ODE's quickstep compiles its warm starting out for the same reason).
  // Safe with damped rows (rigidJointSoftness below), as sub-stepping uses.
  bool warmStarting = false;
  // When set, rows whose joint gives plain ERP/CFM softness (equality rows
  // and limits) use this instead; joints given a physical spring keep it.
  // Unset: every joint's own ERP/CFM, as in ODE.
  std::optional<Softness> rigidJointSoftness;
  BlockMode blockMode = BlockMode::Block;
  // Solve an island's joint equality rows together as one block (LDL^T of
  // the island's K within its profile: island_block.h) when it has at most
  // this many; larger islands keep one block per joint. Exact in one sweep
  // whatever the mass ratios (a light body carrying heavy ones), which
  // per-joint Gauss-Seidel is not. 0: one block per joint, the paper's.
  int islandBlockRows = 0;
  // An island with more joint equality rows than islandBlockRows (a
  // cloth, a lattice) is cut into chains of joints, each of at most that
  // many rows and solved as one block inside the Gauss-Seidel sweep
  // (island_block.h). Off (the default): such an island keeps one block
  // per joint. Measured on the compare runner's scenes at 10 sub-steps,
  // chains lower the largest joint error (cloth32 23 -> 14 mm, softcube
  // 14 -> 5 mm) at 1.5-1.8 times the solve time, and per-joint blocks
  // given that time as more sub-steps do as well or better (README).
  bool chainBlocks = false;
  // An island block whose island touches something (the ground, another
  // island's bodies through contacts) solves the normal rows of its
  // contacts on jointed bodies in the null space of its equality rows,
  // one row at a time, with its joints' limits and motors
  // (island_block.h); friction stays each manifold's. A contact then
  // stops what the joints carry along, not only its own body: a thrown
  // ragdoll's thigh landing at 3.4 m/s went 66 mm deep at one sweep a
  // step without it (its 7 kg stopped, the other 37 kg pulled after it).
  // Islands where that costs more than IslandBlocks::kCoupledContactWork
  // a sweep keep their manifold blocks. Off by default (README: the
  // ragdolls' joints open wider, and it costs up to 4x at one sub-step).
  bool islandBlockContacts = false;
  // The same for a step in which one of the island's contacts is an
  // impact: a point that closes over the sub-step by more than
  // kImpactCouplingDepth plus twice what gravity alone closes (a body
  // resting on the ground closes g h^2 a sub-step). Only those steps pay
  // for the coupling; resting and sliding contacts stay Gauss-Seidel
  // partners, which warm starting carries. Ignored with
  // islandBlockContacts.
  bool islandBlockImpacts = false;
  static constexpr double kImpactCouplingDepth = 0.001;
  // Solve an island of contacts (no joints, no restitution) with at most
  // this many normal rows as one exact block: an active set of the points
  // that push, solved with the LDL^T of the island's K (contact_island.h).
  // Exact whatever the mass ratios, where Gauss-Seidel needs about as
  // many sweeps as the ratio (a 1000 kg block on a 1 kg plank sank
  // through it). Its rows are rigid and rest kRestDepth deep. Larger
  // islands, and those with joints, keep one block per manifold. 0: off,
  // the paper's.
  int contactIslandRows = 0;
  // In an island not solved as one block (a pile; an island with
  // joints), each body three or more times lighter than a body it touches,
  // and held by no joint, gets its manifolds solved together as one exact
  // block like a small island's (at most contactIslandRows rows),
  // Gauss-Seidel with the other manifolds: a 44 g cylinder pressed between
  // a 2 kg ball and the ground otherwise passes on only its share of the
  // ball's weight a sweep and is pushed into the ground. Off: such an
  // island keeps one block per manifold.
  bool lightBodyGroups = false;
  // In an island not solved as one block, each contact that would go more
  // than impactDepth (m) deep within the sub-step if nothing pushed it
  // (its closing speed times h, past its gap) gets the manifolds around it
  // (breadth-first over the bodies they share, at most contactIslandRows
  // rows) solved together as one exact block: a box landing on a column
  // of boxes of like mass otherwise passes its impulse down one contact
  // a sweep, and the contacts below, springs relative to their own
  // effective mass, give under it (the pile's 2.9 kg box went 3.7 mm
  // into the ground under a 3.9 kg box landing at 3.5 m/s). Only contacts
  // found at the sub-step's start (collision every sub-step); not on
  // bodies a joint holds (the joint adds mass the group does not see: the
  // ragdoll pile gained 70 J in a frame). 0: off.
  double impactDepth = 0.0;
  // In an island not solved as one block, each contact found at the
  // sub-step's start that would still go more than sinkingDepth (m)
  // deeper within the sub-step after the sweeps gets the manifolds around
  // it (as for an impact) solved once more as one exact block, rigid and
  // without push-out: it stops the sinking. Gauss-Seidel with soft rows
  // passes a landing load on a sweep at a time and gives under it (the
  // pile's 0.73 kg hull under 12 kg landing at 2.2 m/s sank 0.3-1.5 m/s
  // after every sub-step's sweeps, 7.7 mm deep).
  // ContactIslands::solveSinking. 0: off.
  double sinkingDepth = 0.0;
  // A contact found at this sub-step's start (collision every sub-step)
  // on a body a joint holds gives, under the load it carries, no more
  // than it would under its own body's weight (Solver::carriesLoadThroughJoint
  // says why). Off: its spring stays relative to its own effective mass,
  // and a light body carrying a heavy jointed structure is pushed in
  // (the soft cube's corner box, 6.2 mm).
  bool loadRelativeContacts = false;
  // Threads that sweep independent islands at once (TBB): the result is
  // bitwise the same whatever the count, as islands share no movable
  // body. 1: the calling thread only; 0: one per core (also the most).
  // Each island is still swept by one thread.
  int threads = 1;
  Integrator integrator = Integrator::SemiImplicitEuler;
  // Gyroscopic term w x (I w), integrated implicitly (off by default, as
  // section 4.1 suggests): by the midpoint rule for a free body, by
  // implicit Euler for one a joint or contact holds (integrateVelocities
  // says why).
  bool gyroscopic = false;
  // The runaway guard (runaway_guard.h): an island whose kinetic energy
  // grew beyond what its forces, motors, kinematic bodies and position
  // corrections can give by more than this factor (growth carried from
  // step to step, 0.9 of the last step's as a logarithm: growth that goes
  // on, as a divergence does),
  // or in which a body goes faster than runawaySpeed (m/s), or whose state
  // is not finite, is put back as it was before the step and reported in
  // StepStats. 0 (or infinity): that test off; non-finite states are
  // always caught.
  double runawayEnergyGain = 100.0;
  double runawaySpeed = kInf;
  // Record the residual after every sweep (costs one extra pass over the
  // rows per sweep; on automatically while a tolerance is set).
  bool recordResiduals = false;
  // Record the kinetic and potential energy of the bodies being stepped
  // at the start of every sub-step and after each of its stages
  // (StepStats::stageEnergy): which stage of a step gains or loses
  // energy (its forces, warm start, sweeps, position update or relax).
  // Costs a pass over the bodies a stage; the step itself is the same.
  bool recordStageEnergy = false;

  // The paper's solver: one step, k block iterations, each joint's
  // Baumgarte ERP and CFM, no relax, no warm starting (the default).
  static SolverSettings paper(int iterations) {
    SolverSettings s;
    s.iterations = iterations;
    return s;
  }
  // ODE's dWorldStep counterpart: one step with each row's own ERP and
  // CFM (as ODE builds them), every island's joint equality rows solved
  // exactly as one block (up to kIslandBlockRows rows; larger islands keep
  // per-joint blocks), and the bounded rows (limits, motors, contacts,
  // friction) swept until every residual is below 1e-9 m/s or maxSweeps.
  // ODE's own tests and demos that call dWorldStep expect its answers: a
  // motor with infinite force at its target within the step, joints that
  // hold to a micrometre, a star of ball joints turning as one body.
  static SolverSettings direct(int maxSweeps = kDirectSweeps) {
    SolverSettings s;
    s.iterations = maxSweeps;
    s.tolerance = 1e-9;
    s.islandBlockRows = kIslandBlockRows;
    return s;
  }
  // Sub-stepping: n sub-steps of one block sweep and one relax sweep each,
  // warm started, rigid rows as a spring at 0.4 of the sub-step rate with
  // damping ratio 2. Stiff chains and cloth need this
  // (../shared/SCENES.md: one step per frame tears them whatever the
  // iteration count; springs stiffer than about 0.5 / h_sub jitter).
  static SolverSettings subStepped(int substeps) {
    SolverSettings s;
    s.islandBlockRows = kIslandBlockRows;
    s.contactIslandRows = kContactIslandRows;
    s.lightBodyGroups = true;
    s.loadRelativeContacts = true;
    s.islandBlockImpacts = true;
    s.substeps = substeps;
    s.iterations = 1;
    s.relaxIterations = 1;
    s.maxTurnPerSubstep = kMaxTurnPerSubstep;
    s.retakeTurningParts = true;
    s.maxSurfaceTravelPerSubstep = kMaxSurfaceTravelPerSubstep;
    s.impactDepth = kImpactDepth;
    s.sinkingDepth = kSinkingDepth;
    s.maxTurnPerRefresh = kMaxTurnPerRefresh;
    s.warmStarting = true;
    s.rigidJointSoftness = Softness::stepSpring(0.4, 2.0);
    s.positionProjections = 1;
    s.projectionTolerance = kProjectionTolerance;
    return s;
  }
};

struct ResidualSample {
  std::int32_t substep = 0;
  std::int32_t iteration = 0;  // 1-based sweep within the sub-step
  double max = 0.0;            // largest |residual| over all rows
  double rms = 0.0;
};

// The energy of the bodies a sub-step moves, at its start or after one
// of its stages (SolverSettings::recordStageEnergy). Islands turning at
// different rates may be stepped apart with their own sub-step counts
// (`substeps`), one after the other, each summing its own bodies.
struct StageEnergySample {
  enum class After : std::uint8_t {
    Forces,     // gravity, forces and damping added to the velocities
    WarmStart,  // the last sub-step's impulses applied again
    Sweeps,     // the velocity sweeps (and sinking groups), with position correction
    Positions,  // the positions moved with the new velocities
    Relax,      // the bias-free sweeps
    // The sub-step's start, recorded before its forces: each sub-step's
    // samples begin with it, so one class's sub-steps read apart from
    // another's stepped before or after it.
    Start,
    // The step's last pose projected onto its rigid joints
    // (positionProjections): after the last sub-step's relax, when the
    // projection moved some island.
    Projection,
  };
  std::int32_t substep = 0;   // 0-based, within the step
  std::int32_t substeps = 0;  // of the islands stepped together
  After after = After::Forces;
  double kinetic = 0.0;    // J, from the velocities as the stage left them
  double potential = 0.0;  // J, in the world's gravity: -m g . x over bodies it acts on
};

// An island the step left non-finite or running away (RunawayGuard): the
// World put its bodies back as they were before the step.
struct RunawayIsland {
  BodyId culprit = -1;           // the non-finite body, or the one whose energy grew most
  bool nonFinite = false;        // some body's state is not finite
  double energyBefore = 0.0;     // kinetic energy before the step, J
  double energyExplained = 0.0;  // what forces, motors and corrections can give, J
  double energyAfter = 0.0;      // after the step (not finite: not summed), J
  double fastest = 0.0;          // largest linear speed after the step, m/s
  double growth = 0.0;           // unexplained energy growth, carried over steps
  // Caught by the slow test (runaway_guard.h): energyBefore/After then sum
  // the kinetic energy and the energy held in the joint errors.
  bool sustained = false;
  double errorEnergy = 0.0;                     // held in the rows' errors after the step, J
  std::int32_t firstBody = 0, bodyCount = 0;    // into StepStats::runawayBodies
  std::int32_t firstJoint = 0, jointCount = 0;  // into StepStats::runawayJoints
};

struct StepStats {
  int substeps = 0;
  int iterations = 0;        // velocity sweeps run, summed over sub-steps (relax excluded)
  int preparedSubsteps = 0;  // sub-steps that prepared their rows (maxTurnPerRefresh)
  int retakenParts = 0;      // collision every sub-step: parts taken again (World)
  int sinkingGroups = 0;     // groups solved after the sweeps (ContactIslands::solveSinking)
  int islands = 0;
  int blocks = 0;
  int rows = 0;
  double collideSeconds = 0.0;  // the world's own collision (World::collide)
  // The deepest point (m, >= 0) the world's own collision found in the
  // step, at any of its parts (collision every sub-step): what the
  // solver was handed, which a measure at the step's end alone misses.
  double deepestFound = 0.0;
  double solveSeconds = 0.0;                   // the sub-steps: integration, prepare, sweeps, relax
  double stepSeconds = 0.0;                    // the whole step
  std::vector<ResidualSample> residuals;       // when recorded
  std::vector<StageEnergySample> stageEnergy;  // when recorded, in the order taken
  std::vector<JointId> brokenJoints;           // joints that broke in this step
  // Islands the step left non-finite or running away, restored to before
  // the step (their bodies did not move), and their bodies and joints.
  std::vector<RunawayIsland> runaways;
  std::vector<BodyId> runawayBodies;
  std::vector<JointId> runawayJoints;
};

}  // namespace blockstep

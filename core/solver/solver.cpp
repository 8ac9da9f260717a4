#include "core/solver/solver.h"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <variant>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/ldlt.h"
#include "core/constraints/parts/axis.h"
#include "core/solver/row_ops.h"

namespace blockstep {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kNoBudget = -1.0;
// Kept factors of blocks with at least this many equality rows become
// inverses (carryRows); smaller ones solve as fast by substitution.
constexpr int kInvertFromRows = 3;

// x = K^-1 x for a block's own equality rows, from its factor or, once
// inverted (ldltInvert, invertSymmetric3), by one product.
void solveBlock(const ConstraintBlock& blk, const double* matrix, double* x) {
  if (blk.inverted)
    multiplyBlock(matrix, blk.equality, x);
  else
    ldltSolve(matrix, blk.equality, x);
}

// A speculative row's bias without restitution (a contact normal, a
// limit), shared by prepare and by sub-steps that keep their rows: while
// apart (C > 0) it lets the gap close within the sub-step and no further;
// past the stop, soft Baumgarte at `rate` beyond the slop, capped. A
// moving surface (ODE motionN, the row's target) asks for that
// separating speed on top.
void setSpeculativeBias(ConstraintRow& row, double rate, double h) {
  if (row.C > 0.0) {
    row.bias = row.biasRelax = row.C / h;
  } else {
    row.bias = std::max(rate * std::min(0.0, row.C + row.slop), -row.maxBias);
    row.biasRelax = 0.0;
  }
  row.bias -= row.target;
  row.biasRelax -= row.target;
}

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// The rotation vector (axis times angle, world) that turns q0 into q.
Vec3 rotationBetween(const Quat& q0, const Quat& q) {
  Quat d = q * q0.conjugate();
  if (d.w() < 0.0) d.coeffs() = -d.coeffs();
  const double s = d.vec().norm();
  if (s < 1e-12) return 2.0 * d.vec();
  return (2.0 * std::atan2(s, d.w()) / s) * d.vec();
}

// A sphere's or a cube's inertia (a multiple of the identity) has no
// gyroscopic term: w x (I w) = 0 for every w.
bool isotropic(const Mat3& inertia) {
  const double d = inertia(0, 0);
  return inertia(1, 1) == d && inertia(2, 2) == d && inertia(0, 1) == 0.0 && inertia(0, 2) == 0.0 &&
         inertia(1, 2) == 0.0 && inertia(1, 0) == 0.0 && inertia(2, 0) == 0.0 &&
         inertia(2, 1) == 0.0;
}

// Euler's equation in the body frame, I dw/dt + w x (I w) = 0, over h,
// implicitly at m = w + theta (w' - w): the end rate w' with
// I (w' - w) + h m x (I m) = 0, by Newton's method from w (3 x 3). theta
// 1/2 is the implicit midpoint rule, 1 implicit Euler. Newton converges
// quadratically: at h |w| << 1 one or two steps reach rounding (after a
// correction of 1e-7 |w| the next would be about 1e-14 |w|), and the loop
// stops there (four fixed steps with a pivoted LU each were a third of a
// hair sub-step). A diagonal inertia (a box's, a capsule's, a cylinder's
// in their own frames) has its products written out: for I = diag(d),
// m x (I m) and the Jacobian's off-diagonal part are the differences of d
// times products of m, a third of the general path's work (hair's bodies
// spent 16% of a step here).
Vec3 gyroscopicStep(const Mat3& I, const Vec3& w, double h, double theta) {
  Vec3 next = w;
  const bool diagonal = I(0, 1) == 0.0 && I(0, 2) == 0.0 && I(1, 0) == 0.0 && I(1, 2) == 0.0 &&
                        I(2, 0) == 0.0 && I(2, 1) == 0.0;
  const Vec3 d = I.diagonal();
  const double c = theta * h;
  for (int k = 0; k < 4; ++k) {
    const Vec3 m = w + theta * (next - w);
    Vec3 F;
    Mat3 dF;
    if (diagonal) {
      const double d21 = d.z() - d.y(), d02 = d.x() - d.z(), d10 = d.y() - d.x();
      F = d.cwiseProduct(next - w) +
          h * Vec3(m.y() * m.z() * d21, m.z() * m.x() * d02, m.x() * m.y() * d10);
      dF << d.x(), c * m.z() * d21, c * m.y() * d21,  //
          c * m.z() * d02, d.y(), c * m.x() * d02,    //
          c * m.y() * d10, c * m.x() * d10, d.z();
    } else {
      const Vec3 Im = I * m;
      F = I * (next - w) + h * m.cross(Im);
      dF = I + c * (skew(m) * I - skew(Im));
    }
    const Vec3 delta = solve3(dF, F);
    next -= delta;
    if (delta.squaredNorm() <= 1e-14 * next.squaredNorm()) break;
  }
  return next;
}

// One row solved alone with its accumulated impulse clamped to [lo, hi]
// (section 4.3: clamp the total, never the increment).
void solveRow(ConstraintRow& row, bool useBias, SolverBody& a, SolverBody& b) {
  if (relaxSkips(row, useBias)) return;
  const double residual = rowResidual(row, useBias, a, b);
  const double next = std::clamp(row.impulse - residual * row.effMass, row.lo, row.hi);
  const double dP = next - row.impulse;
  row.impulse = next;
  applyImpulse(row, dP, a, b);
}

// The residual a row reports: |J v + b + gamma P + blockSoftness|, or 0
// where the accumulated impulse sits on the bound [lo, hi] the row pushes
// against. blockSoftness: the row's part of Gamma P where its block
// carries the softness (ConstraintBlock::springShare).
double reportedResidual(const ConstraintRow& row, double lo, double hi, const SolverBody& a,
                        const SolverBody& b, double blockSoftness) {
  const double r = rowResidual(row, true, a, b) + blockSoftness;
  if (row.impulse <= lo && r > 0.0) return 0.0;
  if (row.impulse >= hi && r < 0.0) return 0.0;
  return std::abs(r);
}

// A joint's rows at its bodies' current pose, written to `rows` (room for
// kMaxJointSlots) with the joint state given.
RowWriter writeJointRows(const StepInput& in, const Joint& joint, JointState& state,
                         ConstraintRow* rows) {
  const JointCommon& c = common(joint.desc);
  const Body& A = c.bodyA == kWorldBody ? in.worldBody : in.bodies[c.bodyA];
  const Body& B = c.bodyB == kWorldBody ? in.worldBody : in.bodies[c.bodyB];
  const JointPose pose =
      JointPose::make(A.position, A.orientation, B.position, B.orientation, joint.frames);
  RowWriter out(rows);
  std::visit([&](const auto& d) { buildJointRows(d, pose, state, out); }, joint.desc);
  out.finish();
  return out;
}

}  // namespace

std::int32_t Solver::solverIndex(BodyId id) const {
  return id == kWorldBody ? dummy_ : static_cast<std::int32_t>(id);
}

int Solver::mostSubsteps(const SolverSettings& s) {
  const int nominal = std::max(1, s.substeps);
  if (s.maxTurnPerSubstep <= 0.0) return nominal;
  return std::min(SolverSettings::kMaxSubsteps, nominal * std::max(1, s.maxSubstepFactor));
}

int Solver::substepsAt(const SolverSettings& s, double h, double turnRate) {
  return substepsAt(s, h, turnRate, s.substeps);
}

int Solver::substepsAt(const SolverSettings& s, double h, double turnRate, int nominal) {
  nominal = std::max(1, nominal);
  if (s.maxTurnPerSubstep <= 0.0) return nominal;
  const double wanted = std::ceil(turnRate * h / s.maxTurnPerSubstep);
  if (!(wanted > nominal)) return nominal;  // NaN too: the guard deals with it
  return static_cast<int>(std::min<double>(wanted, mostSubsteps(s)));
}

// An island of contacts only whose normals were solved as one exact group
// (contact_island.h): its load is carried at once, whatever the
// sub-steps.
bool Solver::contactsExactlyOnce(std::int32_t island) const {
  if (contactIslandRows_ <= 0 || !contactIslands_.covers(island)) return false;
  const int g = contactIslands_.groupsBegin(island);
  return contactIslands_.groupsEnd(island) == g + 1 && contactIslands_.wholeIsland(g);
}

void Solver::notePeakTurnRate(const StepInput& in, const SolverSettings& s) {
  // An island whose joints the step's end projects back onto their rows
  // (projectIsland) and that touches nothing needs no sub-steps for what
  // its joints' turns open. A whip of thin links at one sub-step held 0.80
  // mm so for 0.084 ms a frame, where the turn's extra sub-steps took 0.13
  // ms and left 1.2 mm (chain_swing). Where contacts hold the island its
  // turns count as before: without them a landing ragdoll at one
  // sub-step rose 64 J instead of 17.5 (its landing's impulses, warm
  // started into fewer sub-steps).
  const bool projects = s.positionProjections > 0 && useIslandBlock_ && s.rigidJointSoftness;
  forEachBody(
      static_cast<int>(in.bodies.size()),
      [&](std::int32_t i) {
        const std::int32_t island = groupOfBody_[i];
        if (island < 0 || island >= islandCount_) {
          bodySolvedExactly_[i] = 0;
          bodyInIslandBlock_[i] = 0;
          return;
        }
        const Vec3& w = bodies_[i].w;
        const double turn = w.squaredNorm();
        peakTurnRate_ = std::max(peakTurnRate_, turn);
        islandFullTurn_[island] = std::max(islandFullTurn_[island], turn);
        if (island >= islandBegin_ && island < islandEnd_) {
          const bool jointsExact =
              projects && !islandTouched_[island] && islandBlocks().covers(island);
          bodySolvedExactly_[i] = jointsExact                   ? kExactJoints
                                  : contactsExactlyOnce(island) ? kExactContacts
                                                                : kNotExact;
          bodyInIslandBlock_[i] = projects && islandBlocks().covers(island);
          exactSerial_[i] = in.bodies[i].serial;
          if (jointsExact) return;
        }
        double& seen = islandTurn_[island];
        switch (leverArms_[i]) {
          case LeverArms::None:
            break;
          case LeverArms::OnAxis: {
            const double along = (in.bodies[i].orientation * leverAxis_[i]).dot(w);
            seen = std::max(seen, turn - along * along);
            break;
          }
          case LeverArms::Any:
            seen = std::max(seen, turn);
            break;
        }
      },
      true);
}

// What of each body's turn its rows see (notePeakTurnRate): each joint
// kind says which turn of its bodies moves none of its rows (freeTurn,
// joint_kinds.h: about a ball joint's anchor line, about a hinge's axis
// through the centre of mass). A body all of whose joints leave one such
// line free (a capsule chain's link, a hair segment, a flywheel) counts
// only its turn across it: light capsules, spun about their axes by
// glancing contacts, asked for sub-steps their joints did not need. Any
// contact (its point turns with the body) counts the whole turn.
void Solver::noteLeverArms(const StepInput& in) {
  const std::size_t bodyCount = in.bodies.size();
  leverArms_.assign(bodyCount, LeverArms::None);
  leverAxis_.resize(bodyCount);
  auto note = [&](BodyId i, const FreeTurn& free) {
    if (i == kWorldBody || leverArms_[i] == LeverArms::Any) return;
    switch (free.kind) {
      case FreeTurn::Kind::None:
        return;
      case FreeTurn::Kind::Every:
        leverArms_[i] = LeverArms::Any;
        return;
      case FreeTurn::Kind::About:
        if (leverArms_[i] == LeverArms::None) {
          leverArms_[i] = LeverArms::OnAxis;
          leverAxis_[i] = free.axis;
        } else if (free.axis.cross(leverAxis_[i]).norm() > kOnLine) {
          leverArms_[i] = LeverArms::Any;
        }
        return;
    }
  };
  for (const std::int32_t source : active_) {
    if (source < 0) {
      const ContactManifold& m = in.contacts[contactIndex(source)];
      note(m.bodyA, FreeTurn{});
      note(m.bodyB, FreeTurn{});
      continue;
    }
    const Joint& joint = in.joints[source];
    const JointCommon& c = common(joint.desc);
    std::visit(
        [&](const auto& d) {
          note(c.bodyA, freeTurn(d, joint.frames, false));
          note(c.bodyB, freeTurn(d, joint.frames, true));
        },
        joint.desc);
  }
}

Softness Solver::softnessOf(const Softness& soft, double h) const {
  if (soft.mode != Softness::Mode::StepSpring || h == nominalSubstep_) return soft;
  return Softness::spring(soft.stepFraction / nominalSubstep_, soft.dampingRatio);
}

void Solver::step(const StepInput& in, const SolverSettings& s, StepStats& stats) {
  const auto start = Clock::now();
  nominalSubstep_ = in.nominalSubstep > 0.0 ? in.nominalSubstep : in.h / std::max(1, s.substeps);
  peakTurnRate_ = 0.0;
  stepSize_ = in.penetrationStep > 0.0 ? in.penetrationStep : in.h;
  firstFreshContact_ = in.firstFreshContact;
  weightPerMass_ = in.gravity.norm();

  stats.substeps = 0;
  stats.iterations = 0;
  stats.preparedSubsteps = 0;
  stats.sinkingGroups = 0;
  stats.residuals.clear();
  stats.stageEnergy.clear();
  stats.brokenJoints.clear();
  stats.solveSeconds = 0.0;

  buildIslands(in, s);
  if (s.maxTurnPerSubstep > 0.0 || s.maxTurnPerRefresh > 0.0) noteLeverArms(in);
  // The islands a contact holds (the projection treats the others apart).
  islandTouched_.assign(islandCount_, 0);
  for (const std::int32_t source : active_) {
    if (source >= 0) continue;
    const ContactManifold& m = in.contacts[contactIndex(source)];
    for (const BodyId body : {m.bodyA, m.bodyB}) {
      const std::int32_t island = body != kWorldBody ? groupOfBody_[body] : -1;
      if (island >= 0 && island < islandCount_) islandTouched_[island] = 1;
    }
  }
  usePool(s);
  startX_.resize(in.bodies.size());
  startQ_.resize(in.bodies.size());
  for (std::size_t i = 0; i < in.bodies.size(); ++i) {
    startX_[i] = in.bodies[i].position;
    startQ_[i] = in.bodies[i].orientation;
  }
  guard_.begin(in.bodies, groupOfBody_, groupCount_, in.gravity, in.h);
  jointImpulses_.resize(in.joints.size());
  for (std::size_t j = 0; j < in.joints.size(); ++j) {
    const Joint& joint = in.joints[j];
    JointImpulses& impulses = jointImpulses_[j];
    impulses.warm = joint.warmImpulse;
    impulses.slots = joint.warmSlots;
    impulses.stepSize = joint.warmStepSize;
    impulses.step.fill(0.0);
  }
  for (ContactManifold& m : in.contacts) {
    for (ContactPoint& p : m.points) {
      p.stepNormalImpulse = 0.0;
      p.stepTangentImpulse[0] = p.stepTangentImpulse[1] = 0.0;
    }
  }

  const auto substepsStart = Clock::now();
  rowCount_ = 0;
  matrixCount_ = 0;
  for (std::size_t c = 0; c < classes_.size(); ++c) {
    useClass(c);
    runSubsteps(in, s, classes_[c].substeps, start, stats);
    stats.substeps = std::max(stats.substeps, classes_[c].substeps);
  }
  stats.solveSeconds = seconds(substepsStart, Clock::now());
  turnRateSeen_ = true;
  // Each body keeps its island's turns for the next step.
  for (std::size_t i = 0; i < in.bodies.size(); ++i) {
    const std::int32_t island = groupOfBody_[i];
    const bool inIsland = island >= 0 && island < islandCount_;
    bodyTurn_[i] = inIsland ? std::sqrt(islandTurn_[island]) : 0.0;
    bodyFullTurn_[i] = inIsland ? std::sqrt(islandFullTurn_[island]) : 0.0;
  }
  useClass(kEveryClass);
  for (std::size_t j = 0; j < in.joints.size(); ++j) {
    Joint& joint = in.joints[j];
    const JointImpulses& impulses = jointImpulses_[j];
    joint.warmImpulse = impulses.warm;
    joint.warmSlots = impulses.slots;
    joint.warmStepSize = impulses.stepSize;
    joint.stepImpulse = impulses.step;
  }
  finish(in, stats);
  guard_.check(in.bodies, blocks_, islandStart_, islandCount_, s, stats);
  stats.stepSeconds = seconds(start, Clock::now());
}

// The islands, blocks and bodies the stages work on: one class's, or
// (kEveryClass) all of them.
void Solver::useClass(std::size_t c) {
  if (c == kEveryClass || classes_.size() == 1) {
    islandBegin_ = 0;
    islandEnd_ = islandCount_;
    everyBody_ = true;
  } else {
    islandBegin_ = classes_[c].islandBegin;
    islandEnd_ = classes_[c].islandEnd;
    everyBody_ = false;
    classBodyBegin_ = classBodyStart_[c];
    classBodyEnd_ = classBodyStart_[c + 1];
  }
  blockBegin_ = islandStart_[islandBegin_];
  blockEnd_ = islandStart_[islandEnd_];
  rowBase_ = rowCount_;
  matrixBase_ = matrixCount_;
  // Its bodies' turn so far and in the last step (carriesRows).
  peakTurnRate_ = 0.0;
  lastTurnRate_ = 0.0;
  for (int island = islandBegin_; island < islandEnd_; ++island)
    lastTurnRate_ = std::max(lastTurnRate_, islandLastFullTurn_[island]);
  islandBlocksInUse_ = c == kEveryClass ? 0 : c;
  islandBlocksSelected_ = false;
}

// One class's sub-steps, each of h / substeps: integrate velocities,
// prepare (or keep) the rows, warm start, sweep, integrate positions,
// relax.
void Solver::runSubsteps(const StepInput& in, const SolverSettings& s, int substeps,
                         Clock::time_point start, StepStats& stats) {
  const double h = in.h / substeps;
  // A contact island's normals are exact in one sweep; its friction rows
  // stay Gauss-Seidel, and one pass a step left a ten-box ODE stack at
  // one sub-step swaying 1-6 mm (4.5 mm drift in 2000 frames; 100 mm for
  // OdeContacts.StackOnFourPointsRestsAtAnySubstepCount); two passes hold
  // it to 0.1 mm for 10% more time. More sub-steps give friction more
  // passes anyway (a second then cost the drop-in's stack 30%).
  islandFrictionPasses_ = substeps == 1 ? 2 : 1;
  islandMotorPasses_ = std::max(1, kMotorPassesPerStep / substeps);
  // The guard's energy count costs a pass over the rows per sub-step;
  // without an energy limit only non-finite states and speeds are checked.
  const bool countEnergy = s.runawayEnergyGain > 0.0 && std::isfinite(s.runawayEnergyGain);
  IslandBlocks* islands = nullptr;
  using After = StageEnergySample::After;
  for (int sub = 0; sub < substeps; ++sub) {
    sinceStepStart_ = sub * h;
    recordStageEnergy(in, s, After::Start, sub, substeps, stats);
    integrateVelocities(in, s, h);
    recordStageEnergy(in, s, After::Forces, sub, substeps, stats);
    if (carriesRows(s, sub, h)) {
      carryRows(in, s, h);
    } else {
      prepare(in, s, h);
      ++stats.preparedSubsteps;
    }
    islands = useIslandBlock_ ? &islandBlocks() : nullptr;
    if (sub == 0 && countEnergy)
      guard_.addCorrections(blocks_, rows_, bodies_, islandStart_, islandBegin_, islandEnd_, in.h,
                            islands);
    warmStart();
    recordStageEnergy(in, s, After::WarmStart, sub, substeps, stats);
    // Each sub-step gets its share of what remains of the time budget;
    // once it is spent (prepare alone can spend it) a sub-step still runs
    // one sweep. kNoBudget: no budget set. (The clock is read per sub-step
    // only under a budget: a two-body pendulum's step spent 6% of its time
    // reading it twice a sub-step.)
    const double subBudget =
        s.timeBudget > 0.0
            ? std::max(0.0, (s.timeBudget - seconds(start, Clock::now())) / (substeps - sub))
            : kNoBudget;
    stats.iterations += solve(s, sub, subBudget, stats);
    solveSinkingContacts(in, s, h, stats);
    recordStageEnergy(in, s, After::Sweeps, sub, substeps, stats);
    if (s.maxTurnPerSubstep > 0.0 || s.maxTurnPerRefresh > 0.0) notePeakTurnRate(in, s);
    integratePositions(in, s, h);
    recordStageEnergy(in, s, After::Positions, sub, substeps, stats);
    if (s.relaxIterations > 0 && s.relaxCancelsDrift) relaxAgainstDrift(in, h);
    relax(s, h);
    recordStageEnergy(in, s, After::Relax, sub, substeps, stats);
    // The step's last pose closes its rigid joints (payForProjection says
    // what that does to velocities).
    if (sub == substeps - 1 && projectPositions(in, s, h, sub))
      recordStageEnergy(in, s, After::Projection, sub, substeps, stats);
    if (countEnergy) {
      guard_.addWork(blocks_, rows_, bodies_, islandStart_, islandBegin_, islandEnd_);
      if (sub == substeps - 1)
        guard_.addRemainingErrors(blocks_, rows_, bodies_, islandStart_, islandBegin_, islandEnd_,
                                  h, in.h, islands);
    }
    // An impact's group stops a landing within one sub-step: its impulses
    // are the landing's, not the load its contacts go on carrying, and
    // warm started into the next sub-step's per-manifold rows (one sweep)
    // they threw the load back up (a 4 kg box stopped on a column left at
    // 0.65 m/s upward). Each keeps at most what it was warm started with.
    if (contactIslandRows_ > 0) contactIslands_.capImpactImpulses(rows_);
    storeImpulses(in, h);
  }
}

// The energy of the bodies this class steps, from the solver's velocities
// (integratePositions hands them to the bodies; until then the bodies
// keep the sub-step's start).
void Solver::recordStageEnergy(const StepInput& in, const SolverSettings& s,
                               StageEnergySample::After after, int sub, int substeps,
                               StepStats& stats) {
  if (!s.recordStageEnergy) return;
  StageEnergySample sample;
  sample.substep = sub;
  sample.substeps = substeps;
  sample.after = after;
  // Until the sub-step's forces the velocities are the bodies' own (the
  // last sub-step's relax handed them over, storeImpulses).
  const bool atStart = after == StageEnergySample::After::Start;
  forEachBody(
      static_cast<int>(in.bodies.size()),
      [&](std::int32_t i) {
        const Body& b = in.bodies[i];
        if (!b.alive || !b.isDynamic()) return;
        sample.kinetic += atStart ? kineticEnergy(b) : kineticEnergy(b, bodies_[i].v, bodies_[i].w);
        if (b.gravity) sample.potential -= b.mass * in.gravity.dot(b.position);
      },
      true);
  stats.stageEnergy.push_back(sample);
}

void Solver::buildIslands(const StepInput& in, const SolverSettings& s) {
  const auto bodyCount = static_cast<std::int32_t>(in.bodies.size());
  dummy_ = bodyCount;
  bodies_.resize(bodyCount + 1);
  bodies_[dummy_] = SolverBody{};
  startV_.resize(bodyCount);
  startW_.resize(bodyCount);
  gyroOffset_.resize(bodyCount);

  // Union-find over joints between dynamic bodies; static and kinematic
  // bodies do not join islands (they are shared, immovable borders).
  parent_.resize(bodyCount);
  for (std::int32_t i = 0; i < bodyCount; ++i)
    parent_[i] = i;
  auto find = [&](std::int32_t x) {
    while (parent_[x] != x)
      x = parent_[x] = parent_[parent_[x]];
    return x;
  };
  auto dynamicBody = [&](BodyId id) {
    return id != kWorldBody && in.bodies[id].alive && in.bodies[id].isDynamic();
  };
  auto bodiesOf = [&](std::int32_t source) {
    if (source >= 0) {
      const JointCommon& c = common(in.joints[source].desc);
      return std::pair{c.bodyA, c.bodyB};
    }
    const ContactManifold& m = in.contacts[contactIndex(source)];
    return std::pair{m.bodyA, m.bodyB};
  };
  active_.clear();
  auto consider = [&](std::int32_t source) {
    const auto [bodyA, bodyB] = bodiesOf(source);
    const bool dynA = dynamicBody(bodyA), dynB = dynamicBody(bodyB);
    if (!dynA && !dynB) return;  // nothing to move
    active_.push_back(source);
    if (dynA && dynB) {
      const std::int32_t ra = find(bodyA), rb = find(bodyB);
      if (ra != rb) parent_[ra] = rb;
    }
  };
  for (std::int32_t j = 0; j < static_cast<std::int32_t>(in.joints.size()); ++j) {
    Joint& joint = in.joints[j];
    joint.block = -1;
    if (joint.alive && joint.enabled && !joint.broken) consider(j);
  }
  for (std::size_t c = 0; c < in.contacts.size(); ++c) {
    if (in.contacts[c].pointCount > 0) consider(contactSource(static_cast<std::int32_t>(c)));
  }
  // Number the islands by root, then order the blocks island by island
  // (a counting sort) so each island's blocks are contiguous.
  islandOfRoot_.assign(bodyCount, -1);
  islandCount_ = 0;
  sourceIsland_.resize(active_.size());
  for (std::size_t k = 0; k < active_.size(); ++k) {
    const auto [bodyA, bodyB] = bodiesOf(active_[k]);
    const std::int32_t root = find(dynamicBody(bodyA) ? bodyA : bodyB);
    if (islandOfRoot_[root] < 0) islandOfRoot_[root] = islandCount_++;
    sourceIsland_[k] = islandOfRoot_[root];
  }
  heldByRows_.resize(bodyCount);
  for (std::int32_t i = 0; i < bodyCount; ++i)
    heldByRows_[i] = dynamicBody(i) && islandOfRoot_[find(i)] >= 0;
  chooseClasses(in, s, [&](std::int32_t i) {
    return dynamicBody(i) ? islandOfRoot_[find(i)] : std::int32_t{-1};
  });
  islandStart_.assign(islandCount_ + 1, 0);
  for (std::int32_t island : sourceIsland_)
    ++islandStart_[island + 1];
  for (int i = 0; i < islandCount_; ++i)
    islandStart_[i + 1] += islandStart_[i];
  fill_.assign(islandStart_.begin(), islandStart_.end() - 1);
  sourceOfBlock_.resize(active_.size());
  islandOfBlock_.resize(active_.size());
  for (std::size_t k = 0; k < active_.size(); ++k) {
    islandOfBlock_[fill_[sourceIsland_[k]]] = sourceIsland_[k];
    sourceOfBlock_[fill_[sourceIsland_[k]]++] = active_[k];
  }
  islandActive_.resize(islandCount_);
  islandBlocksSelected_ = false;

  // The runaway guard's groups: the islands, then each dynamic body that
  // is in none (it moves under its forces alone).
  groupOfBody_.resize(bodyCount);
  groupCount_ = islandCount_;
  for (std::int32_t i = 0; i < bodyCount; ++i) {
    if (!dynamicBody(i)) {
      groupOfBody_[i] = -1;
      continue;
    }
    const std::int32_t island = islandOfRoot_[find(i)];
    groupOfBody_[i] = island >= 0 ? island : groupCount_++;
  }
  islandTurn_.assign(islandCount_, 0.0);
  islandFullTurn_.assign(islandCount_, 0.0);
  if (classes_.size() > 1) {
    // Each class's bodies, one list after another: its islands' bodies;
    // the first class also moves the dynamic bodies in no island, and
    // every class sets up the bodies that do not move (its rows may hold
    // to them).
    const auto classCount = static_cast<std::int32_t>(classes_.size());
    classBodyStart_.assign(classCount + 1, 0);
    auto classOf = [&](std::int32_t i) {  // -1: every class's
      const std::int32_t island = groupOfBody_[i];
      if (island < 0) return std::int32_t{-1};
      return island < islandCount_ ? classOfIsland_[island] : std::int32_t{0};
    };
    std::int32_t everyClass = 0;
    for (std::int32_t i = 0; i < bodyCount; ++i) {
      const std::int32_t c = classOf(i);
      if (c < 0)
        ++everyClass;
      else
        ++classBodyStart_[c + 1];
    }
    for (std::int32_t c = 0; c < classCount; ++c)
      classBodyStart_[c + 1] += classBodyStart_[c] + everyClass;
    classBodies_.resize(classBodyStart_[classCount]);
    fill_.assign(classBodyStart_.begin(), classBodyStart_.end() - 1);
    for (std::int32_t i = 0; i < bodyCount; ++i) {
      const std::int32_t c = classOf(i);
      if (c >= 0) {
        classBodies_[fill_[c]++] = i;
        continue;
      }
      for (std::int32_t k = 0; k < classCount; ++k)
        classBodies_[fill_[k]++] = i;
    }
  }
}

// Islands step apart (they share no movable body), so each may take the
// sub-steps its own turn asks for (maxTurnPerSubstep): one fast island no
// longer makes every other take its count (hair's 64 strands took 13.9
// sub-steps a step under the fastest strand's count, 10.4 under their
// own). Islands that take the same count form a class; the classes are
// stepped one after another, each island numbered within its class.
// One class (every island at one count, as before) when the step has a
// time budget (it is shared across sub-steps), records residuals (per
// sub-step of the whole world) or moves kinematic bodies (each class
// would move them again).
template <class IslandOf>
void Solver::chooseClasses(const StepInput& in, const SolverSettings& s, IslandOf islandOf) {
  const auto bodyCount = static_cast<std::int32_t>(in.bodies.size());
  islandLastTurn_.assign(islandCount_, 0.0);
  islandLastFullTurn_.assign(islandCount_, 0.0);
  if (bodyTurn_.size() < in.bodies.size()) {
    bodyTurn_.resize(in.bodies.size(), 0.0);
    bodyFullTurn_.resize(in.bodies.size(), 0.0);
  }
  bool classesAllowed = s.timeBudget <= 0.0 && !s.recordResiduals && s.maxTurnPerSubstep > 0.0;
  for (std::int32_t i = 0; i < bodyCount; ++i) {
    const Body& b = in.bodies[i];
    if (b.alive && b.type == BodyType::Kinematic) classesAllowed = false;
    const std::int32_t island = islandOf(i);
    if (island >= 0) islandLastTurn_[island] = std::max(islandLastTurn_[island], bodyTurn_[i]);
  }
  // Islands solved exactly in the last step take their own counts
  // (exactJointIslandSubsteps, exactContactIslandSubsteps): each island the
  // least exact of its bodies (a new body: not), and a joint island only
  // while no contact touches it, where a contact island's contacts are
  // what made it exact.
  if (bodySolvedExactly_.size() < in.bodies.size()) {
    bodySolvedExactly_.resize(in.bodies.size(), kNotExact);
    bodyInIslandBlock_.resize(in.bodies.size(), 0);
    exactSerial_.resize(in.bodies.size(), 0);
  }
  const bool exactFewer = (s.exactJointIslandSubsteps > 0 || s.exactContactIslandSubsteps > 0) &&
                          s.maxTurnPerSubstep > 0.0;
  islandSolvedExactly_.assign(islandCount_, exactFewer ? kExactContacts : kNotExact);
  if (exactFewer) {
    for (std::int32_t i = 0; i < bodyCount; ++i) {
      const std::int32_t island = islandOf(i);
      if (island < 0) continue;
      std::uint8_t& e = islandSolvedExactly_[island];
      const bool sameBody = exactSerial_[i] == in.bodies[i].serial;
      e = std::min(e, sameBody ? bodySolvedExactly_[i] : kNotExact);
    }
    // A contact takes a joint island's exactness, a joint (attached since)
    // a contact island's.
    for (const std::int32_t source : active_) {
      BodyId bodyA = kWorldBody, bodyB = kWorldBody;
      if (source >= 0) {
        const JointCommon& c = common(in.joints[source].desc);
        bodyA = c.bodyA;
        bodyB = c.bodyB;
      } else {
        const ContactManifold& m = in.contacts[contactIndex(source)];
        bodyA = m.bodyA;
        bodyB = m.bodyB;
      }
      const std::uint8_t lost = source < 0 ? kExactJoints : kExactContacts;
      for (const BodyId body : {bodyA, bodyB}) {
        const std::int32_t island = body != kWorldBody ? islandOf(body) : -1;
        if (island >= 0 && islandSolvedExactly_[island] == lost)
          islandSolvedExactly_[island] = kNotExact;
      }
    }
  }
  noteCalmIslands(in, s, islandOf);
  classes_.clear();
  classOfIsland_.resize(islandCount_);
  int most = islandCount_ > 0 ? 1 : substepsAt(s, in.h, 0.0);
  // Relax against drift sets the velocity that closes a sub-step's drift
  // over the next one: over a whole frame's step it overshoots (PyODE's
  // tutorial2 double pendulum gained 6.2% of its energy in 10 s at one
  // sub-step of 1/50 s), so its joint islands keep the nominal count.
  const int exactJointCount = s.relaxCancelsDrift ? 0 : s.exactJointIslandSubsteps;
  for (int k = 0; k < islandCount_; ++k) {
    const std::uint8_t exact = islandSolvedExactly_[k];
    const int exactCount = exact == kExactJoints     ? exactJointCount
                           : exact == kExactContacts ? s.exactContactIslandSubsteps
                           : islandCalm_[k]          ? s.calmTouchedIslandSubsteps
                                                     : 0;
    classOfIsland_[k] =
        substepsAt(s, in.h, islandLastTurn_[k], exactCount > 0 ? exactCount : s.substeps);
    // A calm island turning too fast for its count takes the nominal
    // count: at the 3 sub-steps its turn asked for, a ragdoll tumbling
    // on the ground rose 5.5 J where the nominal 10 rose 2.9 J.
    if (islandCalm_[k] && exact == kNotExact && classOfIsland_[k] > s.calmTouchedIslandSubsteps)
      classOfIsland_[k] = substepsAt(s, in.h, islandLastTurn_[k], s.substeps);
    most = std::max(most, classOfIsland_[k]);
  }
  // Which islands take the exact joint islands' count (projectIsland
  // gives them SHAKE's velocity), before the islands are renumbered.
  islandAtExactJointCount_.resize(islandCount_);
  for (int k = 0; k < islandCount_; ++k)
    islandAtExactJointCount_[k] = islandSolvedExactly_[k] == kExactJoints && exactJointCount > 0;
  // classOfIsland_ holds each island's count for now. Classes pay when
  // they save a good part of the step's block sub-steps: each class's
  // sub-steps go over every stage, and a pile of small islands, one of
  // them a little faster, gained nothing from them.
  double together = 0.0, apart = 0.0;
  if (classesAllowed) {
    for (const std::int32_t island : sourceIsland_) {
      together += most;
      apart += classOfIsland_[island];
    }
  }
  if (!classesAllowed || !(apart < (1.0 - kClassSaving) * together)) {
    classes_.push_back({most, 0, islandCount_});
    std::fill(classOfIsland_.begin(), classOfIsland_.end(), 0);
  } else {
    // The counts in increasing order, each a class; islands renumbered
    // class by class, in their order within it.
    countOfClass_.assign(classOfIsland_.begin(), classOfIsland_.end());
    std::sort(countOfClass_.begin(), countOfClass_.end());
    countOfClass_.erase(std::unique(countOfClass_.begin(), countOfClass_.end()),
                        countOfClass_.end());
    for (int k = 0; k < islandCount_; ++k) {
      classOfIsland_[k] = static_cast<std::int32_t>(
          std::lower_bound(countOfClass_.begin(), countOfClass_.end(), classOfIsland_[k]) -
          countOfClass_.begin());
    }
    const auto classCount = countOfClass_.size();
    fill_.assign(classCount + 1, 0);
    for (int k = 0; k < islandCount_; ++k)
      ++fill_[classOfIsland_[k] + 1];
    for (std::size_t c = 0; c < classCount; ++c) {
      classes_.push_back({countOfClass_[c], fill_[c], fill_[c] + fill_[c + 1]});
      fill_[c + 1] += fill_[c];
    }
    renumbered_.resize(islandCount_);
    for (int k = 0; k < islandCount_; ++k)
      renumbered_[k] = fill_[classOfIsland_[k]]++;
    exactJointCountScratch_.assign(islandAtExactJointCount_.begin(),
                                   islandAtExactJointCount_.end());
    for (int k = 0; k < islandCount_; ++k)
      islandAtExactJointCount_[renumbered_[k]] = exactJointCountScratch_[k];
    for (std::int32_t& island : sourceIsland_)
      island = renumbered_[island];
    for (std::int32_t& island : islandOfRoot_) {
      if (island >= 0) island = renumbered_[island];
    }
    for (std::size_t c = 0; c < classCount; ++c) {
      for (int k = classes_[c].islandBegin; k < classes_[c].islandEnd; ++k)
        classOfIsland_[k] = static_cast<std::int32_t>(c);
    }
  }
  // Each island's whole turn in the last step (carried rows), in the
  // islands' final numbering.
  for (std::int32_t i = 0; i < bodyCount; ++i) {
    const std::int32_t island = islandOf(i);
    if (island >= 0)
      islandLastFullTurn_[island] = std::max(islandLastFullTurn_[island], bodyFullTurn_[i]);
  }
  if (islandBlocksOf_.size() < classes_.size()) islandBlocksOf_.resize(classes_.size());
}

// A touched island of joints that were one island block is calm while
// nothing strikes it: no point of its contacts closes faster than
// calmApproachSpeed at the step's start.
template <class IslandOf>
void Solver::noteCalmIslands(const StepInput& in, const SolverSettings& s, IslandOf islandOf) {
  islandCalm_.assign(islandCount_, 0);
  if (s.calmTouchedIslandSubsteps <= 0 || !(s.maxTurnPerSubstep > 0.0)) return;
  const auto bodyCount = static_cast<std::int32_t>(in.bodies.size());
  // Islands with joints and contacts whose bodies were all in an island block.
  std::fill(islandCalm_.begin(), islandCalm_.end(), 1);
  for (std::int32_t i = 0; i < bodyCount; ++i) {
    const std::int32_t island = islandOf(i);
    if (island < 0) continue;
    const bool sameBody = exactSerial_[i] == in.bodies[i].serial;
    if (!sameBody || !bodyInIslandBlock_[i]) islandCalm_[island] = 0;
  }
  calmScratch_.assign(islandCount_, 0);  // bit 1: a joint, bit 2: a contact
  auto pointVelocity = [&](BodyId body, const Vec3& p) {
    if (body == kWorldBody) return Vec3(Vec3::Zero());
    const Body& b = in.bodies[body];
    return Vec3(b.linearVelocity + b.angularVelocity.cross(p - b.position));
  };
  for (const std::int32_t source : active_) {
    if (source >= 0) {
      const JointCommon& c = common(in.joints[source].desc);
      for (const BodyId body : {c.bodyA, c.bodyB}) {
        const std::int32_t island = body != kWorldBody ? islandOf(body) : -1;
        if (island >= 0) calmScratch_[island] |= 1;
      }
      continue;
    }
    const ContactManifold& m = in.contacts[contactIndex(source)];
    std::int32_t island = m.bodyA != kWorldBody ? islandOf(m.bodyA) : -1;
    if (island < 0 && m.bodyB != kWorldBody) island = islandOf(m.bodyB);
    if (island < 0) continue;
    calmScratch_[island] |= 2;
    for (int k = 0; k < m.pointCount; ++k) {
      const ContactPoint& p = m.points[k];
      const Vec3 n = p.normal.squaredNorm() > 0.0 ? p.normal : m.normal;
      const double closing =
          n.dot(pointVelocity(m.bodyA, p.position) - pointVelocity(m.bodyB, p.position));
      if (!(closing <= s.calmApproachSpeed)) islandCalm_[island] = 0;
    }
  }
  for (int k = 0; k < islandCount_; ++k)
    if (calmScratch_[k] != 3) islandCalm_[k] = 0;
}

void Solver::integrateVelocities(const StepInput& in, const SolverSettings& s, double h) {
  forEachBody(static_cast<int>(in.bodies.size()), [&](std::int32_t i) {
    Body& b = in.bodies[i];
    SolverBody& sb = bodies_[i];
    startV_[i] = b.linearVelocity;
    startW_[i] = b.angularVelocity;
    if (!b.alive || !b.isDynamic()) {
      // Kinematic bodies keep their velocity and show it to the joints.
      sb = SolverBody{};
      if (b.alive) {
        sb.v = b.linearVelocity;
        sb.w = b.angularVelocity;
      }
      return;
    }
    const Mat3 R = b.orientation.toRotationMatrix();
    sb.invMass = b.invMass;
    sb.invI = R * b.invInertiaBody * R.transpose();

    Vec3 v = b.linearVelocity;
    Vec3 w = b.angularVelocity;
    gyroOffset_[i].setZero();
    if (s.gyroscopic && b.rotation.gyroscopic && !isotropic(b.inertiaBody)) {
      // Euler's equation in the body frame, I dw/dt + w x (I w) = 0
      // (gyroscopicStep). A free body takes the implicit midpoint rule,
      // which keeps both |L| and the energy of this equation exactly (the
      // explicit form w -= h I^-1 (w x I w) gains energy and blows up fast
      // spinners; implicit Euler bleeds momentum, 17% in 10 s in
      // tests/core/integrate_test.cpp's tumbling box), and
      // integratePositions() turns it with the midpoint rate (the end rate
      // plus gyroOffset_). A body a joint or contact holds takes implicit
      // Euler and turns with the rate the solve leaves: the midpoint's
      // offset is a turn no row sees, and, neutrally stable, the rule let
      // the rows' drift feed the spin. A capsule rolling round the ball
      // joint at its end (a ragdoll's head on the ground) at 30 rad/s
      // gained 5,700 J in 10 s at 10 sub-steps colliding every sub-step,
      // 65 J at one; implicit Euler loses a little instead
      // (Contact.CapsuleRollingRoundABallJointAtItsEndGainsNoEnergy).
      const Vec3 wb = R.transpose() * w;
      const bool held = heldByRows_[i] != 0;
      const Vec3 next = gyroscopicStep(b.inertiaBody, wb, h, held ? 1.0 : 0.5);
      w = R * next;
      if (!held) gyroOffset_[i] = R * (0.5 * (wb - next));
    }
    const Vec3 g = b.gravity ? in.gravity : Vec3::Zero();
    v += h * (g + b.invMass * b.force);
    w += h * (sb.invI * b.torque);
    if (b.linearDamping > 0.0) v *= 1.0 / (1.0 + h * b.linearDamping);
    if (b.angularDamping > 0.0) w *= 1.0 / (1.0 + h * b.angularDamping);
    const double speed = w.norm();
    if (speed > b.maxAngularSpeed) w *= b.maxAngularSpeed / speed;
    sb.v = v;
    sb.w = w;
  });
}

void Solver::prepare(const StepInput& in, const SolverSettings& s, double h) {
  blocks_.resize(sourceOfBlock_.size());
  // This class's rows and matrices follow the classes stepped before it.
  rowCount_ = rowBase_;
  if (turnStamp_.size() < in.bodies.size()) {  // grows only while warming up
    turnStamp_.resize(in.bodies.size(), 0);
    turnSinceStart_.resize(in.bodies.size());
  }
  if (++prepareStamp_ == 0) {  // wrapped: no stamp may look current
    std::fill(turnStamp_.begin(), turnStamp_.end(), 0u);
    prepareStamp_ = 1;
  }
  std::size_t matrixSize = matrixBase_;
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    // Room for the most rows a block can have; grows only while warming up.
    if (static_cast<int>(rows_.size()) < rowCount_ + kMaxJointSlots) {
      rows_.resize(2 * (rowCount_ + kMaxJointSlots));
      coupling_.resize(rows_.size());
    }
    ConstraintBlock& blk = blocks_[bi];
    blk.firstRow = rowCount_;
    const std::int32_t source = sourceOfBlock_[bi];
    if (source >= 0) {
      buildJointBlock(in, s, h, source, blk);
      in.joints[source].block = bi;
    } else {
      buildContactBlock(in, s, h, contactIndex(source), blk);
    }
    rowCount_ += blk.rowCount();
    blk.matrix = static_cast<std::int32_t>(matrixSize);
    matrixSize += static_cast<std::size_t>(blk.equality) * blk.equality;
  }
  // Grows only while warming up.
  if (blockMatrices_.size() < matrixSize) blockMatrices_.resize(matrixSize);
  matrixCount_ = matrixSize;
  // Only where carriesLoadThroughJoint can ask: fresh contacts (none under
  // the drop-in's own collision) and gravity.
  if (s.loadRelativeContacts && weightPerMass_ > 0.0 &&
      static_cast<std::int32_t>(in.contacts.size()) > firstFreshContact_) {
    heldByJoint_.assign(bodies_.size(), 0);  // grows only while warming up
    for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      if (blk.joint >= 0) heldByJoint_[blk.bodyA] = heldByJoint_[blk.bodyB] = 1;
    }
    heldByJoint_[dummy_] = 0;  // the world: what a pinned cloth hangs from
  }
  // Before the rows' error is kept for carried sub-steps (rest depth).
  selectContactIslands(in, s, h);
  useIslandBlock_ = s.blockMode == BlockMode::Block && s.islandBlockRows > 1;
  if (useIslandBlock_) {
    // Islands and their joints stay the same over a step's sub-steps:
    // choose and order them once.
    if (!islandBlocksSelected_) {
      const bool impacts = s.islandBlockImpacts && !s.islandBlockContacts;
      if (impacts) markImpactIslands(h);
      islandBlocks().selectIslands(blocks_, dummy_, islandStart_, islandBegin_, islandEnd_,
                                   s.islandBlockRows, s.chainBlocks, &startX_,
                                   s.islandBlockContacts, impacts ? &islandImpact_ : nullptr);
      islandBlocksSelected_ = true;
    }
    if (s.rigidJointSoftness) {
      // An island block solves its rows exactly, so they need no softness
      // to converge: the rigid-row spring becomes a rigid row (CFM 0) that
      // corrects position error at the spring's rate. The spring's
      // softness is relative to each row's own effective mass, which a
      // light link carrying a heavy load does not see: solved exactly, a
      // 0.1 kg chain holding 10 kg stretched 60 mm at 20 sub-steps.
      islandRigid_ = Softness::erpCfm(h * softnessOf(*s.rigidJointSoftness, h).biasRate(h), 0.0);
      for (int island = islandBegin_; island < islandEnd_; ++island) {
        if (!islandBlocks().covers(island)) continue;
        for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi) {
          ConstraintBlock& blk = blocks_[bi];
          if (blk.unilateral || !islandBlocks().solvesEquality(bi)) continue;
          for (int i = 0; i < blk.equality; ++i) {
            ConstraintRow& row = rows_[blk.firstRow + i];
            if (row.softness == &*s.rigidJointSoftness) {
              row.softness = &islandRigid_;
              row.projected = true;
            }
          }
        }
      }
    }
  }
  // What carryRows needs to follow the bodies from here (grows only
  // while warming up).
  if (carriedBiasRate_.size() < rows_.size()) {
    carriedBiasRate_.resize(rows_.size());
    preparedC_.resize(rows_.size());
  }
  rowsCarriable_ = s.maxTurnPerRefresh > 0.0;
  factorsInverted_ = false;
  kinematicTurnRate_ = 0.0;
  if (rowsCarriable_) {
    // One more for the dummy static body (solverIndex).
    preparedX_.resize(in.bodies.size());
    preparedQ_.resize(in.bodies.size());
    movedX_.resize(in.bodies.size() + 1);
    movedQ_.resize(in.bodies.size() + 1);
    forEachBody(
        static_cast<int>(in.bodies.size()),
        [&](std::int32_t i) {
          preparedX_[i] = in.bodies[i].position;
          preparedQ_[i] = in.bodies[i].orientation;
        },
        true);
    for (int r = rowBase_; r < rowCount_; ++r)
      preparedC_[r] = rows_[r].C;
    for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      const bool movingSurface =
          blk.contact >= 0 && in.contacts[blk.contact].surface.motionN != 0.0;
      const bool restitutive =
          blk.contact >= 0 ? in.contacts[blk.contact].surface.restitution > 0.0 : false;
      if ((blk.joint >= 0 && blk.bounded > 0) || movingSurface || restitutive)
        rowsCarriable_ = false;
      // A kinematic body turns its rows too, at its own set rate.
      for (const std::int32_t i : {blk.bodyA, blk.bodyB}) {
        if (i != dummy_ && !in.bodies[i].isDynamic())
          kinematicTurnRate_ =
              std::max(kinematicTurnRate_, in.bodies[i].angularVelocity.squaredNorm());
      }
    }
  }
  forEachIndex(blockEnd_ - blockBegin_, [&](int k) {
    const std::int32_t bi = blockBegin_ + k;
    const bool inIslandBlock = useIslandBlock_ && islandBlocks().solvesEquality(bi);
    finishBlock(s, h, blocks_[bi], inIslandBlock && islandBlocks().covers(islandOfBlock_[bi]),
                inIslandBlock, inIslandBlock && islandBlocks().solvesBounded(islandOfBlock_[bi]));
  });
  if (contactIslandRows_ > 0) contactIslands_.prepare(blocks_, rows_, bodies_);
  if (useIslandBlock_) {
    islandBlocks().prepareFactors();
    forEachIndex(
        islandBlocks().count(),
        [&](int k) { islandBlocks().factorOne(k, blocks_, rows_, bodies_); }, 1);
  }
}

// Islands with an impact this step (SolverSettings::islandBlockImpacts):
// a contact point whose gap the sub-step's velocities close by more than
// kImpactCouplingDepth beyond twice gravity's own g h^2, so that contacts
// carrying a body at rest (closing g h^2) never count. Only contacts
// between the island's jointed bodies and the world or one another: a
// free body landing on the joints (the bridge's 100 kg crate on its 1 kg
// planks) stays a Gauss-Seidel partner, as it gained energy coupled
// (median rise over 8 starts at 10 sub-steps 1.0 -> 2.0 kJ, one start 16
// kJ).
void Solver::markImpactIslands(double h) {
  islandImpact_.assign(static_cast<std::size_t>(islandEnd_), 0);  // grows only while warming up
  impactJointed_.assign(bodies_.size(), 0);
  const double depth = SolverSettings::kImpactCouplingDepth + 2.0 * weightPerMass_ * h * h;
  for (int island = islandBegin_; island < islandEnd_; ++island) {
    const std::int32_t begin = islandStart_[island], end = islandStart_[island + 1];
    for (std::int32_t bi = begin; bi < end; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      if (!blk.unilateral) impactJointed_[blk.bodyA] = impactJointed_[blk.bodyB] = 1;
    }
    impactJointed_[dummy_] = 1;  // the world
    auto jointedOrStatic = [&](std::int32_t body) {
      return impactJointed_[body] != 0 || bodies_[body].invMass == 0.0;
    };
    for (std::int32_t bi = begin; bi < end; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      if (!blk.unilateral || blk.contact < 0) continue;
      if (!jointedOrStatic(blk.bodyA) || !jointedOrStatic(blk.bodyB)) continue;
      if (closesBy(blk, h, depth)) {
        islandImpact_[island] = 1;
        break;
      }
    }
  }
}

// The islands whose contact normals are one block this prepare
// (SolverSettings::contactIslandRows, contact_island.h): islands of
// contacts that do not bounce. Their points rest kRestDepth deep: each
// row's error counts from there.
void Solver::selectContactIslands(const StepInput& in, const SolverSettings& s, double h) {
  contactIslandRows_ = s.blockMode == BlockMode::Block ? s.contactIslandRows : 0;
  if (contactIslandRows_ <= 0) return;
  const double impactDepth = s.impactDepth;
  auto eligible = [&](const ConstraintBlock& blk) { return groupableContact(in, blk); };
  auto impact = [&](const ConstraintBlock& blk) { return closesPast(blk, h, impactDepth); };
  contactIslands_.select(blocks_, islandStart_, islandBegin_, islandEnd_, dummy_, bodies_,
                         contactIslandRows_, s.lightBodyGroups, impactDepth > 0.0, eligible,
                         impact);
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    if (!contactIslands_.groups(bi)) continue;
    for (int i = 0; i < blk.equality; ++i)
      rows_[blk.firstRow + i].C += ContactIslands::kRestDepth;
  }
}

// A contact a group may take: one that does not bounce (solved at once,
// Newton's cradle would pass its impulse down the row as one shove) and
// is not a physical spring (its softness is real, group rows are rigid).
bool Solver::groupableContact(const StepInput& in, const ConstraintBlock& blk) const {
  const ContactSurface& surface = in.contacts[blk.contact].surface;
  return surface.restitution <= 0.0 && surface.softness.mode != Softness::Mode::Stiffness;
}

// Whether a point of the contact would be more than `depth` deeper at
// the sub-step's end, unpushed from here: its gap (C) closed at its
// velocity now, counted from where it is. Only contacts found at this
// sub-step's start (collision every sub-step): under the drop-in's frame
// collision the impact groups gained no depth on the 1,000-shape pile and
// it settled deeper (last second 1.44 -> 2.3 mm).
bool Solver::closesPast(const ConstraintBlock& blk, double h, double depth) const {
  return blk.contact >= firstFreshContact_ && closesBy(blk, h, depth);
}

// Whether a point's gap closes over the sub-step, at its velocity now, by
// more than `depth` past where it is (or past touching, if apart).
bool Solver::closesBy(const ConstraintBlock& blk, double h, double depth) const {
  const ConstraintRow* rows = &rows_[blk.firstRow];
  for (int i = 0; i < blk.equality; ++i) {
    const double v = rowVelocity(rows[i], bodies_[blk.bodyA], bodies_[blk.bodyB]);
    if (std::min(rows[i].C, 0.0) - (rows[i].C + h * v) > depth) return true;
  }
  return false;
}

// After the sweeps, the contacts still closing past the sinking depth are
// solved again, exactly, with the manifolds around them
// (SolverSettings::sinkingDepth, ContactIslands::solveSinking).
void Solver::solveSinkingContacts(const StepInput& in, const SolverSettings& s, double h,
                                  StepStats& stats) {
  if (contactIslandRows_ <= 0 || !(s.sinkingDepth > 0.0)) return;
  auto eligible = [&](const ConstraintBlock& blk) { return groupableContact(in, blk); };
  auto sinking = [&](const ConstraintBlock& blk) { return closesPast(blk, h, s.sinkingDepth); };
  stats.sinkingGroups +=
      contactIslands_.solveSinking(blocks_, islandStart_, islandBegin_, islandEnd_, dummy_, bodies_,
                                   contactIslandRows_, eligible, sinking, rows_);
}

// Whether this sub-step keeps the last prepared rows (maxTurnPerRefresh):
// never the step's first, nor in a solver's first step (no rate measured
// yet: a chain released from rest speeds up within it), and only while
// every constrained body (and every kinematic body in a block), at the
// fastest turn rate seen over this step and the last, has turned less
// than the setting since they were prepared, and no row can change its
// kind or count meanwhile: a joint's limit or motor may engage, a contact
// bounce, a moving surface (ODE motionN) move on. Turns are what the
// carried rows leave out: their lever arms and K stay those of the
// prepared pose, and a row's error follows the bodies only to first
// order. The error that leaves grows with the setting, not with the
// sub-step: at 0.005 rad demo_dhinge's swing ended 30 mm from ODE's
// converged answer (against 21 mm preparing every sub-step), at 0.001 it
// is as before.
bool Solver::carriesRows(const SolverSettings& s, int sub, double h) {
  if (sub == 0 || s.maxTurnPerRefresh <= 0.0 || !rowsCarriable_ || !turnRateSeen_) {
    preparedAt_ = sub;
    return false;
  }
  const double rate =
      std::sqrt(std::max({peakTurnRate_, lastTurnRate_ * lastTurnRate_, kinematicTurnRate_}));
  if (!(rate * h * (sub - preparedAt_ + 1) < s.maxTurnPerRefresh)) {
    preparedAt_ = sub;
    return false;
  }
  return true;
}

// Keeps the last prepare's rows, K and factors: each row's error follows
// the bodies' motion since then to first order, C = C0 + J dx (as a
// contact's separation follows the bodies through the sub-steps), and its
// bias is formed again from it.
void Solver::carryRows(const StepInput& in, const SolverSettings& s, double h) {
  // Each body's motion since the prepare: a move and a turn (world frame,
  // as the rows' Jacobians are); the dummy static body has none.
  forEachBody(static_cast<int>(in.bodies.size()), [&](std::int32_t i) {
    movedX_[i] = in.bodies[i].position - preparedX_[i];
    movedQ_[i] = rotationBetween(preparedQ_[i], in.bodies[i].orientation);
  });
  movedX_[dummy_] = movedQ_[dummy_] = Vec3::Zero();
  // The kept factors serve every sweep until the next prepare: the first
  // sub-step that keeps them turns each into the matrix of its solve
  // (ldltInvert), one product a sweep instead of two substitutions.
  if (!factorsInverted_) {
    forEachIndex(blockEnd_ - blockBegin_, [&](int k) {
      ConstraintBlock& blk = blocks_[blockBegin_ + k];
      if (blk.factored && !blk.inverted && blk.equality >= kInvertFromRows) {
        ldltInvert(matrixOf(blk), blk.equality);
        blk.inverted = true;
      }
    });
    factorsInverted_ = true;
  }
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    const Vec3& dxA = movedX_[blk.bodyA];
    const Vec3& dqA = movedQ_[blk.bodyA];
    const Vec3& dxB = movedX_[blk.bodyB];
    const Vec3& dqB = movedQ_[blk.bodyB];
    for (int r = blk.firstRow; r < blk.firstRow + blk.rowCount(); ++r) {
      ConstraintRow& row = rows_[r];
      // Without warm starting every sub-step starts from no impulse, as
      // prepare's does.
      if (!s.warmStarting) row.impulse = 0.0;
      if (row.biasKind == RowBias::Velocity) continue;  // no error to follow
      row.C = preparedC_[r] + row.linA.dot(dxA) + row.angA.dot(dqA) + row.linB.dot(dxB) +
              row.angB.dot(dqB);
      if (row.biasKind == RowBias::Baumgarte) {
        row.bias = carriedBiasRate_[r] * row.C;
      } else if (row.biasKind == RowBias::Speculative && row.bounce == 0.0) {
        // A row apart when prepared keeps the rigid gamma and K it had
        // then, should it close within the kept sub-steps.
        setSpeculativeBias(row, carriedBiasRate_[r], h);
      }
    }
  }
}

void Solver::buildJointBlock(const StepInput& in, const SolverSettings& s, double h, std::int32_t j,
                             ConstraintBlock& blk) {
  Joint& joint = in.joints[j];
  const JointImpulses& impulses = jointImpulses_[j];
  const JointCommon& c = common(joint.desc);
  ConstraintRow* rows = &rows_[blk.firstRow];
  const RowWriter out = writeJointRows(in, joint, joint.state, rows);
  blk.bodyA = solverIndex(c.bodyA);
  blk.bodyB = solverIndex(c.bodyB);
  blk.joint = j;
  blk.contact = -1;
  blk.unilateral = false;
  blk.bounded = static_cast<std::uint8_t>(out.boundedCount());
  blk.equality = static_cast<std::uint8_t>(out.equalityCount());
  const double warmRatio = s.warmStarting && impulses.stepSize > 0.0 ? h / impulses.stepSize : 0.0;
  for (int i = 0; i < blk.rowCount(); ++i) {
    ConstraintRow& row = rows[i];
    const bool warm = (impulses.slots >> row.slot) & 1u;
    row.impulse = warm ? warmRatio * impulses.warm[row.slot] : 0.0;
    if (row.softness && s.rigidJointSoftness && row.softness->mode == Softness::Mode::ErpCfm) {
      row.softness = &*s.rigidJointSoftness;
    }
  }
}

// Body i's turn since the step's start (a rotation vector), worked out
// once per prepare: a body in a pile touches several others, and each of
// its manifolds asked for it (the atan2 alone took 3% of a 1,000-body
// pile's time).
const Vec3& Solver::turnSinceStart(const StepInput& in, BodyId i) {
  if (turnStamp_[i] != prepareStamp_) {
    turnSinceStart_[i] = rotationBetween(startQ_[i], in.bodies[i].orientation);
    turnStamp_[i] = prepareStamp_;
  }
  return turnSinceStart_[i];
}

// One side of a contact point as the sub-steps move its body since the
// step's start (x0, q0; `turn` the rotation vector between): the lever arm
// from the body's centre to the point, and how far its surface moved.
// A round surface (radius > 0, ContactPoint::radiusA) turns about the
// centre of its curvature, `local` in the body, and touches one radius
// from it along `outward` (the normal pointing out of this body):
// a capsule rolling round the ball joint at its other end (a ragdoll's
// head) keeps its contact under its end's centre, and the end dips as it
// goes. With the point's lever kept from the start and its motion to
// first order, the contact lagged behind the rolling end, the push there
// spun the capsule faster and the dip went unseen until the next
// collision (5 to 40 rad/s in 20 s at 10 sub-steps).
// Any other point keeps its lever's world direction (Box2D v3 keeps
// contact anchors for the step too) and moves with the turn to first
// order: turning a point of an unknown surface with its body walks a
// rolling ball's contact up its side (a 1 m ball at 1 m/s rolled to 1.67
// m/s in 10 s, and at 25 m/s sank 67 mm), while a box tipping on an edge
// still lifts its corners.
Solver::ContactSide Solver::contactSide(const Vec3& local, double radius, const Vec3& outward,
                                        const Vec3& x, const Quat& q, const Vec3& x0,
                                        const Quat& q0, const Vec3& turn) {
  const Vec3 start = q0 * local;
  if (radius > 0.0) {
    const Vec3 centre = q * local;
    return ContactSide{centre + radius * outward, x - x0 + centre - start};
  }
  return ContactSide{start, x - x0 + turn.cross(start)};
}

// A manifold's rows: the normal of each point (section 4.2: the paper's
// contact row, with B's side first in our sign convention; each point
// along its own normal), solved together as one unilateral block; then two friction rows per point
// bounded by that point's normal impulse, and rolling and spinning rows
// bounded by the manifold's total normal impulse.
// Row slots: normal i -> i, friction of point i along tangent d ->
// kMaxManifoldPoints + 2 i + d, rolling about t1, t2, n -> 12, 13, 14.
void Solver::buildContactBlock(const StepInput& in, const SolverSettings& s, double h,
                               std::int32_t c, ConstraintBlock& blk) {
  ContactManifold& m = in.contacts[c];
  const ContactSurface& surface = m.surface;
  const Body& A = m.bodyA == kWorldBody ? in.worldBody : in.bodies[m.bodyA];
  const Body& B = m.bodyB == kWorldBody ? in.worldBody : in.bodies[m.bodyB];
  ConstraintRow* rows = &rows_[blk.firstRow];
  const int np = m.pointCount;
  const double warmRatio = s.warmStarting && m.warmStepSize > 0.0 ? h / m.warmStepSize : 0.0;
  const double mus[2] = {surface.mu, surface.mu2 >= 0.0 ? surface.mu2 : surface.mu};
  const double motions[2] = {surface.motion1, surface.motion2};
  const double slips[2] = {surface.slip1, surface.slip2};
  // Where the bodies were when the manifold was made (the step's start).
  auto startOf = [&](BodyId id, const Body& body) {
    if (id == kWorldBody) return std::pair{body.position, body.orientation};
    return std::pair{startX_[id], startQ_[id]};
  };
  const auto [xA0, qA0] = startOf(m.bodyA, A);
  const auto [xB0, qB0] = startOf(m.bodyB, B);
  const Vec3 turnA = m.bodyA == kWorldBody ? Vec3::Zero() : turnSinceStart(in, m.bodyA);
  const Vec3 turnB = m.bodyB == kWorldBody ? Vec3::Zero() : turnSinceStart(in, m.bodyB);
  for (int i = 0; i < np; ++i) {
    const ContactPoint& point = m.points[i];
    JointPose pose;
    // The normal points out of A toward B.
    const ContactSide a = contactSide(point.localA, point.radiusA, point.normal, A.position,
                                      A.orientation, xA0, qA0, turnA);
    const ContactSide b = contactSide(point.localB, point.radiusB, -point.normal, B.position,
                                      B.orientation, xB0, qB0, turnB);
    pose.rA = a.lever;
    pose.rB = b.lever;
    pose.pA = A.position + a.lever;
    pose.pB = B.position + b.lever;
    pose.d = b.moved - a.moved;

    ConstraintRow& normal = rows[i];
    normal = ConstraintRow{};
    directionRow(pose, point.normal, normal);
    // A moving surface (ODE motionN) moves on through the sub-steps: the
    // gap is measured from where it is now. Measured from where the
    // collision found it, a body lifted by a platform (demo_motion) drew
    // away from it within the step, the row let it fall back by that gap,
    // and it rode 1.2 mm deep at 0.242 m/s on a 0.25 m/s platform (one
    // sub-step: 0.046 m/s).
    normal.C = point.separation + point.normal.dot(pose.d) - surface.motionN * sinceStepStart_;
    normal.slot = static_cast<std::uint8_t>(i);
    normal.biasKind = RowBias::Speculative;
    normal.softness = &surface.softness;
    normal.target = surface.motionN;
    normal.bounce = surface.restitution;
    normal.bounceThreshold = surface.restitutionThreshold;
    normal.slop = surface.slop;
    normal.maxBias = surface.maxCorrectingVelocity;
    normal.lo = 0.0;
    normal.impulse = warmRatio * point.normalImpulse;

    const Vec3 tangents[2] = {point.tangent1, point.tangent2};
    for (int d = 0; d < 2; ++d) {
      ConstraintRow& t = rows[np + 2 * i + d];
      t = ConstraintRow{};
      directionRow(pose, tangents[d], t);
      t.slot = static_cast<std::uint8_t>(kMaxManifoldPoints + 2 * i + d);
      t.biasKind = RowBias::Velocity;
      t.target = motions[d];
      t.gamma = slips[d];  // force-dependent slip (ODE slip1/2 is a CFM)
      t.impulse = warmRatio * point.tangentImpulse[d];
      if (surface.friction == ContactSurface::Friction::Force) {
        // A force; prepare turns it into an impulse bound. ODE gives each
        // contact it found this force whatever the load; a point carried
        // over (contact persistence) is not one of them and holds only
        // against the normal. With the force, a stale point on a rolling
        // capsule's end held that material point still (mu = dInfinity in
        // demo_moving_convex), and the capsule was flung 0.94 m.
        const double force = point.carried ? 0.0 : mus[d];
        t.lo = -force;
        t.hi = force;
      } else {
        t.frictionOf = static_cast<std::int8_t>(i);
        t.mu = mus[d];
        t.conePair = d == 0 && surface.friction == ContactSurface::Friction::Cone;
      }
    }
  }
  int n = 3 * np;
  const double resist[3] = {surface.rolling, surface.rolling, surface.spinning};
  const Vec3 axes[3] = {m.tangent1, m.tangent2, m.normal};
  for (int k = 0; k < 3; ++k) {
    if (resist[k] <= 0.0) continue;
    ConstraintRow& r = rows[n++];
    r = ConstraintRow{};
    angularAxisRow(axes[k], 0.0, r);
    r.slot = static_cast<std::uint8_t>(3 * kMaxManifoldPoints + k);
    r.biasKind = RowBias::Velocity;
    r.frictionOf = ConstraintRow::kAllNormals;
    r.mu = resist[k];
    r.impulse = warmRatio * m.rollingImpulse[k];
  }
  blk.bodyA = solverIndex(m.bodyA);
  blk.bodyB = solverIndex(m.bodyB);
  blk.joint = -1;
  blk.contact = c;
  blk.unilateral = true;
  blk.equality = static_cast<std::uint8_t>(np);
  blk.bounded = static_cast<std::uint8_t>(n - np);
}

// How fast a row past its stop is pushed back (1/s). Contacts push out
// no faster than their softness does over the whole step, however many
// sub-steps run: the push is position correction, and a sub-step's one
// relax sweep cannot take it back out of a stack (the boxes above carry
// it away). With the sub-step's rate (0.4 / h_sub: 460/s at 20 sub-steps,
// against ODE's 12/s for ERP 0.2 at 60 Hz) ODE stacks standing 1 mm deep
// on four points jumped apart; with the step's rate all of them rest. A
// physical spring (Stiffness) keeps its own rate: its force is real.
//
// Contacts found at this sub-step's start (collision every sub-step)
// measure their depth rather than extrapolate it, and a deep one is an
// impact or a pull that the step's rate lets through: a landing soft cube
// went 11.4 mm deep and cloth32 pulled over the cube's edge 18.1 mm. Past
// kDeepPenetration such a contact blends to the sub-step's own rate,
// fully at twice that depth: 5.8 mm and 3.5 mm, resting stacks (under
// 2 mm) as before. Contacts carried from the frame's collision keep the
// step's rate: pushed at the sub-step's, the ragdoll sank 71 mm, not
// 38, and a ragdoll pile gained 78 J.
double Solver::penetrationRate(const ConstraintRow& row, const ConstraintBlock& blk,
                               double h) const {
  const double rate = softnessOf(*row.softness, h).biasRate(h);
  if (!blk.unilateral || row.softness->mode == Softness::Mode::Stiffness) return rate;
  const double slow = std::min(rate, row.softness->biasRate(stepSize_));
  if (blk.contact < firstFreshContact_) return slow;
  const double depth = -std::min(0.0, row.C + row.slop);
  const double fast = std::clamp(depth / kDeepPenetration - 1.0, 0.0, 1.0);
  return slow + fast * (rate - slow);
}

// Whether a contact's normal rows take their spring relative to the load
// they carry (SolverSettings::loadRelativeContacts). A spring relative to
// the row's own effective mass m (Softness: gamma = c / m) gives gamma P
// of velocity under an impulse P, so a light body carrying a heavy load
// sinks by the load's ratio to its own weight: the soft cube's corner box
// (0.1 kg) stopping the 12.5 kg lattice as it lands went 4.3-6.2 mm deep
// over five frame steps, cloth32's cells rested 2.4 mm into the cube.
// Held to its own weight's give (|g| h c, 1 mm/s at 600 Hz), the cube
// lands under 0.1 mm deep and the cloth rests 0.1 mm.
// Only for bodies a joint holds: their joints keep the softness that
// keeps warm-started Gauss-Seidel from ringing. Boxes passing a load
// from contact to contact need it on the contacts: with every contact
// load-relative a pyramid of 210 boxes rang and drifted 114 mm (5.5 mm
// with its springs). And only for contacts found at this sub-step's start
// (collision every sub-step): a contact carried from the frame's
// collision can be deep and its anchors drift over the frame, and
// stiffened so, hair's strand-strand contacts ran away.
bool Solver::carriesLoadThroughJoint(const SolverSettings& s, const ConstraintBlock& blk) const {
  if (!s.loadRelativeContacts || blk.contact < firstFreshContact_ || weightPerMass_ <= 0.0)
    return false;
  return heldByJoint_[blk.bodyA] || heldByJoint_[blk.bodyB];
}

double Solver::startVelocity(const ConstraintRow& row, const ConstraintBlock& blk) const {
  auto v = [&](std::int32_t i) { return i == dummy_ ? Vec3(Vec3::Zero()) : startV_[i]; };
  auto w = [&](std::int32_t i) { return i == dummy_ ? Vec3(Vec3::Zero()) : startW_[i]; };
  return row.linA.dot(v(blk.bodyA)) + row.angA.dot(w(blk.bodyA)) + row.linB.dot(v(blk.bodyB)) +
         row.angB.dot(w(blk.bodyB));
}

// The rates of a softness at step h, worked out again only when a row
// asks for another softness than the last one (SoftnessCache).
const SoftnessAtStep& Solver::ratesOf(const Softness& soft, double h, SoftnessCache& cache) const {
  if (cache.of != &soft) {
    cache.rates = softnessOf(soft, h).atStep(h);
    cache.of = &soft;
  }
  return cache.rates;
}

// A spring given relative to a row's effective mass (Spring, StepSpring:
// k = m w^2 with m = 1 / K_ii, softness.h) is not one spring on a block
// of rows: K_ii depends on the axes the rows happen to use. A 1 m ball
// joint holding a 5 cm bob has K = 1 kg^-1 along the rod and 1001 across
// it (the bob turns). Rows along the world axes at 45 degrees each see
// K_ii = 501, and gamma_i = c K_ii made the rod 500 times softer than the
// spring asked for: the joint opened 90 mm, and relax, which keeps gamma
// P, left that creep in every sub-step (the bob kept 9% of its energy
// over 10 s). Gamma = c K, the same spring on every direction of the
// block whatever its axes (Box2D v3's soft joints do the same with their
// mass and impulse scales), needs no K times P in the sweeps: with the
// factor of (1 + c) K, (K + Gamma) dP = -(J v + b + Gamma P) is
//   dP = -((1 + c) K)^-1 (J v + b) - c / (1 + c) P.
// This returns c when every equality row of a joint block has the same
// mass-relative spring, else 0 (the rows keep their own gamma). An
// island block keeps its own (its rows are rigid there, prepare says why).
double Solver::blockSpringShare(const SolverSettings& s, double h, const ConstraintBlock& blk,
                                bool inIslandBlock, SoftnessCache& cache) const {
  if (blk.unilateral || blk.equality < 2 || inIslandBlock || s.blockMode != BlockMode::Block)
    return 0.0;
  const ConstraintRow* eq = &rows_[blk.firstRow];
  double share = 0.0;
  for (int i = 0; i < blk.equality; ++i) {
    if (eq[i].biasKind != RowBias::Baumgarte || !eq[i].softness) return 0.0;
    const SoftnessAtStep& soft = ratesOf(*eq[i].softness, h, cache);
    if (!soft.massRelative) return 0.0;
    const double c = soft.gammaUnit();
    if (i > 0 && c != share) return 0.0;
    share = c;
  }
  return share;
}

// Bias, CFM and effective masses of a block's rows, then K of its
// equality (or contact normal) rows and its LDL^T.
void Solver::finishBlock(const SolverSettings& s, double h, ConstraintBlock& blk,
                         bool inIslandBlock, bool inGroup, bool islandSolvesAll) {
  // A group of contacts solves its normals exactly: they are rigid
  // (contact_island.h).
  const bool rigidNormals =
      blk.unilateral && contactIslandRows_ > 0 && contactIslands_.groups(&blk - blocks_.data());
  const SolverBody& a = bodies_[blk.bodyA];
  const SolverBody& b = bodies_[blk.bodyB];
  ConstraintRow* rows = &rows_[blk.firstRow];
  SoftnessCache cache;
  blk.springShare = blockSpringShare(s, h, blk, inIslandBlock, cache);
  for (int i = 0; i < blk.rowCount(); ++i) {
    ConstraintRow& row = rows[i];
    row.invIangA = a.invI * row.angA;
    row.invIangB = b.invI * row.angB;
    row.gammaShare = 0.0;
    const double kDiag = rowDiagonal(row, a, b);
    switch (row.biasKind) {
      case RowBias::Velocity:  // motors, friction: lo/hi and gamma came per unit force
        row.bias = row.biasRelax = -row.target;
        row.lo *= h;
        row.hi *= h;
        row.gamma /= h;
        break;
      case RowBias::Speculative: {
        // Restitution reverses the approach speed from before this
        // (sub-)step's forces, as ODE and Box2D measure it (with gravity
        // already added the rebound came out 3% higher than ODE's).
        // A moving surface (ODE motionN, the row's target) bounces what
        // meets it at the speed relative to it, as ODE does.
        const double approach = startVelocity(row, blk) - row.target;  // < 0: closing
        if (row.bounce > 0.0 && approach < -row.bounceThreshold && row.C + approach * h <= 0.0) {
          // Restitution: leave at bounce times the approach speed; kept
          // through relax so the rebound survives it.
          row.bias = row.biasRelax = row.bounce * approach;
          row.bounced = true;
          row.bias -= row.target;
          row.biasRelax -= row.target;
          break;
        }
        // The push-out rate, kept for carryRows when the rows may be kept
        // (only then needed while the row is apart).
        const bool apart = row.C > 0.0;
        const double rate =
            !apart || (rowsCarriable_ && row.softness) ? penetrationRate(row, blk, h) : 0.0;
        carriedBiasRate_[&row - rows_.data()] = rate;
        setSpeculativeBias(row, rate, h);
        if (!apart && !rigidNormals) {
          const SoftnessAtStep& soft = ratesOf(*row.softness, h, cache);
          row.gamma = soft.gamma(kDiag);
          row.gammaShare = soft.massRelative ? soft.gammaUnit() : 0.0;
          // The spring relative to the load the row carries (the last
          // sub-step's impulse, warm started), when that is more than
          // its own effective mass's weight: gamma P then stays at what
          // the row's own weight gives, |g| h c.
          if (soft.massRelative && row.impulse > 0.0 && carriesLoadThroughJoint(s, blk)) {
            row.gamma = std::min(row.gamma, soft.gammaUnit() * weightPerMass_ * h / row.impulse);
          }
        }
        break;
      }
      case RowBias::Baumgarte: {
        const SoftnessAtStep& soft = ratesOf(*row.softness, h, cache);
        row.bias = soft.biasRate * row.C;
        carriedBiasRate_[&row - rows_.data()] = soft.biasRate;
        row.biasRelax = 0.0;
        // In a block with a spring share the block carries the softness.
        row.gamma = i < blk.equality && blk.springShare > 0.0 ? 0.0 : soft.gamma(kDiag);
        row.gammaShare = soft.massRelative ? soft.gammaUnit() : 0.0;
        break;
      }
    }
    const double k =
        i < blk.equality ? kDiag * (1.0 + blk.springShare) + row.gamma : kDiag + row.gamma;
    row.effMass = k > 0.0 ? 1.0 / k : 0.0;
    if (row.frictionOf == ConstraintRow::kNoFriction) {
      row.impulse = std::clamp(row.impulse, row.lo, row.hi);
    }
    // Relax keeps gamma P except on contact normals (rowResidual says why).
    // Joints keep it: rigid relax rows on a 100:1 chain blew it apart.
    const bool contactNormal = blk.unilateral && i < blk.equality;
    if (!contactNormal) row.gammaRelax = row.gamma;
    // Relax leaves physical springs alone (relaxSkips). A contact normal
    // is never treated as one, whatever its softness: its
    // push-out is position correction and relax takes its velocity back
    // out (rowResidual). ODE finds contacts once a frame, so a corner can
    // be found 90 mm deep; as a spring (ERP 0.2, soft_cfm 0.01 at 20 Hz:
    // k 400 N/m, d 80 N s/m) it launched a landing box at k x / d =
    // 0.4 m/s, 36% more energy than ODE converged, and the box tumbled
    // onto another face (demo_moving_convex).
    row.spring = row.softness && row.softness->mode == Softness::Mode::Stiffness &&
                 row.gamma > 0.0 && !contactNormal;
    row.softness = nullptr;
  }

  // An island block or chain that solves this joint's equality rows needs
  // no factor of the joint's own, unless the joint's limits and motors
  // are solved in its null space (coupleBoundedRows).
  blk.factored = blk.inverted = false;
  if (islandSolvesAll || (inGroup && blk.bounded == 0)) return;
  blk.factored = true;
  // K = J M^-1 J^T + gamma for the equality rows, factored once here and
  // reused by every sweep of this (sub-)step.
  const int ne = blk.equality;
  const ConstraintRow* eq = rows;
  double* K = matrixOf(blk);  // column-major: K(r, col) at K[r + ne col]
  const double scale = blk.springShare > 0.0 ? 1.0 + blk.springShare : 1.0;  // K + c K (gamma 0)
  for (int r = 0; r < ne; ++r) {
    for (int col = 0; col <= r; ++col) {
      K[r + ne * col] = a.invMass * eq[r].linA.dot(eq[col].linA) +
                        eq[r].angA.dot(eq[col].invIangA) +
                        b.invMass * eq[r].linB.dot(eq[col].linB) + eq[r].angB.dot(eq[col].invIangB);
    }
    K[r + ne * r] += eq[r].gamma;
    for (int col = 0; col <= r; ++col)
      K[r + ne * col] *= scale;
  }
  blk.redundant = false;
  // A joint's 3 x 3 block (a ball joint's point) is inverted outright;
  // contact blocks keep the factor, whose zero pivots name the redundant
  // points (a 3-point manifold by cofactors left one heap of 100 hulls in
  // ConvexWorld's test still creeping at 9.7 mm/s after 8 s).
  if (ne == 3 && !blk.unilateral && invertSymmetric3(K)) {
    blk.inverted = true;
  } else {
    ldltFactor(K, ne);
    for (int r = 0; r < ne; ++r)
      blk.redundant = blk.redundant || K[r + ne * r] == 0.0;
  }
  if (s.blockMode == BlockMode::Block && !blk.unilateral) coupleBoundedRows(blk);
}

// A bounded row (limit, motor) of a joint acts along its own Jacobian
// only: at a lever arm its impulse breaks the joint's equality rows, and
// Gauss-Seidel between the two repairs that slowly (a hinge stop with
// bounce 1 returned 89% of the speed after 10 sweeps). So each bounded row
// is solved in the null space of its joint's equality block: its impulse
// lambda comes with equality impulses w lambda, w = -K_e^-1 J_e M^-1 J_b^T,
// which keep J_e v + gamma P_e unchanged; its effective mass is the Schur
// complement J_b M^-1 (J_b^T + J_e^T w) + gamma_b. One bounded row and the
// equality block are then solved exactly together; several bounded rows
// of one joint still iterate among themselves (they act on different axes).
void Solver::coupleBoundedRows(const ConstraintBlock& blk) {
  const SolverBody& a = bodies_[blk.bodyA];
  const SolverBody& b = bodies_[blk.bodyB];
  const ConstraintRow* eq = &rows_[blk.firstRow];
  const int ne = blk.equality;
  for (int r = blk.boundedBegin(); r < blk.boundedEnd(); ++r) {
    ConstraintRow& row = rows_[r];
    BoundedCoupling& c = coupling_[r];
    double w[6];
    for (int i = 0; i < ne; ++i) {
      w[i] = -(a.invMass * eq[i].linA.dot(row.linA) + eq[i].angA.dot(row.invIangA) +
               b.invMass * eq[i].linB.dot(row.linB) + eq[i].angB.dot(row.invIangB));
    }
    solveBlock(blk, matrixOf(blk), w);
    Vec3 linA = row.linA, linB = row.linB;
    c.dwA = row.invIangA;
    c.dwB = row.invIangB;
    for (int i = 0; i < ne; ++i) {
      c.w[i] = w[i];
      linA += w[i] * eq[i].linA;
      linB += w[i] * eq[i].linB;
      c.dwA += w[i] * eq[i].invIangA;
      c.dwB += w[i] * eq[i].invIangB;
    }
    c.dvA = a.invMass * linA;
    c.dvB = b.invMass * linB;
    const double schur =
        row.linA.dot(c.dvA) + row.angA.dot(c.dwA) + row.linB.dot(c.dvB) + row.angB.dot(c.dwB);
    // A spring relative to the row's effective mass is relative to the
    // one it has here: a hinge stop at a 0.7 m lever sees the pendulum's
    // inertia about the pivot, 75 times its own about its centre, and a
    // gamma from K_ii made the stop that much softer than it asks.
    if (row.gammaShare > 0.0) row.gamma = row.gammaRelax = row.gammaShare * schur;
    const double k = schur + row.gamma;
    // A bounded row that the equality rows already fix has no freedom left.
    c.effMass = k > 1e-12 / std::max(row.effMass, 1e-300) ? 1.0 / k : 0.0;
  }
}

void Solver::solveCoupledRow(int rowIndex, bool useBias, ConstraintRow* eq, int ne, SolverBody& a,
                             SolverBody& b) {
  ConstraintRow& row = rows_[rowIndex];
  const BoundedCoupling& c = coupling_[rowIndex];
  if (relaxSkips(row, useBias)) return;
  const double residual = rowResidual(row, useBias, a, b);
  const double next = std::clamp(row.impulse - residual * c.effMass, row.lo, row.hi);
  const double dP = next - row.impulse;
  row.impulse = next;
  addVelocity(a, dP * c.dvA, dP * c.dwA);
  addVelocity(b, dP * c.dvB, dP * c.dwB);
  for (int i = 0; i < ne; ++i)
    eq[i].impulse += c.w[i] * dP;
}

void Solver::warmStart() {
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    SolverBody& a = bodies_[blk.bodyA];
    SolverBody& b = bodies_[blk.bodyB];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    for (int i = 0; i < blk.rowCount(); ++i) {
      if (rows[i].impulse != 0.0) applyImpulse(rows[i], rows[i].impulse, a, b);
    }
  }
}

void Solver::sweep(int island, bool useBias, BlockMode mode) {
  const bool islandBounded = useIslandBlock_ && islandBlocks().solvesBounded(island);
  const bool contactIsland = contactIslandRows_ > 0 && contactIslands_.covers(island);
  const bool contactsInBlock = islandBounded && islandBlocks().solvesContacts(island);
  for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi) {
    ConstraintBlock& blk = blocks_[bi];
    SolverBody& a = bodies_[blk.bodyA];
    SolverBody& b = bodies_[blk.bodyB];
    ConstraintRow* rows = &rows_[blk.firstRow];
    const int ne = blk.equality;
    if (blk.unilateral) {
      if (contactsInBlock && islandBlocks().solvesContactNormals(bi)) {
        // Its normals with the island's bounded rows below.
        solveFriction(blk, useBias, a, b);
        continue;
      }
      if (contactIsland && contactIslands_.groups(bi)) {
        for (int pass = 0; pass < islandFrictionPasses_; ++pass)
          solveFriction(blk, useBias, a, b);
      } else
        solveContact(blk, useBias, mode, a, b);
      continue;
    }
    if (mode == BlockMode::RowByRow) {
      for (int i = 0; i < blk.rowCount(); ++i)
        solveRow(rows[i], useBias, a, b);
      continue;
    }
    // The rigid block first, then limits and motors in its null space
    // (row.h says why).
    if (!useIslandBlock_ || !islandBlocks().solvesEquality(bi))
      solveEqualityBlock(blk, useBias, a, b);
    if (!islandBounded) {
      for (int i = blk.boundedBegin(); i < blk.boundedEnd(); ++i)
        solveCoupledRow(i, useBias, rows, ne, a, b);
    }
  }
  // The island's equality rows all at once (or chain by chain), then its
  // limits and motors in their null space (row.h says why).
  if (useIslandBlock_) {
    for (int g = islandBlocks().groupsBegin(island); g < islandBlocks().groupsEnd(island); ++g)
      islandBlocks().solve(g, useBias, blocks_, rows_, bodies_);
  }
  if (islandBounded)
    islandBlocks().solveBounded(island, useBias, islandMotorPasses_, blocks_, rows_, bodies_);
  // The island's groups of contact normals, each at once, after their
  // friction; a group's manifolds finish what it leaves (contact_island.h).
  if (!contactIsland) return;
  for (int g = contactIslands_.groupsBegin(island); g < contactIslands_.groupsEnd(island); ++g) {
    if (contactIslands_.solve(g, useBias, blocks_, rows_, bodies_) ==
        ContactIslands::Outcome::Exact)
      continue;
    // In the island's order (a whole island's group keeps its own,
    // breadth-first from the ground, for its factor).
    auto finish = [&](std::int32_t bi) {
      ConstraintBlock& blk = blocks_[bi];
      solveNormals(blk, useBias, mode, bodies_[blk.bodyA], bodies_[blk.bodyB]);
    };
    if (contactIslands_.wholeIsland(g)) {
      for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi)
        finish(bi);
    } else {
      contactIslands_.forEachBlock(g, finish);
    }
  }
}

// Section 4.3: (J M^-1 J^T + c/h) dP = -(J v + b + gamma P) for the whole
// equality block at once, with the factor from prepare().
void Solver::solveEqualityBlock(ConstraintBlock& blk, bool useBias, SolverBody& a, SolverBody& b) {
  ConstraintRow* eq = &rows_[blk.firstRow];
  const int ne = blk.equality;
  double dP[6];
  for (int i = 0; i < ne; ++i)
    dP[i] = relaxSkips(eq[i], useBias) ? 0.0 : -rowResidual(eq[i], useBias, a, b);
  solveBlock(blk, matrixOf(blk), dP);
  if (blk.springShare > 0.0) {  // Gamma = c K (blockSpringShare)
    const double impulseShare = blk.springShare / (1.0 + blk.springShare);
    for (int i = 0; i < ne; ++i)
      dP[i] -= impulseShare * eq[i].impulse;
  }
  if (blk.unilateral) {
    // Accept the block solution only if every accumulated normal impulse
    // stays >= 0 (all points pushing: the resting case).
    for (int i = 0; i < ne; ++i) {
      if (eq[i].impulse + dP[i] < 0.0) return projectedContactSweeps(blk, useBias, a, b);
    }
  }
  Vec3 dvA = Vec3::Zero(), dwA = Vec3::Zero(), dvB = Vec3::Zero(), dwB = Vec3::Zero();
  for (int i = 0; i < ne; ++i) {
    eq[i].impulse += dP[i];
    dvA += dP[i] * eq[i].linA;
    dwA += dP[i] * eq[i].invIangA;
    dvB += dP[i] * eq[i].linB;
    dwB += dP[i] * eq[i].invIangB;
  }
  addVelocity(a, a.invMass * dvA, dwA);
  addVelocity(b, b.invMass * dvB, dwB);
  if (blk.unilateral && blk.redundant) {
    // A point whose row depends on the others (four points of one body on
    // a plane: K has rank 3) was left to them, which holds only while the
    // points' targets agree (a face's corners at one depth). They do not
    // when one point is deeper than the others' plane (a hull's vertices
    // within the margin of the ground): a hull rested 24 mm deep on its
    // deepest vertex, whose push-out the factor left out.
    for (int i = 0; i < ne; ++i) {
      const double r = rowResidual(eq[i], useBias, a, b);
      if (r < -kUnmetResidual || (r > kUnmetResidual && eq[i].impulse > 0.0))
        return projectedContactSweeps(blk, useBias, a, b);
    }
  }
}

// The normal block when some point would pull: a few projected
// Gauss-Seidel passes over the points inside the block (each clamped at
// 0), not an exact small LCP. Both were tried: exact enumeration of the
// active sets (as Box2D v2 does for two points) made the 10-box stack
// drift 9.4 mm in 2000 frames against 0.92 mm with these passes. Four
// coplanar points make the LCP's answer non-unique (K has rank 3), and the
// enumeration settles on three-corner supports that rock; the passes
// spread the load over all four corners.
void Solver::projectedContactSweeps(ConstraintBlock& blk, bool useBias, SolverBody& a,
                                    SolverBody& b) {
  ConstraintRow* eq = &rows_[blk.firstRow];
  // One point alone is exact in one pass (clamped at 0, a second finds it
  // separating and leaves it there).
  const int passes = blk.equality == 1 ? 1 : 3;
  for (int pass = 0; pass < passes; ++pass) {
    for (int i = 0; i < blk.equality; ++i)
      solveRow(eq[i], useBias, a, b);
  }
}

// Friction bounded by the normal impulses as they stand (section 4.2:
// mu times the point's accumulated normal impulse; rolling and spinning
// by the manifold's total).
void Solver::solveFriction(ConstraintBlock& blk, bool useBias, SolverBody& a, SolverBody& b) {
  ConstraintRow* rows = &rows_[blk.firstRow];
  const int ne = blk.equality;
  double normalSum = 0.0;
  for (int i = 0; i < ne; ++i)
    normalSum += rows[i].impulse;
  for (int i = blk.equality; i < blk.rowCount(); ++i) {
    ConstraintRow& row = rows[i];
    if (row.frictionOf != ConstraintRow::kNoFriction) {
      const double load =
          row.frictionOf == ConstraintRow::kAllNormals ? normalSum : rows[row.frictionOf].impulse;
      row.hi = row.mu * load;
      row.lo = -row.hi;
    }
    if (!row.conePair) {
      solveRow(row, useBias, a, b);
      continue;
    }
    // Cone friction: both tangents unclamped, then the pair projected onto
    // the disk of radius mu P_n (no direction preferred, unlike the box).
    ConstraintRow& other = rows[i + 1];
    const double radius = row.hi;
    const double t0 = row.impulse - rowResidual(row, useBias, a, b) * row.effMass;
    const double t1 = other.impulse - rowResidual(other, useBias, a, b) * other.effMass;
    const double len = std::hypot(t0, t1);
    const double scale = len > radius ? radius / len : 1.0;
    const double d0 = t0 * scale - row.impulse, d1 = t1 * scale - other.impulse;
    row.impulse += d0;
    other.impulse += d1;
    applyImpulse(row, d0, a, b);
    applyImpulse(other, d1, a, b);
    ++i;
  }
}

void Solver::solveNormals(ConstraintBlock& blk, bool useBias, BlockMode mode, SolverBody& a,
                          SolverBody& b) {
  ConstraintRow* rows = &rows_[blk.firstRow];
  if (mode == BlockMode::RowByRow) {
    for (int i = 0; i < blk.equality; ++i)
      solveRow(rows[i], useBias, a, b);
    return;
  }
  solveEqualityBlock(blk, useBias, a, b);
}

// Friction first, the normal block last: non-penetration is the most
// important. In the relax pass the normals hold no push (rigid rows, no
// bias), so the friction bound is the load itself: a sliding box
// decelerates at mu g.
void Solver::solveContact(ConstraintBlock& blk, bool useBias, BlockMode mode, SolverBody& a,
                          SolverBody& b) {
  solveFriction(blk, useBias, a, b);
  solveNormals(blk, useBias, mode, a, b);
}

void Solver::islandResidual(int island, double& max, double& sumSq, int& count) const {
  for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    const SolverBody& a = bodies_[blk.bodyA];
    const SolverBody& b = bodies_[blk.bodyB];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    double normalSum = 0.0;
    if (blk.unilateral) {
      for (int i = 0; i < blk.equality; ++i)
        normalSum += rows[i].impulse;
    }
    // Gamma P = c K P = c J M^-1 J^T P: the velocity the equality
    // impulses give the bodies, seen by each row.
    Vec3 softA[2] = {Vec3::Zero(), Vec3::Zero()}, softB[2] = {Vec3::Zero(), Vec3::Zero()};
    if (blk.springShare > 0.0) {
      for (int i = 0; i < blk.equality; ++i) {
        const double cP = blk.springShare * rows[i].impulse;
        softA[0] += (a.invMass * cP) * rows[i].linA;
        softA[1] += cP * rows[i].invIangA;
        softB[0] += (b.invMass * cP) * rows[i].linB;
        softB[1] += cP * rows[i].invIangB;
      }
    }
    for (int i = 0; i < blk.rowCount(); ++i) {
      const ConstraintRow& row = rows[i];
      if (row.effMass == 0.0) continue;  // acts on nothing that moves
      // A friction row's bounds follow the normal impulses as they are now,
      // not as they were when it was last solved: with a cold start its
      // stored bound is 0, and a tolerance stop after one sweep left every
      // box of ODE's demo_friction without friction.
      double lo = row.lo, hi = row.hi;
      if (row.frictionOf != ConstraintRow::kNoFriction) {
        hi = row.mu * (row.frictionOf == ConstraintRow::kAllNormals ? normalSum
                                                                    : rows[row.frictionOf].impulse);
        lo = -hi;
      }
      const double blockSoftness = i < blk.equality && blk.springShare > 0.0
                                       ? row.linA.dot(softA[0]) + row.angA.dot(softA[1]) +
                                             row.linB.dot(softB[0]) + row.angB.dot(softB[1])
                                       : 0.0;
      const double r = reportedResidual(row, lo, hi, a, b, blockSoftness);
      max = std::max(max, r);
      sumSq += r * r;
      ++count;
    }
  }
}

struct Solver::ThreadPool {
  explicit ThreadPool(int n) : threads(n), arena(n) {}
  int threads;
  tbb::task_arena arena;
};

// A pool only where it can help: more than one thread asked for and more
// than one island to sweep. The arena is made again only when the count
// changes.
void Solver::usePool(const SolverSettings& s) {
  // Never more than the machine's cores: TBB has no more workers to give
  // (and says so on stderr when an arena asks for them).
  const int cores = tbb::info::default_concurrency();
  const int threads = s.threads > 0 ? std::min(s.threads, cores) : cores;
  pooled_ = threads > 1;
  if (pooled_ && (!pool_ || pool_->threads != threads))
    pool_ = std::make_shared<ThreadPool>(threads);
}

void Solver::forRanges(int n, int grain, void* fn, void (*range)(void*, int, int)) {
  if (!pooled_ || n < 2 * grain) {
    range(fn, 0, n);
    return;
  }
  pool_->arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, n, grain),
        [&](const tbb::blocked_range<int>& r) { range(fn, r.begin(), r.end()); },
        tbb::static_partitioner());
  });
}

void Solver::sweepIslands(bool useBias, BlockMode mode) {
  forEachIndex(
      islandEnd_ - islandBegin_, [&](int k) { sweep(islandBegin_ + k, useBias, mode); }, 1);
}

int Solver::solve(const SolverSettings& s, int substep, double budget, StepStats& stats) {
  // The clock only under a budget: a tiny world's step reads it 30 times
  // otherwise, 7% of a two-body pendulum's step.
  const auto start = budget != kNoBudget ? Clock::now() : Clock::time_point{};
  const bool measure = s.recordResiduals || s.tolerance > 0.0;
  std::fill(islandActive_.begin(), islandActive_.end(), 1);
  int sweeps = 0;
  for (int it = 0; it < s.iterations; ++it) {
    if (!measure) {  // every island, every sweep: they may go at once
      if (islandEnd_ == islandBegin_) break;
      sweepIslands(true, s.blockMode);
      ++sweeps;
      if (budget != kNoBudget && seconds(start, Clock::now()) >= budget) break;
      continue;
    }
    bool anyActive = false;
    double max = 0.0, sumSq = 0.0;
    int count = 0;
    for (int island = islandBegin_; island < islandEnd_; ++island) {
      if (islandActive_[island]) {
        sweep(island, true, s.blockMode);
        anyActive = true;
      }
      if (!measure) continue;
      double islandMax = 0.0;
      islandResidual(island, islandMax, sumSq, count);
      max = std::max(max, islandMax);
      if (s.tolerance > 0.0 && islandMax < s.tolerance) islandActive_[island] = 0;
    }
    if (!anyActive) break;
    ++sweeps;
    if (s.recordResiduals) {
      stats.residuals.push_back(
          ResidualSample{substep, it + 1, max, count > 0 ? std::sqrt(sumSq / count) : 0.0});
    }
    if (s.tolerance > 0.0 && max < s.tolerance) break;
    if (budget != kNoBudget && seconds(start, Clock::now()) >= budget) break;
  }
  return sweeps;
}

void Solver::integratePositions(const StepInput& in, const SolverSettings& s, double h) {
  const bool explicitEuler = s.integrator == Integrator::ExplicitEuler;
  forEachBody(static_cast<int>(in.bodies.size()), [&](std::int32_t i) {
    Body& b = in.bodies[i];
    if (!b.alive || b.type == BodyType::Static) return;
    if (b.isDynamic()) {
      b.linearVelocity = bodies_[i].v;
      b.angularVelocity = bodies_[i].w;
    }
    // Semi-implicit Euler moves with the new velocity (section 3);
    // explicit Euler with the velocity the step started from.
    const Vec3& v = explicitEuler ? startV_[i] : b.linearVelocity;
    const Vec3& w = explicitEuler ? startW_[i] : b.angularVelocity;
    b.position += h * v;
    if (s.gyroscopic && b.rotation.gyroscopic && b.isDynamic()) {
      const Quat before = b.orientation;
      b.orientation = turn(b.orientation, b.rotation, w + gyroOffset_[i], h);
      const Vec3 turned = b.orientation * (before.conjugate() * b.angularVelocity);
      b.angularVelocity = turned;
      bodies_[i].w = turned;
      return;
    }
    b.orientation = turn(b.orientation, b.rotation, w, h);
  });
}

// Post-stabilization (SolverSettings::positionProjections): each island
// solved as one island block moves its bodies along M^-1 J^T so that its
// rigid equality rows, measured at the pose the step left, close to
// first order: a Newton step on the joints' positions. Its K is the
// sub-step's own factor while the island's bodies turned less than
// kStaleProjectionTurn since their rows were prepared (the Jacobians of
// then, off by about that turn, take out all but that share of the
// error); past it K is formed and factored again at the pose, with the
// inertia turned there too: with the prepared factor a whipping chain's
// links, turned by w h since, took steps that missed by as much as they
// moved and the errors grew pass after pass. Later passes keep the
// factor and measure the errors again. A pass that turns a body farther
// than kLinearProjectionTurn (its second-order error may then rival what
// it closed) is checked, and taken back if it left the island's largest
// error larger than it found it. Velocities are left alone.
bool Solver::projectPositions(const StepInput& in, const SolverSettings& s, double h, int sub) {
  if (s.positionProjections <= 0 || !useIslandBlock_ || !s.rigidJointSoftness) return false;
  // Grow only while warming up.
  if (projectionError_.size() < rows_.size()) {
    projectionError_.resize(rows_.size());
    projectionImpulse_.resize(rows_.size());
    projectionRows_.resize(rows_.size());
  }
  if (projectionMove_.size() < bodies_.size()) {
    projectionMove_.resize(bodies_.size(), Vec3::Zero());
    projectionTurn_.resize(bodies_.size(), Vec3::Zero());
    projectionInvI_.resize(bodies_.size());
    projectionX_.resize(bodies_.size());
    projectionMark_.resize(bodies_.size(), 0);
    projectionStartX_.resize(bodies_.size());
    projectionStartQ_.resize(bodies_.size());
    projectionQ_.resize(bodies_.size());
  }
  const std::size_t slots = pooled_ ? static_cast<std::size_t>(pool_->threads) : 1;
  if (projectionScratch_.size() < slots) projectionScratch_.resize(slots);
  islandBlocks().preparePoseFactors();
  // Time since the rows were prepared (s), this sub-step included.
  const double sincePrepared = h * (sub - preparedAt_ + 1);
  // Islands share no movable body, and each writes only its own rows,
  // bodies and groups: any thread count gives one thread's bits.
  std::atomic<bool> moved{false};
  forEachIndex(
      islandEnd_ - islandBegin_,
      [&](int k) {
        // A thread of the pool's arena has its index there; forRanges runs
        // a short loop on the calling thread, outside the arena, whose
        // index is then another arena's or none (-1: the write went before
        // the scratch and corrupted the heap). Such a loop is serial, and
        // slot 0 is free for it.
        const int index = tbb::this_task_arena::current_thread_index();
        const std::size_t slot =
            pooled_ && index >= 0 && static_cast<std::size_t>(index) < slots ? index : 0;
        if (projectIsland(in, s, islandBegin_ + k, sincePrepared, projectionScratch_[slot]))
          moved.store(true, std::memory_order_relaxed);
      },
      1);
  return moved.load();
}

// One island's projection (projectPositions), with a thread's own room
// for a joint's rows. A body several blocks share is visited once per
// block: each visit does what the first did (saves the same pose, reads
// the same turn) or nothing (its move was applied and cleared).
bool Solver::projectIsland(const StepInput& in, const SolverSettings& s, int island,
                           double sincePrepared, JointRowScratch& scratch) {
  IslandBlocks& islands = islandBlocks();
  if (!islands.covers(island)) return false;
  const std::int32_t first = islandStart_[island], end = islandStart_[island + 1];
  auto movable = [&](std::int32_t i) { return i != dummy_ && bodies_[i].invMass != 0.0; };
  auto forEachBody = [&](auto&& f) {
    for (std::int32_t bi = first; bi < end; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      for (const std::int32_t i : {blk.bodyA, blk.bodyB})
        if (movable(i)) f(i);
    }
  };
  double fastest = 0.0;  // (rad/s)^2, the island's fastest turn this sub-step
  forEachBody([&](std::int32_t i) {
    fastest = std::max(fastest, in.bodies[i].angularVelocity.squaredNorm());
  });
  // An island at the exact joint islands' own count (one sub-step, say)
  // is projected as SHAKE projects (shakeIsland below) while it turned
  // less than kShakeTurn since its rows were prepared, and while nothing
  // touches it (only then do its velocities take the moves).
  bool shakeIsland = islandAtExactJointCount_[island] && !islandTouched_[island] &&
                     std::sqrt(fastest) * sincePrepared <= kShakeTurn;
  bool atPose = !shakeIsland && std::sqrt(fastest) * sincePrepared > kStaleProjectionTurn;
  // M^-1 J^T of the rows at the pose, in the Newton step's metric: only
  // once the island is to be projected (most steps of the preset find it
  // within its tolerance).
  auto useMetricAtPose = [&] {
    // The Newton step's metric: turning a body costs what moving its mass
    // by kProjectionReach times the island's size would, on top of its
    // inertia. With the bodies' own inertia the smallest correction turned
    // the lightest links, whose inertia makes turning cheap, and a turn's
    // second-order opening (r theta^2 / 2) outgrew what the step closed:
    // chain_swing's errors went 16 -> 52 mm in one pass, its links turned
    // by up to 3.5 rad, and it tore at 1-4 sub-steps however many passes.
    // Moves enter the point rows linearly, so this step closes them almost
    // exactly and leaves turns to the rows only a turn closes (angular
    // rows, loops). Any positive metric gives a pose on the rows; moves
    // still go as M^-1 J^T, so a joint
    // between two of the island's bodies leaves their centre of mass
    // where it was. (Below kStaleProjectionTurn the prepared factor, of
    // the bodies' own inertia, serves: the island turned too little since
    // for turns to matter.)
    Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
    forEachBody([&](std::int32_t i) {
      lo = lo.cwiseMin(in.bodies[i].position);
      hi = hi.cwiseMax(in.bodies[i].position);
    });
    const double reach = kProjectionReach * (hi - lo).norm();
    forEachBody([&](std::int32_t i) {
      const Body& b = in.bodies[i];
      // (I + c 1)^-1 = W (1 + c W)^-1 with W = I^-1, which also keeps a
      // locked axis (W singular) locked; W and (1 + c W)^-1 commute.
      const Mat3 W = b.invInertiaWorld();
      const double c = reach * reach / bodies_[i].invMass;
      projectionInvI_[i] = W * (Mat3::Identity() + c * W).inverse();
    });
    for (int g = islands.groupsBegin(island); g < islands.groupsEnd(island); ++g) {
      islands.forEachRow(g, [&](std::int32_t r, std::int32_t bi) {
        const ConstraintBlock& blk = blocks_[bi];
        ConstraintRow& at = projectionRows_[r];
        // The static frame and kinematic bodies do not move (and their
        // inverse inertia is not read: islands on other threads share them).
        at.invIangA =
            movable(blk.bodyA) ? Vec3(projectionInvI_[blk.bodyA] * at.angA) : Vec3(Vec3::Zero());
        at.invIangB =
            movable(blk.bodyB) ? Vec3(projectionInvI_[blk.bodyB] * at.angB) : Vec3(Vec3::Zero());
        at.gamma = 0.0;
      });
    }
  };
  int moves = 0;           // passes whose moves the pose keeps
  bool madeWorse = false;  // the last pass was taken back
  auto project = [&] {
    const std::vector<ConstraintRow>& jacobians = atPose ? projectionRows_ : rows_;
    double lastError = kInf;
    bool check = false;  // the last pass is to be checked
    for (int pass = 0; pass < s.positionProjections || check; ++pass) {
      // The rows' errors at the pose now; on the first pass at the pose
      // their Jacobians and M^-1 J^T too.
      double error = 0.0;
      for (std::int32_t bi = first; bi < end; ++bi) {
        const ConstraintBlock& blk = blocks_[bi];
        if (blk.joint < 0 || blk.equality == 0 || !islands.solvesEquality(bi)) continue;
        const Joint& joint = in.joints[blk.joint];
        JointState state = joint.state;  // rows at a pose the step may still move
        const RowWriter out = writeJointRows(in, joint, state, scratch.data());
        const bool same = out.equalityCount() == blk.equality;
        for (int i = 0; i < blk.equality; ++i) {
          const std::int32_t r = blk.firstRow + i;
          const bool rigid = same && rows_[r].projected && rows_[r].biasKind == RowBias::Baumgarte;
          projectionError_[r] = rigid ? scratch[i].C : 0.0;
          error = std::max(error, std::abs(projectionError_[r]));
          if (pass > 0 || !atPose) continue;
          ConstraintRow& at = projectionRows_[r];
          const ConstraintRow& fresh = same ? scratch[i] : rows_[r];
          at.linA = fresh.linA;
          at.angA = fresh.angA;
          at.linB = fresh.linB;
          at.angB = fresh.angB;
        }
      }
      // The last pass made it worse, or SHAKE's rows closed too little of
      // it: back to before it.
      const bool shakeStalled =
          shakeIsland && error > s.projectionTolerance && error > kShakeContraction * lastError;
      if (error > lastError || shakeStalled) {
        forEachBody([&](std::int32_t i) {
          in.bodies[i].position = projectionX_[i];
          in.bodies[i].orientation = projectionQ_[i];
        });
        --moves;
        madeWorse = true;
        return;
      }
      if (pass == s.positionProjections || error == 0.0) return;
      // Closed well enough (a SHAKE island closes any error: its velocity
      // takes the moves).
      if (pass == 0 && !shakeIsland && error <= s.projectionTolerance) return;
      if (pass == 0) {
        if (atPose) useMetricAtPose();
        forEachBody([&](std::int32_t i) {
          projectionStartX_[i] = in.bodies[i].position;
          projectionStartQ_[i] = in.bodies[i].orientation;
        });
      }
      lastError = error;
      for (int g = islands.groupsBegin(island); g < islands.groupsEnd(island); ++g) {
        if (pass == 0 && atPose) islands.factorAtPose(g, blocks_, projectionRows_, bodies_);
        islands.solvePositionErrors(g, projectionError_, projectionImpulse_, atPose);
        islands.forEachRow(g, [&](std::int32_t r, std::int32_t bi) {
          const ConstraintRow& row = jacobians[r];
          const ConstraintBlock& blk = blocks_[bi];
          const double lambda = projectionImpulse_[r];
          // Only movable bodies: the others are shared with other islands.
          if (movable(blk.bodyA)) {
            projectionMove_[blk.bodyA] += (bodies_[blk.bodyA].invMass * lambda) * row.linA;
            projectionTurn_[blk.bodyA] += lambda * row.invIangA;
          }
          if (movable(blk.bodyB)) {
            projectionMove_[blk.bodyB] += (bodies_[blk.bodyB].invMass * lambda) * row.linB;
            projectionTurn_[blk.bodyB] += lambda * row.invIangB;
          }
        });
      }
      forEachBody([&](std::int32_t i) {
        projectionX_[i] = in.bodies[i].position;
        projectionQ_[i] = in.bodies[i].orientation;
      });
      double largestTurn = 0.0;
      forEachBody([&](std::int32_t i) {
        Vec3& move = projectionMove_[i];
        Vec3& turnBy = projectionTurn_[i];
        if (move.isZero() && turnBy.isZero()) return;
        Body& b = in.bodies[i];
        largestTurn = std::max(largestTurn, turnBy.squaredNorm());
        b.position += move;
        b.orientation = integrateRotation(b.orientation, turnBy, 1.0);
        move.setZero();
        turnBy.setZero();
      });
      ++moves;
      check = largestTurn > kLinearProjectionTurn * kLinearProjectionTurn ||
              (shakeIsland && lastError > s.projectionTolerance);
    }
  };
  project();
  // SHAKE's rows, prepared at the sub-step's start, made the errors worse
  // or closed too little of them (kShakeContraction): projected at the
  // pose instead, as an island that turned too fast is. From quickstep's
  // pose of a 100:1 chain (the A/B mode's) they opened 3.0 mm to 3.7, and
  // its joints stayed as open as quickstep's for four steps.
  if (shakeIsland && madeWorse && moves == 0) {
    shakeIsland = false;
    atPose = true;
    madeWorse = false;
    project();
  }
  // Only an island that touches nothing pays: a touched one's moves
  // push its bodies into their contacts, and their velocity along the
  // moves then went into the contacts too (the bridge under its crate
  // rose 1.4 kJ instead of 0.55 at the drop-in's ten sub-steps, median
  // of five starts).
  if (moves > 0 && !islandTouched_[island]) payForProjection(in, island, shakeIsland);
  return moves > 0;
}

// The projection moves bodies without the forces that would move them so:
// the work W that gravity and the applied forces do along those moves is
// energy no stage accounts for. Semi-implicit Euler moves a pendulum's bob
// along its tangent and the projection lifts it back onto its circle,
// where the true motion rises the same way and pays for it in speed.
// Where a joint's linearization lets a body's velocity run against what
// holds it (a 100 kg weight at the end of a thin chain, its links turning
// over a radian a sub-step), the projection puts it back every step while
// gravity goes on speeding it: chain_heavy_swing gained 316 kJ in 10 s at
// one sub-step. So where W < 0 the kinetic energy pays it, taken along
// the moves themselves: v += alpha dx / h (and w += alpha dtheta / h),
// the velocity that would have made them (SHAKE's alpha = 1), with the
// least alpha in [0, 1] that takes W out, or as much as that direction
// holds. Bodies the projection did not move keep their velocities: a
// uniform scale of the island's instead froze the bridge's crate as the
// planks were lifted back under it, and warm started impulses then threw
// it (1.4 kJ gained). The moves of joints between the island's own bodies
// leave its centre of mass where it was, so under gravity alone they do
// no work. What the moves would give (W > 0) is not added: the projection
// never speeds an island up.
void Solver::payForProjection(const StepInput& in, int island, bool shake) {
  const std::int32_t first = islandStart_[island], end = islandStart_[island + 1];
  auto forEachMovedBody = [&](auto&& f) {
    for (std::int32_t bi = first; bi < end; ++bi) {
      const ConstraintBlock& blk = blocks_[bi];
      for (const std::int32_t i : {blk.bodyA, blk.bodyB}) {
        if (i == dummy_ || bodies_[i].invMass == 0.0 || projectionMark_[i]) continue;
        projectionMark_[i] = 1;
        f(i);
      }
    }
  };
  // Only movable bodies: the static and kinematic ones are shared with
  // islands on other threads.
  auto unmark = [&] {
    for (std::int32_t bi = first; bi < end; ++bi)
      for (const std::int32_t i : {blocks_[bi].bodyA, blocks_[bi].bodyB})
        if (i != dummy_ && bodies_[i].invMass != 0.0) projectionMark_[i] = 0;
  };
  // Per body, the velocity u that makes its move over the step; then
  // W = sum (m g + F) . dx + tau . dtheta, and the kinetic energy's change
  // along u, alpha <v, u> + alpha^2 <u, u> / 2 in the bodies' mass metric.
  const double h = in.h;
  double work = 0.0, along = 0.0, norm = 0.0;
  forEachMovedBody([&](std::int32_t i) {
    const Body& b = in.bodies[i];
    const Vec3 dx = b.position - projectionStartX_[i];
    const Eigen::AngleAxisd turned(b.orientation * projectionStartQ_[i].conjugate());
    const Vec3 dtheta = turned.angle() * turned.axis();
    const Vec3 weight = b.gravity ? Vec3(b.mass * in.gravity) : Vec3(Vec3::Zero());
    work += (weight + b.force).dot(dx) + b.torque.dot(dtheta);
    const Mat3 R = b.orientation.toRotationMatrix();
    const Vec3 spin = R * (b.inertiaBody * (R.transpose() * dtheta)) / h;  // I u_w
    projectionMove_[i] = dx / h;
    projectionTurn_[i] = dtheta / h;
    along += b.mass * bodies_[i].v.dot(dx / h) + bodies_[i].w.dot(spin);
    norm += b.mass * (dx / h).squaredNorm() + (dtheta / h).dot(spin);
  });
  unmark();
  double alpha = shake ? 1.0 : 0.0;
  if (!shake && work < 0.0 && along < 0.0 && norm > 0.0) {
    const double least = -along * along / (2.0 * norm);  // at alpha = -along / norm
    alpha = least <= work ? (-along - std::sqrt(along * along + 2.0 * norm * work)) / norm
                          : -along / norm;
    alpha = std::min(alpha, 1.0);
  }
  forEachMovedBody([&](std::int32_t i) {
    bodies_[i].v += alpha * projectionMove_[i];
    bodies_[i].w += alpha * projectionTurn_[i];
    projectionMove_[i].setZero();
    projectionTurn_[i].setZero();
  });
  unmark();
}

// One body's orientation update (RotationUpdate says which).
Quat Solver::turn(const Quat& q, const RotationUpdate& r, const Vec3& w, double h) {
  if (!r.finite) return integrateRotation(q, w, h);
  if (r.axis.isZero()) return rotateExactly(q, w, h);
  // ODE's finite rotation about an axis: exactly about it, then the rest
  // of w first-order (ODE gives the rest half of h there; we give it h).
  const Vec3 along = r.axis.dot(w) * r.axis;
  return integrateRotation(rotateExactly(q, along, h), w - along, h);
}

// The rows are linear in the bodies' motion: a joint turning at w opens
// by about r (w h)^2 / 2 over a sub-step whatever the solve did (a
// pendulum's bob moves along the tangent and off its circle). The solve's
// position correction pulls it back in, and relax used to take that
// velocity out again, so the next sub-step's rows, turned by w h, took
// the outward part of the motion out instead: each sub-step lost about
// (w h)^2 of a turning chain's kinetic energy (PyODE's tutorial2 double
// pendulum kept 84% of its energy over 10 s at 10 sub-steps, ODE's
// quickstep with sub-steps 97%). With relaxCancelsDrift, relax leaves
// each joint equality row the velocity that closes the drift it just measured, C at the new
// pose minus C + h J v (what the rows predicted), over the next sub-step:
// the rebuilt velocity turns with the joint instead of losing its outward
// part. Relax still removes the correction velocity exactly (the same
// rows), so no correction turns into motion: relaxing with rows prepared
// at the new pose kept the energy too, but left part of a large
// correction as spin (a distorted chain's links spun up from 5 to 50
// rad/s in one step).
void Solver::relaxAgainstDrift(const StepInput& in, double h) {
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    if (blk.joint < 0 || blk.equality == 0) continue;
    const Joint& joint = in.joints[blk.joint];
    JointState state = joint.state;  // rows at a pose the step does not keep
    const RowWriter out = writeJointRows(in, joint, state, movedRows_.data());
    if (out.equalityCount() != blk.equality) continue;
    const SolverBody& a = bodies_[blk.bodyA];
    const SolverBody& b = bodies_[blk.bodyB];
    ConstraintRow* rows = &rows_[blk.firstRow];
    for (int i = 0; i < blk.equality; ++i) {
      ConstraintRow& row = rows[i];
      if (row.biasKind != RowBias::Baumgarte) continue;
      const double drift = movedRows_[i].C - (row.C + h * rowVelocity(row, a, b));
      row.biasRelax = drift / h;
    }
  }
}

void Solver::relax(const SolverSettings& s, double h) {
  if (s.relaxIterations <= 0) return;
  // The bodies have moved since prepare(): a one-sided row's gap is now
  // C + h J v (to first order, with the velocity they moved with). Relax
  // must allow only what is left of it, or it lets a contact close a gap
  // the position update already closed (Box2D recomputes the separation
  // from the bodies' motion in each stage for the same reason).
  // One-sided rows are a manifold's normals and a joint's bounded rows
  // (limits): a joint's equality rows, most of a cloth's, are not read.
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    const SolverBody& a = bodies_[blk.bodyA];
    const SolverBody& b = bodies_[blk.bodyB];
    ConstraintRow* rows = &rows_[blk.firstRow];
    const int end = blk.unilateral ? blk.equality : blk.rowCount();
    for (int i = blk.unilateral ? 0 : blk.equality; i < end; ++i) {
      ConstraintRow& row = rows[i];
      if (row.biasKind != RowBias::Speculative || row.biasRelax < -row.target)
        continue;  // bouncing
      const double v = rowVelocity(row, a, b);
      // A restitutive stop or contact approached faster than its bounce
      // threshold keeps prepare's allowance: the next sub-step bounces it
      // at its approach speed. Limiting it here would make it arrive
      // slowly and lose the rebound (a hinge stop with bounce 0.5 returned
      // 0.22 of 1.30 rad/s).
      if (row.bounce > 0.0 && v - row.target < -row.bounceThreshold) continue;
      const double gap = row.C + h * (v - row.target);  // a moving surface moved on too
      row.biasRelax = std::max(gap, 0.0) / h - row.target;
    }
  }
  for (int it = 0; it < s.relaxIterations; ++it)
    sweepIslands(false, s.blockMode);
}

void Solver::storeImpulses(const StepInput& in, double h) {
  // The relax sweeps changed velocities after the position update; the
  // bodies carry them into the next sub-step.
  forEachBody(
      static_cast<int>(in.bodies.size()),
      [&](std::int32_t i) {
        Body& b = in.bodies[i];
        if (b.alive && b.isDynamic()) {
          b.linearVelocity = bodies_[i].v;
          b.angularVelocity = bodies_[i].w;
        }
      },
      true);
  for (std::int32_t bi = blockBegin_; bi < blockEnd_; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    if (blk.contact >= 0) {
      storeContactImpulses(in.contacts[blk.contact], rows, blk.rowCount(), h);
      continue;
    }
    JointImpulses& joint = jointImpulses_[blk.joint];
    joint.slots = 0;
    for (int i = 0; i < blk.rowCount(); ++i) {
      joint.warm[rows[i].slot] = rows[i].impulse;
      joint.slots |= 1u << rows[i].slot;
      joint.step[rows[i].slot] += rows[i].impulse;
    }
    joint.stepSize = h;
  }
}

// A point that bounced this (sub-)step keeps no impulse to warm start the
// next: its impulse answered the impact, and applied again it pushed the
// bodies apart once more (Newton's cradle, elastic, gained 0.57 J in 300
// frames under the drop-in and its balls met 29 mm deep; not carried, it
// keeps its energy and they meet 15 mm deep).
void Solver::storeContactImpulses(ContactManifold& m, const ConstraintRow* rows, int n, double h) {
  for (int i = 0; i < n; ++i) {
    const int slot = rows[i].slot;
    const double P = rows[i].impulse;
    if (slot < kMaxManifoldPoints) {
      m.points[slot].normalImpulse = rows[i].bounced ? 0.0 : P;
      m.points[slot].stepNormalImpulse += P;
    } else if (slot < 3 * kMaxManifoldPoints) {
      const int pointIndex = (slot - kMaxManifoldPoints) / 2;
      ContactPoint& point = m.points[pointIndex];
      const int d = (slot - kMaxManifoldPoints) % 2;
      point.tangentImpulse[d] = rows[pointIndex].bounced ? 0.0 : P;
      point.stepTangentImpulse[d] += P;
    } else {
      m.rollingImpulse[slot - 3 * kMaxManifoldPoints] = P;
    }
  }
  m.warmStepSize = h;
}

void Solver::finish(const StepInput& in, StepStats& stats) {
  const double h = in.h;
  for (const ConstraintBlock& blk : blocks_) {
    if (blk.joint < 0) continue;
    Joint& joint = in.joints[blk.joint];
    // Breakable joints: the force and torque carried over this step.
    const JointCommon& c = common(joint.desc);
    if (std::isinf(c.breakForce) && std::isinf(c.breakTorque)) continue;
    double forceSq = 0.0, torqueSq = 0.0;
    const ConstraintRow* rows = &rows_[blk.firstRow];
    for (int i = 0; i < blk.rowCount(); ++i) {
      const double P = joint.stepImpulse[rows[i].slot];
      (rows[i].angular ? torqueSq : forceSq) += P * P;
    }
    if (std::sqrt(forceSq) > c.breakForce * h || std::sqrt(torqueSq) > c.breakTorque * h) {
      joint.broken = true;
      joint.warmSlots = 0;
      stats.brokenJoints.push_back(blk.joint);
    }
  }
  if (in.clearForces) {
    for (Body& b : in.bodies) {
      b.force.setZero();
      b.torque.setZero();
    }
  }
  stats.islands = islandCount_;
  stats.blocks = static_cast<int>(blocks_.size());
  stats.rows = rowCount_;
}

JointFeedback Solver::feedback(const Joint& joint, double h) const {
  JointFeedback fb;
  if (joint.block < 0 || joint.block >= static_cast<std::int32_t>(blocks_.size())) return fb;
  const ConstraintBlock& blk = blocks_[joint.block];
  const ConstraintRow* rows = &rows_[blk.firstRow];
  for (int i = 0; i < blk.rowCount(); ++i) {
    const double f = joint.stepImpulse[rows[i].slot] / h;
    fb.forceA += f * rows[i].linA;
    fb.torqueA += f * rows[i].angA;
    fb.forceB += f * rows[i].linB;
    fb.torqueB += f * rows[i].angB;
  }
  return fb;
}

}  // namespace blockstep

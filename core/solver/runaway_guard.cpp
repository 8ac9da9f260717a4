#include "core/solver/runaway_guard.h"

#include <algorithm>
#include <cmath>

#include "core/solver/row_ops.h"

namespace blockstep {
namespace {

// Kinetic energy below that of every body moving at this speed is noise.
constexpr double kQuietSpeed = 0.01;  // m/s
// Each step's unexplained growth (a log of an energy ratio) carries this
// much of the last step's, so what counts is growth that goes on: sweeps
// diverging at 3-5x per step (demo_I's star on per-joint blocks) pass a
// gain of 100 within five or six steps. A structure springing back from
// errors coupled beyond their diagonals does not go on: a taut hinge
// bridge struck by a weight gained 30x in one step (ODE's demo_feedback),
// a per-joint 100:1 chain recoiling from its stretch 1.3-1.8x per step
// for 15 steps (about 55 carried).
constexpr double kCarry = 0.9;
// The slow test's carry: growth at 5% a step (the star of ODE's demo_I on
// the paper's solver, 0.46 J to 5410 J in 250 frames) passes a gain of 100
// in about 100 steps; with kCarry it never would (0.05 / (1 - 0.9)).
constexpr double kSlowCarry = 0.99;
// How long an island's peak kinetic energy explains what comes back to
// it (an e-folding time, s). ODE's demo_feedback: a half bridge ringing
// at 30-80 Hz after a weight struck it fell to 0.001 J at its turning
// points and was back at 0.1-0.9 J a few 2 ms steps later.
constexpr double kPeakMemory = 0.1;

// Kinetic energy of a body moving at (v, w) in its current orientation.
double energyAt(const Body& b, const Vec3& v, const Vec3& w) {
  const Vec3 wb = b.orientation.conjugate() * w;
  return 0.5 * b.mass * v.squaredNorm() + 0.5 * wb.dot(b.inertiaBody * wb);
}

bool finiteState(const Body& b) {
  return b.position.allFinite() && b.orientation.coeffs().allFinite() &&
         b.linearVelocity.allFinite() && b.angularVelocity.allFinite();
}

// The velocity a row sees from a body that does not move under impulses
// (a kinematic body, the world: zero).
double drivenBy(const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
  double d = 0.0;
  if (a.invMass == 0.0) d += row.linA.dot(a.v) + row.angA.dot(a.w);
  if (b.invMass == 0.0) d += row.linB.dot(b.v) + row.angB.dot(b.w);
  return d;
}

// The speed, along the row, that closes an error C within the whole step
// h: a joint's error, a contact's or a stop's penetration (capped as the
// row caps its push-out).
double closingSpeed(const ConstraintRow& row, double C, double h) {
  switch (row.biasKind) {
    case RowBias::Velocity:
      return 0.0;
    case RowBias::Speculative: {
      const double push = std::max(0.0, -(C + row.slop)) / h;
      return std::min(push, row.maxBias);
    }
    case RowBias::Baumgarte:
      break;
  }
  return -C / h;
}

// 1/2 d^2 / K_rr for a row whose error is C, d its closing speed over h.
double errorEnergy(const ConstraintRow& row, double C, const SolverBody& a, const SolverBody& b,
                   double h) {
  const double d = closingSpeed(row, C, h);
  const double k = rowDiagonal(row, a, b);
  return d != 0.0 && k > 0.0 ? 0.5 * d * d / k : 0.0;
}

}  // namespace

double kineticEnergy(const Body& b) {
  return energyAt(b, b.linearVelocity, b.angularVelocity);
}

double kineticEnergy(const Body& b, const Vec3& v, const Vec3& w) {
  return energyAt(b, v, w);
}

void RunawayGuard::begin(const std::vector<Body>& bodies,
                         const std::vector<std::int32_t>& groupOfBody, int groups,
                         const Vec3& gravity, double h) {
  groupOfBody_ = &groupOfBody;
  h_ = h;
  groups_.assign(static_cast<std::size_t>(groups), Group{});
  start_.resize(bodies.size());
  growth_.resize(bodies.size(), 0.0);
  slowGrowth_.resize(bodies.size(), 0.0);
  peak_.resize(bodies.size(), 0.0);
  const double forget = std::exp(-h / kPeakMemory);
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const std::int32_t g = groupOfBody[i];
    if (g < 0) continue;
    const Body& b = bodies[i];
    BodyStart& start = start_[i];
    start.energy = kineticEnergy(b);
    start.position = b.position;
    start.angularVelocity = b.angularVelocity;
    start.force = b.gravity ? Vec3(b.force + b.mass * gravity) : b.force;
    start.torque = b.torque;
    // What the forces alone would give over the step, from rest as much as
    // along the path: a body resting on a contact keeps some of the
    // velocity gravity gave it within the step.
    // (Most bodies bear no torque: their world inertia is not needed.)
    const Vec3 freeW = b.torque.isZero(0.0)
                           ? b.angularVelocity
                           : Vec3(b.angularVelocity + h * (b.invInertiaWorld() * b.torque));
    start.freeGain =
        energyAt(b, b.linearVelocity + h * b.invMass * start.force, freeW) - start.energy;
    Group& group = groups_[g];
    group.before += start.energy;
    group.explained += start.energy;
    group.mass += b.mass;
    group.peak = std::max(group.peak, forget * peak_[i]);
  }
  for (Group& group : groups_)
    group.explained += std::max(0.0, group.peak - group.before);
}

// Adds f(row, a, b) over each island's rows to the island's `sum`.
template <class F>
void RunawayGuard::addOverRows(const std::vector<ConstraintBlock>& blocks,
                               const std::vector<ConstraintRow>& rows,
                               const std::vector<SolverBody>& bodies,
                               const std::vector<std::int32_t>& groupStart, int firstIsland,
                               int endIsland, double Group::*sum, F f) {
  for (int g = firstIsland; g < endIsland; ++g) {
    double total = 0.0;
    for (std::int32_t bi = groupStart[g]; bi < groupStart[g + 1]; ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      const SolverBody& a = bodies[blk.bodyA];
      const SolverBody& b = bodies[blk.bodyB];
      for (int r = blk.firstRow; r < blk.firstRow + blk.rowCount(); ++r)
        total += f(rows[r], a, b);
    }
    groups_[g].*sum += total;
  }
}

template <class ErrorOf>
void RunawayGuard::addErrorEnergy(const std::vector<ConstraintBlock>& blocks,
                                  const std::vector<ConstraintRow>& rows,
                                  const std::vector<SolverBody>& bodies,
                                  const std::vector<std::int32_t>& groupStart, int firstIsland,
                                  int endIsland, double h, IslandBlocks* islands,
                                  double Group::*sum, ErrorOf errorOf) {
  for (int g = firstIsland; g < endIsland; ++g) {
    const bool exact = islands && islands->covers(g);
    double total = 0.0;
    for (std::int32_t bi = groupStart[g]; bi < groupStart[g + 1]; ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      const SolverBody& a = bodies[blk.bodyA];
      const SolverBody& b = bodies[blk.bodyB];
      // The island's factor measures its joints' equality rows.
      const int first = exact && blk.joint >= 0 ? blk.firstRow + blk.equality : blk.firstRow;
      for (int r = first; r < blk.firstRow + blk.rowCount(); ++r)
        total += errorEnergy(rows[r], errorOf(rows[r], a, b), a, b, h);
    }
    if (exact) {
      total +=
          islands->inverseQuadratic(g, rows, [&](const ConstraintRow& row, std::int32_t block) {
            const ConstraintBlock& blk = blocks[block];
            return closingSpeed(row, errorOf(row, bodies[blk.bodyA], bodies[blk.bodyB]), h);
          });
    }
    groups_[g].*sum += total;
  }
}

void RunawayGuard::addCorrections(const std::vector<ConstraintBlock>& blocks,
                                  const std::vector<ConstraintRow>& rows,
                                  const std::vector<SolverBody>& bodies,
                                  const std::vector<std::int32_t>& groupStart, int firstIsland,
                                  int endIsland, double h, IslandBlocks* islands) {
  addErrorEnergy(
      blocks, rows, bodies, groupStart, firstIsland, endIsland, h, islands, &Group::errorsBefore,
      [](const ConstraintRow& row, const SolverBody&, const SolverBody&) { return row.C; });
}

void RunawayGuard::addRemainingErrors(const std::vector<ConstraintBlock>& blocks,
                                      const std::vector<ConstraintRow>& rows,
                                      const std::vector<SolverBody>& bodies,
                                      const std::vector<std::int32_t>& groupStart, int firstIsland,
                                      int endIsland, double hLast, double h,
                                      IslandBlocks* islands) {
  addErrorEnergy(blocks, rows, bodies, groupStart, firstIsland, endIsland, h, islands,
                 &Group::errorsAfter,
                 [hLast](const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
                   return row.C + hLast * rowVelocity(row, a, b);
                 });
}

void RunawayGuard::addWork(const std::vector<ConstraintBlock>& blocks,
                           const std::vector<ConstraintRow>& rows,
                           const std::vector<SolverBody>& bodies,
                           const std::vector<std::int32_t>& groupStart, int firstIsland,
                           int endIsland) {
  addOverRows(blocks, rows, bodies, groupStart, firstIsland, endIsland, &Group::explained,
              [](const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
                return std::abs(row.impulse) *
                       (std::abs(row.target) + std::abs(drivenBy(row, a, b)));
              });
}

void RunawayGuard::check(const std::vector<Body>& bodies,
                         const std::vector<ConstraintBlock>& blocks,
                         const std::vector<std::int32_t>& groupStart, int islandCount,
                         const SolverSettings& s, StepStats& stats) {
  stats.runaways.clear();
  stats.runawayBodies.clear();
  stats.runawayJoints.clear();
  if (!groupOfBody_) return;
  const std::vector<std::int32_t>& groupOf = *groupOfBody_;
  for (Group& group : groups_) {
    group.after = 0.0;
    group.fastest = 0.0;
    group.nonFinite = false;
    group.culprit = -1;
    group.culpritGain = -kInf;
  }
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const std::int32_t g = groupOf[i];
    if (g < 0) continue;
    const Body& b = bodies[i];
    Group& group = groups_[g];
    if (group.nonFinite) continue;
    if (!finiteState(b)) {
      group.nonFinite = true;
      group.culprit = static_cast<BodyId>(i);
      continue;
    }
    const BodyStart& start = start_[i];
    // The work of gravity and the applied force and torque, constant over
    // the step, along the path the body took (a pendulum swinging down
    // gains what gravity gives it whichever way its joint turned it), or
    // what they give the free body, whichever is larger.
    group.explained +=
        std::max(start.freeGain,
                 start.force.dot(b.position - start.position) +
                     start.torque.dot(0.5 * h_ * (start.angularVelocity + b.angularVelocity)));
    const double e = kineticEnergy(b);
    group.after += e;
    group.fastest = std::max(group.fastest, b.linearVelocity.norm());
    if (e - start.energy > group.culpritGain) {
      group.culpritGain = e - start.energy;
      group.culprit = static_cast<BodyId>(i);
    }
  }
  // Unexplained growth, carried from step to step on each body: one step
  // far beyond what it explains, or a few in a row somewhat beyond it.
  for (Group& group : groups_) {
    // Below this the energy is noise: every body at 1 cm/s.
    const double floor = 0.5 * group.mass * kQuietSpeed * kQuietSpeed;
    // Slow test: the kinetic energy and the energy held in the errors
    // together, against the work done. A step that turns error into motion
    // keeps their sum (a taut chain springing back, whose release the
    // diagonals undercount fivefold, changes it by a few per mille); a
    // divergence that tears the joints while it speeds the bodies up
    // grows both. Only steps whose kinetic energy is itself beyond the work
    // (and its recent peak) add to it: hair strands torn slowly where they
    // lie on the head grow their errors, not their speed (handed to ODE,
    // its Baumgarte push on the torn joints flung them 8.8 km apart).
    group.ledgerBefore = std::max(group.explained, 0.0) + group.errorsBefore;
    group.ledgerAfter = group.after + group.errorsAfter;
    const double ledgerExcess =
        std::log((group.ledgerAfter + floor) / (group.ledgerBefore + floor));
    const bool faster = group.after > std::max(group.explained, 0.0);
    group.slowExcess = faster ? ledgerExcess : std::min(ledgerExcess, 0.0);
    // Fast test: the errors the step started with explain all they hold.
    group.explained += group.errorsBefore;
    group.excess = group.nonFinite
                       ? kInf
                       : std::log((group.after + floor) / (std::max(group.explained, 0.0) + floor));
    group.growth = 0.0;
    group.slowGrowth = 0.0;
  }
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const std::int32_t g = groupOf[i];
    if (g < 0) continue;
    Group& group = groups_[g];
    double& growth = growth_[i];
    growth = std::max(0.0, kCarry * growth + group.excess);
    double& slow = slowGrowth_[i];
    slow = std::max(0.0, kSlowCarry * slow + group.slowExcess);
    group.growth = std::max(group.growth, growth);
    group.slowGrowth = std::max(group.slowGrowth, slow);
    peak_[i] = std::max(group.peak, group.after);
  }
  const double allowed = s.runawayEnergyGain > 0.0 && std::isfinite(s.runawayEnergyGain)
                             ? std::log(s.runawayEnergyGain)
                             : kInf;
  for (int g = 0; g < static_cast<int>(groups_.size()); ++g) {
    const Group& group = groups_[g];
    // Both tests allow the same gain: at half of it (10x) the slow test
    // took ODE's demo_feedback, its bridge snapping under the weights, for
    // a runaway.
    const bool gained = group.growth > allowed || group.slowGrowth > allowed;
    const bool fast = group.fastest > s.runawaySpeed;
    if (!group.nonFinite && !gained && !fast) continue;
    RunawayIsland r;
    r.culprit = group.culprit;
    r.nonFinite = group.nonFinite;
    r.energyBefore = group.before;
    // Worded by the test that caught it.
    r.sustained = !(group.growth > allowed) && group.slowGrowth > allowed;
    r.energyExplained = r.sustained ? group.ledgerBefore : group.explained;
    r.energyAfter = r.sustained ? group.ledgerAfter : group.after;
    r.errorEnergy = group.errorsAfter;
    r.fastest = group.fastest;
    r.growth = std::exp(r.sustained ? group.slowGrowth : group.growth);
    r.firstBody = static_cast<std::int32_t>(stats.runawayBodies.size());
    for (std::size_t i = 0; i < bodies.size(); ++i) {
      if (groupOf[i] != g) continue;
      stats.runawayBodies.push_back(static_cast<BodyId>(i));
      growth_[i] = 0.0;  // put back: it starts afresh
      slowGrowth_[i] = 0.0;
      peak_[i] = group.before;
    }
    r.bodyCount = static_cast<std::int32_t>(stats.runawayBodies.size()) - r.firstBody;
    r.firstJoint = static_cast<std::int32_t>(stats.runawayJoints.size());
    if (g < islandCount) {
      for (std::int32_t bi = groupStart[g]; bi < groupStart[g + 1]; ++bi) {
        if (blocks[bi].joint >= 0) stats.runawayJoints.push_back(blocks[bi].joint);
      }
    }
    r.jointCount = static_cast<std::int32_t>(stats.runawayJoints.size()) - r.firstJoint;
    stats.runaways.push_back(r);
  }
}

}  // namespace blockstep

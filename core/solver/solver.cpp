#include "core/solver/solver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <variant>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/ldlt.h"

namespace blockstep {
namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

double rowVelocity(const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
  return row.linA.dot(a.v) + row.angA.dot(a.w) + row.linB.dot(b.v) + row.angB.dot(b.w);
}

void applyImpulse(const ConstraintRow& row, double dP, SolverBody& a, SolverBody& b) {
  a.v += (a.invMass * dP) * row.linA;
  a.w += dP * row.invIangA;
  b.v += (b.invMass * dP) * row.linB;
  b.w += dP * row.invIangB;
}

// One row solved alone with its accumulated impulse clamped to [lo, hi]
// (section 4.3: clamp the total, never the increment).
void solveRow(ConstraintRow& row, bool useBias, SolverBody& a, SolverBody& b) {
  const double bias = useBias ? row.bias : row.biasRelax;
  const double residual = rowVelocity(row, a, b) + bias + row.gamma * row.impulse;
  const double next = std::clamp(row.impulse - residual * row.effMass, row.lo, row.hi);
  const double dP = next - row.impulse;
  row.impulse = next;
  applyImpulse(row, dP, a, b);
}

// The residual a row reports: |J v + b + gamma P|, or 0 where the
// accumulated impulse sits on the bound the row pushes against.
double rowResidual(const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
  const double r = rowVelocity(row, a, b) + row.bias + row.gamma * row.impulse;
  if (row.impulse <= row.lo && r > 0.0) return 0.0;
  if (row.impulse >= row.hi && r < 0.0) return 0.0;
  return std::abs(r);
}

}  // namespace

std::int32_t Solver::solverIndex(BodyId id) const {
  return id == kWorldBody ? dummy_ : static_cast<std::int32_t>(id);
}

void Solver::step(const StepInput& in, const SolverSettings& s, StepStats& stats) {
  const auto start = Clock::now();
  const int substeps = std::max(1, s.substeps);
  const double h = in.h / substeps;
  const double deadline = s.timeBudget > 0.0 ? s.timeBudget : 0.0;

  stats.substeps = substeps;
  stats.iterations = 0;
  stats.residuals.clear();
  stats.brokenJoints.clear();
  stats.solveSeconds = 0.0;

  buildIslands(in);
  for (Joint& j : in.joints)
    j.stepImpulse.fill(0.0);

  for (int sub = 0; sub < substeps; ++sub) {
    integrateVelocities(in, s, h);
    const auto solveStart = Clock::now();
    prepare(in, s, h);
    warmStart();
    // Each sub-step gets its share of what remains of the time budget.
    const double subDeadline =
        deadline > 0.0 ? (deadline - seconds(start, solveStart)) / (substeps - sub) : 0.0;
    stats.iterations += solve(s, sub, subDeadline, stats);
    integratePositions(in, s, h);
    relax(s);
    storeImpulses(in, h);
    stats.solveSeconds += seconds(solveStart, Clock::now());
  }
  finish(in, stats);
  stats.stepSeconds = seconds(start, Clock::now());
}

void Solver::buildIslands(const StepInput& in) {
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
  activeJoints_.clear();
  for (std::int32_t j = 0; j < static_cast<std::int32_t>(in.joints.size()); ++j) {
    Joint& joint = in.joints[j];
    joint.block = -1;
    if (!joint.alive || !joint.enabled || joint.broken) continue;
    const JointCommon& c = common(joint.desc);
    const bool dynA = dynamicBody(c.bodyA), dynB = dynamicBody(c.bodyB);
    if (!dynA && !dynB) continue;  // nothing to move
    activeJoints_.push_back(j);
    if (dynA && dynB) {
      const std::int32_t ra = find(c.bodyA), rb = find(c.bodyB);
      if (ra != rb) parent_[ra] = rb;
    }
  }
  // Number the islands by root, then order the joints island by island
  // (a counting sort) so each island's blocks are contiguous.
  islandOfRoot_.assign(bodyCount, -1);
  islandCount_ = 0;
  jointIsland_.resize(activeJoints_.size());
  for (std::size_t k = 0; k < activeJoints_.size(); ++k) {
    const JointCommon& c = common(in.joints[activeJoints_[k]].desc);
    const std::int32_t root = find(dynamicBody(c.bodyA) ? c.bodyA : c.bodyB);
    if (islandOfRoot_[root] < 0) islandOfRoot_[root] = islandCount_++;
    jointIsland_[k] = islandOfRoot_[root];
  }
  islandStart_.assign(islandCount_ + 1, 0);
  for (std::int32_t island : jointIsland_)
    ++islandStart_[island + 1];
  for (int i = 0; i < islandCount_; ++i)
    islandStart_[i + 1] += islandStart_[i];
  fill_.assign(islandStart_.begin(), islandStart_.end() - 1);
  jointOfBlock_.resize(activeJoints_.size());
  for (std::size_t k = 0; k < activeJoints_.size(); ++k) {
    jointOfBlock_[fill_[jointIsland_[k]]++] = activeJoints_[k];
  }
  islandActive_.resize(islandCount_);
}

void Solver::integrateVelocities(const StepInput& in, const SolverSettings& s, double h) {
  for (std::size_t i = 0; i < in.bodies.size(); ++i) {
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
      continue;
    }
    const Mat3 R = b.orientation.toRotationMatrix();
    sb.invMass = b.invMass;
    sb.invI = R * b.invInertiaBody * R.transpose();

    Vec3 v = b.linearVelocity;
    Vec3 w = b.angularVelocity;
    gyroOffset_[i].setZero();
    if (s.gyroscopic) {
      // Euler's equation in the body frame, I dw/dt + w x (I w) = 0, by
      // the implicit midpoint rule: I (w' - w) + h m x (I m) = 0 with
      // m = (w + w') / 2, solved by Newton's method (3x3, a few steps).
      // The midpoint rule keeps both |L| and the energy of this equation
      // exactly; the explicit form w -= h I^-1 (w x I w) gains energy and
      // blows up fast spinners, implicit Euler bleeds momentum (17% in
      // 10 s in tests/core/integrate_test.cpp's tumbling box).
      // integratePositions() turns the body with the midpoint rate (the
      // end rate plus gyroOffset_) and carries the body-frame rate along.
      const Vec3 wb = R.transpose() * w;
      Vec3 next = wb;
      for (int k = 0; k < 4; ++k) {
        const Vec3 mid = 0.5 * (wb + next);
        const Vec3 Imid = b.inertiaBody * mid;
        const Vec3 F = b.inertiaBody * (next - wb) + h * mid.cross(Imid);
        const Mat3 dF = b.inertiaBody + 0.5 * h * (skew(mid) * b.inertiaBody - skew(Imid));
        next -= dF.partialPivLu().solve(F);
      }
      w = R * next;
      gyroOffset_[i] = R * (0.5 * (wb - next));
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
  }
}

void Solver::prepare(const StepInput& in, const SolverSettings& s, double h) {
  const auto blockCount = jointOfBlock_.size();
  blocks_.resize(blockCount);
  rowCount_ = 0;
  for (std::size_t bi = 0; bi < blockCount; ++bi) {
    const std::int32_t j = jointOfBlock_[bi];
    Joint& joint = in.joints[j];
    const JointCommon& c = common(joint.desc);
    const Body& A = c.bodyA == kWorldBody ? in.worldBody : in.bodies[c.bodyA];
    const Body& B = c.bodyB == kWorldBody ? in.worldBody : in.bodies[c.bodyB];
    const JointPose pose =
        JointPose::make(A.position, A.orientation, B.position, B.orientation, joint.frames);
    // Room for the most rows a joint can emit; grows only while warming up.
    if (static_cast<int>(rows_.size()) < rowCount_ + kMaxJointSlots) {
      rows_.resize(2 * (rowCount_ + kMaxJointSlots));
      coupling_.resize(rows_.size());
    }
    ConstraintRow* rows = &rows_[rowCount_];
    RowWriter out(rows);
    std::visit([&](const auto& d) { buildJointRows(d, pose, out); }, joint.desc);
    out.finish();

    ConstraintBlock& blk = blocks_[bi];
    blk.bodyA = solverIndex(c.bodyA);
    blk.bodyB = solverIndex(c.bodyB);
    blk.joint = j;
    blk.firstRow = rowCount_;
    blk.bounded = static_cast<std::uint8_t>(out.boundedCount());
    blk.equality = static_cast<std::uint8_t>(out.equalityCount());
    joint.block = static_cast<std::int32_t>(bi);
    const int n = blk.rowCount();
    rowCount_ += n;

    const SolverBody& a = bodies_[blk.bodyA];
    const SolverBody& b = bodies_[blk.bodyB];
    const double warmRatio =
        s.warmStarting && joint.warmStepSize > 0.0 ? h / joint.warmStepSize : 0.0;
    for (int i = 0; i < n; ++i) {
      ConstraintRow& row = rows[i];
      if (row.softness && s.rigidJointSoftness && row.softness->mode == Softness::Mode::ErpCfm) {
        row.softness = &*s.rigidJointSoftness;
      }
      row.invIangA = a.invI * row.angA;
      row.invIangB = b.invI * row.angB;
      const double kDiag = a.invMass * row.linA.squaredNorm() + row.angA.dot(row.invIangA) +
                           b.invMass * row.linB.squaredNorm() + row.angB.dot(row.invIangB);
      switch (row.biasKind) {
        case RowBias::Velocity:  // a motor: lo/hi came as forces
          row.bias = row.biasRelax = -row.target;
          row.gamma = 0.0;
          row.lo *= h;
          row.hi *= h;
          break;
        case RowBias::Speculative: {
          const double approach = rowVelocity(row, a, b);  // < 0: closing on the stop
          if (row.bounce > 0.0 && approach < 0.0 && row.C + approach * h <= 0.0) {
            // Restitution: leave the stop at bounce times the approach
            // speed; kept through relax so the rebound survives it.
            row.bias = row.biasRelax = row.bounce * approach;
            row.gamma = 0.0;
            break;
          }
          if (row.C > 0.0) {
            row.bias = row.biasRelax = row.C / h;
            row.gamma = 0.0;
            break;
          }
          row.bias = row.softness->biasRate(h) * row.C;
          row.biasRelax = 0.0;
          row.gamma = row.softness->gamma(h, kDiag);
          break;
        }
        case RowBias::Baumgarte:
          row.bias = row.softness->biasRate(h) * row.C;
          row.biasRelax = 0.0;
          row.gamma = row.softness->gamma(h, kDiag);
          break;
      }
      const double k = kDiag + row.gamma;
      row.effMass = k > 0.0 ? 1.0 / k : 0.0;
      const double warm = (joint.warmSlots >> row.slot) & 1u ? joint.warmImpulse[row.slot] : 0.0;
      row.impulse = std::clamp(warmRatio * warm, row.lo, row.hi);
      row.softness = nullptr;
    }

    // K = J M^-1 J^T + gamma for the equality rows, factored once here and
    // reused by every sweep of this (sub-)step.
    const int ne = blk.equality;
    const ConstraintRow* eq = rows;
    for (int r = 0; r < ne; ++r) {
      for (int col = 0; col <= r; ++col) {
        blk.ldl(r, col) =
            a.invMass * eq[r].linA.dot(eq[col].linA) + eq[r].angA.dot(eq[col].invIangA) +
            b.invMass * eq[r].linB.dot(eq[col].linB) + eq[r].angB.dot(eq[col].invIangB);
      }
      blk.ldl(r, r) += eq[r].gamma;
    }
    ldltFactor(blk.ldl, ne);
    if (s.blockMode == BlockMode::Block) coupleBoundedRows(blk);
  }
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
    const ConstraintRow& row = rows_[r];
    BoundedCoupling& c = coupling_[r];
    double w[6];
    for (int i = 0; i < ne; ++i) {
      w[i] = -(a.invMass * eq[i].linA.dot(row.linA) + eq[i].angA.dot(row.invIangA) +
               b.invMass * eq[i].linB.dot(row.linB) + eq[i].angB.dot(row.invIangB));
    }
    ldltSolve(blk.ldl, ne, w);
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
    const double k = row.linA.dot(c.dvA) + row.angA.dot(c.dwA) + row.linB.dot(c.dvB) +
                     row.angB.dot(c.dwB) + row.gamma;
    // A bounded row that the equality rows already fix has no freedom left.
    c.effMass = k > 1e-12 / std::max(row.effMass, 1e-300) ? 1.0 / k : 0.0;
  }
}

void Solver::solveCoupledRow(int rowIndex, bool useBias, ConstraintRow* eq, int ne, SolverBody& a,
                             SolverBody& b) {
  ConstraintRow& row = rows_[rowIndex];
  const BoundedCoupling& c = coupling_[rowIndex];
  const double bias = useBias ? row.bias : row.biasRelax;
  const double residual = rowVelocity(row, a, b) + bias + row.gamma * row.impulse;
  const double next = std::clamp(row.impulse - residual * c.effMass, row.lo, row.hi);
  const double dP = next - row.impulse;
  row.impulse = next;
  a.v += dP * c.dvA;
  a.w += dP * c.dwA;
  b.v += dP * c.dvB;
  b.w += dP * c.dwB;
  for (int i = 0; i < ne; ++i)
    eq[i].impulse += c.w[i] * dP;
}

void Solver::warmStart() {
  for (const ConstraintBlock& blk : blocks_) {
    SolverBody& a = bodies_[blk.bodyA];
    SolverBody& b = bodies_[blk.bodyB];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    for (int i = 0; i < blk.rowCount(); ++i) {
      if (rows[i].impulse != 0.0) applyImpulse(rows[i], rows[i].impulse, a, b);
    }
  }
}

void Solver::sweep(int island, bool useBias, BlockMode mode) {
  for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi) {
    ConstraintBlock& blk = blocks_[bi];
    SolverBody& a = bodies_[blk.bodyA];
    SolverBody& b = bodies_[blk.bodyB];
    ConstraintRow* rows = &rows_[blk.firstRow];
    ConstraintRow* eq = rows;
    const int ne = blk.equality;
    if (mode == BlockMode::RowByRow) {
      for (int i = 0; i < blk.rowCount(); ++i)
        solveRow(rows[i], useBias, a, b);
      continue;
    }
    // Limits and motors first, the rigid block last (row.h says why).
    for (int i = blk.boundedBegin(); i < blk.boundedEnd(); ++i) {
      solveCoupledRow(i, useBias, eq, ne, a, b);
    }

    // Section 4.3: (J M^-1 J^T + c/h) dP = -(J v + b + gamma P) for the
    // whole block at once, with the factor from prepare().
    double dP[6];
    for (int i = 0; i < ne; ++i) {
      const double bias = useBias ? eq[i].bias : eq[i].biasRelax;
      dP[i] = -(rowVelocity(eq[i], a, b) + bias + eq[i].gamma * eq[i].impulse);
    }
    ldltSolve(blk.ldl, ne, dP);
    Vec3 dvA = Vec3::Zero(), dwA = Vec3::Zero(), dvB = Vec3::Zero(), dwB = Vec3::Zero();
    for (int i = 0; i < ne; ++i) {
      eq[i].impulse += dP[i];
      dvA += dP[i] * eq[i].linA;
      dwA += dP[i] * eq[i].invIangA;
      dvB += dP[i] * eq[i].linB;
      dwB += dP[i] * eq[i].invIangB;
    }
    a.v += a.invMass * dvA;
    a.w += dwA;
    b.v += b.invMass * dvB;
    b.w += dwB;
  }
}

void Solver::islandResidual(int island, double& max, double& sumSq, int& count) const {
  for (std::int32_t bi = islandStart_[island]; bi < islandStart_[island + 1]; ++bi) {
    const ConstraintBlock& blk = blocks_[bi];
    const SolverBody& a = bodies_[blk.bodyA];
    const SolverBody& b = bodies_[blk.bodyB];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    for (int i = 0; i < blk.rowCount(); ++i) {
      if (rows[i].effMass == 0.0) continue;  // acts on nothing that moves
      const double r = rowResidual(rows[i], a, b);
      max = std::max(max, r);
      sumSq += r * r;
      ++count;
    }
  }
}

int Solver::solve(const SolverSettings& s, int substep, double budget, StepStats& stats) {
  const auto start = Clock::now();
  const bool measure = s.recordResiduals || s.tolerance > 0.0;
  std::fill(islandActive_.begin(), islandActive_.end(), 1);
  int sweeps = 0;
  for (int it = 0; it < s.iterations; ++it) {
    bool anyActive = false;
    double max = 0.0, sumSq = 0.0;
    int count = 0;
    for (int island = 0; island < islandCount_; ++island) {
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
    if (budget > 0.0 && seconds(start, Clock::now()) >= budget) break;
  }
  return sweeps;
}

void Solver::integratePositions(const StepInput& in, const SolverSettings& s, double h) {
  const bool explicitEuler = s.integrator == Integrator::ExplicitEuler;
  for (std::size_t i = 0; i < in.bodies.size(); ++i) {
    Body& b = in.bodies[i];
    if (!b.alive || b.type == BodyType::Static) continue;
    if (b.isDynamic()) {
      b.linearVelocity = bodies_[i].v;
      b.angularVelocity = bodies_[i].w;
    }
    // Semi-implicit Euler moves with the new velocity (section 3);
    // explicit Euler with the velocity the step started from.
    const Vec3& v = explicitEuler ? startV_[i] : b.linearVelocity;
    const Vec3& w = explicitEuler ? startW_[i] : b.angularVelocity;
    b.position += h * v;
    if (s.gyroscopic && b.isDynamic()) {
      const Quat before = b.orientation;
      b.orientation = integrateRotation(b.orientation, w + gyroOffset_[i], h);
      const Vec3 turned = b.orientation * (before.conjugate() * b.angularVelocity);
      b.angularVelocity = turned;
      bodies_[i].w = turned;
      continue;
    }
    b.orientation = integrateRotation(b.orientation, w, h);
  }
}

void Solver::relax(const SolverSettings& s) {
  if (s.relaxIterations <= 0) return;
  for (int it = 0; it < s.relaxIterations; ++it) {
    for (int island = 0; island < islandCount_; ++island)
      sweep(island, false, s.blockMode);
  }
}

void Solver::storeImpulses(const StepInput& in, double h) {
  // The relax sweeps changed velocities after the position update; the
  // bodies carry them into the next sub-step.
  for (std::size_t i = 0; i < in.bodies.size(); ++i) {
    Body& b = in.bodies[i];
    if (b.alive && b.isDynamic()) {
      b.linearVelocity = bodies_[i].v;
      b.angularVelocity = bodies_[i].w;
    }
  }
  for (const ConstraintBlock& blk : blocks_) {
    Joint& joint = in.joints[blk.joint];
    const ConstraintRow* rows = &rows_[blk.firstRow];
    joint.warmSlots = 0;
    for (int i = 0; i < blk.rowCount(); ++i) {
      joint.warmImpulse[rows[i].slot] = rows[i].impulse;
      joint.warmSlots |= 1u << rows[i].slot;
      joint.stepImpulse[rows[i].slot] += rows[i].impulse;
    }
    joint.warmStepSize = h;
  }
}

void Solver::finish(const StepInput& in, StepStats& stats) {
  const double h = in.h;
  for (const ConstraintBlock& blk : blocks_) {
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
  for (Body& b : in.bodies) {
    b.force.setZero();
    b.torque.setZero();
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

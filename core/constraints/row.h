// One constraint row and one block of rows: the data the block
// Sequential-Impulses iteration (section 4.3) works on.
#pragma once

#include <cstdint>
#include <limits>

#include "core/constraints/softness.h"
#include "core/math/math.h"

namespace blockstep {

// How a row's bias is formed in prepare().
enum class RowBias : std::uint8_t {
  Baumgarte,    // b = beta/h C (soft); equality rows and limits past their stop
  Speculative,  // a one-sided row not yet touching: C > 0 may close within the step,
                // b = C / h, never pulls (kept in the relax pass)
  Velocity,     // a motor: b = -target velocity
};

// A row of J (12 columns: linear and angular for body A, then body B),
// with what the iteration needs cached beside it.
struct ConstraintRow {
  Vec3 linA = Vec3::Zero(), angA = Vec3::Zero();
  Vec3 linB = Vec3::Zero(), angB = Vec3::Zero();
  Vec3 invIangA = Vec3::Zero(), invIangB = Vec3::Zero();  // M^-1 J^T, angular parts
  double C = 0.0;           // position error (m or rad), written by the joint's parts
  double target = 0.0;      // motor target velocity
  double bias = 0.0;        // b in  J v + b + gamma P = 0
  double biasRelax = 0.0;   // b kept in the bias-free relax pass (speculative rows, motors)
  double gamma = 0.0;       // CFM / h (Velocity rows are built with the CFM; prepare divides)
  double gammaRelax = 0.0;  // gamma in the relax pass (all but contact normals)
  // c of a spring relative to the row's effective mass (Softness Spring,
  // StepSpring: gamma = c / m), 0 for absolute softness. A bounded row
  // solved in its joint's null space sees the Schur complement as 1 / m,
  // and its gamma is set from that (Solver::coupleBoundedRows).
  double gammaShare = 0.0;
  double effMass = 0.0;  // 1 / (K_ii + gamma): used when the row is solved alone
  double lo = -kInf;     // bounds on the accumulated impulse, N s
  double hi = kInf;
  double impulse = 0.0;  // accumulated impulse of the current (sub)step
  // One-sided rows (limits, contact normals):
  double bounce = 0.0;           // restitution
  double bounceThreshold = 0.0;  // approach speed below which there is no bounce
  double slop = 0.0;             // error allowed before Baumgarte pushes back
  double maxBias = kInf;         // cap on the Baumgarte push-back speed
  // Friction rows: bounds of +-mu times the accumulated impulse of row
  // frictionOf of the same block (kAllNormals: the sum of its normal rows).
  double mu = 0.0;
  const Softness* softness = nullptr;  // prepare-time only
  std::int8_t frictionOf = kNoFriction;
  bool conePair = false;  // this row and the next share one friction disk
  RowBias biasKind = RowBias::Baumgarte;
  bool angular = false;  // torque-like row (for feedback and breaking)
  bool spring = false;   // a physical spring (Softness::Stiffness): relax leaves it alone
  bool bounced = false;  // restitution set its target: its impulse answered an impact
  // A rigid row of an island block (Solver::prepare): position projection
  // closes its error at the new pose (SolverSettings::positionProjections).
  bool projected = false;
  std::uint8_t slot = 0;  // the joint's stable name for this row: warm starting follows it

  static constexpr std::int8_t kNoFriction = -1;
  static constexpr std::int8_t kAllNormals = -2;
};

// One joint's rows. Rows [first, first + equality) are the joint's
// equality rows, solved together as one block with K = J M^-1 J^T + gamma
// factored once by LDL^T; the following `bounded` rows are one-sided or
// force-limited rows (motors, limits) solved one at a time with the
// accumulated impulse clamped, after the block in every sweep.
//
// Why bounded rows are not inside the LDL^T block: clamping one component
// of a block solution and keeping the others changes what the others
// should have been, and re-solving with that row fixed is a small
// active-set method whose active set can flip between iterations, which is
// the jitter section 4.3 reports. Instead each bounded row is solved alone
// with its accumulated impulse clamped, but in the null space of the
// equality block (the Schur complement, Solver::coupleBoundedRows): its
// impulse carries the equality impulses that keep the rigid rows as they
// were, so a limit or motor acting at a lever arm is exact in one sweep.
// So the bounded rows come after the rigid block, not before it as Jolt
// and Box2D order motor, limit, point: solved last in the null space they
// leave the block's rows as the block left them, and one sweep ends with
// both holding. Solved first, the block's own impulses (closing its
// drift, taking up gravity) then moved the bounded rows off: a hinge stop
// hit with bounce 0 kept 0.9 rad/s into its stop after the sweep, which
// relax and the push-out turned into a rebound (the bob came back 0.13
// rad off its equation of motion, ODE's dWorldStep 0.10; now 0.011).
// Every sub-solve is exact and every clamp is on the accumulated impulse:
// a block Gauss-Seidel on a convex problem, which converges without
// flipping.
struct ConstraintBlock {
  std::int32_t bodyA = 0;  // solver body indices (the static dummy for the world)
  std::int32_t bodyB = 0;
  std::int32_t firstRow = 0;
  std::uint8_t bounded = 0;
  std::uint8_t equality = 0;
  std::int32_t joint = -1;    // the joint it came from, or -1
  std::int32_t contact = -1;  // the contact manifold it came from, or -1
  // Contact normals: the block's rows are one-sided (impulses >= 0).
  bool unilateral = false;
  // Some equality row depends on the others (a zero pivot in ldl): the
  // block's solution leaves that row's residual to them.
  bool redundant = false;
  // Where the equality block's matrix starts in the solver's pool
  // (equality x equality doubles, ldlt.h): LDL^T, unit lower L below the
  // diagonal, 1/D on the diagonal (0 where the pivot vanished: a
  // redundant row); or, once `inverted`, the matrix of its solve
  // (ldltInvert).
  std::int32_t matrix = 0;
  bool factored = false;  // the matrix holds this (sub-)step's factor of the block's own
  bool inverted = false;
  // c where the equality rows' spring is relative to the block's own
  // effective mass, Gamma = c K (Solver::blockSpringShare says why), the
  // rows' gamma then 0 and ldl the factor of (1 + c) K; 0 otherwise.
  double springShare = 0.0;

  int rowCount() const { return bounded + equality; }
  // Equality rows come first, then the bounded rows.
  int boundedBegin() const { return firstRow + equality; }
  int boundedEnd() const { return firstRow + equality + bounded; }
};

}  // namespace blockstep

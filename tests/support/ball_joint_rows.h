// Solver rows of ball joints written by hand, for tests and benchmarks of
// the island blocks that need a chain or a star without a World.
#pragma once

#include <cstdint>
#include <vector>

#include "core/constraints/row.h"
#include "core/solver/solver_body.h"

namespace blockstep::test {

// A ball joint's three point rows (world axes x, y, z) between solver
// bodies a and b at world arms armA and armB, as prepare() leaves them
// (M^-1 J^T included); the static body's side stays zero. Each row has
// softness gamma and a bias of 0.01, 0.02 and 0.03 m/s.
inline void addBallJointRows(const std::vector<SolverBody>& bodies, std::int32_t staticBody,
                             std::int32_t joint, std::int32_t a, std::int32_t b, const Vec3& armA,
                             const Vec3& armB, double gamma, std::vector<ConstraintBlock>& blocks,
                             std::vector<ConstraintRow>& rows) {
  ConstraintBlock blk;
  blk.bodyA = a;
  blk.bodyB = b;
  blk.firstRow = static_cast<std::int32_t>(rows.size());
  blk.equality = 3;
  blk.joint = joint;
  blocks.push_back(blk);
  for (int axis = 0; axis < 3; ++axis) {
    ConstraintRow r;
    const Vec3 u = Vec3::Unit(axis);
    if (a != staticBody) {
      r.linA = -u;
      r.angA = -armA.cross(u);
      r.invIangA = bodies[a].invI * r.angA;
    }
    if (b != staticBody) {
      r.linB = u;
      r.angB = armB.cross(u);
      r.invIangB = bodies[b].invI * r.angB;
    }
    r.gamma = gamma;
    r.bias = 0.01 * (axis + 1);
    rows.push_back(r);
  }
}

}  // namespace blockstep::test

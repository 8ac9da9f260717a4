// Fixed: point part + three rotation rows, one 6x6 block. Section 4.3:
// solved as one block this converges in one iteration where six 1x1 rows
// stay soft (tests/core/fixed_block_test.cpp measures it).
#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/point.h"
#include "core/constraints/parts/rotation.h"

namespace blockstep {

void validateJoint(const FixedJointDesc& d) {
  validateCommon(d.common, "fixed");
}

JointFrames setupJoint(FixedJointDesc&, const Body& a, const Body& b) {
  // Anchor midway between the centres, so the rows are equally
  // conditioned for both bodies; at the moving body's centre when the
  // other side is static (the world).
  const Vec3 anchor = a.type == BodyType::Static   ? b.position
                      : b.type == BodyType::Static ? a.position
                                                   : 0.5 * (a.position + b.position);
  return framesAt(a, b, anchor, Quat::Identity());
}

void buildJointRows(const FixedJointDesc& d, const JointPose& p, RowWriter& out) {
  addPointRows(p, d.common.softness, 0, out);
  addRotationRows(RelativeRotation(p), 0b111, d.common.softness, 3, out);
}

}  // namespace blockstep

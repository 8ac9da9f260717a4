// Ball and socket: the point part alone (3 rows, one 3x3 block).
#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/point.h"

namespace blockstep {

void validateJoint(const BallJointDesc& d) {
  validateCommon(d.common, "ball");
  requireFinite(d.anchor, "ball joint anchor");
}

JointFrames setupJoint(BallJointDesc& d, const Body& a, const Body& b) {
  return framesAt(a, b, d.anchor, Quat::Identity());
}

void buildJointRows(const BallJointDesc& d, const JointPose& p, RowWriter& out) {
  addPointRows(p, d.common.softness, 0, out);
}

// The point rows hold the anchor, which a turn about the line through it
// and the centre of mass leaves where it is.
FreeTurn freeTurn(const BallJointDesc&, const JointFrames& f, bool bodyB) {
  return turnAboutAnchor(bodyB ? f.localAnchorB : f.localAnchorA);
}

}  // namespace blockstep

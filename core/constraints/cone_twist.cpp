// Cone-twist (a ragdoll shoulder): point part (3x3 block) + a cone that
// bounds how far the twist axis swings + a twist limit about it.
//
// The relative rotation is split into swing and twist (rotation.h,
// SwingTwist); the swing axis lies in A's frame y-z plane.
#include <algorithm>
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/point.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const ConeTwistJointDesc& d) {
  validateCommon(d.common, "cone-twist");
  requireFinite(d.anchor, "cone-twist joint anchor");
  requireAxis(d.twistAxis, "cone-twist joint twist axis");
  if (!(d.swingLimit >= 0.0) || std::isnan(d.swingLimit)) {
    throw Error("cone-twist joint swing limit must be >= 0 (got " + std::to_string(d.swingLimit) +
                ")");
  }
  validateLimit(d.twistLimit, "cone-twist joint twist");
}

JointFrames setupJoint(ConeTwistJointDesc& d, const Body& a, const Body& b) {
  d.twistAxis = d.twistAxis.normalized();
  return framesAt(a, b, d.anchor, frameFromAxis(d.twistAxis));
}

void buildJointRows(const ConeTwistJointDesc& d, const JointPose& p, RowWriter& out) {
  addPointRows(p, d.common.softness, 0, out);
  const SwingTwist st(RelativeRotation(p).r);
  if (d.swingLimit < kPi && st.swingAngle > 1e-9) {
    // One-sided: swingAngle <= swingLimit. The swing grows at (wB - wA).axis.
    const Vec3 swingAxis = p.frameA * st.swingAxis;
    ConstraintRow& cone = out.bounded(3);
    angularAxisRow(-swingAxis, d.swingLimit - st.swingAngle, cone);
    cone.biasKind = RowBias::Speculative;
    cone.softness = &d.twistLimit.softness;
    cone.lo = 0.0;
    cone.hi = kInf;
  }
  ConstraintRow rate;
  angularAxisRow(p.axisB(0), 0.0, rate);
  addCoordinateRows(rate, st.twistAngle, d.twistLimit, Motor{}, 6, out);
}

}  // namespace blockstep

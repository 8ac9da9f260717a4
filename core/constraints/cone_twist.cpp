// Cone-twist (a ragdoll shoulder): point part (3x3 block) + a cone that
// bounds how far the twist axis swings + a twist limit about it.
//
// The relative rotation r = FA* FB is split as r = swing * twist, twist
// about the frame's x axis (the twist axis): twist = (w, x, 0, 0) / norm,
// swing = r twist*. The swing angle is 2 acos(swing.w) about the swing
// axis swing.vec / |swing.vec|, which lies in A's frame y-z plane.
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
  const RelativeRotation rel(p);
  const Quat& r = rel.r;

  const double twistNorm = std::hypot(r.w(), r.x());
  const Quat twist =
      twistNorm > 1e-9 ? Quat(r.w() / twistNorm, r.x() / twistNorm, 0.0, 0.0) : Quat::Identity();
  const Quat swing = r * twist.conjugate();
  const double swingSin = swing.vec().norm();
  if (d.swingLimit < kPi && swingSin > 1e-9) {
    const double swingAngle = 2.0 * std::atan2(swingSin, std::abs(swing.w()));
    const Vec3 swingAxis = p.frameA * (swing.vec() / swingSin * (swing.w() < 0.0 ? -1.0 : 1.0));
    // One-sided: swingAngle <= swingLimit. The swing grows at (wB - wA).axis.
    ConstraintRow& cone = out.bounded(3);
    angularAxisRow(-swingAxis, d.swingLimit - swingAngle, cone);
    cone.biasKind = RowBias::Speculative;
    cone.softness = &d.twistLimit.softness;
    cone.lo = 0.0;
    cone.hi = kInf;
  }
  ConstraintRow rate;
  angularAxisRow(p.axisB(0), 0.0, rate);
  const double twistAngle = 2.0 * std::atan2(twist.x(), twist.w());
  addCoordinateRows(rate, twistAngle, d.twistLimit, Motor{}, 6, out);
}

}  // namespace blockstep

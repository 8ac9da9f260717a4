// Universal (Cardan): point part + one row keeping axis1 (fixed in A)
// perpendicular to axis2 (fixed in B), one 4x4 block. The two angles are
// read from the relative rotation r = FA* FB written as
// r = Rx(t1) Ry(t2): w = c1 c2, x = s1 c2, y = c1 s2 (half angles), so
// t1 = 2 atan2(x, w), t2 = 2 atan2(y, w). Limits and motors on both.
// With a suspension (ODE's hinge2) the anchors may part along axis2.
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/point.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const UniversalJointDesc& d) {
  validateCommon(d.common, "universal");
  requireFinite(d.anchor, "universal joint anchor");
  const Vec3 a1 = requireAxis(d.axis1, "universal joint axis1");
  const Vec3 a2 = requireAxis(d.axis2, "universal joint axis2");
  if (a1.cross(a2).norm() < 1e-6) throw Error("universal joint axes are parallel");
  validateLimit(d.limit1, "universal joint axis1");
  validateLimit(d.limit2, "universal joint axis2");
  validateMotor(d.motor1, "universal joint axis1");
  validateMotor(d.motor2, "universal joint axis2");
  if (d.suspension && !d.suspensionSoftness.valid()) {
    throw Error("universal joint suspension softness is invalid");
  }
}

JointFrames setupJoint(UniversalJointDesc& d, const Body& a, const Body& b) {
  const Mat3 R = frameFromAxes(d.axis1, d.axis2);
  d.axis1 = R.col(0);
  d.axis2 = R.col(1);
  return framesAt(a, b, d.anchor, Quat(R));
}

void buildJointRows(const UniversalJointDesc& d, const JointPose& p, RowWriter& out) {
  if (d.suspension) {
    // The point part along B's frame axes, the one along axis2 sprung.
    for (int i = 0; i < 3; ++i) {
      ConstraintRow& row = out.equality(i);
      attachedToBAxisRow(p, p.axisB(i), row);
      row.softness = i == 1 ? &d.suspensionSoftness : &d.common.softness;
    }
  } else {
    addPointRows(p, d.common.softness, 0, out);
  }
  ConstraintRow& perp = out.equality(3);
  perpendicularRow(p.axisA(0), p.axisB(1), perp);
  perp.softness = &d.common.softness;

  const RelativeRotation rel(p);
  ConstraintRow rate;
  angularAxisRow(p.axisA(0), 0.0, rate);
  addCoordinateRows(rate, rel.angle(0), d.limit1, d.motor1, 6, out);
  angularAxisRow(p.axisB(1), 0.0, rate);
  addCoordinateRows(rate, rel.angle(1), d.limit2, d.motor2, 9, out);
}

// Body A turning about axis1 (A's frame x) or B about axis2 (B's frame
// y) keeps the two axes perpendicular; through the anchor the point (or
// ODE's hinge2 suspension) rows stay too.
FreeTurn freeTurn(const UniversalJointDesc&, const JointFrames& f, bool bodyB) {
  return bodyB ? turnAboutAxle(f.localFrameB * Vec3::UnitY(), f.localAnchorB)
               : turnAboutAxle(f.localFrameA * Vec3::UnitX(), f.localAnchorA);
}

}  // namespace blockstep

// Hinge: point part + the two rotation rows perpendicular to the axis
// (section 4.4 quaternion part, frame x = hinge axis) in one 5x5 block,
// with an angle limit and a motor about the axis as bounded rows.
#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/point.h"
#include "core/constraints/parts/rotation.h"

namespace blockstep {

void validateJoint(const HingeJointDesc& d) {
  validateCommon(d.common, "hinge");
  requireFinite(d.anchor, "hinge joint anchor");
  requireAxis(d.axis, "hinge joint axis");
  validateLimit(d.limit, "hinge joint angle");
  validateMotor(d.motor, "hinge joint");
}

JointFrames setupJoint(HingeJointDesc& d, const Body& a, const Body& b) {
  d.axis = d.axis.normalized();
  return framesAt(a, b, d.anchor, frameFromAxis(d.axis));
}

void buildJointRows(const HingeJointDesc& d, const JointPose& p, RowWriter& out) {
  addPointRows(p, d.common.softness, 0, out);
  const RelativeRotation rel(p);
  addRotationRows(rel, 0b110, d.common.softness, 3, out);
  ConstraintRow rate;
  angularAxisRow(p.axisA(0), 0.0, rate);
  addCoordinateRows(rate, rel.angle(0), d.limit, d.motor, 6, out);
}

// A turn about the hinge's axis (frame x) leaves the rotation rows as
// they were and moves the angle row linearly; through the anchor it
// leaves the point rows too (a wheel, a flywheel).
FreeTurn freeTurn(const HingeJointDesc&, const JointFrames& f, bool bodyB) {
  return bodyB ? turnAboutAxle(f.localFrameB * Vec3::UnitX(), f.localAnchorB)
               : turnAboutAxle(f.localFrameA * Vec3::UnitX(), f.localAnchorA);
}

}  // namespace blockstep

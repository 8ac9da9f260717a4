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

}  // namespace blockstep

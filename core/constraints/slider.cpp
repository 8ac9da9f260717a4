// Slider (prismatic): all three rotation rows (section 4.4 part) and two
// linear rows across the axis, one 5x5 block; limit and motor along the
// axis. The axis is fixed in body A.
#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/rotation.h"

namespace blockstep {

void validateJoint(const SliderJointDesc& d) {
  validateCommon(d.common, "slider");
  requireAxis(d.axis, "slider joint axis");
  validateLimit(d.limit, "slider joint position");
  validateMotor(d.motor, "slider joint");
}

JointFrames setupJoint(SliderJointDesc& d, const Body& a, const Body& b) {
  d.axis = d.axis.normalized();
  // Anchored at B's centre, so the position along the axis starts at 0.
  return framesAt(a, b, b.position, frameFromAxis(d.axis));
}

void buildJointRows(const SliderJointDesc& d, const JointPose& p, RowWriter& out) {
  const RelativeRotation rel(p);
  addRotationRows(rel, 0b111, d.common.softness, 0, out);
  for (int i = 1; i < 3; ++i) {
    ConstraintRow& row = out.equality(2 + i);
    attachedAxisRow(p, p.axisA(i), row);
    row.softness = &d.common.softness;
  }
  ConstraintRow rate;
  attachedAxisRow(p, p.axisA(0), rate);
  addCoordinateRows(rate, rate.C, d.limit, d.motor, 6, out);
}

}  // namespace blockstep

// Double hinge: the distance part of distance.cpp as an equality row, the
// section 4.4 quaternion rows locking rotation about the two axes across
// the hinge axis (frame x = axis), and one row keeping the anchors in the
// same plane across the axis (their separation along the axis fixed in A).
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const DoubleHingeJointDesc& d) {
  validateCommon(d.common, "double hinge");
  requireFinite(d.anchorA, "double hinge joint anchorA");
  requireFinite(d.anchorB, "double hinge joint anchorB");
  requireAxis(d.axis, "double hinge joint axis");
  if (!std::isfinite(d.length)) throw Error("double hinge joint length must be finite");
}

JointFrames setupJoint(DoubleHingeJointDesc& d, const Body& a, const Body& b) {
  d.axis = d.axis.normalized();
  if (d.length < 0.0) d.length = (d.anchorB - d.anchorA).norm();
  JointFrames f;
  f.localAnchorA = a.localPoint(d.anchorA);
  f.localAnchorB = b.localPoint(d.anchorB);
  const Quat frame = frameFromAxis(d.axis);
  f.localFrameA = a.orientation.conjugate() * frame;
  f.localFrameB = b.orientation.conjugate() * frame;
  return f;
}

void buildJointRows(const DoubleHingeJointDesc& d, const JointPose& p, RowWriter& out) {
  const double length = p.d.norm();
  const Vec3 n = length > 1e-9 ? Vec3(p.d / length) : p.axisA(1);
  ConstraintRow& rod = out.equality(0);
  directionRow(p, n, rod);
  rod.C = length - d.length;
  rod.softness = &d.common.softness;
  ConstraintRow& plane = out.equality(1);
  attachedAxisRow(p, p.axisA(0), plane);
  plane.softness = &d.common.softness;
  const RelativeRotation rel(p);
  addRotationRows(rel, 0b110, d.common.softness, 3, out);
}

}  // namespace blockstep

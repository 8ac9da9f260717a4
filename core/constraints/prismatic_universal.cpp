// Prismatic-universal (ODE's PU): the universal part of universal.cpp
// (the joint frame has x = axis1 fixed in A, y = axis2 fixed in B; one row
// keeps them perpendicular; the angles from r = Rx(t1) Ry(t2)) and a
// slide: B's anchor stays on the line through A's anchor along axisP,
// which is fixed in B, so the two locked rows run along directions fixed
// in B perpendicular to axisP, and the slide's rate along axisP.
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const PrismaticUniversalJointDesc& d) {
  validateCommon(d.common, "prismatic-universal");
  requireFinite(d.anchor, "prismatic-universal joint anchor");
  requireAxis(d.axisP, "prismatic-universal joint prismatic axis");
  const Vec3 a1 = requireAxis(d.axis1, "prismatic-universal joint axis1");
  const Vec3 a2 = requireAxis(d.axis2, "prismatic-universal joint axis2");
  if (a1.cross(a2).norm() < 1e-6) throw Error("prismatic-universal joint axes are parallel");
  validateLimit(d.limitP, "prismatic-universal joint slide");
  validateLimit(d.limit1, "prismatic-universal joint axis1");
  validateLimit(d.limit2, "prismatic-universal joint axis2");
  validateMotor(d.motorP, "prismatic-universal joint slide");
  validateMotor(d.motor1, "prismatic-universal joint axis1");
  validateMotor(d.motor2, "prismatic-universal joint axis2");
}

void keepCreationGeometry(PrismaticUniversalJointDesc& next,
                          const PrismaticUniversalJointDesc& made) {
  next.axisPInFrameB = made.axisPInFrameB;
}

JointFrames setupJoint(PrismaticUniversalJointDesc& d, const Body& a, const Body& b) {
  const Mat3 R = frameFromAxes(d.axis1, d.axis2);
  d.axisPInFrameB = R.transpose() * d.axisP.normalized();
  return framesAt(a, b, d.anchor, Quat(R));
}

void buildJointRows(const PrismaticUniversalJointDesc& d, const JointPose& p, RowWriter& out) {
  // The perpendiculars are taken in B's frame and turned with it, so they
  // move continuously (their slots carry warm-start impulses).
  Vec3 uB, vB;
  perpendicularBasis(d.axisPInFrameB, uB, vB);
  const Vec3 slide = p.frameB * d.axisPInFrameB;
  int slot = 0;
  for (const Vec3& n : {Vec3(p.frameB * uB), Vec3(p.frameB * vB)}) {
    ConstraintRow& row = out.equality(slot++);
    attachedToBAxisRow(p, n, row);
    row.softness = &d.common.softness;
  }
  ConstraintRow& perp = out.equality(2);
  perpendicularRow(p.axisA(0), p.axisB(1), perp);
  perp.softness = &d.common.softness;

  ConstraintRow rate;
  attachedToBAxisRow(p, slide, rate);
  addCoordinateRows(rate, rate.C, d.limitP, d.motorP, 6, out);
  const RelativeRotation rel(p);
  angularAxisRow(p.axisA(0), 0.0, rate);
  addCoordinateRows(rate, rel.angle(0), d.limit1, d.motor1, 9, out);
  angularAxisRow(p.axisB(1), 0.0, rate);
  addCoordinateRows(rate, rel.angle(1), d.limit2, d.motor2, 12, out);
}

}  // namespace blockstep

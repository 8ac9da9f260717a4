// Prismatic-rotoide (ODE's PR): the joint frame has x = axisR and
// y = axisP. Rotation: the section 4.4 quaternion rows lock the relative
// rotation about y and z (axisR stays aligned), the angle about x is free.
// Translation: B's anchor stays on the line through A's anchor along
// axisP; the line is fixed in B (the prismatic stage belongs to B), so the
// two locked rows use B's frame axes x and z; y is the slide, whose stops
// and motor act along ODE's own row for them (parts/axis.h). A turning
// about axisR through its anchor does not move that anchor, so the locked
// rows stay independent of the angle.
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const PrismaticRotoideJointDesc& d) {
  validateCommon(d.common, "prismatic-rotoide");
  requireFinite(d.anchor, "prismatic-rotoide joint anchor");
  const Vec3 p = requireAxis(d.axisP, "prismatic-rotoide joint prismatic axis");
  const Vec3 r = requireAxis(d.axisR, "prismatic-rotoide joint rotoide axis");
  if (std::abs(p.dot(r)) > 1e-3) {
    throw Error("prismatic-rotoide joint axes must be perpendicular");
  }
  validateLimit(d.limitP, "prismatic-rotoide joint slide");
  validateLimit(d.limitR, "prismatic-rotoide joint angle");
  validateMotor(d.motorP, "prismatic-rotoide joint slide");
  validateMotor(d.motorR, "prismatic-rotoide joint angle");
}

JointFrames setupJoint(PrismaticRotoideJointDesc& d, const Body& a, const Body& b) {
  const Mat3 R = frameFromAxes(d.axisR, d.axisP);
  d.axisR = R.col(0);
  d.axisP = R.col(1);
  return framesAt(a, b, d.anchor, Quat(R));
}

void buildJointRows(const PrismaticRotoideJointDesc& d, const JointPose& p, RowWriter& out) {
  const RelativeRotation rel(p);
  addRotationRows(rel, 0b110, d.common.softness, 3, out);
  for (const int axis : {0, 2}) {
    ConstraintRow& row = out.equality(axis);
    attachedToBAxisRow(p, p.axisB(axis), row);
    row.softness = &d.common.softness;
  }
  // The slide's position is the anchors' (as ODE's dJointGetPRPosition);
  // its stops and motor push along ODE's centres row.
  ConstraintRow rate;
  const double slide = p.axisB(1).dot(p.d);
  centresAxisRow(p, p.axisB(1), rate);
  addCoordinateRows(rate, slide, d.limitP, d.motorP, 6, out);
  angularAxisRow(p.axisA(0), 0.0, rate);
  addCoordinateRows(rate, rel.angle(0), d.limitR, d.motorR, 9, out);
}

}  // namespace blockstep

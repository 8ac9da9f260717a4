// Motor joint: only bounded rows, one coordinate part per axis (motor and
// stops, parts/coordinate.h), about (angular) or along (linear) axes that
// turn with the body they are fixed in. The frames make each body's frame
// the world frame at creation, so p.frameA * axis is an A-fixed axis now.
// Linear rows act on the centres of mass (anchors there), as ODE's LMotor.
#include <cmath>
#include <string>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/coordinate.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const MotorJointDesc& d) {
  validateCommon(d.common, d.angular ? "angular motor" : "linear motor");
  if (d.axisCount < 1 || d.axisCount > 3) throw Error("motor joint needs 1 to 3 axes");
  static const char* names[3] = {"motor joint axis 1", "motor joint axis 2", "motor joint axis 3"};
  for (int i = 0; i < d.axisCount; ++i) {
    requireAxis(d.axes[i].axis, names[i]);
    validateLimit(d.axes[i].limit, names[i]);
    validateMotor(d.axes[i].motor, names[i]);
    if (!std::isfinite(d.axes[i].value))
      throw Error(std::string(names[i]) + " value is not finite");
  }
}

JointFrames setupJoint(MotorJointDesc& d, const Body& a, const Body& b) {
  for (int i = 0; i < d.axisCount; ++i)
    d.axes[i].axis.normalize();
  JointFrames f;  // anchors at the centres of mass
  f.localFrameA = a.orientation.conjugate();
  f.localFrameB = b.orientation.conjugate();
  return f;
}

void buildJointRows(const MotorJointDesc& d, const JointPose& p, RowWriter& out) {
  using Frame = MotorJointDesc::Frame;
  ConstraintRow rate;
  for (int i = 0; i < d.axisCount; ++i) {
    const MotorJointDesc::Axis& ax = d.axes[i];
    const Vec3 axis = ax.frame == Frame::A   ? Vec3(p.frameA * ax.axis)
                      : ax.frame == Frame::B ? Vec3(p.frameB * ax.axis)
                                             : ax.axis;
    if (d.angular) {
      angularAxisRow(axis, 0.0, rate);
    } else {
      directionRow(p, axis, rate);
    }
    addCoordinateRows(rate, ax.value, ax.limit, ax.motor, kCoordinateSlots * i, out);
  }
}

}  // namespace blockstep

// Motor joint: only bounded rows, one coordinate part per axis (motor and
// stops, parts/coordinate.h), about (angular) or along (linear) axes that
// turn with the body they are fixed in. The frames make each body's frame
// the world frame at creation, so p.frameA * axis is an A-fixed axis now.
// Linear rows act on the centres of mass (anchors there), as ODE's LMotor.
// The Euler form computes ODE's AMotor Euler angles from the current
// poses in every sub-step (a value frozen over the sub-steps repeated a
// stop's correction in each and blew up).
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
  if (d.euler &&
      (!d.angular || d.axisCount != 3 || d.axes[0].axis.cross(d.axes[2].axis).norm() < 1e-6 ||
       !(d.eulerRefA.norm() > 1e-9) || !(d.eulerRefB.norm() > 1e-9))) {
    throw Error(
        "Euler motor joint needs 3 angular axes, axes 1 and 3 not parallel, and references");
  }
  static const char* names[3] = {"motor joint axis 1", "motor joint axis 2", "motor joint axis 3"};
  for (int i = 0; i < d.axisCount; ++i) {
    requireAxis(d.axes[i].axis, names[i]);
    validateLimit(d.axes[i].limit, names[i]);
    validateMotor(d.axes[i].motor, names[i]);
    if (!std::isfinite(d.axes[i].value))
      throw Error(std::string(names[i]) + " value is not finite");
  }
}

void keepCreationGeometry(MotorJointDesc& next, const MotorJointDesc& made) {
  for (int i = 0; i < 3; ++i)
    next.axes[i].axis = made.axes[i].axis;
  next.eulerRefA = made.eulerRefA;
  next.eulerRefB = made.eulerRefB;
}

JointFrames setupJoint(MotorJointDesc& d, const Body& a, const Body& b) {
  for (int i = 0; i < d.axisCount; ++i)
    d.axes[i].axis.normalize();
  JointFrames f;  // anchors at the centres of mass
  f.localFrameA = a.orientation.conjugate();
  f.localFrameB = b.orientation.conjugate();
  return f;
}

// ODE's Euler angles (amotor.cpp computeEulerAngles) and their rows.
void buildEulerRows(const MotorJointDesc& d, const JointPose& p, JointState& state,
                    RowWriter& out) {
  const Vec3 ax0 = p.frameB * d.axes[0].axis;
  const Vec3 ax2 = p.frameA * d.axes[2].axis;
  const Vec3 refB = p.frameB * d.eulerRefB, refA = p.frameA * d.eulerRefA;
  const Vec3 ax1 = ax2.cross(ax0).normalized();
  const double angle[3] = {-std::atan2(ax2.dot(ax0.cross(refB)), ax2.dot(refB)),
                           -std::atan2(ax2.dot(ax0), ax2.dot(ax0.cross(ax1))),
                           -std::atan2(refA.dot(ax1), refA.dot(ax1.cross(ax2)))};
  const Vec3 rowAxis[3] = {ax1.cross(ax2), ax1, ax0.cross(ax1)};
  for (int i = 0; i < 3; ++i)
    state.angle[i] = angle[i];
  ConstraintRow rate;
  for (int i = 0; i < 3; ++i) {
    angularAxisRow(rowAxis[i], 0.0, rate);
    addCoordinateRows(rate, angle[i], d.axes[i].limit, d.axes[i].motor, kCoordinateSlots * i, out);
  }
}

void buildJointRows(const MotorJointDesc& d, const JointPose& p, JointState& state,
                    RowWriter& out) {
  if (d.euler) return buildEulerRows(d, p, state, out);
  buildJointRows(d, p, out);
}

void buildJointRows(const MotorJointDesc& d, const JointPose& p, RowWriter& out) {
  using Frame = MotorJointDesc::Frame;
  if (d.euler) {
    JointState unused;
    return buildEulerRows(d, p, unused, out);
  }
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

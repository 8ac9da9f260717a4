// Generic 6-DOF joint: each axis of a joint frame fixed in A is free,
// locked or limited, and may have a motor. Locked axes go into one
// equality block (translation: rows along A's frame axes, rotation: the
// section 4.4 quaternion rows); limits and motors are bounded rows.
// A limited rotation axis reads its angle as 2 atan2(r_i, r_w): exact when
// it is the only rotation axis not locked. With two or more rotation axes
// free or limited that reading is not an angle any more (it jumps once a
// free axis turns past a half turn), so limits there need a swing-twist
// decomposition, which this joint does not have yet: validateJoint refuses
// a rotation limit beside another unlocked rotation axis.
#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/constraints/parts/rotation.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const SixDofJointDesc& d) {
  validateCommon(d.common, "6-DOF");
  requireFinite(d.anchor, "6-DOF joint anchor");
  if (!d.frame.coeffs().allFinite() || std::abs(d.frame.norm() - 1.0) > 1e-6) {
    throw Error("6-DOF joint frame must be a finite unit quaternion");
  }
  static const char* names[6] = {"6-DOF joint x",     "6-DOF joint y",     "6-DOF joint z",
                                 "6-DOF joint rot x", "6-DOF joint rot y", "6-DOF joint rot z"};
  for (int i = 0; i < 6; ++i) {
    const auto& ax = d.axes[i];
    if (ax.mode == SixDofJointDesc::Mode::Limited) {
      Limit l;
      l.enabled = true;
      l.lo = ax.lo;
      l.hi = ax.hi;
      validateLimit(l, names[i]);
    }
    validateMotor(ax.motor, names[i]);
  }
  int unlockedRotations = 0, limitedRotations = 0;
  for (int i = 3; i < 6; ++i) {
    unlockedRotations += d.axes[i].mode != SixDofJointDesc::Mode::Locked;
    limitedRotations += d.axes[i].mode == SixDofJointDesc::Mode::Limited;
  }
  if (limitedRotations > 0 && unlockedRotations > 1) {
    throw Error("6-DOF joint: a rotation limit needs the other two rotation axes locked");
  }
}

JointFrames setupJoint(SixDofJointDesc& d, const Body& a, const Body& b) {
  return framesAt(a, b, d.anchor, d.frame);
}

void buildJointRows(const SixDofJointDesc& d, const JointPose& p, RowWriter& out) {
  using Mode = SixDofJointDesc::Mode;
  ConstraintRow rate;
  for (int i = 0; i < 3; ++i) {
    const auto& ax = d.axes[i];
    attachedAxisRow(p, p.axisA(i), rate);
    if (ax.mode == Mode::Locked) {
      ConstraintRow& row = out.equality(i);
      row = rate;
      row.slot = static_cast<std::uint8_t>(i);
      row.softness = &d.common.softness;
      continue;
    }
    const Stops stops{ax.mode == Mode::Limited, ax.lo, ax.hi};
    addCoordinateRows(rate, rate.C, stops, d.limitSoftness, ax.motor, 6 + 3 * i, out);
  }
  const RelativeRotation rel(p);
  unsigned locked = 0;
  for (int i = 0; i < 3; ++i) {
    const auto& ax = d.axes[3 + i];
    if (ax.mode == Mode::Locked) {
      locked |= 1u << i;
      continue;
    }
    angularAxisRow(p.axisA(i), 0.0, rate);
    const Stops stops{ax.mode == Mode::Limited, ax.lo, ax.hi};
    addCoordinateRows(rate, rel.angle(i), stops, d.limitSoftness, ax.motor, 15 + 3 * i, out);
  }
  addRotationRows(rel, locked, d.common.softness, 3, out);
}

}  // namespace blockstep

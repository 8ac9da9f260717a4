// Generic 6-DOF joint: each axis of a joint frame fixed in A is free,
// locked or limited, and may have a motor. Locked axes go into one
// equality block (translation: rows along A's frame axes, rotation: the
// section 4.4 quaternion rows); limits and motors are bounded rows.
// Rotation: with at most one rotation axis unlocked, the locked ones are
// the quaternion rows and the free one's angle is 2 atan2(r_i, r_w), exact
// for a rotation about that axis alone. With two or three unlocked, that
// reading is not an angle any more (it jumps once another axis turns past
// a half turn), so the angles come from the swing-twist split instead:
// twist about x (rate about B's x axis), swing about y and z as a rotation
// vector (rates about A's y and z axes); locked axes are then equality
// rows on those angles.
#include <cmath>

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
      l.bounce = ax.bounce;
      l.softness = ax.stopSoftness;
      validateLimit(l, names[i]);
    }
    validateMotor(ax.motor, names[i]);
  }
  // Swing-twist angles (two or more rotation axes unlocked) are singular
  // at a half-turn swing; a free swing axis reaches it, which breaks the
  // other swing axis's reading. Free both swing axes, or limit both.
  using Mode = SixDofJointDesc::Mode;
  int unlocked = 0;
  for (int i = 3; i < 6; ++i)
    unlocked += d.axes[i].mode != Mode::Locked;
  const bool freeY = d.axes[4].mode == Mode::Free, freeZ = d.axes[5].mode == Mode::Free;
  if (unlocked >= 2 && freeY != freeZ) {
    throw Error(
        "6-DOF joint: with two or more rotation axes unlocked, the swing axes (rot y, "
        "rot z) must be both free or both locked/limited (use a limit below pi)");
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
    const Stops stops{ax.mode == Mode::Limited, ax.lo, ax.hi, ax.bounce};
    addCoordinateRows(rate, rate.C, stops, ax.stopSoftness, ax.motor, 6 + 3 * i, out);
  }
  const RelativeRotation rel(p);
  int unlocked = 0;
  for (int i = 3; i < 6; ++i)
    unlocked += d.axes[i].mode != Mode::Locked;
  if (unlocked <= 1) {
    unsigned locked = 0;
    for (int i = 0; i < 3; ++i) {
      const auto& ax = d.axes[3 + i];
      if (ax.mode == Mode::Locked) {
        locked |= 1u << i;
        continue;
      }
      angularAxisRow(p.axisA(i), 0.0, rate);
      const Stops stops{ax.mode == Mode::Limited, ax.lo, ax.hi, ax.bounce};
      addCoordinateRows(rate, rel.angle(i), stops, ax.stopSoftness, ax.motor, 15 + 3 * i, out);
    }
    addRotationRows(rel, locked, d.common.softness, 3, out);
    return;
  }
  const SwingTwist st(rel.r);
  const Vec3 twistA = p.axisA(0), twistB = p.axisB(0);
  const double cosSwing = twistA.dot(twistB);
  for (int i = 0; i < 3; ++i) {
    const auto& ax = d.axes[3 + i];
    const double angle = i == 0 ? st.twistAngle : st.swingAbout(i);
    // The relative rate is swing rate + twist rate about B's twist axis.
    // A swing row along A's axis i would also see the twist spin (by the
    // swing angle); u = a_i - (a_i.b_x / a_x.b_x) a_x is blind to b_x and
    // still reads the swing rate about a_i.
    Vec3 axis = i == 0 ? twistB : p.axisA(i);
    if (i > 0 && std::abs(cosSwing) > 0.1) axis -= (axis.dot(twistB) / cosSwing) * twistA;
    angularAxisRow(axis, angle, rate);
    if (ax.mode == Mode::Locked) {
      ConstraintRow& row = out.equality(3 + i);
      row = rate;
      row.slot = static_cast<std::uint8_t>(3 + i);
      row.softness = &d.common.softness;
      continue;
    }
    const Stops stops{ax.mode == Mode::Limited, ax.lo, ax.hi, ax.bounce};
    addCoordinateRows(rate, angle, stops, ax.stopSoftness, ax.motor, 15 + 3 * i, out);
  }
}

}  // namespace blockstep

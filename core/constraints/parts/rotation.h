// Quaternion rotational constraint part (section 4.4).
//
// The paper keeps the bodies' initial rotations qa0, qb0 and a constraint
// frame qc, and measures r = qa* qb (qa0* qb0)*, constraining components
// of r about the axes R[qa0 qc*]. We fold the initial rotations and qc
// into one joint frame per body (JointFrames::localFrameA/B, chosen at
// creation so both frames coincide in the world); then, with
// FA = qA localFrameA and FB = qB localFrameB,
//   r = FA* FB                   (identity when the joint is at rest),
// which is the paper's r expressed in the constraint frame. Rotation about
// the frame's axis i is allowed iff component i of r's vector part may
// change, so the error of a locked axis is C_i = 2 r_i (= the angle for
// small errors; we flip r to w >= 0 to take the short way round).
//
// Jacobian, from the quaternion derivative dF/dt = 1/2 (0, w) F (world w):
//   dr/dt = 1/2 (FA* (wB - wA) FA) r = 1/2 (0, w') r,  w' = R_FA^T (wB - wA)
// and the vector part of (0, w') (w, v) is  w w' + w' x v, so
//   dC/dt = 2 d v/dt = (w I - [v]x) R_FA^T (wB - wA).
// Row i of M = (w I - [v]x) R_FA^T is the exact Jacobian for any rotation
// size (no small-angle step); for a hinge at angle t about x its locked
// rows are cos(t/2) y + sin(t/2) z and its mirror, unit length at every t.
#pragma once

#include <cmath>

#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/joint_pose.h"
#include "core/constraints/parts/row_writer.h"

namespace blockstep {

struct RelativeRotation {
  Quat r;  // FA* FB with r.w() >= 0
  Mat3 M;  // dC/dt = M (wB - wA) for C = 2 r.vec()

  explicit RelativeRotation(const JointPose& p) {
    r = p.frameA.conjugate() * p.frameB;
    if (r.w() < 0.0) r.coeffs() = -r.coeffs();
    const Mat3 RT = p.frameA.toRotationMatrix().transpose();
    M = (r.w() * Mat3::Identity() - skew(r.vec())) * RT;
  }

  // The locked-axis error and row of axis i (0 = x, 1 = y, 2 = z of the frame).
  void lockedRow(int i, ConstraintRow& row) const {
    row.linA.setZero();
    row.linB.setZero();
    row.angB = M.row(i).transpose();
    row.angA = -row.angB;
    row.C = 2.0 * r.vec()[i];
    row.angular = true;
  }

  // Angle about frame axis i when the rotation is about that axis alone;
  // the twist angle about i otherwise. In (-pi, pi].
  double angle(int i) const { return 2.0 * std::atan2(r.vec()[i], r.w()); }
};

// The relative rotation split as r = swing * twist, twist about the
// frame's x axis: twist = (w, x, 0, 0) / norm, swing = r twist*, whose
// axis lies in the frame's y-z plane. Used by the cone-twist joint and by
// 6-DOF joints with more than one rotation axis unlocked, where single-
// axis angles 2 atan2(r_i, w) stop being angles once another axis turns.
struct SwingTwist {
  double twistAngle = 0.0;         // about x, in (-pi, pi]
  double swingAngle = 0.0;         // >= 0
  Vec3 swingAxis = Vec3::UnitY();  // unit, in the frame (x component ~ 0)

  explicit SwingTwist(const Quat& r) {
    const double twistNorm = std::hypot(r.w(), r.x());
    const Quat twist =
        twistNorm > 1e-9 ? Quat(r.w() / twistNorm, r.x() / twistNorm, 0.0, 0.0) : Quat::Identity();
    twistAngle = 2.0 * std::atan2(twist.x(), twist.w());
    Quat swing = r * twist.conjugate();
    if (swing.w() < 0.0) swing.coeffs() = -swing.coeffs();
    const double s = swing.vec().norm();
    if (s > 1e-12) {
      swingAngle = 2.0 * std::atan2(s, swing.w());
      swingAxis = swing.vec() / s;
    }
  }
  // Swing as a rotation vector's y and z components (rad): the swing
  // angles about the frame's y and z axes.
  double swingAbout(int axis) const { return swingAngle * swingAxis[axis]; }
};

// Locks the frame axes whose bit is set in mask (bit i = axis i).
inline void addRotationRows(const RelativeRotation& rel, unsigned mask, const Softness& softness,
                            int firstSlot, RowWriter& out) {
  for (int i = 0; i < 3; ++i) {
    if (!(mask & (1u << i))) continue;
    ConstraintRow& row = out.equality(firstSlot + i);
    rel.lockedRow(i, row);
    row.softness = &softness;
  }
}

}  // namespace blockstep

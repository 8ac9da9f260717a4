// Rows along a single direction: the building block of point, slider,
// distance and 6-DOF translation rows, and of rotation about one axis.
//
// Section 4.2 derives, for a contact at anchor p with normal n,
//   Cdot = n.vA + (rA x n).wA - n.vB - (rB x n).wB.
// Here every row measures B relative to A (C grows as B moves along n), so
// the signs are the mirror of the paper's: J = [-n, -(rA x n), n, rB x n].
#pragma once

#include "core/constraints/parts/joint_pose.h"
#include "core/constraints/row.h"

namespace blockstep {

// C = n . (pB - pA) with n a fixed world direction over the step.
inline void directionRow(const JointPose& p, const Vec3& n, ConstraintRow& row) {
  row.linA = -n;
  row.angA = -p.rA.cross(n);
  row.linB = n;
  row.angB = p.rB.cross(n);
  row.C = n.dot(p.d);
  row.angular = false;
}

// C = n . (pB - pA) with n fixed in body A (a slider's axis): n turns with
// A, so dC/dt gains d . (wA x n) = wA . (n x d), which moves A's angular
// term to -(rA + d) x n.
inline void attachedAxisRow(const JointPose& p, const Vec3& n, ConstraintRow& row) {
  row.linA = -n;
  row.angA = -(p.rA + p.d).cross(n);
  row.linB = n;
  row.angB = p.rB.cross(n);
  row.C = n.dot(p.d);
  row.angular = false;
}

// C = n . (pB - pA) with n fixed in body B (hinge2's suspension axis):
// dC/dt gains d . (wB x n) = wB . (n x d), so B's angular term is
// (rB - d) x n.
inline void attachedToBAxisRow(const JointPose& p, const Vec3& n, ConstraintRow& row) {
  row.linA = -n;
  row.angA = -p.rA.cross(n);
  row.linB = n;
  row.angB = (p.rB - p.d).cross(n);
  row.C = n.dot(p.d);
  row.angular = false;
}

// ODE's rate row for a linear limit or motor (its "linear limot torque
// decoupling"): the centres' relative velocity along n, with the torque
// that keeps it invariant under a common rotation split evenly between
// the bodies. With the stage's own body rotating (ODE's PR) it is what
// ODE's stops and motors push along. C is left to the caller.
inline void centresAxisRow(const JointPose& p, const Vec3& n, ConstraintRow& row) {
  const Vec3 xA = p.pA - p.rA, xB = p.pB - p.rB;
  const Vec3 split = 0.5 * (xA - xB).cross(n);
  row.linA = -n;
  row.angA = split;
  row.linB = n;
  row.angB = split;
  row.angular = false;
}

// Relative rotation rate about world axis a: dC/dt = (wB - wA) . a.
inline void angularAxisRow(const Vec3& a, double C, ConstraintRow& row) {
  row.linA.setZero();
  row.angA = -a;
  row.linB.setZero();
  row.angB = a;
  row.C = C;
  row.angular = true;
}

// C = a1 . a2 for a1 fixed in A and a2 fixed in B (universal, hinge-2):
// dC/dt = (wA x a1) . a2 + a1 . (wB x a2) = (a1 x a2) . (wA - wB).
inline void perpendicularRow(const Vec3& a1, const Vec3& a2, ConstraintRow& row) {
  const Vec3 c = a1.cross(a2);
  row.linA.setZero();
  row.angA = c;
  row.linB.setZero();
  row.angB = -c;
  row.C = a1.dot(a2);
  row.angular = true;
}

}  // namespace blockstep

// Fixed-size math types and the few helpers the solver needs.
// Double precision throughout: ODE's Debian build is double, and the
// adapter must not lose precision on the way in or out.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <limits>

namespace blockstep {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kInf = std::numeric_limits<double>::infinity();

// [v]x such that skew(v) * w == v.cross(w).
inline Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

inline bool isFinite(const Vec3& v) {
  return v.allFinite();
}
inline bool isFinite(const Quat& q) {
  return q.coeffs().allFinite();
}
inline bool isFinite(const Mat3& m) {
  return m.allFinite();
}

// x with A x = b by Cramer's rule (A's inverse from the cross products of
// its rows); for the small, well-conditioned systems of one body, where
// it is several times cheaper than a pivoted LU. A (near-)singular A
// falls back to the LU.
inline Vec3 solve3(const Mat3& A, const Vec3& b) {
  const Vec3 r0 = A.row(0), r1 = A.row(1), r2 = A.row(2);
  const Vec3 c0 = r1.cross(r2), c1 = r2.cross(r0), c2 = r0.cross(r1);
  const double det = r0.dot(c0);
  if (!(std::abs(det) > 1e-12 * A.cwiseAbs().maxCoeff() * A.squaredNorm()))
    return A.partialPivLu().solve(b);
  return (b.x() * c0 + b.y() * c1 + b.z() * c2) / det;
}

// Quaternion time derivative for a world-frame angular velocity:
// dq/dt = 1/2 (0, w) q. Integrating it with one Euler step and renormalizing
// is the semi-implicit update of section 3 applied to rotations.
inline Quat integrateRotation(const Quat& q, const Vec3& w, double h) {
  const Quat wq(0.0, w.x(), w.y(), w.z());
  Quat dq = wq * q;
  Quat out(q.w() + 0.5 * h * dq.w(), q.x() + 0.5 * h * dq.x(), q.y() + 0.5 * h * dq.y(),
           q.z() + 0.5 * h * dq.z());
  out.normalize();
  return out;
}

// The exact rotation by the rotation vector w h, applied to q (ODE's
// finite rotation): [cos(|w| h / 2), sin(|w| h / 2) w / |w|] q.
inline Quat rotateExactly(const Quat& q, const Vec3& w, double h) {
  const double angle = w.norm() * h;
  if (angle < 1e-12) return q;
  const Quat turn(Eigen::AngleAxisd(angle, w / w.norm()));
  return (turn * q).normalized();
}

// Two unit vectors perpendicular to n and to each other (n must be unit).
inline void perpendicularBasis(const Vec3& n, Vec3& t1, Vec3& t2) {
  // Pick the axis least aligned with n to stay well conditioned.
  if (std::abs(n.x()) >= 0.57735) {
    t1 = Vec3(n.y(), -n.x(), 0.0).normalized();
  } else {
    t1 = Vec3(0.0, n.z(), -n.y()).normalized();
  }
  t2 = n.cross(t1);
}

// The joint frame (as columns) whose x axis is `x` and whose y axis is
// `y` made perpendicular to it (Gram-Schmidt); z completes it.
inline Mat3 frameFromAxes(const Vec3& x, const Vec3& y) {
  const Vec3 u = x.normalized();
  const Vec3 v = (y - y.dot(u) * u).normalized();
  Mat3 R;
  R << u, v, u.cross(v);
  return R;
}

// A rotation taking the x axis to `axis` (unit): a joint frame whose first
// axis is the joint axis.
inline Quat frameFromAxis(const Vec3& axis) {
  return Quat::FromTwoVectors(Vec3::UnitX(), axis);
}

}  // namespace blockstep

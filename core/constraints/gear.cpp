// Gear joint: where the wheels touch (the mesh geometry of ODE's
// transmission joint, joints/transmission.cpp), how far each has turned
// (counted over whole turns in the JointState), and one row: the arcs the
// two rims travel at their contact must stay equal,
//   C    = sA rA thetaA - sB rB thetaB,
//   Cdot = sA rA (wA . nA) - sB rB (wB . nB),
// with sX = +-1 the direction a rim turning forward moves along the mesh
// tangent at its contact point, taken from the geometry, so Cdot = J v in
// every mode (ODE fixes the signs per mode, which for some bevel
// arrangements turns its position correction against the motion).
//
// The row is about the wheel axes only. ODE's row pushes at the contact
// points (linear terms too), so the axles also feel the mesh force; coupled
// through those terms to the wheels' hinge rows, a pendulum-driven chain
// diverged within ten steps at the sub-stepped solver's row stiffness. On
// wheels that turn about their axes (mounted on hinges, as gears are) the
// motion is ODE's; the hinges then carry no mesh force, and a transmission's
// feedback is a pure torque about each axis.
#include <algorithm>
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/coordinate.h"
#include "core/world/error.h"

namespace blockstep {
namespace {

constexpr double kTiny = 1e-9;

// Where the wheels touch now. Wheel 0 is A's, 1 is B's.
struct Mesh {
  Vec3 contact[2];  // world contact point on each rim
  Vec3 radius[2];   // contact point - wheel centre
  Vec3 tangent[2];  // unit direction of the mesh at each contact
};

Mesh meshOf(const GearJointDesc& d, const Vec3 centre[2], const Vec3 axis[2]) {
  using Kind = GearJointDesc::Kind;
  Mesh m;
  switch (d.kind) {
    case Kind::ParallelAxes: {
      // The contact splits the line of centres as ratio : 1.
      const Vec3 line = centre[1] - centre[0];
      const Vec3 c = centre[0] + line * (d.ratio / (1.0 + d.ratio));
      const Vec3 u = line.normalized();
      for (int i = 0; i < 2; ++i) {
        m.contact[i] = c;
        m.tangent[i] = u.cross(axis[i]).normalized();
      }
      break;
    }
    case Kind::IntersectingAxes: {
      // The contacts lie on the line where the wheels' planes meet: each
      // wheel's centre projected onto it.
      const Vec3 l = axis[0].cross(axis[1]).normalized();
      const double nn = axis[0].dot(axis[1]);
      const double h0 = axis[0].dot(centre[0]), h1 = axis[1].dot(centre[1]);
      const double s = 1.0 / (1.0 - nn * nn);
      const Vec3 origin = axis[0] * ((h0 - h1 * nn) * s) + axis[1] * ((h1 - h0 * nn) * s);
      for (int i = 0; i < 2; ++i) {
        m.contact[i] = origin + l * l.dot(centre[i] - origin);
        m.tangent[i] = l;
      }
      break;
    }
    case Kind::Chain: {
      // Where a straight chain leaves each sprocket (the outer tangent of
      // the two circles), on the side of  (centre A - centre B) x axis.
      const Vec3 line = centre[0] - centre[1];
      const double length = line.norm();
      const Vec3 u = line / length;
      const double cosine = std::clamp((d.radiusB - d.radiusA) / length, -1.0, 1.0);
      const double sine = std::sqrt(1.0 - cosine * cosine);
      const double radius[2] = {d.radiusA, d.radiusB};
      for (int i = 0; i < 2; ++i) {
        const Vec3 side = u.cross(axis[i]).normalized();
        m.contact[i] = centre[i] + radius[i] * (cosine * u + sine * side);
        m.tangent[i] = (m.contact[i] - centre[i]).cross(axis[i]).normalized();
      }
      break;
    }
  }
  for (int i = 0; i < 2; ++i)
    m.radius[i] = m.contact[i] - centre[i];
  return m;
}

// A wheel's frame: x toward its contact point, z along its axis.
Quat wheelFrame(const Vec3& radius, const Vec3& axis) {
  const Vec3 x = (radius - axis * axis.dot(radius)).normalized();
  Mat3 r;
  r << x, axis.cross(x), axis;
  return Quat(r);
}

}  // namespace

void validateJoint(const GearJointDesc& d) {
  using Kind = GearJointDesc::Kind;
  validateCommon(d.common, "gear");
  requireFinite(d.centreA, "gear joint centreA");
  requireFinite(d.centreB, "gear joint centreB");
  const Vec3 axisA = requireAxis(d.axisA, "gear joint axisA");
  const Vec3 axisB = requireAxis(d.axisB, "gear joint axisB");
  if (!(d.backlash >= 0.0) || !std::isfinite(d.backlash))
    throw Error("gear joint backlash must be finite and >= 0");
  const Vec3 line = d.centreB - d.centreA;
  switch (d.kind) {
    case Kind::ParallelAxes:
      if (!(d.ratio > 0.0) || !std::isfinite(d.ratio))
        throw Error("gear joint ratio must be finite and > 0");
      if (line.cross(axisA).norm() < kTiny || line.cross(axisB).norm() < kTiny)
        throw Error("gear joint on parallel axes: the wheel centres must be apart, not on an axis");
      break;
    case Kind::IntersectingAxes:
      if (axisA.cross(axisB).norm() < 1e-6)
        throw Error("gear joint on intersecting axes: the axes must not be parallel");
      break;
    case Kind::Chain:
      if (!(d.radiusA > 0.0) || !(d.radiusB > 0.0) || !std::isfinite(d.radiusA) ||
          !std::isfinite(d.radiusB))
        throw Error("chain joint radii must be finite and > 0");
      if (line.cross(axisA).norm() < kTiny || line.cross(axisB).norm() < kTiny)
        throw Error("chain joint: the sprocket centres must be apart, not on an axis");
      break;
    default:
      throw Error("gear joint: unknown kind");
  }
}

// Ratio, radii and backlash may change between steps (as ODE's setters
// allow); the kind, centres and axes are those of creation.
void keepCreationGeometry(GearJointDesc& next, const GearJointDesc& made) {
  next.kind = made.kind;
  next.centreA = made.centreA;
  next.centreB = made.centreB;
  next.axisA = made.axisA;
  next.axisB = made.axisB;
}

JointFrames setupJoint(GearJointDesc& d, const Body& a, const Body& b) {
  d.axisA.normalize();
  d.axisB.normalize();
  if (d.axisA.dot(d.axisB) < 0.0) d.axisB = -d.axisB;
  const Vec3 centre[2] = {d.centreA, d.centreB};
  const Vec3 axis[2] = {d.axisA, d.axisB};
  const Mesh m = meshOf(d, centre, axis);
  for (int i = 0; i < 2; ++i) {
    if ((m.radius[i] - axis[i] * axis[i].dot(m.radius[i])).norm() < kTiny)
      throw Error(i == 0 ? "gear joint: the contact point lies on wheel A's axis"
                         : "gear joint: the contact point lies on wheel B's axis");
  }
  JointFrames f;
  f.localAnchorA = a.localPoint(d.centreA);
  f.localAnchorB = b.localPoint(d.centreB);
  f.localFrameA = a.orientation.conjugate() * wheelFrame(m.radius[0], axis[0]);
  f.localFrameB = b.orientation.conjugate() * wheelFrame(m.radius[1], axis[1]);
  return f;
}

void buildJointRows(const GearJointDesc& d, const JointPose& p, JointState& state, RowWriter& out) {
  const Vec3 centre[2] = {p.pA, p.pB};
  const Vec3 axis[2] = {p.axisA(2), p.axisB(2)};
  const Quat frame[2] = {p.frameA, p.frameB};
  Mesh m = meshOf(d, centre, axis);

  // Each wheel's turn: the contact direction seen from the wheel, which
  // turns the other way, continued from the last (sub-)step's value.
  double arc[2], lever[2];
  for (int i = 0; i < 2; ++i) {
    const Vec3 seen = frame[i].conjugate() * m.radius[i];
    const double turn = -std::atan2(seen.y(), seen.x());
    double& angle = state.angle[i];
    angle += std::remainder(turn - angle, 2.0 * kPi);
    const double forward = m.tangent[i].dot(axis[i].cross(m.radius[i])) >= 0.0 ? 1.0 : -1.0;
    lever[i] = forward * m.radius[i].norm();
    arc[i] = lever[i] * angle;
  }
  const double C = arc[0] - arc[1];

  // A chain pulls with its taut side: ODE takes the other side when the
  // arcs say the chain has gone slack on this one.
  if (d.kind == GearJointDesc::Kind::Chain && C < 0.0) {
    const Vec3 normal = axis[0].cross(centre[0] - centre[1]).normalized();
    for (int i = 0; i < 2; ++i) {
      m.radius[i] -= 2.0 * normal.dot(m.radius[i]) * normal;
      m.contact[i] = centre[i] + m.radius[i];
    }
  }
  for (int i = 0; i < 2; ++i) {
    state.contactPoint[i] = m.contact[i];
    state.contactRadius[i] = m.radius[i].norm();
  }

  ConstraintRow rate;
  rate.angA = lever[0] * axis[0];
  rate.angB = -lever[1] * axis[1];
  rate.angular = false;  // its impulse is a force at the rims
  // Backlash: free play of +-backlash, then a one-sided push (ODE's
  // unilateral row); none: one equality row.
  const Stops play{true, -d.backlash, d.backlash, 0.0};
  addCoordinateRows(rate, C, play, d.common.softness, Motor{}, 0, out);
}

}  // namespace blockstep

// Per-kind reading of ODE 0.16's joints (semantics from ODE's
// joints/*.cpp getInfo2 and its public getters).
#include "adapters/ode/joint_mapping.h"

#include "adapters/ode/clamped_input.h"

#include <algorithm>
#include <cmath>

#include "adapters/ode/body_state.h"
#include "core/world/error.h"

namespace blockstep::ode {
namespace {

// Stand-in for an absent stop: far beyond any angle (which ODE keeps in
// [-pi, pi]) and any sensible slider travel.
constexpr double kFarStop = 1e9;

using ParamGetter = dReal (*)(dJointID, int);

// ODE's limit-motor of one axis (dxJointLimitMotor): stops at lo/hi with
// StopERP/StopCFM and Bounce, a velocity motor Vel with FMax and CFM.
void readAxis(dJointID j, ParamGetter get, int group, const JointWorldParams& w, Limit& limit,
              Motor& motor) {
  const double lo = get(j, dParamLoStop + group);
  const double hi = get(j, dParamHiStop + group);
  // ODE ignores stops when lo > hi: its setters take them as they come,
  // and each joint tests its stops only when lo <= hi (demo_feedback's
  // slider with stops 0 and -0.2 slides free, held by its motor alone).
  limit.enabled = (lo > -dInfinity || hi < dInfinity) && lo <= hi;
  limit.lo = std::isfinite(lo) ? lo : -kFarStop;
  limit.hi = std::isfinite(hi) ? hi : kFarStop;
  limit.softness = w.of(get(j, dParamStopERP + group), get(j, dParamStopCFM + group));
  limit.bounce = get(j, dParamBounce + group);
  if (limit.bounce < 0.0 || limit.bounce > 1.0) {
    limit.bounce = std::clamp(limit.bounce, 0.0, 1.0);
    if (w.clamped) *w.clamped |= kClampedLimitBounce;
  }
  motor.targetVelocity = get(j, dParamVel + group);
  motor.maxForce = get(j, dParamFMax + group);
  // A powered axis's row has ODE's dParamCFM (the world's CFM by default).
  // FudgeFactor is not read: ODE scales with it the motor force it applies
  // by hand while the axis sits on a stop (its one row per axis serves the
  // stop then); the core keeps a motor row and stop rows apart and solves
  // both, the case the factor stands in for.
  motor.cfm = std::max(0.0, double(get(j, dParamCFM + group)));
}

JointCommon commonOf(BodyId body1, BodyId body2, const Softness& softness) {
  JointCommon c;
  c.bodyA = body2;
  c.bodyB = body1;
  c.softness = softness;
  return c;
}

void readBall(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2;
  dJointGetBallAnchor(j, a1);
  dJointGetBallAnchor2(j, a2);
  BallJointDesc d;
  // Ball, fixed and DBall joints carry their own ERP and CFM (set from the
  // world's when the joint was made).
  d.common =
      commonOf(b1, b2, w.of(dJointGetBallParam(j, dParamERP), dJointGetBallParam(j, dParamCFM)));
  // An error the joint has when blockstep first sees it (another stepper
  // stepped it) stays one: each side's anchor where ODE keeps it (the
  // core's A is ODE's body2). Taken from body1's alone, quickstep's
  // stretch of a chain became its rest and the first blockstep step was
  // 0.3 to 1 m/s off dWorldStep's from the same state; now it is the
  // same to 1e-13. Below a nanometre the anchors differ by rounding.
  d.anchor = vec(a1);
  if ((vec(a1) - vec(a2)).norm() > 1e-9) {
    d.anchor = vec(a2);
    d.common.anchorOnB = vec(a1);
  }
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
}

void readHinge(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2, axis;
  dJointGetHingeAnchor(j, a1);
  dJointGetHingeAnchor2(j, a2);
  dJointGetHingeAxis(j, axis);
  HingeJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = vec(a1);
  d.axis = vec(axis);
  readAxis(j, dJointGetHingeParam, 0, w, d.limit, d.motor);
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
  out.geometry.add(vec(axis), false, 1);
  out.coordinateCount = 1;
  out.coordinate[0] = dJointGetHingeAngle(j);
}

void readSlider(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 axis;
  dJointGetSliderAxis(j, axis);
  SliderJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.axis = vec(axis);
  readAxis(j, dJointGetSliderParam, 0, w, d.limit, d.motor);
  out.desc = d;
  out.geometry.add(vec(axis), false, 1);
  out.coordinateCount = 1;
  out.coordinate[0] = dJointGetSliderPosition(j);
}

void readFixed(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  FixedJointDesc d;
  d.common =
      commonOf(b1, b2, w.of(dJointGetFixedParam(j, dParamERP), dJointGetFixedParam(j, dParamCFM)));
  out.desc = d;
}

// ODE's getters of a two-axis joint (universal, hinge2).
struct TwoAxisGetters {
  void (*anchor)(dJointID, dVector3);
  void (*anchor2)(dJointID, dVector3);
  void (*axis1)(dJointID, dVector3);
  void (*axis2)(dJointID, dVector3);
  ParamGetter param;
  dReal (*angle1)(dJointID);
  dReal (*angle2)(dJointID);
};

// Universal and hinge2: ODE's axis1 is fixed in body1 (core B), axis2 in
// body2 (core A); the core's axis1 is the one fixed in A. So core axis1 =
// ODE axis2, core axis2 = ODE axis1, and their limits, motors and angles
// swap likewise.
UniversalJointDesc readTwoAxes(dJointID j, BodyId b1, BodyId b2, const TwoAxisGetters& get,
                               JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2, axis1, axis2;
  get.anchor(j, a1);
  get.anchor2(j, a2);
  get.axis1(j, axis1);
  get.axis2(j, axis2);
  UniversalJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = vec(a1);
  d.axis1 = vec(axis2);
  d.axis2 = vec(axis1);
  readAxis(j, get.param, dParamGroup, w, d.limit1, d.motor1);
  readAxis(j, get.param, 0, w, d.limit2, d.motor2);
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
  out.geometry.add(vec(axis1), false, 1);
  out.geometry.add(vec(axis2), false, 2);
  out.coordinateCount = 2;
  out.coordinate[0] = get.angle2(j);  // core angle 1
  out.coordinate[1] = get.angle1(j);  // core angle 2
  return d;
}

void readUniversal(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  static constexpr TwoAxisGetters kUniversal{dJointGetUniversalAnchor, dJointGetUniversalAnchor2,
                                             dJointGetUniversalAxis1,  dJointGetUniversalAxis2,
                                             dJointGetUniversalParam,  dJointGetUniversalAngle1,
                                             dJointGetUniversalAngle2};
  out.desc = readTwoAxes(j, b1, b2, kUniversal, out, w);
}

// Hinge2 (a steered, sprung wheel): axis1 (steering and suspension) in
// body1, axis2 (the axle) in body2: the universal joint plus a suspension
// along ODE's axis1 (SuspensionERP / SuspensionCFM). ODE's limit-motor 1
// acts on the steering angle, 2 on the axle.
void readHinge2(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  static constexpr TwoAxisGetters kHinge2{
      dJointGetHinge2Anchor, dJointGetHinge2Anchor2, dJointGetHinge2Axis1, dJointGetHinge2Axis2,
      dJointGetHinge2Param,  dJointGetHinge2Angle1,  dJointGetHinge2Angle2};
  UniversalJointDesc d = readTwoAxes(j, b1, b2, kHinge2, out, w);
  d.suspension = true;
  d.suspensionSoftness = w.of(dJointGetHinge2Param(j, dParamSuspensionERP),
                              dJointGetHinge2Param(j, dParamSuspensionCFM));
  out.desc = d;
}

// One axis of a core 6-DOF joint from an ODE limit-motor: free, or
// limited by the stops, with the motor.
SixDofJointDesc::Axis sixDofAxis(dJointID j, ParamGetter get, int group,
                                 const JointWorldParams& w) {
  Limit limit;
  Motor motor;
  readAxis(j, get, group, w, limit, motor);
  SixDofJointDesc::Axis a;
  a.mode = limit.enabled ? SixDofJointDesc::Mode::Limited : SixDofJointDesc::Mode::Free;
  a.lo = limit.lo;
  a.hi = limit.hi;
  a.bounce = limit.bounce;
  a.stopSoftness = limit.softness;
  a.motor = motor;
  return a;
}

// Piston (cylindrical): slides along and turns about one axis (fixed in
// body1). A core 6-DOF joint with the frame's x on that axis: x
// translation and x rotation free or limited (ODE's limit-motors 1 and 2),
// the rest locked.
void readPiston(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2, axis;
  dJointGetPistonAnchor(j, a1);
  dJointGetPistonAnchor2(j, a2);
  dJointGetPistonAxis(j, axis);
  SixDofJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = vec(a1);
  d.frame = frameFromAxis(vec(axis).normalized());
  d.axes[0] = sixDofAxis(j, dJointGetPistonParam, 0, w);
  d.axes[3] = sixDofAxis(j, dJointGetPistonParam, dParamGroup, w);
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
  out.geometry.add(vec(axis), false, 1);
  out.coordinateCount = 2;
  out.coordinate[0] = dJointGetPistonPosition(j);
  out.coordinate[1] = dJointGetPistonAngle(j);
}

// ODE's axis frames (0 global, 1 body1, 2 body2) as the core's (body1 is
// the core's B).
MotorJointDesc::Frame motorFrame(int rel) {
  return rel == 1   ? MotorJointDesc::Frame::B
         : rel == 2 ? MotorJointDesc::Frame::A
                    : MotorJointDesc::Frame::World;
}

// AMotor. User mode: a motor and stops on each of its 1-3 axes; the stops
// act on the angles the program sets (dJointSetAMotorAngle), as in ODE.
// Euler mode: the core motor joint's Euler form, from axis 0 (fixed in
// body1), axis 2 (fixed in body2) and the reference vectors ODE derived
// when they were set (the registry records them as ODE keeps them).
void readAMotorEuler(dJointID j, BodyId b1, BodyId b2, const JointSetOnly& set, JointRead& out,
                     const JointWorldParams& w) {
  // Attached as (0, body), ODE keeps these public roles (body1 the world).
  const dBodyID body1 = dJointGetBody(j, 0), body2 = dJointGetBody(j, 1);
  auto rotate = [](dBodyID b, const Vec3& v) -> Vec3 {
    if (!b) return v;
    const dReal* q = dBodyGetQuaternion(b);
    return Quat(q[0], q[1], q[2], q[3]) * v;
  };
  MotorJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.angular = true;
  d.euler = true;
  d.axisCount = 3;
  d.axes[0].axis = rotate(body1, set.amotorAxis[0]);
  d.axes[0].frame = MotorJointDesc::Frame::B;
  d.axes[1].axis = Vec3::UnitX();  // derived each sub-step
  d.axes[2].axis = rotate(body2, set.amotorAxis[2]);
  d.axes[2].frame = MotorJointDesc::Frame::A;
  d.eulerRefB = rotate(body1, set.eulerRef1);
  d.eulerRefA = rotate(body2, set.eulerRef2);
  if (d.axes[0].axis.cross(d.axes[2].axis).norm() < 1e-9 || d.eulerRefA.norm() < 1e-9 ||
      d.eulerRefB.norm() < 1e-9) {
    out.unsupported = "Euler mode (dAMotorEuler) without axes 0 and 2 set";
    return;
  }
  for (int i = 0; i < 3; ++i) {
    readAxis(j, dJointGetAMotorParam, dParamGroup * i, w, d.axes[i].limit, d.axes[i].motor);
  }
  out.desc = d;
  // Remade when the program sets the axes again.
  out.geometry.add(set.amotorAxis[0], false, 0);
  out.geometry.add(set.amotorAxis[2], false, 0);
  out.geometry.add(set.eulerRef1, false, 0);
  out.geometry.add(set.eulerRef2, false, 0);
}

void readAMotor(dJointID j, BodyId b1, BodyId b2, const JointSetOnly& set, JointRead& out,
                const JointWorldParams& w) {
  if (dJointGetAMotorMode(j) == dAMotorEuler) {
    readAMotorEuler(j, b1, b2, set, out, w);
    return;
  }
  MotorJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.angular = true;
  d.axisCount = dJointGetAMotorNumAxes(j);
  if (d.axisCount < 1) {
    out.hasRows = false;
    return;
  }
  for (int i = 0; i < d.axisCount; ++i) {
    dVector3 axis;
    dJointGetAMotorAxis(j, i, axis);
    MotorJointDesc::Axis& a = d.axes[i];
    a.axis = vec(axis);
    const int rel = dJointGetAMotorAxisRel(j, i);
    a.frame = motorFrame(rel);
    readAxis(j, dJointGetAMotorParam, dParamGroup * i, w, a.limit, a.motor);
    a.value = dJointGetAMotorAngle(j, i);
    out.geometry.add(vec(axis), false, rel);
  }
  out.desc = d;
}

// LMotor: a motor on each of its 1-3 axes, driving body1's centre
// relative to body2's. ODE gives it no position, so no stops either.
void readLMotor(dJointID j, BodyId b1, BodyId b2, const int rel[3], JointRead& out,
                const JointWorldParams& w) {
  MotorJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.angular = false;
  d.axisCount = dJointGetLMotorNumAxes(j);
  if (d.axisCount < 1) {
    out.hasRows = false;
    return;
  }
  for (int i = 0; i < d.axisCount; ++i) {
    dVector3 axis;
    dJointGetLMotorAxis(j, i, axis);
    MotorJointDesc::Axis& a = d.axes[i];
    a.axis = vec(axis);
    a.frame = motorFrame(rel[i]);
    Limit unused;
    readAxis(j, dJointGetLMotorParam, dParamGroup * i, w, unused, a.motor);
    out.geometry.add(vec(axis), false, rel[i]);
  }
  out.desc = d;
}

// Plane2D: the body stays in the plane z = 0 and turns only about z
// (ODE's rows: vz = 0 pulled back to z = 0, wx = wy = 0), with velocity
// motors along x, y and about z. A core 6-DOF joint with the world frame
// anchored at the body's centre: it holds the z of the first step, so the
// body must be on z = 0, as in ODE's own use.
void readPlane2D(dJointID j, BodyId b1, BodyId b2, const JointSetOnly& set, JointRead& out,
                 const JointWorldParams& w) {
  dBodyID body = dJointGetBody(j, 0);
  if (!body || dJointGetBody(j, 1)) {
    out.unsupported = "plane2d attached other than to one body (as ODE's body1)";
    return;
  }
  const dReal* x = dBodyGetPosition(body);
  SixDofJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = Vec3(x[0], x[1], 0.0);
  using Mode = SixDofJointDesc::Mode;
  const int freeAxes[3] = {0, 1, 5};  // x, y translation; rotation about z
  for (int k = 0; k < 3; ++k) {
    SixDofJointDesc::Axis& a = d.axes[freeAxes[k]];
    a.mode = Mode::Free;
    a.motor.targetVelocity = set.plane2dVel[k];
    a.motor.maxForce = std::max(0.0, set.plane2dFMax[k]);
  }
  out.desc = d;
  // The core joint keeps the z of its creation (ODE pulls toward 0): a
  // body more than 1 mm off the plane is refused rather than held there.
  if (std::abs(x[2]) > 1e-3) out.unsupported = "plane2d on a body that is off z = 0";
}

// PR: ODE's axis1 (prismatic) and the rotoide axis are fixed in body1,
// the anchor on the rotoide axis in body2: the core's prismatic-rotoide
// joint with body1 as B. Limit-motor 1 on the slide, 2 on the angle.
void readPR(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 anchor, axisP, axisR;
  dJointGetPRAnchor(j, anchor);
  dJointGetPRAxis1(j, axisP);
  dJointGetPRAxis2(j, axisR);
  PrismaticRotoideJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = vec(anchor);
  d.axisP = vec(axisP);
  d.axisR = vec(axisR);
  readAxis(j, dJointGetPRParam, 0, w, d.limitP, d.motorP);
  readAxis(j, dJointGetPRParam, dParamGroup, w, d.limitR, d.motorR);
  out.desc = d;
  out.geometry.add(vec(axisP), false, 1);
  out.geometry.add(vec(axisR), false, 1);
  out.coordinateCount = 2;
  out.coordinate[0] = dJointGetPRPosition(j);
  out.coordinate[1] = dJointGetPRAngle(j);
}

// PU: ODE's axis1 and the prismatic axis (its "axis 3") are fixed in
// body1, axis2 in body2; as for the universal joint the core's axis1 (in
// A) is ODE's axis2. Limit-motors: 1 and 2 on the angles, 3 (dParamLoStop3)
// on the slide.
void readPU(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, axis1, axis2, axisP;
  dJointGetPUAnchor(j, a1);
  dJointGetPUAxis1(j, axis1);
  dJointGetPUAxis2(j, axis2);
  dJointGetPUAxis3(j, axisP);
  PrismaticUniversalJointDesc d;
  d.common = commonOf(b1, b2, w.of(w.erp, w.cfm));
  d.anchor = vec(a1);
  d.axisP = vec(axisP);
  d.axis1 = vec(axis2);
  d.axis2 = vec(axis1);
  readAxis(j, dJointGetPUParam, 2 * dParamGroup, w, d.limitP, d.motorP);
  readAxis(j, dJointGetPUParam, dParamGroup, w, d.limit1, d.motor1);
  readAxis(j, dJointGetPUParam, 0, w, d.limit2, d.motor2);
  out.desc = d;
  out.geometry.add(vec(axis1), false, 1);
  out.geometry.add(vec(axis2), false, 2);
  out.geometry.add(vec(axisP), false, 1);
  out.coordinateCount = 3;
  out.coordinate[0] = dJointGetPUAngle2(j);  // core angle 1
  out.coordinate[1] = dJointGetPUAngle1(j);  // core angle 2
  out.coordinate[2] = dJointGetPUPosition(j);
}

// DHinge: DBall's rod plus the axis (fixed in body1) kept aligned and the
// anchors kept in one plane across it.
void readDHinge(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2, axis;
  dJointGetDHingeAnchor1(j, a1);
  dJointGetDHingeAnchor2(j, a2);
  dJointGetDHingeAxis(j, axis);
  DoubleHingeJointDesc d;
  d.common = commonOf(b1, b2,
                      w.of(dJointGetDHingeParam(j, dParamERP), dJointGetDHingeParam(j, dParamCFM)));
  d.anchorA = vec(a2);
  d.anchorB = vec(a1);
  d.axis = vec(axis);
  d.length = dJointGetDHingeDistance(j);
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
  out.geometry.add(vec(axis), false, 1);
}

// DBall: the anchors keep ODE's set distance (a rod).
void readDBall(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  dVector3 a1, a2;
  dJointGetDBallAnchor1(j, a1);
  dJointGetDBallAnchor2(j, a2);
  DistanceJointDesc d;
  d.common =
      commonOf(b1, b2, w.of(dJointGetDBallParam(j, dParamERP), dJointGetDBallParam(j, dParamCFM)));
  d.anchorA = vec(a2);
  d.anchorB = vec(a1);
  d.minLength = d.maxLength = dJointGetDBallDistance(j);
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
}

// Transmission: the core gear joint. ODE's wheel 1 (body1) is the core's
// B, so the core ratio (A's radius over B's) is 1 / ODE's and the radii
// swap. ODE keeps its own ERP and CFM on the joint (from the world's when
// made) and counts the angles from its first step after a setter, as the
// core counts them from when the joint is made (which a setter causes).
void readTransmission(dJointID j, BodyId b1, BodyId b2, JointRead& out, const JointWorldParams& w) {
  if (b1 == kWorldBody || b2 == kWorldBody) {
    throw Error(
        "ODE transmission joint attached to one body: it needs two (ODE's own stepper would "
        "crash on it)");
  }
  dVector3 a1, a2, axis1, axis2;
  dJointGetTransmissionAnchor1(j, a1);
  dJointGetTransmissionAnchor2(j, a2);
  dJointGetTransmissionAxis1(j, axis1);
  dJointGetTransmissionAxis2(j, axis2);
  GearJointDesc d;
  d.common = commonOf(
      b1, b2,
      w.of(dJointGetTransmissionParam(j, dParamERP), dJointGetTransmissionParam(j, dParamCFM)));
  switch (dJointGetTransmissionMode(j)) {
    case dTransmissionParallelAxes:
      d.kind = GearJointDesc::Kind::ParallelAxes;
      break;
    case dTransmissionIntersectingAxes:
      d.kind = GearJointDesc::Kind::IntersectingAxes;
      break;
    case dTransmissionChainDrive:
      d.kind = GearJointDesc::Kind::Chain;
      break;
    default:
      out.unsupported = "unknown transmission mode";
      return;
  }
  d.centreA = vec(a2);
  d.centreB = vec(a1);
  d.axisA = vec(axis2);
  d.axisB = vec(axis1);
  const double ratio = dJointGetTransmissionRatio(j);
  d.ratio = ratio > 0.0 ? 1.0 / ratio : ratio;  // the core refuses ratio <= 0
  if (d.kind == GearJointDesc::Kind::Chain) {   // otherwise ODE derives them when stepping
    d.radiusA = dJointGetTransmissionRadius2(j);
    d.radiusB = dJointGetTransmissionRadius1(j);
  }
  d.backlash = dJointGetTransmissionBacklash(j);
  out.desc = d;
  out.geometry.add(vec(a1), true, 1);
  out.geometry.add(vec(a2), true, 2);
  out.geometry.add(vec(axis1), false, 1);
  out.geometry.add(vec(axis2), false, 2);
}

void shift(Limit& l, double offset) {
  if (!l.enabled) return;
  l.lo -= offset;
  l.hi -= offset;
}

}  // namespace

const char* odeJointTypeName(int type) {
  switch (type) {
    case dJointTypeBall:
      return "ball";
    case dJointTypeHinge:
      return "hinge";
    case dJointTypeSlider:
      return "slider";
    case dJointTypeContact:
      return "contact";
    case dJointTypeUniversal:
      return "universal";
    case dJointTypeHinge2:
      return "hinge2";
    case dJointTypeFixed:
      return "fixed";
    case dJointTypeNull:
      return "null";
    case dJointTypeAMotor:
      return "angular motor (AMotor)";
    case dJointTypeLMotor:
      return "linear motor (LMotor)";
    case dJointTypePlane2D:
      return "plane2d";
    case dJointTypePR:
      return "PR";
    case dJointTypePU:
      return "PU";
    case dJointTypePiston:
      return "piston";
    case dJointTypeDBall:
      return "DBall";
    case dJointTypeDHinge:
      return "DHinge";
    case dJointTypeTransmission:
      return "transmission";
    default:
      return "unknown";
  }
}

void readJoint(dJointID j, BodyId body1, BodyId body2, const JointWorldParams& world,
               const JointSetOnly& setOnly, JointRead& out) {
  out.geometry.count = 0;
  out.coordinateCount = 0;
  out.coordinate[0] = out.coordinate[1] = out.coordinate[2] = 0.0;
  out.hasRows = true;
  out.unsupported = nullptr;
  switch (dJointGetType(j)) {
    case dJointTypeBall:
      readBall(j, body1, body2, out, world);
      break;
    case dJointTypeHinge:
      readHinge(j, body1, body2, out, world);
      break;
    case dJointTypeSlider:
      readSlider(j, body1, body2, out, world);
      break;
    case dJointTypeFixed:
      readFixed(j, body1, body2, out, world);
      break;
    case dJointTypeUniversal:
      readUniversal(j, body1, body2, out, world);
      break;
    case dJointTypeDBall:
      readDBall(j, body1, body2, out, world);
      break;
    case dJointTypeHinge2:
      readHinge2(j, body1, body2, out, world);
      break;
    case dJointTypePiston:
      readPiston(j, body1, body2, out, world);
      break;
    case dJointTypeAMotor:
      readAMotor(j, body1, body2, setOnly, out, world);
      break;
    case dJointTypeLMotor:
      readLMotor(j, body1, body2, setOnly.lmotorRel, out, world);
      break;
    case dJointTypePlane2D:
      readPlane2D(j, body1, body2, setOnly, out, world);
      break;
    case dJointTypePR:
      readPR(j, body1, body2, out, world);
      break;
    case dJointTypePU:
      readPU(j, body1, body2, out, world);
      break;
    case dJointTypeDHinge:
      readDHinge(j, body1, body2, out, world);
      break;
    case dJointTypeTransmission:
      readTransmission(j, body1, body2, out, world);
      break;
    case dJointTypeNull:
      out.hasRows = false;
      break;
    default:
      out.unsupported = "this joint kind has no blockstep mapping yet";
      break;
  }
}

void shiftLimits(JointDesc& desc, const double offset[3]) {
  if (auto* h = std::get_if<HingeJointDesc>(&desc)) {
    shift(h->limit, offset[0]);
  } else if (auto* s = std::get_if<SliderJointDesc>(&desc)) {
    shift(s->limit, offset[0]);
  } else if (auto* u = std::get_if<UniversalJointDesc>(&desc)) {
    shift(u->limit1, offset[0]);
    shift(u->limit2, offset[1]);
  } else if (auto* pr = std::get_if<PrismaticRotoideJointDesc>(&desc)) {
    shift(pr->limitP, offset[0]);
    shift(pr->limitR, offset[1]);
  } else if (auto* pu = std::get_if<PrismaticUniversalJointDesc>(&desc)) {
    shift(pu->limit1, offset[0]);
    shift(pu->limit2, offset[1]);
    shift(pu->limitP, offset[2]);
  } else if (auto* x = std::get_if<SixDofJointDesc>(&desc)) {
    // Piston: coordinate 0 is the x translation, 1 the x rotation.
    x->axes[0].lo -= offset[0];
    x->axes[0].hi -= offset[0];
    x->axes[3].lo -= offset[1];
    x->axes[3].hi -= offset[1];
  }
}

}  // namespace blockstep::ode

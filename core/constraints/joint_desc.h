// What a user says to create a joint. Anchors and axes are given in world
// coordinates at creation, in the bodies' current poses (as in ODE); the
// world turns them into frames fixed in each body. Limits, motors,
// softness and break thresholds may be changed between steps through
// World::jointDesc().
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <variant>

#include "core/body/body.h"
#include "core/constraints/softness.h"

namespace blockstep {

using JointId = std::int32_t;

// A one-sided pair of stops. lo == hi locks the axis; lo > hi is invalid.
struct Limit {
  bool enabled = false;
  double lo = 0.0;  // rad for angles, m for distances
  double hi = 0.0;
  Softness softness = Softness::erpCfm(0.2, 0.0);  // ODE's StopERP / StopCFM
  double bounce = 0.0;  // restitution at the stops, 0..1 (ODE's dParamBounce)
};

// A velocity motor: drives the axis toward targetVelocity with at most
// maxForce (N or N m). maxForce == 0 turns it off; infinity makes the axis
// reach its target within the step whatever it takes (ODE's dInfinity FMax).
struct Motor {
  double targetVelocity = 0.0;
  double maxForce = 0.0;
  // Compliance: the axis lags the target by cfm times the motor's force
  // (m/s per N, rad/s per N m; ODE's dParamCFM of a powered axis). 0: stiff.
  double cfm = 0.0;
  bool active() const { return maxForce > 0.0; }
};

// Settings every joint has.
struct JointCommon {
  BodyId bodyA = kWorldBody;
  BodyId bodyB = kWorldBody;
  Softness softness = Softness::erpCfm(0.2, 1e-5);  // of the equality rows
  // The joint breaks (stops acting, and is reported) when the force or
  // torque it transmitted over one step exceeds these.
  double breakForce = std::numeric_limits<double>::infinity();   // N
  double breakTorque = std::numeric_limits<double>::infinity();  // N m
  // Where body B's side of the anchor is, when the joint is made with an
  // error already (a joint another stepper stepped, seen first mid-run):
  // B's anchor point is made there, so the error stays an error that the
  // rows correct instead of becoming the joint's rest. Unset: at the
  // anchor. Read by the joints made at an anchor point (ball, hinge,
  // universal, cone-twist, 6-DOF, PR, PU).
  std::optional<Vec3> anchorOnB;
};

// Point-to-point (ball and socket): 3 rows.
struct BallJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
};

// Ball + 2 rotational rows about the axis's perpendiculars; angle limit
// and motor about the axis.
struct HingeJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
  Limit limit;  // angle of B relative to A about the axis, 0 at creation
  Motor motor;
};

// Translation along one axis only: 2 linear rows + 3 rotational rows;
// limit and motor along the axis.
struct SliderJointDesc {
  JointCommon common;
  Vec3 axis = Vec3::UnitZ();
  Limit limit;  // displacement of B relative to A along the axis, 0 at creation
  Motor motor;
};

// Holds the two bodies in their relative pose at creation: 6 rows, one block.
struct FixedJointDesc {
  JointCommon common;
};

// Ball + rotation kept about axis1 (fixed in A) and axis2 (fixed in B),
// which start perpendicular; limits on both angles.
struct UniversalJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Vec3 axis1 = Vec3::UnitX();
  Vec3 axis2 = Vec3::UnitY();
  Limit limit1, limit2;
  Motor motor1, motor2;
  // A wheel suspension (ODE's hinge2): the anchors may part along axis2
  // (fixed in B) as a spring of this softness; the other two directions
  // stay rigid.
  bool suspension = false;
  Softness suspensionSoftness = Softness::erpCfm(0.2, 1e-5);
};

// Ragdoll shoulder: ball + a cone limiting how far the twist axis swings
// (half angle) + a twist limit about it.
struct ConeTwistJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Vec3 twistAxis = Vec3::UnitX();
  double swingLimit = kPi;  // rad, cone half angle; >= pi means no cone
  Limit twistLimit;
};

// Each of 6 axes of a joint frame (x, y, z translation, then x, y, z
// rotation) is free, locked or limited, and may carry a motor.
struct SixDofJointDesc {
  enum class Mode : std::uint8_t { Free, Locked, Limited };
  struct Axis {
    Mode mode = Mode::Locked;
    double lo = 0.0, hi = 0.0;
    Motor motor;
    double bounce = 0.0;                                 // restitution at the stops, 0..1
    Softness stopSoftness = Softness::erpCfm(0.2, 0.0);  // ODE's StopERP / StopCFM
  };
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Quat frame = Quat::Identity();  // world orientation of the joint frame at creation
  Axis axes[6];
};

// Keeps the distance between two anchors within [minLength, maxLength]
// (a rope: minLength = 0). With spring softness it is a damped spring.
struct DistanceJointDesc {
  JointCommon common;
  Vec3 anchorA = Vec3::Zero();
  Vec3 anchorB = Vec3::Zero();
  double minLength = -1.0;  // < 0: the distance at creation
  double maxLength = -1.0;
};

// Prismatic then rotoide (ODE's PR): B slides along axisP (fixed in B)
// relative to A, and A turns about axisR (through the anchor, fixed in A;
// kept aligned with B's). axisP and axisR are perpendicular. Limits and
// motors on the slide (B relative to A along axisP) and on the angle.
struct PrismaticRotoideJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Vec3 axisP = Vec3::UnitX();
  Vec3 axisR = Vec3::UnitY();
  Limit limitP, limitR;
  Motor motorP, motorR;
};

// Prismatic then universal (ODE's PU): B's anchor stays on the line
// through A's along axisP (fixed in B), and the bodies turn as a universal
// joint does about axis1 (fixed in A) and axis2 (fixed in B), kept
// perpendicular. Limits and motors on the slide and both angles.
struct PrismaticUniversalJointDesc {
  JointCommon common;
  Vec3 anchor = Vec3::Zero();
  Vec3 axisP = Vec3::UnitZ();
  Vec3 axis1 = Vec3::UnitX();
  Vec3 axis2 = Vec3::UnitY();
  Limit limitP, limit1, limit2;
  Motor motorP, motor1, motor2;
  // Set at creation: axisP in the joint frame (which turns with B).
  Vec3 axisPInFrameB = Vec3::UnitZ();
};

// Double hinge (ODE's DHinge): two anchors, one on each body, at a fixed
// distance, and the axis (fixed in both) kept aligned, with both anchors
// in the same plane across it: a rod hinged at both ends about parallel
// axes. 4 rows, one block.
struct DoubleHingeJointDesc {
  JointCommon common;
  Vec3 anchorA = Vec3::Zero();
  Vec3 anchorB = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
  double length = -1.0;  // < 0: the distance at creation
};

// Motors (and stops) on up to three axes, constraining nothing else: ODE's
// AMotor (angular, user mode) and LMotor (linear). Each axis is fixed in
// the world, in A or in B (given in world coordinates at creation; they
// keep those of creation); an angular axis drives the relative rotation
// rate of B over A about it, a linear one the relative velocity of B's
// centre over A's along it. Stops act on `value`, the axis's coordinate as
// the caller measures it (ODE's user-set AMotor angles), refreshed by
// updateJoint.
struct MotorJointDesc {
  enum class Frame : std::uint8_t { World, A, B };
  struct Axis {
    Vec3 axis = Vec3::UnitX();
    Frame frame = Frame::World;
    Limit limit;
    Motor motor;
    double value = 0.0;
  };
  JointCommon common;
  bool angular = true;
  int axisCount = 1;  // 1..3
  Axis axes[3];
  // ODE's AMotor Euler mode (angular, 3 axes): axes[0].axis is fixed in
  // B, axes[2].axis in A (perpendicular at creation), eulerRefB/A the
  // reference vectors fixed in B/A (world at creation). The three angles
  // and their rows (ax1 x ax2, ax1 = unit(ax2 x ax0), ax0 x ax1) are
  // computed from the current poses each (sub-)step, as ODE computes them;
  // axes[i].value is then unused.
  bool euler = false;
  Vec3 eulerRefB = Vec3::UnitX(), eulerRefA = Vec3::UnitX();
};

// Two wheels that turn together (ODE's transmission joint): spur gears on
// parallel axes, bevel gears on intersecting axes, or sprockets joined by a
// chain. One row keeps the arcs the wheels' rims travel at their contact
// point equal (gears mesh: the wheels turn opposite ways; a chain: the
// same way), counted from creation over whole turns. With backlash the
// rims may part by up to that arc either way (the row then only pushes).
// Each wheel's contact radius is fixed at creation: the distance from its
// centre to the contact point (spur: on the line of centres, splitting it
// as `ratio`; bevel: on the line where the wheels' planes meet; chain:
// where the taut chain leaves the sprocket of the given radius).
struct GearJointDesc {
  enum class Kind : std::uint8_t { ParallelAxes, IntersectingAxes, Chain };
  JointCommon common;
  Kind kind = Kind::ParallelAxes;
  Vec3 centreA = Vec3::Zero(), centreB = Vec3::Zero();  // wheel centres, world
  // Wheel axes, world. B's is turned to point as A's does if they oppose.
  // ParallelAxes and Chain need them parallel, IntersectingAxes not.
  Vec3 axisA = Vec3::UnitZ(), axisB = Vec3::UnitZ();
  double ratio = 1.0;                   // ParallelAxes: A's radius over B's (> 0)
  double radiusA = 0.0, radiusB = 0.0;  // Chain: the sprockets' radii (> 0)
  double backlash = 0.0;                // m of rim travel either way, >= 0
};

using JointDesc = std::variant<BallJointDesc, HingeJointDesc, SliderJointDesc, FixedJointDesc,
                               UniversalJointDesc, ConeTwistJointDesc, SixDofJointDesc,
                               DistanceJointDesc, MotorJointDesc, PrismaticRotoideJointDesc,
                               PrismaticUniversalJointDesc, DoubleHingeJointDesc, GearJointDesc>;

inline const JointCommon& common(const JointDesc& d) {
  return std::visit([](const auto& j) -> const JointCommon& { return j.common; }, d);
}
inline JointCommon& common(JointDesc& d) {
  return std::visit([](auto& j) -> JointCommon& { return j.common; }, d);
}

const char* jointKindName(const JointDesc& d);

}  // namespace blockstep

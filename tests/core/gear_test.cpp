// Gear joints: meshing wheels turn at the ratio of their radii (spur gears
// the opposite way, a chain the same way, bevel gears as their geometry
// says), over many turns without drift; backlash lets the driven wheel
// rest until the gap closes; bad descriptions are refused.
#include <cmath>

#include "core/world/error.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

using test::boxBody;

struct Wheels {
  World world;
  BodyId a, b;
  JointId gear = -1;
};

// Two wheels on hinges to the world at their centres; A driven at `speed`
// with at most `torque`.
void makeWheels(Wheels& w, const Vec3& centreA, const Vec3& axisA, const Vec3& centreB,
                const Vec3& axisB, double speed, double torque = 1000.0) {
  w.world.setGravity(Vec3::Zero());
  w.world.setSettings(SolverSettings::subStepped(10));
  w.a = w.world.createBody(boxBody(centreA, 1.0, Vec3(0.5, 0.5, 0.5)));
  w.b = w.world.createBody(boxBody(centreB, 1.0, Vec3(0.5, 0.5, 0.5)));
  HingeJointDesc h;
  h.common.bodyB = w.a;
  h.anchor = centreA;
  h.axis = axisA;
  h.motor = Motor{speed, torque};
  w.world.createJoint(h);
  h.common.bodyB = w.b;
  h.anchor = centreB;
  h.axis = axisB;
  h.motor = Motor{};
  w.world.createJoint(h);
}

GearJointDesc gear(const Wheels& w, GearJointDesc::Kind kind, const Vec3& centreA,
                   const Vec3& axisA, const Vec3& centreB, const Vec3& axisB) {
  GearJointDesc g;
  g.common.bodyA = w.a;
  g.common.bodyB = w.b;
  g.kind = kind;
  g.centreA = centreA;
  g.centreB = centreB;
  g.axisA = axisA;
  g.axisB = axisB;
  return g;
}

void run(World& world, double seconds) {
  test::stepN(world, static_cast<int>(std::lround(seconds * 60.0)), 1.0 / 60.0);
}

TEST(Gears, SpurGearsTurnOppositeAtTheirRatioOverManyTurns) {
  // Radii 2 and 1 (centres 3 m apart, ratio 2): B turns twice as fast the
  // other way; 5 s at 2 rad/s is 10 rad for A and 20 rad (3 turns) for B.
  Wheels w;
  const Vec3 ca(0, 0, 0), cb(3, 0, 0), z = Vec3::UnitZ();
  makeWheels(w, ca, z, cb, z, 2.0);
  GearJointDesc g = gear(w, GearJointDesc::Kind::ParallelAxes, ca, z, cb, z);
  g.ratio = 2.0;
  w.gear = w.world.createJoint(g);
  run(w.world, 5.0);
  EXPECT_NEAR(w.world.body(w.a).angularVelocity.z(), 2.0, 1e-4);
  EXPECT_NEAR(w.world.body(w.b).angularVelocity.z(), -4.0, 1e-3);
  const JointState& s = w.world.jointState(w.gear);
  EXPECT_NEAR(s.angle[0], 10.0, 0.02);
  EXPECT_NEAR(s.angle[1], -20.0, 0.04);
  EXPECT_NEAR(s.contactRadius[0], 2.0, 1e-9);
  EXPECT_NEAR(s.contactRadius[1], 1.0, 1e-9);
  EXPECT_LT(w.world.jointError(w.gear).linear, 1e-4) << "rim arcs must stay equal over turns";
}

TEST(Gears, ChainTurnsBothSprocketsTheSameWay) {
  // Sprockets of radius 0.5 and 0.25 two metres apart: B at twice A's rate.
  Wheels w;
  const Vec3 ca(0, 0, 0), cb(2, 0, 0), y = Vec3::UnitY();
  makeWheels(w, ca, y, cb, y, 1.5);
  GearJointDesc g = gear(w, GearJointDesc::Kind::Chain, ca, y, cb, y);
  g.radiusA = 0.5;
  g.radiusB = 0.25;
  w.gear = w.world.createJoint(g);
  run(w.world, 6.0);
  EXPECT_NEAR(w.world.body(w.b).angularVelocity.y(), 3.0, 1e-3);
  const JointState& s = w.world.jointState(w.gear);
  EXPECT_NEAR(s.angle[1], 2.0 * s.angle[0], 0.02);
  EXPECT_GT(s.angle[1], 2.0 * 2.0 * kPi) << "more than two turns";
  EXPECT_LT(w.world.jointError(w.gear).linear, 1e-4);
}

TEST(Gears, BevelGearsFollowTheirGeometryEitherWay) {
  // A turns about z; B about x with its centre above or below the plane
  // of A. Both rims are at (1, 0, 0) with radius 1: above, the rims there
  // move along +y when both turn forward; below, B must turn backward.
  for (double side : {1.0, -1.0}) {
    SCOPED_TRACE(side);
    Wheels w;
    const Vec3 ca(0, 0, 0), cb(1, 0, side);
    makeWheels(w, ca, Vec3::UnitZ(), cb, Vec3::UnitX(), 1.0);
    w.gear = w.world.createJoint(
        gear(w, GearJointDesc::Kind::IntersectingAxes, ca, Vec3::UnitZ(), cb, Vec3::UnitX()));
    run(w.world, 20.0);  // 3 turns
    EXPECT_NEAR(w.world.body(w.b).angularVelocity.x(), side * 1.0, 1e-3);
    const JointState& s = w.world.jointState(w.gear);
    EXPECT_NEAR(s.angle[1], side * s.angle[0], 0.02);
    EXPECT_TRUE(s.contactPoint[0].isApprox(Vec3(1, 0, 0), 1e-9));
    EXPECT_LT(w.world.jointError(w.gear).linear, 1e-4);
  }
}

TEST(Gears, BacklashLetsTheDrivenWheelRestUntilTheGapCloses) {
  // Equal wheels, 0.1 m of play either way: A's rim travels 0.1 m at
  // 1 m/s before B moves; after 1 s B has turned 0.9 rad. Reversed, A
  // must cross the whole 0.2 m gap before B turns back. The drive is a
  // 5 N m motor: B leaves each impact 2% faster than A (warm starting the
  // impact impulse with one sweep per sub-step; 13% with 1000 N m).
  Wheels w;
  const Vec3 ca(0, 0, 0), cb(2, 0, 0), z = Vec3::UnitZ();
  makeWheels(w, ca, z, cb, z, 1.0, 5.0);
  GearJointDesc g = gear(w, GearJointDesc::Kind::ParallelAxes, ca, z, cb, z);
  g.backlash = 0.1;
  w.gear = w.world.createJoint(g);
  run(w.world, 0.05);
  EXPECT_NEAR(w.world.jointState(w.gear).angle[1], 0.0, 1e-9) << "inside the gap";
  run(w.world, 0.95);
  EXPECT_NEAR(w.world.jointState(w.gear).angle[1], -0.9, 0.03);
  // Reversed, A turns -1 rad/s while B coasts on at -1 rad/s: the rims
  // close the 0.2 m gap at 2 m/s, in 0.1 s; then A drives B at +1 rad/s.
  HingeJointDesc drive = std::get<HingeJointDesc>(w.world.joint(0));
  drive.motor = Motor{-1.0, 5.0};
  w.world.updateJoint(0, drive);
  const double before = w.world.jointState(w.gear).angle[1];
  run(w.world, 0.05);
  EXPECT_NEAR(w.world.jointState(w.gear).angle[1] - before, -0.05, 0.01)
      << "B coasts at its own speed inside the gap";
  run(w.world, 1.0);
  EXPECT_NEAR(w.world.body(w.b).angularVelocity.z(), 1.0, 0.03) << "driven back the other way";
}

TEST(Gears, BadDescriptionsAreRefused) {
  Wheels w;
  const Vec3 ca(0, 0, 0), cb(2, 0, 0), z = Vec3::UnitZ();
  makeWheels(w, ca, z, cb, z, 0.0);
  GearJointDesc g = gear(w, GearJointDesc::Kind::ParallelAxes, ca, z, cb, z);
  g.ratio = 0.0;
  EXPECT_THROW(w.world.createJoint(g), Error);
  g.ratio = 1.0;
  g.centreB = ca;  // no line of centres
  EXPECT_THROW(w.world.createJoint(g), Error);
  g = gear(w, GearJointDesc::Kind::IntersectingAxes, ca, z, cb, z);  // parallel axes
  EXPECT_THROW(w.world.createJoint(g), Error);
  g = gear(w, GearJointDesc::Kind::Chain, ca, z, cb, z);  // radii not given
  EXPECT_THROW(w.world.createJoint(g), Error);
  g.radiusA = g.radiusB = 0.3;
  g.backlash = -1.0;
  EXPECT_THROW(w.world.createJoint(g), Error);
  EXPECT_EQ(w.world.jointCount(), 2) << "only the two hinges";
}

}  // namespace
}  // namespace blockstep

// The block solver itself: pendulum period, block vs row-by-row, LDL^T on
// a singular K, heavy chains, stopping modes, residuals, islands, warm
// starting, and bad input.
#include <cmath>

#include "compare/native/scenes.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

using test::boxBody;

TEST(Solver, PendulumPeriodMatchesSmallAngleFormula) {
  // A point-like bob on a massless rod of length L: T = 2 pi sqrt(L / g).
  World world;
  const double L = 1.0, amplitude = 0.05, h = 1e-3;
  const double theta = amplitude;
  const BodyId bob = world.createBody(
      test::sphereBody(Vec3(L * std::sin(theta), 0, -L * std::cos(theta)), 1.0, 1e-3));
  BallJointDesc ball;
  ball.common.bodyB = bob;
  ball.anchor = Vec3::Zero();
  world.createJoint(ball);
  // Time between successive crossings of x = 0 going the same way.
  std::vector<double> crossings;
  double prevX = world.body(bob).position.x();
  for (int i = 1; i <= 10000 && crossings.size() < 5; ++i) {
    world.step(h);
    const double x = world.body(bob).position.x();
    if (prevX > 0.0 && x <= 0.0) crossings.push_back((i - 1 + prevX / (prevX - x)) * h);
    prevX = x;
  }
  ASSERT_GE(crossings.size(), 3u);
  const double period = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  const double expected = 2.0 * kPi * std::sqrt(L / 9.81);
  EXPECT_NEAR(period, expected, 0.01 * expected);
}

// Two beams welded end to end by a fixed joint (anchor midway between the
// centres: the linear and angular rows couple through the lever arms),
// hanging from a ball joint and swinging: the weld's worst error.
JointError weldError(BlockMode mode, int iterations) {
  World world;
  SolverSettings s = SolverSettings::paper(iterations);
  s.blockMode = mode;
  world.setSettings(s);
  const BodyId a = world.createBody(boxBody(Vec3(0.25, 0, 0), 1.0, Vec3(0.5, 0.05, 0.05)));
  const BodyId b = world.createBody(boxBody(Vec3(0.75, 0, 0), 1.0, Vec3(0.5, 0.05, 0.05)));
  BallJointDesc pin;
  pin.common.bodyB = a;
  pin.anchor = Vec3::Zero();
  world.createJoint(pin);
  FixedJointDesc f;
  f.common.bodyA = a;
  f.common.bodyB = b;
  const JointId j = world.createJoint(f);
  JointError worst;
  for (int i = 0; i < 120; ++i) {
    world.step(1.0 / 60.0);
    const JointError e = world.jointError(j);
    worst.linear = std::max(worst.linear, e.linear);
    worst.angular = std::max(worst.angular, e.angular);
  }
  return worst;
}

TEST(Solver, FixedJointBlockIsStifferThanRowByRow) {
  // Section 4.3: a fixed joint solved as six 1x1 rows is much softer than
  // as one 6x6 block, which is exact in one iteration.
  for (int iterations : {1, 2}) {
    const JointError block = weldError(BlockMode::Block, iterations);
    const JointError rows = weldError(BlockMode::RowByRow, iterations);
    std::printf(
        "welded beams, %d iterations: block %.3f mm %.4f rad, row by row %.3f mm %.4f rad\n",
        iterations, 1e3 * block.linear, block.angular, 1e3 * rows.linear, rows.angular);
    EXPECT_LT(block.linear, 0.5 * rows.linear) << iterations << " iterations";
  }
}

TEST(Solver, SingularBlockStaysFinite) {
  // Two ball joints with coincident anchors on the same pair and CFM = 0:
  // the second repeats the first. A fixed joint on top makes the world
  // overdetermined. LDL^T must drop the dependent pivots, not divide by 0.
  World world;
  const BodyId a = world.createBody(boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  const BodyId b = world.createBody(boxBody(Vec3(0.2, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  for (int k = 0; k < 2; ++k) {
    BallJointDesc ball;
    ball.common.bodyA = a;
    ball.common.bodyB = b;
    ball.common.softness = Softness::erpCfm(0.2, 0.0);
    ball.anchor = Vec3(0.1, 0, 0);
    world.createJoint(ball);
  }
  FixedJointDesc f;
  f.common.bodyA = a;
  f.common.bodyB = b;
  f.common.softness = Softness::erpCfm(0.2, 0.0);
  const JointId fixedId = world.createJoint(f);
  BallJointDesc pin;
  pin.common.bodyB = a;
  pin.common.softness = Softness::erpCfm(0.2, 0.0);
  world.createJoint(pin);
  test::stepN(world, 60, 1.0 / 60.0);
  EXPECT_TRUE(world.body(b).position.allFinite());
  EXPECT_LT(world.jointError(fixedId).linear, 0.01);
  // A ball joint whose anchor sits on both centres at once (a zero-length
  // lever on each side) is still well posed.
  BallJointDesc centre;
  centre.common.bodyA = a;
  centre.common.bodyB = b;
  centre.common.softness = Softness::erpCfm(0.2, 0.0);
  centre.anchor = world.body(b).position;
  world.createJoint(centre);
  test::stepN(world, 10, 1.0 / 60.0);
  EXPECT_TRUE(world.body(b).position.allFinite());
}

TEST(Solver, HeavyEndChainStretchStaysBounded) {
  // 20 ball-jointed links, the last 100x heavier, hanging at rest.
  for (const auto& [name, settings, bound] :
       {std::tuple{"paper 20", SolverSettings::paper(20), 0.5},
        std::tuple{"substep 20", SolverSettings::subStepped(20), 0.005}}) {
    World world;
    world.setSettings(settings);
    std::vector<JointId> joints;
    BodyId previous = kWorldBody;
    for (int i = 0; i < 20; ++i) {
      const BodyId link = world.createBody(
          boxBody(Vec3(0, 0, -0.1 * i - 0.05), i == 19 ? 10.0 : 0.1, Vec3(0.02, 0.02, 0.1)));
      BallJointDesc ball;
      ball.common.bodyA = previous;
      ball.common.bodyB = link;
      ball.anchor = Vec3(0, 0, -0.1 * i);
      joints.push_back(world.createJoint(ball));
      previous = link;
    }
    double worst = 0.0;
    for (int f = 0; f < 300; ++f) {
      world.step(1.0 / 60.0);
      for (JointId j : joints)
        worst = std::max(worst, world.jointError(j).linear);
    }
    RecordProperty(std::string(name) + "_stretch_mm", std::to_string(1e3 * worst));
    std::printf("heavy-end chain, %s: worst joint stretch %.2f mm\n", name, 1e3 * worst);
    EXPECT_LT(worst, bound) << name;
  }
}

TEST(Solver, ResidualHistoryFallsAndToleranceStopsEarly) {
  scenes::Scene scene;
  scenes::makeScene("chain", scene);
  SolverSettings s = SolverSettings::paper(50);
  s.recordResiduals = true;
  scene.world.setSettings(s);
  scene.world.step(scene.frameStep);
  const auto& r = scene.world.lastStepStats().residuals;
  ASSERT_EQ(r.size(), 50u);
  EXPECT_LT(r.back().max, 0.5 * r.front().max);
  EXPECT_LE(r.back().rms, r.back().max);

  scenes::Scene again;
  scenes::makeScene("chain", again);
  s.tolerance = 0.5 * r.front().max;
  again.world.setSettings(s);
  again.world.step(again.frameStep);
  const StepStats& st = again.world.lastStepStats();
  EXPECT_LT(st.iterations, 50);
  EXPECT_LT(st.residuals.back().max, s.tolerance);
}

TEST(Solver, TimeBudgetStopsTheSweeps) {
  scenes::Scene scene;
  scenes::makeScene("cloth32", scene);
  SolverSettings s = SolverSettings::paper(100000);
  s.timeBudget = 1e-3;
  scene.world.setSettings(s);
  scene.world.step(scene.frameStep);
  EXPECT_LT(scene.world.lastStepStats().iterations, 100000);
  EXPECT_GE(scene.world.lastStepStats().iterations, 1);
  // A budget spent before the sweeps start (prepare alone takes longer)
  // still gives every sub-step exactly one sweep.
  s.timeBudget = 1e-9;
  s.substeps = 3;
  scene.world.setSettings(s);
  scene.world.step(scene.frameStep);
  EXPECT_EQ(scene.world.lastStepStats().iterations, 3);
}

TEST(Solver, WarmStartingCutsTheSweepsANearRestChainNeeds) {
  auto sweepsAfterSettling = [](bool warm) {
    scenes::Scene scene;
    scenes::makeScene("chain", scene);
    SolverSettings s = SolverSettings::subStepped(4);
    s.iterations = 200;
    s.relaxIterations = 0;
    s.tolerance = 1e-3;
    s.warmStarting = warm;
    scene.world.setSettings(s);
    for (int f = 0; f < 120; ++f)
      scene.world.step(scene.frameStep);
    return scene.world.lastStepStats().iterations;
  };
  const int warm = sweepsAfterSettling(true), cold = sweepsAfterSettling(false);
  EXPECT_LT(warm, cold / 2) << "warm " << warm << " cold " << cold;
}

TEST(Solver, IslandsAreCounted) {
  World world;
  for (int k = 0; k < 3; ++k) {  // three separate pendulums
    const BodyId b = world.createBody(boxBody(Vec3(k, 0, -1), 1.0, Vec3(0.1, 0.1, 0.1)));
    BallJointDesc ball;
    ball.common.bodyB = b;
    ball.anchor = Vec3(k, 0, 0);
    world.createJoint(ball);
  }
  world.step(1.0 / 60.0);
  EXPECT_EQ(world.lastStepStats().islands, 3);
  EXPECT_EQ(world.lastStepStats().blocks, 3);
  EXPECT_EQ(world.lastStepStats().rows, 9);
}

TEST(Validation, BadInputIsRefusedAndTheWorldKept) {
  World world;
  const BodyId b = world.createBody(boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  BodyDesc bad = boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1));
  bad.mass = 0.0;
  EXPECT_THROW(world.createBody(bad), Error);
  bad.mass = -1.0;
  EXPECT_THROW(world.createBody(bad), Error);
  bad = boxBody(Vec3(NAN, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1));
  EXPECT_THROW(world.createBody(bad), Error);
  bad = boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1));
  bad.inertia = Mat3::Zero();
  EXPECT_THROW(world.createBody(bad), Error);
  bad.inertia = Vec3(1, 1, 5).asDiagonal();  // violates the triangle inequality
  EXPECT_THROW(world.createBody(bad), Error);
  EXPECT_THROW(boxMass(1.0, Vec3(0, 1, 1)), Error);

  HingeJointDesc h;
  h.common.bodyB = b;
  h.axis = Vec3::Zero();
  EXPECT_THROW(world.createJoint(h), Error);
  h.axis = Vec3::UnitX();
  h.common.bodyA = b;  // the same body on both sides
  EXPECT_THROW(world.createJoint(h), Error);
  h.common.bodyA = 42;  // no such body
  EXPECT_THROW(world.createJoint(h), Error);
  h.common.bodyA = kWorldBody;
  h.limit = Limit{true, 1.0, -1.0};
  EXPECT_THROW(world.createJoint(h), Error);
  UniversalJointDesc u;
  u.common.bodyB = b;
  u.axis1 = u.axis2 = Vec3::UnitZ();
  EXPECT_THROW(world.createJoint(u), Error);
  SixDofJointDesc six;
  six.common.bodyB = b;
  six.axes[3].mode = SixDofJointDesc::Mode::Free;
  six.axes[4].mode = SixDofJointDesc::Mode::Free;  // one swing axis free, the other limited
  six.axes[5] = {SixDofJointDesc::Mode::Limited, -0.2, 0.2, {}};
  EXPECT_THROW(world.createJoint(six), Error);
  EXPECT_EQ(world.jointCount(), 0);

  EXPECT_THROW(world.step(0.0), Error);
  EXPECT_THROW(world.step(-0.01), Error);
  EXPECT_THROW(world.step(NAN), Error);
  EXPECT_THROW(world.step(10.0), Error);
  EXPECT_THROW(world.setLinearVelocity(b, Vec3(INFINITY, 0, 0)), Error);
  EXPECT_THROW(world.addForce(b, Vec3(NAN, 0, 0)), Error);
  EXPECT_THROW(world.setMass(b, 1.0, Mat3::Identity() * NAN), Error);
  SolverSettings s;
  s.iterations = 0;
  EXPECT_THROW(world.setSettings(s), Error);
  EXPECT_THROW(world.body(7), Error);

  // After all that the world is as it was and steps normally.
  EXPECT_EQ(world.bodyCount(), 1);
  world.step(1.0 / 60.0);
  EXPECT_TRUE(world.body(b).position.allFinite());
  EXPECT_LT(world.body(b).position.z(), 0.0);
}

TEST(Validation, DestroyingABodyRemovesItsJoints) {
  World world;
  const BodyId a = world.createBody(boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  const BodyId b = world.createBody(boxBody(Vec3(0, 0, -0.5), 1.0, Vec3(0.1, 0.1, 0.1)));
  BallJointDesc ball;
  ball.common.bodyA = a;
  ball.common.bodyB = b;
  const JointId j = world.createJoint(ball);
  world.step(1.0 / 60.0);
  world.destroyBody(a);
  EXPECT_THROW(world.joint(j), Error);
  EXPECT_EQ(world.jointCount(), 0);
  world.step(1.0 / 60.0);
  EXPECT_TRUE(world.body(b).position.allFinite());
}

}  // namespace
}  // namespace blockstep

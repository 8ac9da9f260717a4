// The block solver itself: pendulum period, block vs row-by-row, LDL^T on
// a singular K, heavy chains, stopping modes, residuals, islands, warm
// starting, and bad input.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>

#include "compare/native/scenes.h"
#include "core/constraints/ldlt.h"
#include "core/solver/island_block.h"
#include "core/solver/row_ops.h"
#include "support/ball_joint_rows.h"
#include "support/test_world.h"
#include "support/two_islands.h"

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
    // Per-joint blocks: an island block solves the chain exactly in one
    // sweep, warm or cold, which is not what this test measures.
    s.islandBlockRows = 0;
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
  s = SolverSettings::subStepped(4);
  s.maxSurfaceTravelPerSubstep = -0.001;
  EXPECT_THROW(world.setSettings(s), Error);
  s.maxSurfaceTravelPerSubstep = INFINITY;
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
  EXPECT_TRUE(world.jointsOf(b).empty());
  world.step(1.0 / 60.0);
  EXPECT_TRUE(world.body(b).position.allFinite());
}

// A chain of five bodies on the world: each body knows its joints, through
// destroyed joints, destroyed bodies and reused slots, and destroying a
// body takes exactly its own.
TEST(Validation, EachBodyKnowsItsJointsThroughDestructionAndReuse) {
  World world;
  std::vector<BodyId> body;
  std::vector<JointId> joint;
  for (int i = 0; i < 5; ++i) {
    body.push_back(world.createBody(boxBody(Vec3(0, 0, -0.2 * i), 1.0, Vec3(0.1, 0.1, 0.1))));
    BallJointDesc ball;
    ball.common.bodyA = body[i];
    ball.common.bodyB = i == 0 ? kWorldBody : body[i - 1];
    joint.push_back(world.createJoint(ball));
  }
  auto sorted = [&](BodyId b) {
    std::vector<JointId> j = world.jointsOf(b);
    std::sort(j.begin(), j.end());
    return j;
  };
  EXPECT_EQ(sorted(body[0]), (std::vector<JointId>{joint[0], joint[1]}));
  EXPECT_EQ(sorted(body[4]), (std::vector<JointId>{joint[4]}));
  world.destroyJoint(joint[1]);
  EXPECT_EQ(sorted(body[0]), (std::vector<JointId>{joint[0]}));
  EXPECT_EQ(sorted(body[1]), (std::vector<JointId>{joint[2]}));
  world.destroyBody(body[2]);  // takes joints 2 and 3, not 4
  EXPECT_EQ(world.jointCount(), 2);
  EXPECT_THROW(world.joint(joint[2]), Error);
  EXPECT_THROW(world.joint(joint[3]), Error);
  EXPECT_NO_THROW(world.joint(joint[4]));
  EXPECT_TRUE(world.jointsOf(body[1]).empty());
  EXPECT_EQ(sorted(body[3]), (std::vector<JointId>{joint[4]}));
  // The freed body and joint slots are reused; the new body starts with
  // no joints and gets only its own.
  const BodyId again = world.createBody(boxBody(Vec3(1, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  EXPECT_EQ(again, body[2]);
  EXPECT_TRUE(world.jointsOf(again).empty());
  BallJointDesc ball;
  ball.common.bodyA = again;
  ball.common.bodyB = body[4];
  const JointId fresh = world.createJoint(ball);
  EXPECT_EQ(sorted(again), (std::vector<JointId>{fresh}));
  EXPECT_EQ(sorted(body[4]),
            (std::vector<JointId>{std::min(joint[4], fresh), std::max(joint[4], fresh)}));
  world.destroyBody(body[4]);
  EXPECT_EQ(world.jointCount(), 1);  // joint 0 on the world
  EXPECT_TRUE(world.jointsOf(again).empty());
  EXPECT_TRUE(world.jointsOf(body[3]).empty());
}

}  // namespace
}  // namespace blockstep

namespace blockstep {
namespace {

// ODE's demo_I built natively: a light anchor carrying ten heavier
// particles on ball joints turns under a torque exactly as one rigid body
// with their summed mass and inertia (parallel axes) does. The particles'
// mass is far from the anchor's, the case per-joint Gauss-Seidel solves
// badly (demo_I under the plugin reached 1e10 rad/s); an island block
// solves the star exactly.
double starAgainstRigidBody(SolverSettings settings) {
  World world;
  world.setGravity(Vec3::Zero());
  // The single body turns its angular momentum as the compound does only
  // with the gyroscopic term (ODE's default, on in demo_I).
  settings.gyroscopic = true;
  world.setSettings(settings);
  const Vec3 centre(0, 0, 1), twin(3, 0, 1);
  const MassProperties anchorMass = boxMass(0.1, Vec3(0.15, 0.15, 0.15));
  BodyDesc anchor;
  anchor.position = centre;
  anchor.mass = anchorMass.mass;
  anchor.inertia = anchorMass.inertia;
  const BodyId hub = world.createBody(anchor);
  double mass = anchorMass.mass;
  Mat3 inertia = anchorMass.inertia;
  const MassProperties particle = sphereMass(1.0, 0.05);
  // Fixed, spread-out offsets (demo_I draws them at random), shifted so
  // the compound's centre of mass is the anchor's centre, as demo_I does.
  Vec3 offsets[10];
  double masses[10];
  Vec3 moment = Vec3::Zero();
  for (int i = 0; i < 10; ++i) {
    offsets[i] = Vec3(0.3 * std::cos(1.7 * i), 0.3 * std::sin(2.3 * i), 0.25 * std::cos(0.9 * i));
    masses[i] = 0.1 + 0.1 * i;  // 0.1 .. 1.0 kg against the anchor's 0.1
    moment += masses[i] * offsets[i];
    mass += masses[i];
  }
  for (int i = 0; i < 10; ++i) {
    const Vec3 offset = offsets[i] - moment / mass;
    BodyDesc p;
    p.position = centre + offset;
    p.mass = masses[i];
    p.inertia = particle.inertia * masses[i];  // spheres of one radius
    const BodyId id = world.createBody(p);
    BallJointDesc ball;
    ball.common.bodyA = hub;
    ball.common.bodyB = id;
    ball.anchor = p.position;
    world.createJoint(ball);
    // Ball joints leave the particles' own spin alone: only their masses
    // at their offsets turn with the anchor.
    inertia += masses[i] * (offset.squaredNorm() * Mat3::Identity() - offset * offset.transpose());
  }
  // The rigid twin carries the compound's mass and inertia.
  BodyDesc rigid;
  rigid.position = twin;
  rigid.mass = mass;
  rigid.inertia = inertia;
  const BodyId single = world.createBody(rigid);
  const Vec3 torque(0.03, -0.02, 0.045);
  double worst = 0.0;
  for (int i = 0; i < 100; ++i) {
    world.addTorque(hub, torque);
    world.addTorque(single, torque);
    world.step(0.03);
    worst = std::max(worst,
                     (world.body(hub).angularVelocity - world.body(single).angularVelocity).norm());
  }
  return worst;
}

// The runaway guard measures the energy a joint island's errors hold as
// 1/2 d^T K^-1 d with the island's factor. Checked against K formed
// densely, J M^-1 J^T + gamma, for a chain of three bodies on two
// three-row joints with unequal masses and lever arms (the factor works
// in its own row order; the result must not depend on it).
TEST(Solver, IslandFactorGivesTheErrorsEnergy) {
  std::vector<SolverBody> bodies(4);  // the last: the static dummy
  const double masses[3] = {0.1, 2.0, 10.0};
  for (int i = 0; i < 3; ++i) {
    bodies[i].invMass = 1.0 / masses[i];
    bodies[i].invI = Vec3(3.0 + i, 1.0, 0.5 * (i + 1)).asDiagonal();
  }
  std::vector<ConstraintBlock> blocks(2);
  std::vector<ConstraintRow> rows(6);
  for (int j = 0; j < 2; ++j) {
    blocks[j].bodyA = j;
    blocks[j].bodyB = j + 1;
    blocks[j].firstRow = 3 * j;
    blocks[j].equality = 3;
    blocks[j].joint = j;
    const Vec3 armA(0.3, 0.1 * j, -0.2), armB(-0.25, 0.2, 0.1 + 0.1 * j);
    for (int k = 0; k < 3; ++k) {
      ConstraintRow& r = rows[3 * j + k];
      const Vec3 axis = Vec3::Unit(k);
      r.linA = -axis;
      r.angA = -armA.cross(axis);
      r.linB = axis;
      r.angB = armB.cross(axis);
      r.invIangA = bodies[j].invI * r.angA;
      r.invIangB = bodies[j + 1].invI * r.angB;
      r.gamma = 1e-3 * (k + 1);
      r.C = 0.01 * (k + 1) * (j == 0 ? 1.0 : -2.0);
    }
  }
  IslandBlocks islands;
  islands.select(blocks, 3, {0, 2}, 1, 100);
  ASSERT_TRUE(islands.covers(0));
  islands.factorAll(blocks, rows, bodies);
  const double measured =
      islands.inverseQuadratic(0, rows, [](const ConstraintRow& r, std::int32_t) { return r.C; });

  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, 18), Minv = Eigen::MatrixXd::Zero(18, 18);
  Eigen::VectorXd d(6), gamma(6);
  for (int i = 0; i < 3; ++i) {
    Minv.block<3, 3>(6 * i, 6 * i) = bodies[i].invMass * Mat3::Identity();
    Minv.block<3, 3>(6 * i + 3, 6 * i + 3) = bodies[i].invI;
  }
  for (int r = 0; r < 6; ++r) {
    const ConstraintBlock& b = blocks[r / 3];
    J.block<1, 3>(r, 6 * b.bodyA) = rows[r].linA.transpose();
    J.block<1, 3>(r, 6 * b.bodyA + 3) = rows[r].angA.transpose();
    J.block<1, 3>(r, 6 * b.bodyB) = rows[r].linB.transpose();
    J.block<1, 3>(r, 6 * b.bodyB + 3) = rows[r].angB.transpose();
    d[r] = rows[r].C;
    gamma[r] = rows[r].gamma;
  }
  const Eigen::MatrixXd K = J * Minv * J.transpose() + Eigen::MatrixXd(gamma.asDiagonal());
  const double expected = 0.5 * d.dot(K.ldlt().solve(d));
  // The sum of the diagonals (what the guard uses elsewhere) is another
  // number here (1.6% off), so the check above tells the two apart.
  double diagonals = 0.0;
  for (int r = 0; r < 6; ++r)
    diagonals += 0.5 * d[r] * d[r] / K(r, r);
  std::printf("  error energy %.6g (dense %.6g, diagonals alone %.6g)\n", measured, expected,
              diagonals);
  EXPECT_NEAR(measured, expected, 1e-10 * expected);
  EXPECT_GT(std::abs(diagonals - expected), 0.005 * expected) << "the check tells them apart";
}

// A chain of 20 ball joints (60 rows) hanging from the static body, its
// joints listed in a scrambled order: the island's rows are ordered along
// the chain, so each joint's rows reach back only to the joint before
// (6 + 15 x 19 = 291 factor entries; in the order given, 831), and one
// solve leaves every residual at zero. The choice stands
// while the structure does (the same entries again) and is made afresh
// when a joint goes: broken in the middle, the two chains of 10 and 9
// joints keep 141 + 126 entries.
TEST(Solver, AnIslandOrdersAScrambledChainAlongItAndChoosesAgainWhenAJointGoes) {
  constexpr int kJoints = 20;
  const std::int32_t staticBody = kJoints;
  std::vector<SolverBody> bodies(kJoints + 1);
  for (int i = 0; i < kJoints; ++i) {
    bodies[i].invMass = 1.0 / (0.1 + 0.05 * i);
    bodies[i].invI = Vec3(50.0, 40.0 + i, 30.0).asDiagonal();
    bodies[i].v = Vec3(0.1 * i, -0.05, 0.02 * (i % 3));
    bodies[i].w = Vec3(0.2, -0.1 * (i % 2), 0.05 * i);
  }
  // Joint k holds body k - 1 (the static body for k = 0) to body k, at
  // the point between them; listed as 7 k mod 20.
  std::vector<ConstraintBlock> blocks;
  std::vector<ConstraintRow> rows;
  for (int listed = 0; listed < kJoints; ++listed) {
    const int k = (7 * listed) % kJoints;
    test::addBallJointRows(bodies, staticBody, listed, k == 0 ? staticBody : k - 1, k,
                           Vec3(0.0, 0.0, -0.05), Vec3(0.0, 0.0, 0.05), 1e-4, blocks, rows);
  }
  const std::vector<std::int32_t> islandStart = {0, kJoints};
  IslandBlocks islands;
  islands.select(blocks, staticBody, islandStart, 1, 192);
  ASSERT_TRUE(islands.covers(0));
  EXPECT_EQ(islands.factorEntries(), 291u);
  islands.factorAll(blocks, rows, bodies);
  islands.solve(islands.groupsBegin(0), true, blocks, rows, bodies);
  for (const ConstraintBlock& blk : blocks) {
    for (int r = blk.firstRow; r < blk.firstRow + 3; ++r)
      EXPECT_NEAR(rowResidual(rows[r], true, bodies[blk.bodyA], bodies[blk.bodyB]), 0.0, 1e-12)
          << "joint " << blk.joint << " row " << r - blk.firstRow;
  }
  islands.select(blocks, staticBody, islandStart, 1, 192);
  ASSERT_TRUE(islands.covers(0));
  EXPECT_EQ(islands.factorEntries(), 291u);
  // Joint 10 (listed 10th: 7 x 10 mod 20 = 10) breaks.
  ASSERT_EQ(blocks[10].bodyB, 10);
  blocks[10].equality = 0;
  islands.select(blocks, staticBody, islandStart, 1, 192);
  ASSERT_TRUE(islands.covers(0));
  EXPECT_FALSE(islands.solvesEquality(10));
  EXPECT_EQ(islands.coveredRows(), 57);
  EXPECT_EQ(islands.factorEntries(), 141u + 126u);
}

// A 4 x 4 grid of bodies on ball joints (24 joints, 72 rows) with blocks
// of at most 12 rows is cut into chains: its four rows and four columns of
// three joints each, every joint in one chain, each chain's factor within
// its profile (36 entries of a 9 x 9 lower triangle's 45). One solve of a
// chain leaves every one of its rows' residuals at zero, whatever the
// other chains' impulses (their rows are not touched).
TEST(Solver, AGridIsCutIntoItsRowsAndColumnsEachSolvedExactly) {
  constexpr int kSide = 4;
  const auto bodyAt = [](int i, int j) { return kSide * i + j; };
  const std::int32_t staticBody = kSide * kSide;
  std::vector<SolverBody> bodies(kSide * kSide + 1);
  std::vector<Vec3> positions(kSide * kSide);
  for (int i = 0; i < kSide; ++i) {
    for (int j = 0; j < kSide; ++j) {
      SolverBody& b = bodies[bodyAt(i, j)];
      b.invMass = 1.0 / (0.5 + 0.1 * (i + 2 * j));
      b.invI = Vec3(40.0 + i, 30.0 + j, 20.0).asDiagonal();
      b.v = Vec3(0.1 * i, -0.2 * j, 0.05 * (i - j));
      b.w = Vec3(0.3 * j, 0.1, -0.2 * i);
      positions[bodyAt(i, j)] = Vec3(0.05 * j, 0.05 * i, 0.0);
    }
  }
  std::vector<ConstraintBlock> blocks;
  std::vector<ConstraintRow> rows;
  // Joints in the order a program makes them: each body's right, then
  // its lower neighbour.
  for (int i = 0; i < kSide; ++i) {
    for (int j = 0; j < kSide; ++j) {
      for (int down = 0; down < 2; ++down) {
        const int ni = i + down, nj = j + 1 - down;
        if (ni >= kSide || nj >= kSide) continue;
        ConstraintBlock blk;
        blk.bodyA = bodyAt(i, j);
        blk.bodyB = bodyAt(ni, nj);
        blk.firstRow = static_cast<std::int32_t>(rows.size());
        blk.equality = 3;
        blk.joint = static_cast<std::int32_t>(blocks.size());
        blocks.push_back(blk);
        const Vec3 anchor = 0.5 * (positions[blk.bodyA] + positions[blk.bodyB]);
        const Vec3 armA = anchor - positions[blk.bodyA], armB = anchor - positions[blk.bodyB];
        for (int k = 0; k < 3; ++k) {
          ConstraintRow r;
          const Vec3 axis = Vec3::Unit(k);
          r.linA = -axis;
          r.angA = -armA.cross(axis);
          r.linB = axis;
          r.angB = armB.cross(axis);
          r.invIangA = bodies[blk.bodyA].invI * r.angA;
          r.invIangB = bodies[blk.bodyB].invI * r.angB;
          r.gamma = 1e-3;
          r.bias = 0.01 * (k + 1);
          r.impulse = 0.002 * k;
          rows.push_back(r);
        }
      }
    }
  }
  ASSERT_EQ(blocks.size(), 24u);
  IslandBlocks chains;
  chains.select(blocks, staticBody, {0, 24}, 1, 12, true, &positions);
  EXPECT_FALSE(chains.covers(0)) << "72 rows are more than one block of 12";
  ASSERT_EQ(chains.groupsEnd(0) - chains.groupsBegin(0), 2 * kSide);
  for (std::int32_t bi = 0; bi < 24; ++bi)
    EXPECT_TRUE(chains.solvesEquality(bi)) << "joint " << bi;
  EXPECT_EQ(chains.factorEntries(), 2u * kSide * 36u);
  chains.factorAll(blocks, rows, bodies);
  // The joints a chain's solve moves are its own: three, on one line.
  for (int g = chains.groupsBegin(0); g < chains.groupsEnd(0); ++g) {
    const std::vector<ConstraintRow> before = rows;
    chains.solve(g, true, blocks, rows, bodies);
    std::vector<Vec3> lines;  // per moved joint: its direction, then where it lies across
    for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      if (rows[blk.firstRow].impulse == before[blk.firstRow].impulse) continue;
      for (int k = 0; k < 3; ++k) {
        const ConstraintRow& r = rows[blk.firstRow + k];
        EXPECT_NEAR(rowResidual(r, true, bodies[blk.bodyA], bodies[blk.bodyB]), 0.0, 1e-12)
            << "chain " << g << " joint " << bi << " row " << k;
      }
      const Vec3 along = positions[blk.bodyB] - positions[blk.bodyA];
      const bool horizontal = along.y() == 0.0;
      lines.push_back(Vec3(horizontal ? 1.0 : 0.0,
                           horizontal ? positions[blk.bodyA].y() : positions[blk.bodyA].x(), 0.0));
    }
    ASSERT_EQ(lines.size(), static_cast<std::size_t>(kSide - 1)) << "chain " << g;
    for (const Vec3& line : lines)
      EXPECT_EQ(line, lines.front()) << "chain " << g << " is not one straight line";
  }
}

// The swinging chain (50 links on ball joints, 150 rows, a 100x heavier
// end) one step from a stretched, moving state, by the paper's solver with
// 5 sweeps: cut into two chains of at most 120 rows (40 joints and 10) it
// ends nearer the exact step (the whole island as one block) than
// per-joint blocks: 0.084 against 0.153 m/s. (Gauss-Seidel between the
// two chains is what is left: at most 60 rows, three chains, 0.13.)
TEST(Solver, ChainBlocksCarryAPullFartherPerSweepThanJointBlocks) {
  auto velocitiesAfter = [](int islandRows, bool chains) {
    scenes::Scene scene;
    scenes::makeScene("chain_swing", scene);
    SolverSettings s = SolverSettings::subStepped(10);
    scene.world.setSettings(s);
    for (int f = 0; f < 20; ++f)
      scene.world.step(scene.frameStep);
    s = SolverSettings::paper(5);
    s.islandBlockRows = islandRows;
    s.chainBlocks = chains;
    scene.world.setSettings(s);
    scene.world.step(scene.frameStep);
    std::vector<Vec3> v;
    for (BodyId b = 0; b < static_cast<BodyId>(scene.world.bodyCount()); ++b)
      v.push_back(scene.world.body(b).linearVelocity);
    return v;
  };
  const std::vector<Vec3> exact = velocitiesAfter(192, false);
  auto farthest = [&](const std::vector<Vec3>& v) {
    double worst = 0.0;
    for (std::size_t i = 0; i < v.size(); ++i)
      worst = std::max(worst, (v[i] - exact[i]).norm());
    return worst;
  };
  const double chains = farthest(velocitiesAfter(120, true));
  const double joints = farthest(velocitiesAfter(120, false));
  std::printf("5 sweeps, largest speed off the exact step: chains %.4g m/s, joints %.4g m/s\n",
              chains, joints);
  EXPECT_LT(chains, 0.65 * joints);
}

TEST(Solver, IslandBlockTurnsALightAnchorWithHeavyParticlesAsOneBody) {
  SolverSettings perJoint = SolverSettings::subStepped(10);
  perJoint.islandBlockRows = 0;
  perJoint.runawayEnergyGain = 0.0;  // the raw per-joint solve, not the guard

  const double island = starAgainstRigidBody(SolverSettings::subStepped(10));
  const double joints = starAgainstRigidBody(perJoint);
  std::printf(
      "light anchor, ten heavier particles: angular velocity error %.3g rad/s (island "
      "block), %.3g rad/s (per-joint blocks)\n",
      island, joints);
  // dWorldStep reaches 4e-4 rad/s on demo_I (h = 0.03, 100 steps).
  EXPECT_LT(island, 1e-3);
  EXPECT_LT(island, 0.1 * joints) << "the island block is what makes the star rigid";
}

// A 1 m pendulum (a 1 kg ball of radius 5 cm on a ball joint) released
// from horizontal, 10 s at 60 Hz, sub-stepped: the energy it keeps and
// its period against the closed form of a physical pendulum,
// T = 4 sqrt(I_p / (m g L)) K(sin(theta0 / 2)).
struct PendulumRun {
  double energyKept = 0.0;  // lowest energy over the run, as a share of m g L
  double period = 0.0;      // s, mean over the whole swings seen
  double worstGap = 0.0;    // m
};

PendulumRun swingPendulum(const SolverSettings& settings) {
  World world;
  world.setSettings(settings);
  const double mass = 1.0, radius = 0.05, length = 1.0, g = 9.81;
  const BodyId bob = world.createBody(test::sphereBody(Vec3(length, 0, 0), mass, radius));
  BallJointDesc ball;
  ball.common.bodyA = kWorldBody;
  ball.common.bodyB = bob;
  ball.anchor = Vec3::Zero();
  const JointId joint = world.createJoint(ball);
  const double inertia = 0.4 * mass * radius * radius;
  auto energy = [&] {  // 0 at the start: at rest, level with the pivot
    const Body& b = world.body(bob);
    return 0.5 * mass * b.linearVelocity.squaredNorm() +
           0.5 * inertia * b.angularVelocity.squaredNorm() + mass * g * b.position.z();
  };
  PendulumRun run;
  double lowest = 0.0, lastX = length, firstCrossing = -1.0, lastCrossing = -1.0;
  int crossings = 0;
  const double h = 1.0 / 60.0;
  for (int f = 1; f <= 600; ++f) {
    world.step(h);
    lowest = std::min(lowest, energy());
    run.worstGap = std::max(run.worstGap, world.jointError(joint).linear);
    // The bob passes x = 0 going the way it started (-x) once a period.
    const double x = world.body(bob).position.x();
    if (lastX > 0.0 && x <= 0.0) {
      const double t = (f - 1 + lastX / (lastX - x)) * h;
      if (firstCrossing < 0.0) firstCrossing = t;
      lastCrossing = t;
      ++crossings;
    }
    lastX = x;
  }
  run.energyKept = 1.0 + lowest / (mass * g * length);
  run.period = crossings > 1 ? (lastCrossing - firstCrossing) / (crossings - 1) : 0.0;
  return run;
}

TEST(Solver, SubsteppedPendulumKeepsItsEnergyAndTheClosedFormPeriod) {
  const double mass = 1.0, radius = 0.05, length = 1.0, g = 9.81;
  const double pivotInertia = 0.4 * mass * radius * radius + mass * length * length;
  const double K = 1.8540746773013719;  // K(sin 45 deg), the complete elliptic integral
  const double closedForm = 4.0 * std::sqrt(pivotInertia / (mass * g * length)) * K;
  struct Case {
    const char* name;
    int relaxIterations;
    bool relaxCancelsDrift;
  };
  for (const Case c : {Case{"no relax", 0, false}, Case{"relax (the preset)", 1, false},
                       Case{"relax cancelling drift", 1, true}}) {
    SolverSettings s = SolverSettings::subStepped(10);
    s.relaxIterations = c.relaxIterations;
    s.relaxCancelsDrift = c.relaxCancelsDrift;
    const PendulumRun run = swingPendulum(s);
    std::printf(
        "1 m pendulum from horizontal, 10 s, 10 sub-steps, %s: energy kept %.4f, period %.4f s "
        "(closed form %.4f s), joint gap %.3g mm\n",
        c.name, run.energyKept, run.period, closedForm, 1e3 * run.worstGap);
    SCOPED_TRACE(c.name);
    // The ball joint's spring acts on its block as a whole: with one
    // gamma per world axis (from each row's K_ii) the rod was 500 times
    // softer across the axes, and under relax it opened 69 mm and kept 9%.
    EXPECT_LT(run.worstGap, 1e-3);
    // Relax that targets J v = 0 drains about (w h)^2 a sub-step (see
    // Solver::relaxAgainstDrift), and the swing's period shortens as it
    // decays; the other two keep the energy and the closed-form period.
    const bool drains = c.relaxIterations > 0 && !c.relaxCancelsDrift;
    EXPECT_GT(run.energyKept, drains ? 0.85 : c.relaxIterations > 0 ? 0.97 : 0.99);
    EXPECT_NEAR(run.period, closedForm, (drains ? 0.02 : 0.003) * closedForm);
  }
}

// A chain along x from a world pin at `pin`: body i is linkOf(i), on a
// ball joint at pin + i * spacing along x to the one before it.
struct BallChain {
  std::vector<BodyId> links;
  std::vector<JointId> joints;
};
template <class LinkOf>
BallChain horizontalBallChain(World& world, int count, const Vec3& pin, double spacing,
                              LinkOf linkOf) {
  BallChain chain;
  BodyId previous = kWorldBody;
  for (int i = 0; i < count; ++i) {
    const BodyId link = world.createBody(linkOf(i));
    BallJointDesc ball;
    ball.common.bodyA = previous;
    ball.common.bodyB = link;
    ball.anchor = pin + Vec3(spacing * i, 0, 0);
    chain.joints.push_back(world.createJoint(ball));
    chain.links.push_back(link);
    previous = link;
  }
  return chain;
}

// The chain that flew apart at 3e8 m/s under the plugin: 40 light spheres
// on ball joints ending in one 100 times heavier, released horizontally.
TEST(Solver, HeavyEndChainReleasedHorizontallyHolds) {
  World world;
  world.setSettings(SolverSettings::subStepped(10));
  const double length = 0.05;
  const auto [links, joints] = horizontalBallChain(world, 40, Vec3(0, 0, 2), length, [&](int i) {
    return test::sphereBody(Vec3(length * (i + 1), 0, 2), i == 39 ? 10.0 : 0.1, 0.02);
  });
  double worst = 0.0, fastest = 0.0;
  for (int f = 0; f < 300; ++f) {
    world.step(1.0 / 60.0);
    for (JointId j : joints)
      worst = std::max(worst, world.jointError(j).linear);
    for (BodyId b : links)
      fastest = std::max(fastest, world.body(b).linearVelocity.norm());
  }
  std::printf(
      "40-link chain, 100:1 end, released horizontally: worst gap %.3g mm, fastest link "
      "%.3g m/s\n",
      1e3 * worst, fastest);
  EXPECT_LT(worst, 1e-3);
  // Free fall of the heavy end from 2 m of chain gives about 9 m/s; the
  // whip's light links go a little faster, nothing runs away.
  EXPECT_LT(fastest, 30.0);
}

// Post-stabilization (SolverSettings::positionProjections): a chain of
// ten 0.1 kg balls on ball joints, released horizontally, at one
// sub-step of 1/60 s. The velocity solve is linear in the bodies' motion,
// so each step opens the turning joints by about r (w h)^2 / 2 and the
// push-back leaves errors of that size; projected, the step's last pose
// closes them to the second order of what the projection moved. What
// the projection lifts against gravity the bodies' speed pays, along the
// moves: from one state, a step with it and one without leave velocities
// apart by one share alpha of the moves' own velocity, and no more energy
// than the lift; an island resting on the ground keeps its velocities.
TEST(Solver, PositionProjectionClosesAOneSubstepChainAndPaysForItsLift) {
  auto chainWorld = [](int projections) {
    auto world = std::make_unique<World>();
    SolverSettings s = SolverSettings::subStepped(1);
    s.positionProjections = projections;
    s.projectionTolerance = 0.0;  // every step (the preset's 1 mm: below)
    world->setSettings(s);
    BodyId previous = kWorldBody;
    for (int i = 0; i < 10; ++i) {
      const BodyId link = world->createBody(test::sphereBody(Vec3(0.1 * (i + 1), 0, 2), 0.1, 0.02));
      BallJointDesc ball;
      ball.common.bodyA = previous;
      ball.common.bodyB = link;
      ball.anchor = Vec3(0.1 * i, 0, 2);
      world->createJoint(ball);
      previous = link;
    }
    return world;
  };
  auto worstGap = [](World& world, int frames) {
    double worst = 0.0;
    for (int f = 0; f < frames; ++f) {
      world.step(1.0 / 60.0);
      for (JointId j = 0; j < 10; ++j)
        worst = std::max(worst, world.jointError(j).linear);
    }
    return worst;
  };
  auto plain = chainWorld(0);
  auto projected = chainWorld(1);
  auto twice = chainWorld(2);
  const double plainGap = worstGap(*plain, 120);
  const double projectedGap = worstGap(*projected, 120);
  const double twiceGap = worstGap(*twice, 120);
  std::printf(
      "10-ball chain released horizontally, one 1/60 s sub-step a frame, 2 s: worst gap %.3g mm "
      "plain, %.3g mm projected once, %.3g mm twice\n",
      1e3 * plainGap, 1e3 * projectedGap, 1e3 * twiceGap);
  EXPECT_GT(plainGap, 5e-3);
  EXPECT_LT(projectedGap, 0.02 * plainGap);
  EXPECT_LT(twiceGap, projectedGap);

  // From the plain chain's state, a fresh world each way, one step.
  auto takeState = [&](World& w, BodyId b) {
    w.setPosition(b, plain->body(b).position);
    w.setOrientation(b, plain->body(b).orientation);
    w.setLinearVelocity(b, plain->body(b).linearVelocity);
    w.setAngularVelocity(b, plain->body(b).angularVelocity);
  };
  auto without = chainWorld(0);
  auto with = chainWorld(1);
  for (World* w : {without.get(), with.get()}) {
    for (BodyId b = 0; b < 10; ++b)
      takeState(*w, b);
    w->step(1.0 / 60.0);
  }
  // The projection moved the bodies by dx (and turned them by dtheta);
  // their velocities differ from the unprojected step's by alpha dx / h
  // (alpha dtheta / h), one alpha for all, in (0, 1].
  const double h = 1.0 / 60.0;
  double moved = 0.0, lifted = 0.0, alpha = 0.0;
  for (BodyId b = 0; b < 10; ++b) {
    const Vec3 u = (with->body(b).position - without->body(b).position) / h;
    if (u.norm() > 1e-6)
      alpha =
          (with->body(b).linearVelocity - without->body(b).linearVelocity).dot(u) / u.squaredNorm();
  }
  for (BodyId b = 0; b < 10; ++b) {
    const Body& on = with->body(b);
    const Body& off = without->body(b);
    const Vec3 u = (on.position - off.position) / h;
    const Eigen::AngleAxisd turned(on.orientation * off.orientation.conjugate());
    const Vec3 spin = turned.angle() * turned.axis() / h;
    EXPECT_LT((on.linearVelocity - off.linearVelocity - alpha * u).norm(),
              1e-9 * off.linearVelocity.norm())
        << b;
    EXPECT_LT((on.angularVelocity - off.angularVelocity - alpha * spin).norm(),
              1e-9 * off.angularVelocity.norm() + 1e-12)
        << b;
    moved = std::max(moved, (on.position - off.position).norm());
    lifted += on.mass * 9.81 * (on.position.z() - off.position.z());
  }
  EXPECT_GT(moved, 1e-4);   // the projection did move them
  EXPECT_GT(lifted, 1e-4);  // up, onto their circles: J
  EXPECT_GT(alpha, 0.0);
  EXPECT_LE(alpha, 1.0);
  // What it lifted, paid in part by the speed along the moves (as much as
  // the velocity running against them holds): never more than the lift.
  const double paid =
      test::mechanicalEnergy(*without, 10) + lifted - test::mechanicalEnergy(*with, 10);
  std::printf("one step projected: lifted %.3g mJ, %.3g mJ of it paid (alpha %.3g)\n", 1e3 * lifted,
              1e3 * paid, alpha);
  EXPECT_GT(paid, 0.0);
  EXPECT_LE(paid, lifted * (1.0 + 1e-9));

  // An island a contact holds does not pay (its moves' velocity went into
  // its contacts): with the lowest ball resting on the ground, the
  // projected step moves the balls and leaves the unprojected step's
  // velocities, bit for bit.
  BodyId lowest = 0;
  for (BodyId b = 0; b < 10; ++b)
    if (plain->body(b).position.z() < plain->body(lowest).position.z()) lowest = b;
  auto touchingWithout = chainWorld(0);
  auto touchingWith = chainWorld(1);
  for (World* w : {touchingWithout.get(), touchingWith.get()}) {
    for (BodyId b = 0; b < 10; ++b) {
      takeState(*w, b);
      w->addShape(Shape::sphere(b, 0.02));
    }
    w->addShape(Shape::plane(Vec3::UnitZ(), plain->body(lowest).position.z() - 0.019));
    w->step(h);
  }
  double touchedMove = 0.0;
  for (BodyId b = 0; b < 10; ++b) {
    EXPECT_EQ(touchingWith->body(b).linearVelocity, touchingWithout->body(b).linearVelocity) << b;
    EXPECT_EQ(touchingWith->body(b).angularVelocity, touchingWithout->body(b).angularVelocity) << b;
    touchedMove = std::max(
        touchedMove, (touchingWith->body(b).position - touchingWithout->body(b).position).norm());
  }
  EXPECT_FALSE(touchingWith->contacts().empty());
  EXPECT_GT(touchedMove, 1e-4);  // the projection did move them

  // With a tolerance, an island already that close is left as it is: the
  // worst row stays within it (a ball joint's gap within sqrt(3) of it),
  // and a step whose rows close within it is the unprojected step, bit
  // for bit.
  const double tolerance = 5e-4;
  auto tolerant = chainWorld(1);
  SolverSettings s = tolerant->settings();
  s.projectionTolerance = tolerance;
  tolerant->setSettings(s);
  const double tolerantGap = worstGap(*tolerant, 120);
  std::printf("the same with projections only past %.3g mm: worst gap %.3g mm\n", 1e3 * tolerance,
              1e3 * tolerantGap);
  EXPECT_LT(tolerantGap, std::sqrt(3.0) * tolerance);
  EXPECT_GT(tolerantGap, 2.0 * projectedGap);  // it did leave some steps alone
  // The chain's first two steps from rest open it by micrometres.
  auto unprojected = chainWorld(0);
  auto everyStep = chainWorld(1);
  auto pastTolerance = chainWorld(1);
  pastTolerance->setSettings(s);
  for (World* w : {unprojected.get(), everyStep.get(), pastTolerance.get()})
    test::stepN(*w, 2, 1.0 / 60.0);
  bool projectionMoved = false;
  for (BodyId b = 0; b < 10; ++b) {
    EXPECT_EQ(pastTolerance->body(b).position, unprojected->body(b).position);
    projectionMoved |= everyStep->body(b).position != unprojected->body(b).position;
  }
  EXPECT_TRUE(projectionMoved);  // without the tolerance those steps are projected
}

// The compare runner's chain_heavy_swing in the core: fifty 0.1 kg rods
// on ball joints ending in a 100 kg weight (1000:1), released horizontally
// from a pin, projected at one sub-step of 1/60 s. Where the light links
// turn over a radian a step, the joints' linearization lets the weight's
// velocity run against the chain; the projection puts it back every
// step, and while it moved positions only, gravity went on speeding the
// weight for nothing: the chain ended with about fifty times the energy
// of its fall. Its speed now pays for what the projection lifts.
TEST(Solver, PositionProjectionGivesAHeavyEndedChainNoEnergy) {
  World world;
  SolverSettings s = SolverSettings::subStepped(1);
  s.positionProjections = 1;
  s.projectionTolerance = 0.0;
  world.setSettings(s);
  const double length = 0.1;
  const auto [links, joints] = horizontalBallChain(world, 50, Vec3(0, 0, 6), length, [&](int i) {
    return test::boxBody(Vec3(length * (i + 0.5), 0, 6), i == 49 ? 100.0 : 0.1,
                         Vec3(0.1, 0.02, 0.02));
  });
  const int n = static_cast<int>(links.size());
  const double start = test::mechanicalEnergy(world, n);
  const double fall = 100.0 * 9.81 * 5.0;  // J, the weight's drop to below the pin
  double rise = 0.0, worst = 0.0;
  for (int f = 0; f < 600; ++f) {
    world.step(1.0 / 60.0);
    rise = std::max(rise, test::mechanicalEnergy(world, n) - start);
    for (JointId j : joints)
      worst = std::max(worst, world.jointError(j).linear);
  }
  std::printf(
      "50 rods, 100 kg end, released horizontally, one sub-step projected: energy above the "
      "start at most %.3g J (of %.0f J of fall), worst gap %.3g mm\n",
      rise, fall, 1e3 * worst);
  EXPECT_LT(rise, 0.01 * fall);
  EXPECT_LT(worst, 0.01);
}

// A whip of thin links (SCENES.md's chain_swing): fifty 0.1 kg rods of
// 0.1 m on ball joints, the last 10 kg, released horizontally from a pin,
// at one sub-step of 1/60 s. Its light links turn fast; projected with
// the bodies' own inertia as the metric, the smallest correction turned
// them (their inertia makes that cheap), the turns' second-order opening
// outgrew what each pass closed, and the chain tore (9 m at 300 frames).
// With turns priced as the island's size (Solver::kProjectionReach) the
// step's pose closes to within a tenth of a millimetre, and the chain
// never has more energy than it started with (what the projection lifts,
// its speed along the moves pays for where it can).
TEST(Solver, PositionProjectionHoldsAWhipOfThinLinks) {
  auto whip = [](int projections, double& worstGap, double& energyRise) {
    World world;
    SolverSettings s = SolverSettings::subStepped(1);
    s.positionProjections = projections;
    s.projectionTolerance = 0.0;  // every step
    world.setSettings(s);
    const double length = 0.1;
    const auto [links, joints] = horizontalBallChain(world, 50, Vec3(0, 0, 6), length, [&](int i) {
      return test::boxBody(Vec3(length * (i + 0.5), 0, 6), i == 49 ? 10.0 : 0.1,
                           Vec3(0.1, 0.02, 0.02));
    });
    const int n = static_cast<int>(links.size());
    auto energy = [&] { return test::mechanicalEnergy(world, n); };
    const double start = energy();
    worstGap = 0.0;
    energyRise = 0.0;
    for (int f = 0; f < 300; ++f) {
      world.step(1.0 / 60.0);
      for (JointId j : joints)
        worstGap = std::max(worstGap, world.jointError(j).linear);
      energyRise = std::max(energyRise, energy() - start);
    }
  };
  double plainGap = 0.0, plainRise = 0.0, projectedGap = 0.0, projectedRise = 0.0;
  whip(0, plainGap, plainRise);
  whip(1, projectedGap, projectedRise);
  std::printf(
      "50 thin links, 10 kg end, released horizontally, one sub-step: worst gap %.3g mm plain, "
      "%.3g mm projected; energy above the start at most %.3g J and %.3g J (of %.0f J of fall)\n",
      1e3 * plainGap, 1e3 * projectedGap, plainRise, projectedRise, 10.0 * 9.81 * 5.0);
  EXPECT_GT(plainGap, 0.1);  // unprojected, one sub-step tears it
  EXPECT_LT(projectedGap, 1e-3);
  EXPECT_LT(projectedRise, 1e-3 * 10.0 * 9.81 * 5.0);
}

// Only the rows made rigid in an island block are projected: a joint
// given a physical spring keeps the stretch its load gives it. Five 0.1 kg
// balls hang from a pin on ball joints, the third joint a spring of
// 50 N/m (well damped) carrying the three balls below it: 3 m g / k =
// 58.9 mm at rest, projected or not, and the rigid joints stay closed.
TEST(Solver, PositionProjectionLeavesASpringJointsStretch) {
  auto hang = [](int projections, double& springStretch, double& rigidGap) {
    World world;
    SolverSettings s = SolverSettings::subStepped(2);
    s.positionProjections = projections;
    world.setSettings(s);
    BodyId previous = kWorldBody;
    std::vector<JointId> joints;
    for (int i = 0; i < 5; ++i) {
      const BodyId ball =
          world.createBody(test::sphereBody(Vec3(0, 0, 2 - 0.1 * (i + 1)), 0.1, 0.02));
      BallJointDesc joint;
      joint.common.bodyA = previous;
      joint.common.bodyB = ball;
      joint.anchor = Vec3(0, 0, 2 - 0.1 * i);
      if (i == 2) joint.common.softness = Softness::springDamper(50.0, 2.0);
      joints.push_back(world.createJoint(joint));
      previous = ball;
    }
    for (int f = 0; f < 240; ++f)
      world.step(1.0 / 60.0);
    springStretch = world.jointError(joints[2]).linear;
    rigidGap = 0.0;
    for (int i : {0, 1, 3, 4})
      rigidGap = std::max(rigidGap, world.jointError(joints[i]).linear);
  };
  double plainStretch = 0.0, plainGap = 0.0, projectedStretch = 0.0, projectedGap = 0.0;
  hang(0, plainStretch, plainGap);
  hang(1, projectedStretch, projectedGap);
  std::printf(
      "spring joint under three 0.1 kg balls: stretch %.4f mm plain, %.4f mm projected (3 m g / k "
      "= %.4f mm); rigid joints %.3g and %.3g mm\n",
      1e3 * plainStretch, 1e3 * projectedStretch, 1e3 * 3 * 0.1 * 9.81 / 50.0, 1e3 * plainGap,
      1e3 * projectedGap);
  EXPECT_NEAR(plainStretch, 3 * 0.1 * 9.81 / 50.0, 1e-3);
  EXPECT_NEAR(projectedStretch, plainStretch, 1e-6);
  EXPECT_LT(projectedGap, 1e-6);
}

// Planks of ODE's demo_feedback bridge (0.9 x 4 x 0.1 m, 0.36 kg) from x0
// along x at 5 m, on hinges whose motors hold them (target 0, 8000 N m at
// most); the first plank (and the last, if bothEnds) on a slider along
// the span with a 4000 N motor, the first with stops [0, 0.2] m.
std::vector<BodyId> motorHeldPlanks(World& world, int planks, double x0, bool bothEnds) {
  std::vector<BodyId> bodies;
  for (int i = 0; i < planks; ++i)
    bodies.push_back(world.createBody(boxBody(Vec3(x0 + i, 0, 5), 0.36, Vec3(0.9, 4, 0.1))));
  for (int i = 0; i + 1 < planks; ++i) {
    HingeJointDesc hinge;
    hinge.common.bodyA = bodies[i];
    hinge.common.bodyB = bodies[i + 1];
    hinge.anchor = Vec3(x0 + i + 0.5, 0, 5);
    hinge.axis = Vec3::UnitY();
    hinge.motor.maxForce = 8000.0;
    world.createJoint(hinge);
  }
  for (int end = 0; end < (bothEnds ? 2 : 1); ++end) {
    SliderJointDesc slider;
    slider.common.bodyA = bodies[end == 0 ? 0 : planks - 1];
    slider.axis = Vec3::UnitX();
    slider.motor.maxForce = 4000.0;
    slider.limit.enabled = end == 0;
    slider.limit.hi = 0.2;
    world.createJoint(slider);
  }
  return bodies;
}

// ODE's demo_feedback bridge: 16 planks on hinges whose motors hold them
// (target 0, 8000 N m at most), its ends on sliders along the span. The
// motors make the bridge one rigid beam, as ODE's dWorldStep holds it
// (2e-15 J). Each motor solved in the null space of its own joint only
// overshot what the island's equality block then took back: the bridge
// shook (1e-3 J), calmed, then gained energy again from 3e-7 to 6e-5 J
// over 70 steps, and ran away once a weight landed on it. At one or two
// sub-steps one pass over the motors a sweep lagged behind their coupling
// through the beam: it swung up to 0.068 J (one sub-step) and 0.037 J
// (two, caught by the runaway guard) before the passes per step
// (Solver::kMotorPassesPerStep). It sags 1.16, 0.61 and 0.21 mm at 1,
// 2 and 10 sub-steps, as the joints' softness (ODE's CFM) gives at those
// sub-steps.
TEST(Solver, MotorHeldBridgeInOneIslandBlockStaysStill) {
  for (const int substeps : {1, 2, 10}) {
    World world;
    world.setSettings(SolverSettings::subStepped(substeps));
    world.setGravity(Vec3(0, 0, -9.8));
    const int planks = 16;
    const std::vector<BodyId> bridge = motorHeldPlanks(world, planks, -planks / 2.0, true);
    double settled = 0.0, sag = 0.0;
    for (int step = 0; step < 400; ++step) {
      world.step(0.002);
      ASSERT_TRUE(world.lastStepStats().runaways.empty())
          << substeps << " sub-steps, step " << step;
      double energy = 0.0;
      for (BodyId b : bridge)
        energy += kineticEnergy(world.body(b));
      if (step >= 200) settled = std::max(settled, energy);
      sag = std::max(sag, 5.0 - world.body(bridge[planks / 2]).position.z());
    }
    std::printf(
        "motor-held bridge, %d sub-steps: kinetic energy after 0.4 s at most %.3g J, sag %.3g mm\n",
        substeps, settled, 1e3 * sag);
    EXPECT_LT(settled, 1e-6) << substeps << " sub-steps";
    EXPECT_LT(sag, 1.5e-3) << substeps << " sub-steps";
  }
}

// The runaway guard: per-joint blocks diverge on the star; the island is
// put back as it was before the step that ran away, named, and the rest
// of the world keeps its step.
TEST(RunawayGuard, DivergingIslandIsPutBackAndNamed) {
  World world;
  world.setGravity(Vec3::Zero());
  SolverSettings s = SolverSettings::subStepped(10);
  s.islandBlockRows = 0;
  s.gyroscopic = true;
  world.setSettings(s);
  const BodyId hub = world.createBody(boxBody(Vec3(0, 0, 1), 0.1, Vec3(0.15, 0.15, 0.15)));
  std::vector<BodyId> star{hub};
  for (int i = 0; i < 10; ++i) {
    const Vec3 offset(0.3 * std::cos(1.7 * i), 0.3 * std::sin(2.3 * i), 0.25 * std::cos(0.9 * i));
    star.push_back(world.createBody(test::sphereBody(Vec3(0, 0, 1) + offset, 0.1 + 0.1 * i, 0.05)));
    BallJointDesc ball;
    ball.common.bodyA = hub;
    ball.common.bodyB = star.back();
    ball.anchor = world.body(star.back()).position;
    world.createJoint(ball);
  }
  // A body far away, falling on its own: its own group, never caught.
  const BodyId faller = world.createBody(boxBody(Vec3(5, 0, 0), 1.0, Vec3(0.1, 0.1, 0.1)));
  world.setLinearVelocity(faller, Vec3(0, 0, 1));

  int caughtAt = -1;
  double spinWhenCaught = 0.0;
  for (int step = 0; step < 100 && caughtAt < 0; ++step) {
    std::vector<Body> before;
    for (BodyId b : star)
      before.push_back(world.body(b));
    const Vec3 fallerBefore = world.body(faller).position;
    world.addTorque(hub, Vec3(0.03, -0.02, 0.045));
    world.step(0.03);
    EXPECT_NEAR((world.body(faller).position - fallerBefore).z(), 0.03, 1e-12)
        << "an island that did not run away keeps its step";
    const StepStats& stats = world.lastStepStats();
    if (stats.runaways.empty()) continue;
    caughtAt = step;
    ASSERT_EQ(stats.runaways.size(), 1u);
    const RunawayIsland& r = stats.runaways[0];
    EXPECT_FALSE(r.nonFinite);
    EXPECT_EQ(r.bodyCount, 11);
    EXPECT_EQ(r.jointCount, 10);
    EXPECT_GT(r.growth, 100.0);
    EXPECT_GT(r.energyAfter, r.energyExplained);
    EXPECT_NE(std::find(star.begin(), star.end(), r.culprit), star.end());
    for (std::size_t k = 0; k < star.size(); ++k) {
      EXPECT_EQ(world.body(star[k]).position, before[k].position);
      EXPECT_EQ(world.body(star[k]).angularVelocity, before[k].angularVelocity);
    }
    spinWhenCaught = world.body(hub).angularVelocity.norm();
  }
  std::printf("per-joint star caught at step %d, anchor at %.3g rad/s\n", caughtAt, spinWhenCaught);
  ASSERT_GE(caughtAt, 0) << "the per-joint star diverges: the guard must catch it";
  // Caught early: the anchor turns at a few rad/s, not the 1e15 it reaches.
  EXPECT_LT(spinWhenCaught, 10.0);
}

// Half of ODE's demo_feedback bridge after a joint snapped: eight planks
// held straight by hinge motors, one end on a slider, the other free,
// struck from below. It rings and its kinetic energy nearly vanishes at
// each turning point before coming back (0.001 J, then 0.156 J one 2 ms
// step later): energy returning to its recent peak is not a runaway. The
// guard used to hand it to ODE's stepper.
TEST(RunawayGuard, RingingStructureIsNotARunaway) {
  World world;
  world.setSettings(SolverSettings::subStepped(10));
  world.setGravity(Vec3(0, 0, -9.8));
  const std::vector<BodyId> half = motorHeldPlanks(world, 8, -8.0, false);
  world.setLinearVelocity(half.back(), Vec3(0, 0, 3.0));
  double first = 0.0, last = 0.0;
  int turningPoints = 0;
  double previous = kInf;
  bool falling = false;
  for (int step = 0; step < 500; ++step) {
    world.step(0.002);
    EXPECT_TRUE(world.lastStepStats().runaways.empty()) << "step " << step;
    double energy = 0.0;
    for (BodyId b : half)
      energy += kineticEnergy(world.body(b));
    if (step == 0) first = energy;
    if (falling && energy > previous) ++turningPoints;
    falling = energy < previous;
    previous = last = energy;
  }
  std::printf(
      "ringing half bridge: kinetic energy %.3g J after the strike, %.3g J 1 s later, %d "
      "turning points\n",
      first, last, turningPoints);
  EXPECT_GT(turningPoints, 3) << "the scene must ring to test the guard";
  EXPECT_LT(last, first) << "ringing, not gaining";
}

// A state that turns non-finite within the step (a finite torque too large
// for the body) is caught whatever the limits, the island put back.
TEST(RunawayGuard, NonFiniteStateIsPutBackAndNamed) {
  World world;
  SolverSettings s = SolverSettings::paper(10);
  s.runawayEnergyGain = 0.0;  // off: non-finite states are caught anyway
  world.setSettings(s);
  const BodyId spun = world.createBody(boxBody(Vec3(0, 0, 1), 1e-3, Vec3(0.01, 0.01, 0.01)));
  const BodyId other = world.createBody(boxBody(Vec3(3, 0, 1), 1.0, Vec3(0.1, 0.1, 0.1)));
  world.addTorque(spun, Vec3(1e305, 0, 0));
  world.step(1.0 / 60.0);
  const StepStats& stats = world.lastStepStats();
  ASSERT_EQ(stats.runaways.size(), 1u);
  EXPECT_TRUE(stats.runaways[0].nonFinite);
  EXPECT_EQ(stats.runaways[0].culprit, spun);
  EXPECT_EQ(world.body(spun).position, Vec3(0, 0, 1));
  EXPECT_TRUE(world.body(spun).angularVelocity.allFinite());
  EXPECT_LT(world.body(other).position.z(), 1.0) << "the other body fell";
  world.step(1.0 / 60.0);  // the torque was used up: a normal step
  EXPECT_TRUE(world.lastStepStats().runaways.empty());
}

}  // namespace
}  // namespace blockstep

namespace blockstep::test {
namespace {

// A box at the origin spinning about z at `rate` rad/s, hinged to the
// world about z (or free), in a world without gravity. With an offset the
// hinge's axis passes that far along x from the box's centre, which then
// circles it (its anchor turns with the box: the turn asks for sub-steps;
// about an axis through the centre it would not).
BodyId spinningBox(World& world, const SolverSettings& s, double rate, bool hinged,
                   const Limit& limit = {}, double offset = 0.0) {
  world.setGravity(Vec3::Zero());
  world.setSettings(s);
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.4, 0.2, 0.1)));
  if (hinged) {
    HingeJointDesc hinge;
    hinge.common.bodyB = box;
    hinge.anchor = Vec3(offset, 0, 0);
    hinge.axis = Vec3::UnitZ();
    hinge.limit = limit;
    world.createJoint(hinge);
  }
  const Vec3 w(0, 0, rate);
  world.setAngularVelocity(box, w);
  world.setLinearVelocity(box, w.cross(Vec3(-offset, 0, 0)));
  return box;
}

// The sub-step count a step of a world with one such box, hinged 5 cm
// off its centre, takes once the solver has seen it turn (its second
// step).
int substepsWhileSpinning(double rate, bool hinged, double maxTurn, double offset = 0.05) {
  World world;
  SolverSettings s = SolverSettings::subStepped(10);
  s.maxTurnPerSubstep = maxTurn;
  const BodyId box = spinningBox(world, s, rate, hinged, {}, offset);
  world.step(1.0 / 60.0);
  EXPECT_EQ(world.lastStepStats().substeps, 10) << "the first step has seen no turn yet";
  world.step(1.0 / 60.0);
  // A hinge through the centre leaves the spin about its axis alone, at
  // any sub-step count.
  if (offset == 0.0) {
    EXPECT_NEAR(world.body(box).angularVelocity.z(), rate, 1e-9 * rate);
  }
  return world.lastStepStats().substeps;
}

// A step runs as many sub-steps as keep a constrained body's turn within
// maxTurnPerSubstep per sub-step (ceil(rate h / turn)), at least the
// nominal count and at most maxSubstepFactor times it; a body no joint or
// contact holds turns freely at the nominal count.
TEST(Solver, SubstepsFollowHowFastAJointedBodyTurns) {
  const double h = 1.0 / 60.0, turn = SolverSettings::kMaxTurnPerSubstep;
  EXPECT_EQ(substepsWhileSpinning(30.0, true, turn), 10);  // 0.05 rad a sub-step
  EXPECT_EQ(substepsWhileSpinning(150.0, true, turn), static_cast<int>(std::ceil(150 * h / turn)));
  EXPECT_EQ(substepsWhileSpinning(1000.0, true, turn), 40);  // four times the nominal, at most
  EXPECT_EQ(substepsWhileSpinning(150.0, false, turn), 10);  // free
  EXPECT_EQ(substepsWhileSpinning(150.0, true, 0.0), 10);    // off
  // A wheel: turning about its hinge's axis through its centre leaves the
  // hinge's rows as they were.
  EXPECT_EQ(substepsWhileSpinning(150.0, true, turn, 0.0), 10);
}

// A 10 cm rod hung from the world by a ball joint at its top end, in a
// world without gravity, spinning at 150 rad/s about `spin`: the
// sub-steps its second step takes.
int substepsOfASpinningRod(const Vec3& spin) {
  World world;
  world.setGravity(Vec3::Zero());
  world.setSettings(SolverSettings::subStepped(10));
  const BodyId rod = world.createBody(boxBody(Vec3(0, 0, -0.05), 0.01, Vec3(0.01, 0.01, 0.1)));
  BallJointDesc joint;
  joint.common.bodyB = rod;
  joint.anchor = Vec3(0, 0, 0);
  world.createJoint(joint);
  // Turning about the anchor, as the joint holds it.
  const Vec3 w = 150.0 * spin.normalized();
  world.setAngularVelocity(rod, w);
  world.setLinearVelocity(rod, w.cross(Vec3(0, 0, -0.05)));
  world.step(1.0 / 60.0);
  world.step(1.0 / 60.0);
  return world.lastStepStats().substeps;
}

// A turn about the line through a body's centre of mass and its ball
// joint's anchor moves the anchor not at all, so it asks for no more
// sub-steps; the part of the turn across that line does (150 rad/s at
// 0.1 rad a 1/600 s sub-step: 25; tilted 45 degrees, 106 rad/s across:
// 18).
TEST(Solver, SpinAboutTheLineThroughABallJointsAnchorAsksForNoMoreSubsteps) {
  EXPECT_EQ(substepsOfASpinningRod(Vec3::UnitZ()), 10);
  EXPECT_EQ(substepsOfASpinningRod(Vec3::UnitX()), 25);
  EXPECT_EQ(substepsOfASpinningRod(Vec3(1, 0, 1)), 18);
}

// Two islands in one world (support/two_islands.h): a box circling a
// hinge (25 sub-steps a step) and a slow pendulum (10). Each island takes
// its own count and moves exactly as it does alone in a world, on one
// thread or two; with one count for the world the pendulum took the
// box's 25.
TEST(Solver, EachIslandTakesTheSubstepsItsOwnTurnAsksFor) {
  struct Poses {
    Vec3 box, boxSpin, bob, bobVelocity;
    int substeps = 0;
  };
  auto run = [](bool withBox, bool withPendulum, int threads = 1) {
    World world;
    SolverSettings s = SolverSettings::subStepped(10);
    s.threads = threads;
    world.setSettings(s);
    const BodyId box = withBox ? circlingBox(world) : -1;
    const BodyId bob = withPendulum ? slowPendulum(world) : -1;
    Poses p;
    for (int i = 0; i < 30; ++i) {
      world.step(1.0 / 60.0);
      p.substeps = std::max(p.substeps, world.lastStepStats().substeps);
    }
    if (box >= 0) {
      p.box = world.body(box).position;
      p.boxSpin = world.body(box).angularVelocity;
    }
    if (bob >= 0) {
      p.bob = world.body(bob).position;
      p.bobVelocity = world.body(bob).linearVelocity;
    }
    return p;
  };
  const Poses both = run(true, true), box = run(true, false), pendulum = run(false, true);
  EXPECT_EQ(box.substeps, 25);
  EXPECT_EQ(pendulum.substeps, 10);
  EXPECT_EQ(both.substeps, 25);
  EXPECT_EQ(both.box, box.box);
  EXPECT_EQ(both.boxSpin, box.boxSpin);
  EXPECT_EQ(both.bob, pendulum.bob);
  EXPECT_EQ(both.bobVelocity, pendulum.bobVelocity);
  EXPECT_GT(pendulum.bobVelocity.norm(), 0.5);  // it does swing
  // And on two threads (each class's islands shared out), the same bits.
  const Poses twoThreads = run(true, true, 2);
  EXPECT_EQ(twoThreads.box, both.box);
  EXPECT_EQ(twoThreads.bob, both.bob);
  EXPECT_EQ(twoThreads.bobVelocity, both.bobVelocity);
}

// ODE's demo_I star (a 0.1 kg hub carrying ten heavier balls on ball
// joints at their centres) spinning free at 3 rad/s, 600 steps of 1/60 s,
// its island solved exactly at one sub-step a step: projected as SHAKE
// projects (Solver::kShakeTurn), it keeps its energy (99.9%). Relax at
// one sub-step and the bare projection took about (w h)^2 of it a step,
// 0.25% here, and kept 44% (ten sub-steps a step keep 88%).
TEST(Solver, AStarSolvedExactlyAtOneSubstepKeepsItsEnergy) {
  struct Spin {
    double kept = 0.0, worstGap = 0.0;
    int substeps = 0;
  };
  auto spin = [](int exactSubsteps) {
    World world;
    world.setGravity(Vec3::Zero());
    SolverSettings s = SolverSettings::subStepped(10);
    s.exactJointIslandSubsteps = exactSubsteps;
    world.setSettings(s);
    const Vec3 centre(0, 0, 1), w(1.2, -0.9, 2.6);  // |w| = 3 rad/s
    const BodyId hub = world.createBody(boxBody(centre, 0.1, Vec3(0.15, 0.15, 0.15)));
    world.setAngularVelocity(hub, w);
    std::vector<BodyId> balls;
    std::vector<Vec3> offsets;
    for (int i = 0; i < 10; ++i) {
      const Vec3 offset(0.3 * std::cos(1.7 * i), 0.3 * std::sin(2.3 * i), 0.25 * std::cos(0.9 * i));
      balls.push_back(world.createBody(test::sphereBody(centre + offset, 0.1 + 0.1 * i, 0.05)));
      world.setLinearVelocity(balls.back(), w.cross(offset));
      world.setAngularVelocity(balls.back(), w);
      BallJointDesc ball;
      ball.common.bodyA = hub;
      ball.common.bodyB = balls.back();
      ball.anchor = centre + offset;
      world.createJoint(ball);
      offsets.push_back(world.body(hub).orientation.conjugate() * offset);
    }
    auto energy = [&] {
      double e = test::kineticEnergy(world.body(hub));
      for (const BodyId b : balls)
        e += test::kineticEnergy(world.body(b));
      return e;
    };
    const double start = energy();
    Spin out;
    for (int step = 0; step < 600; ++step) {
      world.step(1.0 / 60.0);
      out.substeps = world.lastStepStats().substeps;
      const Body& h = world.body(hub);
      for (std::size_t i = 0; i < balls.size(); ++i) {
        const Vec3 anchor = h.position + h.orientation * offsets[i];
        out.worstGap = std::max(out.worstGap, (world.body(balls[i]).position - anchor).norm());
      }
    }
    out.kept = energy() / start;
    return out;
  };
  const Spin exact = spin(1), nominal = spin(0);
  std::printf(
      "star spinning at 3 rad/s, 600 steps: at 1 sub-step energy kept %.4f, gap %.3g mm; at "
      "10: %.4f, gap %.3g mm\n",
      exact.kept, 1e3 * exact.worstGap, nominal.kept, 1e3 * nominal.worstGap);
  EXPECT_EQ(exact.substeps, 1);
  EXPECT_EQ(nominal.substeps, 10);
  EXPECT_NEAR(exact.kept, 1.0, 0.005);
  EXPECT_LT(exact.worstGap, 1e-3);
  EXPECT_LT(nominal.worstGap, 1e-3);
}

// An island solved exactly (its joints one island block, projected at the
// step's end, touching nothing) takes exactJointIslandSubsteps from its second
// step, and the nominal count again once a contact holds it: ten spheres
// on ball joints released horizontally from a pin 1 m above a plane at
// 0.3 m swing down until their end reaches the plane. While they swing
// at one sub-step a frame their joints stay closed (the projection), and
// the same chain at the nominal ten loses less of its energy: where its
// links turn past Solver::kShakeTurn in a step (the fastest frames of the
// swing), relax at the whole step takes about (w h)^2 of their kinetic
// energy a step (0.153 J lost while free, 0.235 J before slower turns
// were projected as SHAKE projects; 0.036 J at ten sub-steps).
TEST(Solver, AnIslandSolvedExactlyTakesItsOwnSubstepsUntilAContactHoldsIt) {
  struct Swing {
    int firstSubsteps = 0, freeSubsteps = 0, touchingSubsteps = 0;
    int framesFree = 0, framesTouching = 0;
    double worstGapFree = 0.0, energyLostFree = 0.0;
  };
  auto swing = [](int exactSubsteps) {
    World world;
    SolverSettings s = SolverSettings::subStepped(10);
    s.exactJointIslandSubsteps = exactSubsteps;
    world.setSettings(s);
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.3));
    const int n = 10;
    const double spacing = 0.1;
    const auto [links, joints] = horizontalBallChain(world, n, Vec3(0, 0, 1), spacing, [&](int i) {
      return test::sphereBody(Vec3(spacing * (i + 1), 0, 1), 0.1, 0.02);
    });
    world.addShape(Shape::sphere(links.back(), 0.02));
    const double start = test::mechanicalEnergy(world, n);
    Swing r;
    for (int f = 0; f < 120; ++f) {
      world.step(1.0 / 60.0);
      const int substeps = world.lastStepStats().substeps;
      if (f == 0) {
        r.firstSubsteps = substeps;
        continue;
      }
      if (world.contacts().empty() && r.framesTouching == 0) {
        ++r.framesFree;
        r.freeSubsteps = std::max(r.freeSubsteps, substeps);
        for (JointId j : joints)
          r.worstGapFree = std::max(r.worstGapFree, world.jointError(j).linear);
        r.energyLostFree = start - test::mechanicalEnergy(world, n);
      } else if (!world.contacts().empty()) {
        ++r.framesTouching;
        r.touchingSubsteps = std::max(r.touchingSubsteps, substeps);
      }
    }
    return r;
  };
  const Swing exact = swing(1), nominal = swing(0);
  std::printf(
      "ten-link chain swinging onto a plane: %d frames free at %d sub-steps (gap %.3g mm, "
      "%.3g J lost) then %d touching at %d; nominal: %d free at %d (%.3g J lost)\n",
      exact.framesFree, exact.freeSubsteps, 1e3 * exact.worstGapFree, exact.energyLostFree,
      exact.framesTouching, exact.touchingSubsteps, nominal.framesFree, nominal.freeSubsteps,
      nominal.energyLostFree);
  EXPECT_EQ(exact.firstSubsteps, 10) << "the first step has not seen the island solved yet";
  EXPECT_GT(exact.framesFree, 10);
  EXPECT_EQ(exact.freeSubsteps, 1);
  EXPECT_GT(exact.framesTouching, 0) << "the chain's end reaches the plane";
  EXPECT_EQ(exact.touchingSubsteps, 10);
  EXPECT_LT(exact.worstGapFree, 1e-3);
  EXPECT_EQ(nominal.freeSubsteps, 10);
  // Relax at the whole step costs energy, but only a few per cent of the
  // chain's fall (1 kg over its 1 m): a step that stalled the swing would
  // lose most of what it falls before its end touches.
  EXPECT_GT(exact.energyLostFree, nominal.energyLostFree);
  EXPECT_LT(exact.energyLostFree, 0.1 * 1.0 * 9.81 * 1.0);
  EXPECT_LT(nominal.energyLostFree, 0.01 * 1.0 * 9.81 * 1.0);
}

// Steps the native stack scene (compare/native/scenes.cpp) under these
// settings, handing each frame's quality and step statistics to `frame`.
template <class Frame>
void stepStack(const SolverSettings& settings, int frames, Frame frame) {
  scenes::Scene scene;
  scenes::makeScene("stack", scene);
  scene.world.setSettings(settings);
  for (int f = 0; f < frames; ++f) {
    scene.world.step(scene.frameStep);
    frame(f, scenes::measure(scene), scene.world.lastStepStats());
  }
}

// A stack of ten boxes is an island of contacts only, its normals solved
// as one exact group (contact_island.h), which carries the load at once
// whatever the sub-steps: with exactContactIslandSubsteps 1 it takes one
// sub-step a frame from its second and stands as still as at ten (the
// top box within 1 mm over 600 frames).
TEST(Solver, AStackSolvedExactlyTakesOneSubstepAndStandsAsAtTen) {
  struct Run {
    double drift = 0.0, penetration = 0.0;
    int mostSubsteps = 0;
  };
  auto run = [](int exactSubsteps) {
    SolverSettings s = SolverSettings::subStepped(10);
    s.exactContactIslandSubsteps = exactSubsteps;
    Run r;
    stepStack(s, 600, [&](int f, const scenes::Quality& q, const StepStats& stats) {
      r.drift = std::max(r.drift, q.drift);
      r.penetration = std::max(r.penetration, q.penetration);
      if (f > 0) r.mostSubsteps = std::max(r.mostSubsteps, stats.substeps);
    });
    return r;
  };
  const Run one = run(1), ten = run(0);
  std::printf(
      "stack, 600 frames: exact islands at one sub-step drift %.3f mm, depth %.3f mm (at most %d "
      "sub-steps); at ten %.3f mm, %.3f mm\n",
      1e3 * one.drift, 1e3 * one.penetration, one.mostSubsteps, 1e3 * ten.drift,
      1e3 * ten.penetration);
  EXPECT_EQ(one.mostSubsteps, 1);
  EXPECT_EQ(ten.mostSubsteps, 10);
  EXPECT_LT(one.drift, 1e-3);
  EXPECT_LT(one.penetration, 1e-3);
}

// A ragdoll thrown onto the plane (compare/native/scenes.cpp) is an
// island of joints that contacts hold once it lands. With
// calmTouchedIslandSubsteps 1 it takes the nominal ten sub-steps while
// its contacts close fast (the landing) and one once it lies still, where
// its joints stay within SCENES.md's 2 mm, its contacts settle as deep
// as at ten and it gains no energy; at the nominal count it takes ten
// throughout.
TEST(Solver, ACalmRagdollTakesOneSubstepAndHoldsItsJointsAndContacts) {
  struct Run {
    int landingSubsteps = 0, restingSubsteps = 0;
    double worstGap = 0.0, restingDepth = 0.0, restingEnergyRise = 0.0;
  };
  auto run = [](int calmSubsteps) {
    scenes::Scene scene;
    scenes::makeScene("ragdoll", scene);
    // SCENES.md's shapes (the native scene has none) and the plane.
    World& w = scene.world;
    w.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    w.addShape(Shape::box(0, Vec3(0.15, 0.10, 0.10)));
    w.addShape(Shape::box(1, Vec3(0.17, 0.10, 0.20)));
    w.addShape(Shape::capsule(2, 0.08, 0.14));
    w.addShape(Shape::capsule(3, 0.06, 0.38));
    w.addShape(Shape::capsule(4, 0.06, 0.38));
    SolverSettings s = SolverSettings::subStepped(10);
    s.calmTouchedIslandSubsteps = calmSubsteps;
    scene.world.setSettings(s);
    Run r;
    bool landed = false;
    double lowest = std::numeric_limits<double>::infinity();
    const int frames = 300;
    for (int f = 0; f < frames; ++f) {
      scene.world.step(scene.frameStep);
      const scenes::Quality q = scenes::measure(scene);
      const int substeps = scene.world.lastStepStats().substeps;
      r.worstGap = std::max(r.worstGap, q.maxSeparation);
      if (!landed && !scene.world.contacts().empty()) {
        landed = true;
        r.landingSubsteps = substeps;
      }
      if (f >= frames - 60) {
        r.restingSubsteps = std::max(r.restingSubsteps, substeps);
        r.restingDepth = std::max(r.restingDepth, q.penetration);
        const double e = test::mechanicalEnergy(scene.world, scene.world.bodyCount());
        lowest = std::min(lowest, e);
        r.restingEnergyRise = std::max(r.restingEnergyRise, e - lowest);
      }
    }
    return r;
  };
  const Run calm = run(1), nominal = run(0);
  std::printf(
      "thrown ragdoll: calm at one sub-step lands at %d, rests at %d (worst joint %.3f mm, "
      "resting depth %.3f mm, energy rise at rest %.3g J); nominal: %d, %d (%.3f mm, %.3f mm)\n",
      calm.landingSubsteps, calm.restingSubsteps, 1e3 * calm.worstGap, 1e3 * calm.restingDepth,
      calm.restingEnergyRise, nominal.landingSubsteps, nominal.restingSubsteps,
      1e3 * nominal.worstGap, 1e3 * nominal.restingDepth);
  EXPECT_EQ(calm.landingSubsteps, 10) << "a landing is no calm";
  EXPECT_EQ(calm.restingSubsteps, 1);
  EXPECT_EQ(nominal.restingSubsteps, 10);
  EXPECT_LT(calm.worstGap, 2e-3);
  // Its contacts settle as deep as at ten, within 1 mm (here blockstep's
  // own collision leaves about 5 mm at either count).
  EXPECT_LT(calm.restingDepth, nominal.restingDepth + 1e-3);
  EXPECT_LT(calm.restingEnergyRise, 1e-3);
}

// A body made in a destroyed body's slot is new to the solver: the
// stack's top box replaced between two steps by a box in the same slot
// (the world reuses it) puts the stack back to ten sub-steps for a step,
// until the new box has been solved with it once.
TEST(Solver, ABodyInAReusedSlotIsNotTakenAsSolvedExactly) {
  scenes::Scene scene;
  scenes::makeScene("stack", scene);
  SolverSettings s = SolverSettings::subStepped(10);
  s.exactContactIslandSubsteps = 1;
  scene.world.setSettings(s);
  for (int f = 0; f < 30; ++f)
    scene.world.step(scene.frameStep);
  ASSERT_EQ(scene.world.lastStepStats().substeps, 1);
  const Body top = scene.world.body(scene.tracked);
  scene.world.destroyBody(scene.tracked);
  BodyDesc d = boxBody(top.position, top.mass, Vec3(0.5, 0.5, 0.5));
  d.orientation = top.orientation;
  const BodyId again = scene.world.createBody(d);
  ASSERT_EQ(again, scene.tracked) << "the world reuses the slot";
  scene.world.addShape(Shape::box(again, Vec3(0.25, 0.25, 0.25)));
  scene.world.step(scene.frameStep);
  EXPECT_EQ(scene.world.lastStepStats().substeps, 10);
  scene.world.step(scene.frameStep);
  EXPECT_EQ(scene.world.lastStepStats().substeps, 1);
}

// Stepped apart, each class of islands records its own sub-steps, each
// from its start: the circling box's 25 and the pendulum's 10, one class
// after the other. A change read from one sample to the next stays within
// a class (before the start was recorded, the box's first forces read as
// the pendulum's relax minus the box's energy), and the classes' starts
// and ends sum to the world's energy before and after the step, a
// velocity set between steps included.
TEST(Solver, EachClassOfIslandsRecordsItsSubstepsEnergyFromTheirStart) {
  World world;
  SolverSettings s = SolverSettings::subStepped(10);
  s.recordStageEnergy = true;
  world.setSettings(s);
  const BodyId box = circlingBox(world), bob = slowPendulum(world);
  auto energy = [&] {
    double e = 0.0;
    for (const BodyId id : {box, bob}) {
      const Body& b = world.body(id);
      e += test::kineticEnergy(b) - b.mass * world.gravity().dot(b.position);
    }
    return e;
  };
  world.step(1.0 / 60.0);                       // the turn rates seen
  world.setLinearVelocity(bob, Vec3(0, 1, 0));  // across the rod, set between steps
  const double before = energy();
  world.step(1.0 / 60.0);
  const double after = energy();
  using After = StageEnergySample::After;
  const std::vector<StageEnergySample>& e = world.lastStepStats().stageEnergy;
  ASSERT_EQ(e.size(), 6u * (10 + 25));
  double starts = 0.0, ends = 0.0;
  for (std::size_t i = 0; i < e.size(); i += 6) {
    SCOPED_TRACE(i);
    const int substeps = e[i].substeps;
    ASSERT_TRUE(substeps == 10 || substeps == 25);
    const int first = substeps == 10 ? 0 : 6 * 10;  // the pendulum's class goes first
    EXPECT_EQ(e[i].substep, static_cast<int>(i - first) / 6);
    EXPECT_EQ(e[i].after, After::Start);
    for (std::size_t k = 1; k < 6; ++k) {
      EXPECT_EQ(e[i + k].after, static_cast<After>(k - 1));
      EXPECT_EQ(e[i + k].substeps, substeps);
    }
    const double start = e[i].kinetic + e[i].potential;
    if (e[i].substep == 0)
      starts += start;
    else
      EXPECT_NEAR(start, e[i - 1].kinetic + e[i - 1].potential, 1e-12) << "where its relax left it";
    if (e[i].substep == substeps - 1) ends += e[i + 5].kinetic + e[i + 5].potential;
  }
  EXPECT_NEAR(starts, before, 1e-9);
  EXPECT_NEAR(ends, after, 1e-9);
}

// With more sub-steps the rigid-row spring keeps the nominal sub-step's
// stiffness (its stretch under a load does not depend on the sub-step:
// C = K F / omega^2). A 10 kg ball hanging on a hinge about the vertical
// stretches it alike at 10 sub-steps and at the 25 its spin asks for;
// scaled with the sub-step, as a StepSpring is, the spring was 6.25 times
// stiffer (0.00073 against 0.0046 mm), and switching between the two made
// ODE's taut bridge scene in the compare runner bounce its crate (2,400 J
// over its start).
TEST(Solver, MoreSubstepsKeepTheRigidRowSpringsStiffness) {
  auto sag = [](double spin) {
    World world;
    world.setGravity(Vec3(0, 0, -9.81));
    world.setSettings(SolverSettings::subStepped(10));
    // A heavy ball hanging on a hinge 1 m above it, spinning about the
    // vertical: the joint's stretch under the load is the spring's. The
    // hinge's axis passes 10 um beside the ball's centre, so the spin
    // turns its anchor and asks for sub-steps (about an axis through the
    // centre it would not), while the pull it takes to circle that axis
    // (2 N) stays small beside the weight (98 N).
    const BodyId ball = world.createBody(sphereBody(Vec3(0, 0, -1), 10.0, 0.1));
    HingeJointDesc joint;
    joint.common.bodyB = ball;
    joint.anchor = Vec3(1e-5, 0, 0);
    joint.axis = Vec3::UnitZ();
    const JointId j = world.createJoint(joint);
    world.setAngularVelocity(ball, Vec3(0, 0, spin));
    double stretch = 0.0;
    for (int i = 0; i < 120; ++i) {
      world.step(1.0 / 60.0);
      if (i >= 60) stretch = std::max(stretch, world.jointError(j).linear);
    }
    return std::pair{stretch, world.lastStepStats().substeps};
  };
  const auto [still, stillSubsteps] = sag(0.0);
  const auto [spinning, spinningSubsteps] = sag(150.0);
  std::printf("hanging 10 kg ball: joint error %.3g mm at %d sub-steps, %.3g mm at %d\n",
              1e3 * still, stillSubsteps, 1e3 * spinning, spinningSubsteps);
  EXPECT_EQ(stillSubsteps, 10);
  EXPECT_EQ(spinningSubsteps, 25);
  EXPECT_NEAR(spinning, still, 0.2 * still);
}

}  // namespace
}  // namespace blockstep::test

namespace blockstep::test {
namespace {

// How many sub-steps of a step prepared their rows, for a box hinged to
// the world spinning about the hinge at `rate` rad/s (its second step: the
// first has no turn rate measured), and the hinge's largest angular error
// over the two steps.
struct CarryRun {
  int prepared = 0;
  double axisError = 0.0;  // rad
};

CarryRun spinOnAHinge(double rate, double refreshTurn, const Limit& limit = {}) {
  World world;
  SolverSettings s = SolverSettings::subStepped(10);
  s.maxTurnPerRefresh = refreshTurn;
  const BodyId box = spinningBox(world, s, rate, true, limit);
  CarryRun run;
  for (int i = 0; i < 2; ++i) {
    world.step(1.0 / 60.0);
    const Vec3 axis = world.body(box).orientation * Vec3::UnitZ();
    run.axisError = std::max(run.axisError, std::acos(std::min(1.0, axis.z())));
  }
  EXPECT_EQ(world.lastStepStats().substeps, 10);
  run.prepared = world.lastStepStats().preparedSubsteps;
  return run;
}

// Sub-steps keep the rows an earlier sub-step prepared while the bodies
// have turned less than maxTurnPerRefresh since: a sub-step k after the
// prepare at p keeps them while rate h (k - p + 1) < turn. At 0.03 rad/s
// (5e-5 rad a sub-step) one prepare serves the whole step; at 0.1 rad/s
// (1.67e-4) sub-steps 0 and 5 prepare; at 3 rad/s every sub-step does, as
// it does with the setting off or with a limit on the joint (its row may
// engage within the step). Kept rows still hold the hinge.
TEST(Solver, SubstepsKeepTheirRowsWhileBodiesTurnLessThanTheRefreshTurn) {
  const double turn = SolverSettings::kMaxTurnPerRefresh;
  EXPECT_EQ(spinOnAHinge(0.03, turn).prepared, 1);
  EXPECT_EQ(spinOnAHinge(0.1, turn).prepared, 2);
  EXPECT_EQ(spinOnAHinge(3.0, turn).prepared, 10);
  EXPECT_EQ(spinOnAHinge(0.03, 0.0).prepared, 10);
  Limit limit;
  limit.enabled = true;
  limit.lo = -1.0;
  limit.hi = 1.0;
  EXPECT_EQ(spinOnAHinge(0.03, turn, limit).prepared, 10);
  EXPECT_LT(spinOnAHinge(0.1, turn).axisError, 1e-9);
}

// A stack at rest, the sub-stepped preset with and without kept rows
// (SCENES.md's 10 boxes, 300 frames): once settled one prepare serves a
// step's 10 sub-steps, and the stack stands as it does when every
// sub-step prepares (top box drift, contact depth).
TEST(Solver, AStackAtRestKeepsItsRowsAndStandsAsWhenEverySubstepPrepares) {
  struct Run {
    double drift = 0.0, penetration = 0.0, preparedPerStep = 0.0;
  };
  auto run = [](double refreshTurn) {
    SolverSettings s = SolverSettings::subStepped(10);
    s.maxTurnPerRefresh = refreshTurn;
    Run r;
    stepStack(s, 300, [&](int f, const scenes::Quality& q, const StepStats& stats) {
      r.drift = std::max(r.drift, q.drift);
      r.penetration = std::max(r.penetration, q.penetration);
      if (f >= 120) r.preparedPerStep += stats.preparedSubsteps / 180.0;
    });
    return r;
  };
  const Run kept = run(SolverSettings::kMaxTurnPerRefresh), fresh = run(0.0);
  std::printf(
      "stack, 300 frames: kept rows drift %.3f mm, depth %.3f mm, %.2f prepares a step; every "
      "sub-step %.3f mm, %.3f mm, %.2f\n",
      1e3 * kept.drift, 1e3 * kept.penetration, kept.preparedPerStep, 1e3 * fresh.drift,
      1e3 * fresh.penetration, fresh.preparedPerStep);
  EXPECT_NEAR(fresh.preparedPerStep, 10.0, 1e-9);
  EXPECT_LT(kept.preparedPerStep, 1.5);
  EXPECT_NEAR(kept.drift, fresh.drift, 5e-5);
  EXPECT_NEAR(kept.penetration, fresh.penetration, 5e-5);
}

}  // namespace
}  // namespace blockstep::test

namespace blockstep::test {
namespace {

// ldltInvert turns a factor into the matrix of its solve: on a regular
// 6 x 6 K it is K^-1, and on a singular one (two rows alike, rank 5) the
// product gives what the substitutions give, finite, with the redundant
// direction left out.
TEST(Ldlt, InverseIsTheMatrixOfTheSolveOnRegularAndSingularBlocks) {
  Eigen::Matrix<double, 6, 6> A;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      A(i, j) = (i == j ? 2.0 : 0.0) + std::sin(1.0 + 7.0 * i * i + 3.0 * j);
  for (const bool singular : {false, true}) {
    if (singular) A.row(4) = A.row(1);
    const Eigen::Matrix<double, 6, 6> K = A * A.transpose();
    Eigen::Matrix<double, 6, 6> factor = K;
    ldltFactor(factor.data(), 6);
    Eigen::Matrix<double, 6, 6> inverse = factor;
    ldltInvert(inverse.data(), 6);
    for (int trial = 0; trial < 3; ++trial) {
      double bySolve[6], byProduct[6];
      for (int i = 0; i < 6; ++i)
        bySolve[i] = byProduct[i] = std::cos(2.0 * i + trial);
      ldltSolve(factor.data(), 6, bySolve);
      multiplyBlock(inverse.data(), 6, byProduct);
      for (int i = 0; i < 6; ++i) {
        ASSERT_TRUE(std::isfinite(byProduct[i]));
        EXPECT_NEAR(byProduct[i], bySolve[i], 1e-9 * (1.0 + std::abs(bySolve[i])))
            << (singular ? "singular" : "regular") << " row " << i;
      }
    }
    if (!singular) {
      EXPECT_LT((K * inverse - Eigen::Matrix<double, 6, 6>::Identity()).norm(), 1e-9);
    }
  }
}

// invertSymmetric3 gives K^-1 of a ball joint's block (the 3 x 3 of a
// 1 m link holding a 5 cm bob: diagonals 1 and 1001) from its lower
// triangle, and refuses a K whose LDL^T would find a redundant row (two
// rows alike) or a diagonal far below the others, leaving K as it was.
TEST(Ldlt, ClosedForm3x3InverseOrRefusal) {
  Eigen::Matrix3d K;
  K << 1001.0, 0.3, -0.2, 0.3, 1.0, 0.05, -0.2, 0.05, 1001.0;
  const Eigen::Matrix3d expected = K.inverse();
  Eigen::Matrix3d lowerOnly = K;
  lowerOnly(0, 1) = lowerOnly(0, 2) = lowerOnly(1, 2) = 99.0;  // never read
  ASSERT_TRUE(invertSymmetric3(lowerOnly.data()));
  EXPECT_LT((lowerOnly - expected).norm(), 1e-12 * expected.norm());

  Eigen::Matrix3d singular;
  singular << 2.0, 2.0, 0.5, 2.0, 2.0, 0.5, 0.5, 0.5, 3.0;
  const Eigen::Matrix3d before = singular;
  EXPECT_FALSE(invertSymmetric3(singular.data()));
  EXPECT_EQ(singular, before);
  Eigen::Matrix3d lopsided = Eigen::Matrix3d::Zero();
  lopsided.diagonal() << 1.0, 1e-8, 1.0;
  EXPECT_FALSE(invertSymmetric3(lopsided.data()));
}

}  // namespace
}  // namespace blockstep::test

namespace blockstep::test {
namespace {

// A sphere on a ball joint at its centre, 10 mm off its anchor, no
// gravity: the sub-stepped preset's rigid-row spring pulls it back over
// the step's 10 sub-steps. The sphere does not turn, so one prepare
// serves the whole step, and the kept rows' error must follow the
// sphere's move (C = C0 + J dx is exact for a move): the gap after the
// step is the one preparing every sub-step gives. An error kept at C0
// would pull as hard in the last sub-step as in the first and carry the
// sphere past its anchor.
TEST(Solver, KeptRowsFollowAMoveExactly) {
  auto gapAfterAStep = [](double refreshTurn, int& prepared) {
    World world;
    world.setGravity(Vec3::Zero());
    SolverSettings s = SolverSettings::subStepped(10);
    s.maxTurnPerRefresh = refreshTurn;
    world.setSettings(s);
    const BodyId ball = world.createBody(sphereBody(Vec3::Zero(), 1.0, 0.1));
    BallJointDesc joint;
    joint.common.bodyB = ball;
    joint.anchor = Vec3::Zero();
    world.createJoint(joint);
    world.step(1.0 / 60.0);  // the solver measures a turn rate (none)
    world.setPosition(ball, Vec3(0.01, 0.0, 0.0));
    world.step(1.0 / 60.0);
    prepared = world.lastStepStats().preparedSubsteps;
    return world.body(ball).position.x();
  };
  int keptPrepares = 0, freshPrepares = 0;
  const double kept = gapAfterAStep(SolverSettings::kMaxTurnPerRefresh, keptPrepares);
  const double fresh = gapAfterAStep(0.0, freshPrepares);
  std::printf("gap after one step: kept rows %.9g m (%d prepares), every sub-step %.9g m (%d)\n",
              kept, keptPrepares, fresh, freshPrepares);
  EXPECT_EQ(keptPrepares, 1);
  EXPECT_EQ(freshPrepares, 10);
  EXPECT_GT(fresh, 0.0);
  EXPECT_LT(fresh, 0.1 * 0.01) << "the spring closes most of the gap within the step";
  EXPECT_NEAR(kept, fresh, 1e-9 * 0.01);
}

}  // namespace
}  // namespace blockstep::test

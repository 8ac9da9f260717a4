// Section 3: the integrators, checked against closed forms.
#include <cmath>

#include "core/world/error.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

using test::boxBody;

// No gravity, the default solver with the gyroscopic term on.
void torqueFreeWithGyroscopicTerm(World& world) {
  world.setGravity(Vec3::Zero());
  SolverSettings s;
  s.gyroscopic = true;
  world.setSettings(s);
}

TEST(Integrate, FreeFallIsExactForSemiImplicitEuler) {
  // With constant g, semi-implicit Euler gives v_n = v0 + n h g and
  // x_n = x0 + n h v0 + h^2 g n (n + 1) / 2 exactly.
  World world;
  BodyDesc d = boxBody(Vec3(1, 2, 3), 2.0, Vec3(1, 1, 1));
  d.linearVelocity = Vec3(3, -1, 5);
  const BodyId id = world.createBody(d);
  const double h = 1.0 / 60.0;
  const int n = 120;
  test::stepN(world, n, h);
  const Vec3 g = world.gravity();
  const Vec3 expectedV = d.linearVelocity + n * h * g;
  const Vec3 expectedX = d.position + n * h * d.linearVelocity + h * h * g * n * (n + 1) / 2.0;
  EXPECT_LT((world.body(id).linearVelocity - expectedV).norm(), 1e-12);
  EXPECT_LT((world.body(id).position - expectedX).norm(), 1e-12);
}

TEST(Integrate, ExplicitEulerUsesTheOldVelocity) {
  World world;
  SolverSettings s;
  s.integrator = Integrator::ExplicitEuler;
  world.setSettings(s);
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(1, 1, 1));
  d.linearVelocity = Vec3(1, 0, 10);
  const BodyId id = world.createBody(d);
  const double h = 0.01;
  const int n = 100;
  test::stepN(world, n, h);
  const Vec3 g = world.gravity();
  const Vec3 expectedX = n * h * d.linearVelocity + h * h * g * n * (n - 1) / 2.0;
  EXPECT_LT((world.body(id).position - expectedX).norm(), 1e-12);
}

TEST(Integrate, ProjectileLandsWhereTheContinuousSolutionSays) {
  // As h -> 0 the discrete trajectory converges to x0 + v0 t + g t^2 / 2;
  // the first-order error is h g t / 2.
  World world;
  world.setGravity(Vec3(0, 0, -10));
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(1, 1, 1));
  d.linearVelocity = Vec3(4, 0, 10);
  const BodyId id = world.createBody(d);
  const double h = 1e-4;
  test::stepN(world, 20000, h);  // t = 2 s: back at z = 0
  const Vec3 x = world.body(id).position;
  EXPECT_NEAR(x.x(), 8.0, 1e-9);
  EXPECT_NEAR(x.z(), 0.0, 10.0 * h * 2.0 / 2.0 + 1e-9);
}

TEST(Integrate, TorqueFreeSpinKeepsAngularMomentumWithGyroscopicTerm) {
  World world;
  torqueFreeWithGyroscopicTerm(world);
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(0.2, 0.6, 1.0));  // three distinct moments
  d.angularVelocity = Vec3(0.3, 6.0, 0.4);  // near the unstable middle axis: it tumbles
  const BodyId id = world.createBody(d);
  const Vec3 L0 = test::angularMomentum(world.body(id));
  const double E0 = test::kineticEnergy(world.body(id));
  double maxE = E0;
  for (int i = 0; i < 600; ++i) {  // 10 s at 60 Hz
    world.step(1.0 / 60.0);
    maxE = std::max(maxE, test::kineticEnergy(world.body(id)));
  }
  const Vec3 L = test::angularMomentum(world.body(id));
  EXPECT_LT((L - L0).norm() / L0.norm(), 0.01) << "L0 " << L0.transpose() << " L " << L.transpose();
  EXPECT_LE(maxE, E0 * (1.0 + 1e-9)) << "implicit gyroscopic term must not gain energy";
}

// The same tumbling box given in a body frame turned against its
// principal axes (a full inertia tensor, the general path of the
// gyroscopic step) and in its principal frame (a diagonal one, the
// written-out path) moves the same: one body, two descriptions.
TEST(Integrate, GyroscopicStepAgreesForDiagonalAndFullInertia) {
  auto spin = [](bool turnedFrame) {
    World world;
    torqueFreeWithGyroscopicTerm(world);
    BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(0.2, 0.6, 1.0));
    if (turnedFrame) {
      // Body frame B = principal frame P turned by T: q_B = q_P T and
      // I_B = T^T I_P T, so the world inertia R_B I_B R_B^T is the same.
      const Quat T(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
      const Mat3 R = T.toRotationMatrix();
      d.inertia = R.transpose() * d.inertia * R;
      d.orientation = d.orientation * T;
    }
    d.angularVelocity = Vec3(0.3, 6.0, 0.4);
    const BodyId id = world.createBody(d);
    for (int i = 0; i < 120; ++i)
      world.step(1.0 / 60.0);
    return world.body(id).angularVelocity;
  };
  const Vec3 diagonal = spin(false), full = spin(true);
  EXPECT_LT((diagonal - full).norm(), 1e-9 * diagonal.norm())
      << diagonal.transpose() << " / " << full.transpose();
  EXPECT_GT((diagonal - Vec3(0.3, 6.0, 0.4)).norm(), 0.1);  // it does tumble
}

TEST(Integrate, Solve3MatchesPivotedLu) {
  // The gyroscopic Newton step's 3x3 solve (Cramer's rule) against
  // Eigen's pivoted LU, on a well-conditioned system and on a singular
  // one (which falls back to the LU).
  Mat3 A;
  A << 4.0, 1.0, -0.5, 0.3, 2.0, 0.7, -1.0, 0.2, 3.0;
  const Vec3 b(1.0, -2.0, 0.5);
  EXPECT_LT((solve3(A, b) - A.partialPivLu().solve(b)).norm(), 1e-14);
  EXPECT_LT((A * solve3(A, b) - b).norm(), 1e-14);
  Mat3 singular;
  singular << 1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 1.0, 1.0;
  const Vec3 x = solve3(singular, b), lu = singular.partialPivLu().solve(b);
  for (int i = 0; i < 3; ++i)
    EXPECT_TRUE(x[i] == lu[i] || (std::isnan(x[i]) && std::isnan(lu[i]))) << i;
}

TEST(Integrate, CubeSpinsUnchangedWithGyroscopicTerm) {
  // A cube's inertia is a multiple of the identity: w x (I w) = 0, so a
  // torque-free cube keeps its angular velocity whatever its axis.
  World world;
  torqueFreeWithGyroscopicTerm(world);
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(0.5, 0.5, 0.5));
  d.angularVelocity = Vec3(0.3, 6.0, -2.4);
  const BodyId id = world.createBody(d);
  test::stepN(world, 120, 1.0 / 60.0);
  EXPECT_LT((world.body(id).angularVelocity - d.angularVelocity).norm(), 1e-12);
}

TEST(Integrate, WithoutGyroscopicTermAngularVelocityIsConstant) {
  // Dropping w x Iw (the default) keeps w fixed: that is what the
  // gyroscopic test above differs from, so it checks the term acts.
  World world;
  world.setGravity(Vec3::Zero());
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(0.2, 0.6, 1.0));
  d.angularVelocity = Vec3(0.3, 6.0, 0.4);
  const BodyId id = world.createBody(d);
  test::stepN(world, 60, 1.0 / 60.0);
  EXPECT_LT((world.body(id).angularVelocity - d.angularVelocity).norm(), 1e-12);
}

TEST(Integrate, GyroscopicTermCanBeTurnedOffPerBody) {
  // With the world's term on, a body that opts out keeps w fixed while
  // its twin tumbles.
  World world;
  torqueFreeWithGyroscopicTerm(world);
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(0.2, 0.6, 1.0));
  d.angularVelocity = Vec3(0.3, 6.0, 0.4);
  const BodyId tumbling = world.createBody(d);
  d.position = Vec3(5, 0, 0);
  d.rotation.gyroscopic = false;
  const BodyId plain = world.createBody(d);
  test::stepN(world, 60, 1.0 / 60.0);
  EXPECT_LT((world.body(plain).angularVelocity - d.angularVelocity).norm(), 1e-12);
  EXPECT_GT((world.body(tumbling).angularVelocity - d.angularVelocity).norm(), 0.1);
}

TEST(Integrate, FiniteRotationTurnsExactlyByOmegaH) {
  // 100 rad/s about z at 60 Hz is 1.67 rad a step: the first-order
  // quaternion step turns 2 atan(|w| h / 2) = 1.39 rad, the finite one the
  // whole 1.67 rad, so after 1 s the body is at 100 rad (mod 2 pi).
  for (bool finite : {false, true}) {
    World world;
    world.setGravity(Vec3::Zero());
    BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(1, 1, 1));
    d.angularVelocity = Vec3(0, 0, 100.0);
    d.rotation.finite = finite;
    const BodyId id = world.createBody(d);
    test::stepN(world, 60, 1.0 / 60.0);
    const Quat q = world.body(id).orientation;
    const double angle = 2.0 * std::atan2(q.z(), q.w());
    const double expected = finite ? 100.0 : 60.0 * 2.0 * std::atan(100.0 / 120.0);
    EXPECT_NEAR(std::remainder(angle - expected, 2.0 * kPi), 0.0, 1e-9) << finite;
  }
}

TEST(Integrate, FiniteRotationAboutAnAxisOnly) {
  // A wheel spinning at 100 rad/s about its axle (z) and steered slowly
  // about x: the spin turns exactly, the steering first-order.
  World world;
  world.setGravity(Vec3::Zero());
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(1, 1, 1));
  d.angularVelocity = Vec3(0.5, 0, 100.0);
  d.rotation.finite = true;
  d.rotation.axis = Vec3(0, 0, 2);  // made unit
  const BodyId id = world.createBody(d);
  EXPECT_EQ(world.body(id).rotation.axis, Vec3::UnitZ());
  world.step(1.0 / 60.0);
  const Quat expected = integrateRotation(Quat(Eigen::AngleAxisd(100.0 / 60.0, Vec3::UnitZ())),
                                          Vec3(0.5, 0, 0), 1.0 / 60.0);
  EXPECT_TRUE(world.body(id).orientation.isApprox(expected, 1e-12));
  RotationUpdate bad;
  bad.axis = Vec3(0, std::nan(""), 0);
  EXPECT_THROW(world.setRotationUpdate(id, bad), Error);
}

TEST(Integrate, DampingAndMaxAngularSpeed) {
  World world;
  world.setGravity(Vec3::Zero());
  BodyDesc d = boxBody(Vec3::Zero(), 1.0, Vec3(1, 1, 1));
  d.linearVelocity = Vec3(2, 0, 0);
  d.angularVelocity = Vec3(0, 0, 50);
  d.linearDamping = 0.5;
  d.maxAngularSpeed = 10.0;
  const BodyId id = world.createBody(d);
  world.step(0.1);
  EXPECT_NEAR(world.body(id).linearVelocity.x(), 2.0 / 1.05, 1e-12);
  EXPECT_NEAR(world.body(id).angularVelocity.norm(), 10.0, 1e-12);
}

TEST(Integrate, StaticAndKinematicBodies) {
  World world;
  BodyDesc s;
  s.type = BodyType::Static;
  s.position = Vec3(0, 0, 1);
  const BodyId fixedId = world.createBody(s);
  BodyDesc k;
  k.type = BodyType::Kinematic;
  k.linearVelocity = Vec3(1, 0, 0);
  k.angularVelocity = Vec3(0, 0, kPi);
  const BodyId kin = world.createBody(k);
  test::stepN(world, 100, 0.01);
  EXPECT_EQ(world.body(fixedId).position, Vec3(0, 0, 1));
  EXPECT_NEAR(world.body(kin).position.x(), 1.0, 1e-12);
  EXPECT_NEAR(world.body(kin).position.z(), 0.0, 1e-12) << "gravity must not move a kinematic body";
  // Half a turn about z.
  EXPECT_NEAR(std::abs(world.body(kin).orientation.z()), 1.0, 1e-3);
}

}  // namespace
}  // namespace blockstep

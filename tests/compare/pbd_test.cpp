// The position-based baseline (compare/pbd) against closed forms: free
// fall, a compliant hanger's stretch, a pendulum's period, the friction
// threshold on an incline, resting on a box; and the property the paper
// points out, that PBD's stiffness depends on its iteration count while
// XPBD's does not.
#include <gtest/gtest.h>

#include <cmath>

#include "compare/pbd/particles.h"

namespace blockstep::pbd {
namespace {

constexpr double kG = 9.81;

TEST(Pbd, FreeFallIsSemiImplicitEuler) {
  // v_{n+1} = v_n - g h, x_{n+1} = x_n + h v_{n+1}: after N steps
  // z = z0 + v0 N h - g h^2 N (N + 1) / 2.
  for (Settings::Mode mode : {Settings::Mode::Pbd, Settings::Mode::Xpbd}) {
    ParticleSystem ps;
    ps.addParticle(Vec3(0, 0, 10), Vec3(1, 0, 2), 1.0, 0.1);
    Settings s;
    s.mode = mode;
    s.substeps = 4;
    const double dt = 0.02, h = dt / s.substeps;
    const int frames = 50, n = frames * s.substeps;
    for (int f = 0; f < frames; ++f)
      ps.step(dt, s);
    const double z = 10.0 + 2.0 * n * h - kG * h * h * n * (n + 1) / 2.0;
    EXPECT_NEAR(ps.position(0).z(), z, 1e-9);
    EXPECT_NEAR(ps.position(0).x(), 1.0 * n * h, 1e-9);
    EXPECT_NEAR(ps.velocity(0).z(), 2.0 - kG * n * h, 1e-9);
    // And within g h t of the exact parabola.
    const double t = n * h;
    EXPECT_NEAR(ps.position(0).z(), 10.0 + 2.0 * t - 0.5 * kG * t * t, kG * h * t);
  }
}

TEST(Pbd, XpbdHangerStretchesByWeightTimesCompliance) {
  // A 2 kg particle on a pin of compliance 1e-3 m/N: a spring of 1000 N/m
  // stretched by m g / k = 19.6 mm at rest, however it is stepped.
  for (int iterations : {1, 4}) {
    for (int substeps : {1, 5}) {
      ParticleSystem ps;
      ps.addParticle(Vec3(0, 0, 1), Vec3::Zero(), 2.0, 0.01);
      ps.addPin(0, Vec3(0, 0, 2));
      Settings s;
      s.mode = Settings::Mode::Xpbd;
      s.iterations = iterations;
      s.substeps = substeps;
      s.compliance = 1e-3;
      s.linearDamping = 0.02;  // to settle the bounce
      for (int f = 0; f < 3000; ++f)
        ps.step(1.0 / 60.0, s);
      const double stretch = (2.0 - ps.position(0).z()) - 1.0;
      EXPECT_NEAR(stretch, 2.0 * kG * 1e-3, 2e-4)
          << iterations << " iterations, " << substeps << " sub-steps";
    }
  }
}

TEST(Pbd, PbdStiffnessDependsOnIterationsXpbdDoesNot) {
  // A hanging chain of 20 particles, 1 kg each, 0.1 m apart: PBD's stretch
  // falls as iterations rise; rigid XPBD with sub-steps stays near rigid.
  auto chainStretch = [](Settings s) {
    ParticleSystem ps;
    ps.addParticle(Vec3(0, 0, 0), Vec3::Zero(), 1.0, 0.01);
    ps.addPin(0, Vec3(0, 0, 0));
    for (int i = 1; i < 20; ++i) {
      ps.addParticle(Vec3(0, 0, -0.1 * i), Vec3::Zero(), 1.0, 0.01);
      ps.addDistance(i - 1, i);
    }
    for (int f = 0; f < 120; ++f)
      ps.step(1.0 / 60.0, s);
    return (ps.position(0) - ps.position(19)).norm() - 1.9;
  };
  Settings pbd;
  pbd.iterations = 5;
  const double few = chainStretch(pbd);
  pbd.iterations = 20;
  const double more = chainStretch(pbd);
  pbd.iterations = 80;
  const double many = chainStretch(pbd);
  EXPECT_GT(few, 2.0 * more);
  EXPECT_GT(more, 2.0 * many);
  EXPECT_GT(many, 0.0);
  Settings small;
  small.mode = Settings::Mode::Xpbd;
  small.iterations = 1;
  small.substeps = 40;
  EXPECT_LT(chainStretch(small), 0.5 * many);
}

TEST(Pbd, PendulumPeriod) {
  // A rigid pin of length 1 m swung 0.1 rad: period 2 pi sqrt(L / g)
  // (the small-angle correction, 1 + theta^2 / 16, is 0.06%).
  ParticleSystem ps;
  const double L = 1.0, theta = 0.1;
  ps.addParticle(Vec3(L * std::sin(theta), 0, -L * std::cos(theta)), Vec3::Zero(), 1.0, 0.01);
  ps.addPin(0, Vec3::Zero());
  Settings s;
  s.mode = Settings::Mode::Xpbd;
  s.iterations = 1;
  s.substeps = 20;
  const double dt = 1.0 / 60.0;
  double previousX = ps.position(0).x(), firstCrossing = -1.0, lastCrossing = -1.0;
  int crossings = 0;
  for (int f = 1; f <= 60 * 20; ++f) {
    ps.step(dt, s);
    const double x = ps.position(0).x();
    if (previousX > 0.0 && x <= 0.0) {  // crossing the bottom moving -x
      const double t = (f - 1 + previousX / (previousX - x)) * dt;
      if (firstCrossing < 0.0) firstCrossing = t;
      lastCrossing = t;
      ++crossings;
    }
    previousX = x;
  }
  ASSERT_GE(crossings, 5);
  const double period = (lastCrossing - firstCrossing) / (crossings - 1);
  EXPECT_NEAR(period, 2.0 * M_PI * std::sqrt(L / kG), 0.01 * 2.0 * M_PI * std::sqrt(L / kG));
  // Rigid: the length holds.
  EXPECT_LT(ps.maxDistanceError(), 1e-6);
}

// How far a particle at rest on a plane tilted by `degrees` slides down
// it in one second (m, along the slope; downhill is -x).
double slideAfterOneSecond(double degrees, double mu) {
  const double a = degrees * M_PI / 180.0;
  ParticleSystem ps;
  StaticShape plane;
  plane.normal = Vec3(-std::sin(a), 0, std::cos(a));
  plane.offset = 0.0;
  ps.addShape(plane);
  ps.addParticle(0.05 * plane.normal, Vec3::Zero(), 1.0, 0.05);
  ps.setCollisionMask(0, 1);
  Settings s;
  s.friction = mu;
  s.iterations = 10;
  for (int f = 0; f < 60; ++f)
    ps.step(1.0 / 60.0, s);
  return -(ps.position(0).x() - 0.05 * plane.normal.x()) / std::cos(a);
}

TEST(Pbd, FrictionHoldsBelowTheThresholdAndSlidesAbove) {
  // mu 0.6: tan 25 deg = 0.47 holds, tan 35 deg = 0.70 slides at
  // g (sin a - mu cos a) = 1.6 m/s^2, 0.8 m in a second.
  EXPECT_LT(std::abs(slideAfterOneSecond(25.0, 0.6)), 1e-3);
  const double a = 35.0 * M_PI / 180.0;
  const double expected = 0.5 * kG * (std::sin(a) - 0.6 * std::cos(a));
  EXPECT_NEAR(slideAfterOneSecond(35.0, 0.6), expected, 0.1 * expected);
}

TEST(Pbd, RestsOnABoxAtItsRadius) {
  ParticleSystem ps;
  StaticShape box;
  box.kind = StaticShape::Kind::Box;
  box.centre = Vec3(0, 0, 0.5);
  box.halfExtents = Vec3(0.3, 0.3, 0.3);
  ps.addShape(box);
  ps.addParticle(Vec3(0.1, 0.05, 1.5), Vec3::Zero(), 0.01, 0.025);
  ps.setCollisionMask(0, 1);
  Settings s;
  for (int f = 0; f < 180; ++f)
    ps.step(1.0 / 60.0, s);
  EXPECT_NEAR(ps.position(0).z(), 0.8 + 0.025, 1e-3);
  EXPECT_NEAR(ps.position(0).x(), 0.1, 1e-6);
  EXPECT_NEAR(ps.position(0).y(), 0.05, 1e-6);
  EXPECT_LT(ps.kineticEnergy(), 1e-6);
  int contacts = 0;
  EXPECT_LT(ps.deepestContact(&contacts), 1e-3);
}

}  // namespace
}  // namespace blockstep::pbd

// Contacts (section 4.2 rows, section 4.3 clamping): resting, friction
// thresholds, restitution, mass ratios, warm starting, caller contacts.
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include "compare/native/scenes.h"
#include "core/body/mass.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

using test::boxBody;

BodyId addBox(World& world, const Vec3& position, double mass, const Vec3& half,
              double friction = 0.6, const Quat& q = Quat::Identity()) {
  BodyDesc d = boxBody(position, mass, 2.0 * half);
  d.orientation = q;
  const BodyId id = world.createBody(d);
  Shape s = Shape::box(id, half);
  s.friction = friction;
  world.addShape(s);
  return id;
}

double rotationDegrees(const Quat& q) {
  return 2.0 * std::acos(std::min(1.0, std::abs(q.w()))) * 180.0 / kPi;
}

TEST(Contact, BoxRestsOnAPlane) {
  World world;  // default settings
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const BodyId box = addBox(world, Vec3(0, 0, 0.25), 1.0, Vec3(0.25, 0.25, 0.25));
  const Vec3 start = world.body(box).position;
  double drift = 0.0, rotation = 0.0;
  for (int i = 0; i < 600; ++i) {  // 10 s
    world.step(1.0 / 60.0);
    drift = std::max(drift, (world.body(box).position - start).norm());
    rotation = std::max(rotation, rotationDegrees(world.body(box).orientation));
  }
  EXPECT_LT(drift, 1e-3);
  EXPECT_LT(rotation, 0.1);
  ASSERT_EQ(world.contacts().size(), 1u);
  EXPECT_EQ(world.contacts()[0].pointCount, 4);
  double load = 0.0;
  for (int i = 0; i < 4; ++i)
    load += world.contacts()[0].points[i].stepNormalImpulse;
  EXPECT_NEAR(load * 60.0, 9.81, 0.01 * 9.81) << "the contact carries the weight";
}

// A box on a plane tilted by `angle` about x (gravity stays -z).
struct Incline {
  World world;
  BodyId box;
  Vec3 downhill;
};

void makeIncline(Incline& in, double angle, double mu, ContactSurface::Friction model) {
  // Warm started: cold, every step's friction starts from zero and lets
  // the box creep a little before it catches (5.7 mm in 10 s).
  SolverSettings s = SolverSettings::paper(10);
  s.warmStarting = true;
  in.world.setSettings(s);
  const Quat tilt(Eigen::AngleAxisd(angle, Vec3::UnitX()));
  const Vec3 n = tilt * Vec3::UnitZ();
  in.downhill = tilt * Vec3(0, 1, 0);  // -y tilted: gravity pulls along +y' when angle > 0
  if (in.downhill.z() > 0) in.downhill = -in.downhill;
  in.world.collisionSettings().surface.friction = model;
  Shape plane = Shape::plane(n, 0.0);
  plane.friction = mu;
  in.world.addShape(plane);
  in.box = addBox(in.world, 0.25 * n, 1.0, Vec3(0.25, 0.25, 0.25), mu, tilt);
}

// A box resting on the ground on its four corners, each given once or
// three times (alternating steps) by the caller, as ODE's colliders give
// trimesh points; one warm-started sweep per step, so what the warm start
// brings is what moves the box. Returns the fastest the box went.
double restingOnCopiedCorners(bool copies) {
  World world;
  SolverSettings s = SolverSettings::paper(1);
  s.warmStarting = true;
  world.setSettings(s);
  const double half = 0.25;
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, half), 1.0, Vec3(0.5, 0.5, 0.5)));
  double fastest = 0.0;
  for (int step = 0; step < 120; ++step) {
    const int count = copies && step % 2 ? 3 : 1;
    ContactManifold m;
    m.bodyA = kWorldBody;
    m.bodyB = box;
    m.normal = Vec3::UnitZ();
    m.pointCount = 1;
    const Vec3 centre = world.body(box).position;
    for (int corner = 0; corner < 4; ++corner) {
      const Vec3 offset((corner & 1) ? half : -half, (corner & 2) ? half : -half, -half);
      for (int copy = 0; copy < count; ++copy) {
        m.points[0].position = centre + offset + Vec3(1e-5 * copy, 0, 0);
        m.points[0].separation = centre.z() - half;
        world.addContact(m);
      }
    }
    world.step(1.0 / 60.0);
    if (step >= 20) fastest = std::max(fastest, world.body(box).linearVelocity.norm());
  }
  return fastest;
}

// Each point of the last step hands its impulse to the nearest new point:
// a pair's total carries over whatever the number of copies. When every
// copy took its nearest old point's impulse, three copies warm started
// three times the box's weight and threw it; in ODE's demo_moving_trimesh
// a resting body's friction impulses grew to 0.86 N s (its weight gives
// 0.003 N s a step) until a change of the contact set threw it at 1.35 m/s.
TEST(Contact, CopiedContactPointsDoNotMultiplyWarmStarting) {
  const double once = restingOnCopiedCorners(false), copied = restingOnCopiedCorners(true);
  std::printf(
      "box resting on its corners, one warm-started sweep: fastest after settling %.3g "
      "m/s (each corner once), %.3g m/s (three copies every other step)\n",
      once, copied);
  EXPECT_LT(once, 1e-3);
  EXPECT_LT(copied, 1e-3) << "copies multiplied the warm start (0.057 m/s so)";
}

// A ball rolling on the ground keeps its speed (nothing drives it, rolling
// without slip dissipates nothing) and stays on the surface. Contacts are
// made once per step and the sub-steps follow the bodies from there: when
// the contact's lever arm turned with the ball, the contact walked up its
// side within each step, and a ball rolling at 1 m/s reached 1.8 m/s in
// 10 s (through the plugin, sinking 2.7 mm; at 25 m/s it sank 23 mm).
TEST(Contact, RollingBallKeepsItsSpeedAndHeight) {
  for (const double speed : {1.0, 25.0}) {
    World world;
    world.setSettings(SolverSettings::subStepped(10));
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const double radius = 0.5;
    BodyDesc d = test::sphereBody(Vec3(0, 0, radius), 1.0, radius);
    d.linearVelocity = Vec3(speed, 0, 0);
    d.angularVelocity = Vec3(0, speed / radius, 0);
    const BodyId ball = world.createBody(d);
    world.addShape(Shape::sphere(ball, radius));
    double lowest = radius;
    for (int f = 0; f < 600; ++f) {
      world.step(1.0 / 60.0);
      lowest = std::min(lowest, world.body(ball).position.z());
    }
    const double end = world.body(ball).linearVelocity.norm();
    std::printf("ball rolling at %g m/s: %.5g m/s after 10 s, at most %.3g mm deep\n", speed, end,
                1e3 * (radius - lowest));
    EXPECT_NEAR(end, speed, 0.01 * speed);
    EXPECT_LT(radius - lowest, 5e-4);
  }
}

TEST(Contact, BoxStaysBelowTheFrictionAngleAndSlidesAboveIt) {
  const double mu = 0.5;  // friction angle atan(0.5) = 26.6 degrees
  for (auto model : {ContactSurface::Friction::Box, ContactSurface::Friction::Cone}) {
    SCOPED_TRACE(model == ContactSurface::Friction::Box ? "box friction" : "cone friction");
    {
      Incline in;
      makeIncline(in, 0.8 * std::atan(mu), mu, model);
      const Vec3 start = in.world.body(in.box).position;
      test::stepN(in.world, 600, 1.0 / 60.0);
      EXPECT_LT((in.world.body(in.box).position - start).norm(), 1e-3) << "creep over 10 s";
    }
    {
      const double angle = 0.6;  // 34.4 degrees
      Incline in;
      makeIncline(in, angle, mu, model);
      test::stepN(in.world, 30, 1.0 / 60.0);  // let it start sliding
      const double v0 = in.world.body(in.box).linearVelocity.dot(in.downhill);
      test::stepN(in.world, 60, 1.0 / 60.0);
      const double v1 = in.world.body(in.box).linearVelocity.dot(in.downhill);
      const double expected = 9.81 * (std::sin(angle) - mu * std::cos(angle));
      EXPECT_NEAR(v1 - v0, expected, 0.02 * expected) << "acceleration over 1 s";
    }
  }
}

// A tolerance stop must see friction rows against the normal impulses as
// they are, not as they were when friction was last solved: cold started,
// every friction bound is 0 after the first sweep, and the stop ended the
// solve there (ODE's demo_friction under dWorldStep: every box slid).
TEST(Contact, ToleranceStopKeepsFrictionBelowTheFrictionAngle) {
  const double mu = 0.5;
  for (auto model : {ContactSurface::Friction::Box, ContactSurface::Friction::Cone}) {
    SCOPED_TRACE(model == ContactSurface::Friction::Box ? "box friction" : "cone friction");
    for (const SolverSettings& settings : {SolverSettings::direct(), SolverSettings::paper(50)}) {
      Incline in;
      makeIncline(in, 0.8 * std::atan(mu), mu, model);
      SolverSettings s = settings;
      s.tolerance = 1e-9;
      in.world.setSettings(s);
      const Vec3 start = in.world.body(in.box).position;
      test::stepN(in.world, 300, 1.0 / 60.0);
      EXPECT_LT((in.world.body(in.box).position - start).norm(), 1e-3) << "creep over 5 s";
      EXPECT_GT(in.world.lastStepStats().iterations, 1) << "friction needs more than one sweep";
    }
  }
}

TEST(Contact, ConeFrictionHasNoPreferredDirection) {
  // Pushed diagonally with more than the friction limit, a box on cone
  // friction slides along the push; box friction (each axis clamped
  // alone) turns it toward the nearest axis diagonal.
  auto slideDirection = [](ContactSurface::Friction model, const Vec3& push) {
    World world;
    world.collisionSettings().surface.friction = model;
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const BodyId box = addBox(world, Vec3(0, 0, 0.25), 1.0, Vec3(0.25, 0.25, 0.25), 0.5);
    for (int i = 0; i < 60; ++i) {
      world.addForce(box, push);
      world.step(1.0 / 60.0);
    }
    return Vec3(world.body(box).linearVelocity.normalized());
  };
  const Vec3 push = 8.0 * Vec3(std::cos(0.3), std::sin(0.3), 0.0);
  const Vec3 cone = slideDirection(ContactSurface::Friction::Cone, push);
  EXPECT_GT(cone.dot(push.normalized()), 0.9999);
}

TEST(Contact, RestitutionBouncesToESquaredTimesTheHeight) {
  for (double e : {0.5, 0.8}) {
    World world;
    SolverSettings s = SolverSettings::paper(10);
    world.setSettings(s);
    world.collisionSettings().surface.restitutionThreshold = 0.5;
    Shape plane = Shape::plane(Vec3::UnitZ(), 0.0);
    plane.restitution = e;
    world.addShape(plane);
    const double r = 0.1, drop = 1.0;
    const BodyId ball = world.createBody(test::sphereBody(Vec3(0, 0, r + drop), 1.0, r));
    world.addShape(Shape::sphere(ball, r));
    const double h = 1.0 / 600.0;
    bool bounced = false;
    double apex = 0.0;
    for (int i = 0; i < 2400; ++i) {
      world.step(h);
      const double vz = world.body(ball).linearVelocity.z();
      if (!bounced && vz > 0.0) bounced = true;
      if (bounced) apex = std::max(apex, world.body(ball).position.z() - r);
      if (bounced && vz < 0.0) break;
    }
    EXPECT_NEAR(apex, e * e * drop, 0.03 * e * e * drop) << "e = " << e;
  }
}

TEST(Contact, SlowImpactsBelowTheThresholdDoNotBounce) {
  World world;
  world.collisionSettings().surface.restitutionThreshold = 1.0;  // m/s
  Shape plane = Shape::plane(Vec3::UnitZ(), 0.0);
  plane.restitution = 0.9;
  world.addShape(plane);
  const double r = 0.1;
  const BodyId ball = world.createBody(test::sphereBody(Vec3(0, 0, r + 0.03), 1.0, r));
  world.addShape(Shape::sphere(ball, r));  // lands at about 0.77 m/s
  test::stepN(world, 120, 1.0 / 60.0);
  EXPECT_NEAR(world.body(ball).position.z(), r, 1e-3);
  EXPECT_LT(std::abs(world.body(ball).linearVelocity.z()), 1e-3);
}

TEST(Contact, HeavyOnLightAndLightUnderHeavyDoNotSink) {
  // A 100 kg box on a 1 kg box, and a 100 kg plank resting on two 1 kg
  // boxes: every contact's penetration stays within the slop + 1 mm (the
  // plank sits on two such contacts: legs into the ground, plank into legs).
  // A 100:1 mass ratio needs more than one sweep per sub-step: with one,
  // the light box rocks up to 18 mm into the ground.
  World world;
  SolverSettings settings = SolverSettings::subStepped(8);
  settings.iterations = 4;
  world.setSettings(settings);
  world.collisionSettings().surface.slop = 0.005;
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const BodyId light = addBox(world, Vec3(0, 0, 0.25), 1.0, Vec3(0.25, 0.25, 0.25));
  const BodyId heavy = addBox(world, Vec3(0, 0, 0.75), 100.0, Vec3(0.25, 0.25, 0.25));
  const BodyId legA = addBox(world, Vec3(3, -1, 0.25), 1.0, Vec3(0.25, 0.25, 0.25));
  const BodyId legB = addBox(world, Vec3(3, 1, 0.25), 1.0, Vec3(0.25, 0.25, 0.25));
  const BodyId plank = addBox(world, Vec3(3, 0, 0.6), 100.0, Vec3(0.3, 1.5, 0.1));
  double worst = 0.0;
  for (int i = 0; i < 300; ++i) {
    world.step(1.0 / 60.0);
    if (i < 60) continue;  // after the landing of the 100 kg loads
    for (const ContactManifold& m : world.contacts()) {
      for (int k = 0; k < m.pointCount; ++k)
        worst = std::max(worst, -m.points[k].separation);
    }
  }
  EXPECT_LT(worst, 0.005 + 1e-3);
  EXPECT_NEAR(world.body(heavy).position.z(), 0.75, 2 * (0.005 + 1e-3));
  EXPECT_NEAR(world.body(plank).position.z(), 0.6, 2 * (0.005 + 1e-3));
  EXPECT_NEAR(world.body(light).position.z(), 0.25, 0.005 + 1e-3);
  EXPECT_NEAR(world.body(legA).position.z(), 0.25, 0.005 + 1e-3);
  EXPECT_NEAR(world.body(legB).position.z(), 0.25, 0.005 + 1e-3);
}

// A 1000 kg block on a 1 kg plank laid across two supports (the compare
// runner's plank_load, natively). Gauss-Seidel between the manifolds
// passes the plank only its own share of the load per sweep: the supports
// need about a thousand sweeps to carry the block, and the plank is pushed
// through them. The island's normal rows as one exact block
// (contactIslandRows, on in the sub-stepped preset) hold it at any
// sub-step count; the block's weight is spread evenly over its four
// corners (the least-norm impulses of a face: the rows are dependent).
struct PlankLoad {
  double blockDrop = 0.0;     // m, after 5 s (the top block's)
  double plankDrop = 0.0;     // m, after 5 s
  double deepest = 0.0;       // m, over the run
  double cornerSpread = 0.0;  // largest / smallest of the block's corner impulses
};
PlankLoad plankLoad(int substeps, int contactIslandRows, bool lightBodyGroups = true,
                    int blocks = 1, bool jointed = false) {
  World world;
  SolverSettings s = SolverSettings::subStepped(substeps);
  s.contactIslandRows = contactIslandRows;
  s.lightBodyGroups = lightBodyGroups;
  world.setSettings(s);
  const BodyId plank = test::plankOnTwoSupports(world);
  BodyId block = kWorldBody;
  for (int k = 0; k < blocks; ++k) {
    const BodyId below = block;
    block = addBox(world, Vec3(0, 0, 0.75 + 0.4 * k), 1000.0, Vec3(0.2, 0.2, 0.2));
    if (jointed && k > 0) {  // glued to the one below
      FixedJointDesc glue;
      glue.common.bodyA = below;
      glue.common.bodyB = block;
      world.createJoint(glue);
    }
  }
  PlankLoad out;
  for (int i = 0; i < 300; ++i) {
    world.step(1.0 / 60.0);
    for (const ContactManifold& m : world.contacts()) {
      for (int k = 0; k < m.pointCount; ++k)
        out.deepest = std::max(out.deepest, -m.points[k].separation);
    }
  }
  out.blockDrop = 0.75 + 0.4 * (blocks - 1) - world.body(block).position.z();
  out.plankDrop = 0.525 - world.body(plank).position.z();
  for (const ContactManifold& m : world.contacts()) {
    if (m.bodyA != block && m.bodyB != block) continue;
    double lo = kInf, hi = 0.0;
    for (int k = 0; k < m.pointCount; ++k) {
      lo = std::min(lo, m.points[k].normalImpulse);
      hi = std::max(hi, m.points[k].normalImpulse);
    }
    out.cornerSpread = m.pointCount == 4 && lo > 0.0 ? hi / lo : kInf;
  }
  return out;
}

TEST(Contact, ThousandKilogramsOnAOneKilogramPlankRestAtAnySubstepCount) {
  for (int substeps : {1, 2, 10}) {
    const PlankLoad block = plankLoad(substeps, SolverSettings::kContactIslandRows);
    const PlankLoad manifolds = plankLoad(substeps, 0);
    std::printf(
        "%2d sub-steps: block drops %.3f mm (deepest %.3f mm, corners within %.4f); "
        "manifold by manifold %.1f mm (deepest %.1f mm)\n",
        substeps, 1e3 * block.blockDrop, 1e3 * block.deepest, block.cornerSpread,
        1e3 * manifolds.blockDrop, 1e3 * manifolds.deepest);
    EXPECT_LT(std::abs(block.blockDrop), 1e-4) << substeps;
    EXPECT_LT(block.deepest, 1e-4) << substeps;
    EXPECT_LT(block.cornerSpread, 1.01) << substeps;
    EXPECT_GT(manifolds.blockDrop, 0.01) << substeps;  // what the block is for
  }
}

// Islands larger than contactIslandRows, and islands with joints, keep
// one block per manifold, but a body three or more times lighter than one
// it touches has its manifolds solved as one exact group
// (SolverSettings::lightBodyGroups): two 1000 kg blocks on the 1 kg plank
// make an island of 16 normal rows, here over a limit of 12, and the
// plank's 12 rows (both supports and the block) pass the load to the
// supports at once. The same with the blocks glued by a fixed joint,
// under the default limit (an island with a joint is never one group).
TEST(Contact, ALightBodyInALargerIslandPassesItsLoadOnAtOnce) {
  for (const bool jointed : {false, true}) {
    const int limit = jointed ? SolverSettings::kContactIslandRows : 12;
    for (int substeps : {1, 10}) {
      const PlankLoad grouped = plankLoad(substeps, limit, true, 2, jointed);
      const PlankLoad manifolds = plankLoad(substeps, limit, false, 2, jointed);
      std::printf(
          "%2d sub-steps, 2 t on the plank%s: with the light-body group the plank drops %.3f mm "
          "(the top block %.3f mm); manifold by manifold %.1f mm (%.1f mm)\n",
          substeps, jointed ? " (jointed)" : "", 1e3 * grouped.plankDrop, 1e3 * grouped.blockDrop,
          1e3 * manifolds.plankDrop, 1e3 * manifolds.blockDrop);
      EXPECT_LT(std::abs(grouped.plankDrop), 1e-4) << substeps << jointed;
      // The blocks' own manifold stays one soft block (not light: 1:1).
      EXPECT_LT(std::abs(grouped.blockDrop), 5e-3) << substeps << jointed;
      EXPECT_GT(manifolds.plankDrop, 0.01) << substeps << jointed;  // what the group is for
    }
  }
}

// A 0.1 kg ball on the ground carrying two 5 kg balls above it on ball
// joints, all falling at 2 m/s, stepped once by one sweep with the
// joints' rows as one island block. With the island's contacts in the
// null space of its joints (islandBlockContacts), the ground's one point
// stops all 10.1 kg in that sweep: its impulse is the column's momentum
// with the step's gravity, 10.1 kg (2 + g h) m/s, and no body moves on
// down but for what the rows' CFM of 1e-5 gives (CFM / h times the
// impulse: about 0.013 m/s at the contact, as much again at the joints).
// As a Gauss-Seidel partner of the joints, the point stops the light
// ball alone and the joints then pull it down with the others. Coupled in
// steps with an impact only (islandBlockImpacts), the landing is coupled
// as well, and the column standing on the ground, or hit by a free ball,
// is stepped as partners are, bit for bit.
TEST(Contact, AContactOnAJointedBodyStopsWhatItsJointsCarry) {
  enum class Coupling { Partners, Always, Impacts };
  struct Column {
    double impulse = 0.0;  // the ground's normal impulse, N s
    double slowest = 0.0;  // the most downward speed after the step, m/s (< 0: down)
    std::vector<double> state;
  };
  // freeSpeed >= 0: a free 5 kg ball, touching the top ball, falls on the
  // column at that speed.
  auto drop = [](Coupling coupling, double speed, double freeSpeed = -1.0) {
    World world;
    SolverSettings s = SolverSettings::paper(1);
    s.islandBlockRows = SolverSettings::kIslandBlockRows;
    s.islandBlockContacts = coupling == Coupling::Always;
    s.islandBlockImpacts = coupling == Coupling::Impacts;
    world.setSettings(s);
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const double r = 0.05;
    const double masses[3] = {0.1, 5.0, 5.0};
    BodyId bodies[3];
    for (int i = 0; i < 3; ++i) {
      BodyDesc d = test::sphereBody(Vec3(0, 0, r + 0.2 * i), masses[i], r);
      d.linearVelocity = Vec3(0, 0, -speed);
      bodies[i] = world.createBody(d);
      world.addShape(Shape::sphere(bodies[i], r));
    }
    for (int i = 0; i < 2; ++i) {
      BallJointDesc ball;
      ball.common.bodyA = bodies[i];
      ball.common.bodyB = bodies[i + 1];
      ball.anchor = Vec3(0, 0, r + 0.2 * i + 0.1);
      world.createJoint(ball);
    }
    if (freeSpeed >= 0.0) {
      BodyDesc d = test::sphereBody(Vec3(0, 0, 3 * r + 0.4), 5.0, r);
      d.linearVelocity = Vec3(0, 0, -freeSpeed);
      world.addShape(Shape::sphere(world.createBody(d), r));
    }
    world.step(1.0 / 60.0);
    Column c;
    for (const ContactManifold& m : world.contacts())
      for (int p = 0; p < m.pointCount; ++p)
        c.impulse += m.points[p].stepNormalImpulse;
    for (BodyId b : bodies) {
      const Body& body = world.body(b);
      c.slowest = std::min(c.slowest, body.linearVelocity.z());
      for (const Vec3& v : {body.position, body.linearVelocity, body.angularVelocity})
        c.state.insert(c.state.end(), {v.x(), v.y(), v.z()});
    }
    return c;
  };
  const Column coupled = drop(Coupling::Always, 2.0), partners = drop(Coupling::Partners, 2.0);
  const Column impacts = drop(Coupling::Impacts, 2.0);
  const double momentum = 10.1 * (2.0 + 9.81 / 60.0);
  std::printf(
      "0.1 kg under 10 kg, one sweep: in the joints' null space the ground takes %.3f N s "
      "(the column's momentum %.3f), fastest down %.3f m/s; coupled at impacts %.3f N s, "
      "%.3f m/s; as a partner %.3f N s, %.3f m/s\n",
      coupled.impulse, momentum, coupled.slowest, impacts.impulse, impacts.slowest,
      partners.impulse, partners.slowest);
  EXPECT_NEAR(coupled.impulse, momentum, 0.015 * momentum);
  EXPECT_GT(coupled.slowest, -0.03);
  EXPECT_NEAR(impacts.impulse, momentum, 0.015 * momentum);
  EXPECT_GT(impacts.slowest, -0.03);
  EXPECT_LT(partners.slowest, -1.0) << "what the setting is for";
  // Standing still on the ground, its one point closes g h^2 in the step:
  // no impact, so the step is the partners' own.
  EXPECT_EQ(drop(Coupling::Impacts, 0.0).state, drop(Coupling::Partners, 0.0).state);
  EXPECT_NE(drop(Coupling::Always, 0.0).state, drop(Coupling::Partners, 0.0).state)
      << "the comparison above could not tell";
  // A free body landing on the joints is no impact of theirs: coupled, the
  // bridge's 100 kg crate on its 1 kg planks gained energy.
  EXPECT_EQ(drop(Coupling::Impacts, 0.0, 2.0).state, drop(Coupling::Partners, 0.0, 2.0).state);
  EXPECT_NE(drop(Coupling::Always, 0.0, 2.0).state, drop(Coupling::Partners, 0.0, 2.0).state)
      << "the comparison above could not tell";
}

TEST(Contact, WarmStartingCutsTheSweepsAStackNeeds) {
  auto sweeps = [](bool warm) {
    World world;
    SolverSettings s = SolverSettings::paper(200);
    s.tolerance = 1e-4;
    s.warmStarting = warm;
    world.setSettings(s);
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    for (int i = 0; i < 2; ++i)
      addBox(world, Vec3(0, 0, 0.25 + 0.5 * i), 1.0, Vec3(0.25, 0.25, 0.25));
    int total = 0;
    for (int f = 0; f < 120; ++f) {
      world.step(1.0 / 60.0);
      if (f >= 60) total += world.lastStepStats().iterations;
    }
    return total;
  };
  const int warm = sweeps(true), cold = sweeps(false);
  std::printf("2-box stack, sweeps over 60 frames to 1e-4: warm %d, cold %d\n", warm, cold);
  EXPECT_LT(warm, cold / 2);
}

// The manifold a caller (the ODE adapter) would give for a box of half
// size `half` standing on the plane z = 0: its four bottom corners.
ContactManifold groundContact(const World& world, BodyId box, double half) {
  ContactManifold m;
  m.bodyB = box;
  m.normal = Vec3::UnitZ();
  m.pointCount = 4;
  const Body& b = world.body(box);
  for (int k = 0; k < 4; ++k) {
    const Vec3 corner = b.worldPoint(Vec3(k & 1 ? half : -half, k & 2 ? half : -half, -half));
    m.points[k].position = Vec3(corner.x(), corner.y(), 0.5 * corner.z());
    m.points[k].separation = corner.z();
    m.points[k].feature = static_cast<std::uint32_t>(k + 1);
  }
  return m;
}

TEST(Contact, CallerGivenContactsHoldABody) {
  // The ODE adapter's path: no shapes, a manifold given every step.
  World world;
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.5), 2.0, Vec3(1, 1, 1)));
  for (int i = 0; i < 120; ++i) {
    world.addContact(groundContact(world, box, 0.5));
    world.step(1.0 / 60.0);
  }
  EXPECT_NEAR(world.body(box).position.z(), 0.5, 1e-3);
  double load = 0.0;
  for (int k = 0; k < 4; ++k)
    load += world.contacts()[0].points[k].stepNormalImpulse;
  EXPECT_NEAR(load * 60.0, 2.0 * 9.81, 0.01 * 2.0 * 9.81);
}

TEST(Contact, ARedundantPointDeeperThanTheOthersIsStillPushedOut) {
  // Three bottom corners of a box at their true depth and, last, a point
  // under its centre 20 mm deeper (as a hull's vertex below its others),
  // with the core collider's rigid surface: four points of one body on a
  // plane, so the contact block's K has rank 3 and its factor leaves the
  // last row to the others, whose targets disagree with it.
  World world;
  world.setSettings(SolverSettings::subStepped(4));
  const double half = 0.1;
  const BodyId box =
      world.createBody(boxBody(Vec3(0, 0, half - 0.003), 2.0, Vec3(2 * half, 2 * half, 2 * half)));
  auto bumpDepth = [&] { return world.body(box).worldPoint(Vec3(0, 0, -half)).z() - 0.02; };
  for (int i = 0; i < 60; ++i) {
    ContactManifold m = groundContact(world, box, half);
    m.surface = world.collisionSettings().surface;
    ContactPoint& bump = m.points[3];
    bump = ContactPoint{};
    const Vec3 under = world.body(box).worldPoint(Vec3(0, 0, -half));
    bump.separation = bumpDepth();
    bump.position = Vec3(under.x(), under.y(), 0.5 * bump.separation);
    bump.feature = 4;
    world.addContact(m);
    world.step(1.0 / 60.0);
  }
  EXPECT_GT(bumpDepth(), -0.006) << "the slop is 5 mm";
}

TEST(Contact, BadContactsAndShapesAreRefused) {
  World world;
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.5), 1.0, Vec3(1, 1, 1)));
  ContactManifold m;
  m.bodyB = box;
  m.pointCount = 0;
  EXPECT_THROW(world.addContact(m), Error);
  m.pointCount = 1;
  m.normal = Vec3::Zero();
  EXPECT_THROW(world.addContact(m), Error);
  m.normal = Vec3::UnitZ();
  m.points[0].separation = NAN;
  EXPECT_THROW(world.addContact(m), Error);
  m.points[0].separation = 0.0;
  m.points[0].radiusB = -0.1;
  EXPECT_THROW(world.addContact(m), Error);
  m.points[0].radiusB = INFINITY;
  EXPECT_THROW(world.addContact(m), Error);
  m.points[0].radiusB = 0.0;
  m.surface.restitution = 2.0;
  EXPECT_THROW(world.addContact(m), Error);
  m.surface.restitution = 0.0;
  m.bodyA = box;
  EXPECT_THROW(world.addContact(m), Error);
  EXPECT_THROW(world.addShape(Shape::sphere(box, -1.0)), Error);
  EXPECT_THROW(world.addShape(Shape::box(box, Vec3(0.1, 0.0, 0.1))), Error);
  EXPECT_THROW(world.addShape(Shape::plane(Vec3::Zero(), 0.0)), Error);
  EXPECT_THROW(world.addShape(Shape::sphere(99, 1.0)), Error);
  world.step(1.0 / 60.0);  // nothing was added: the box falls freely
  EXPECT_TRUE(world.contacts().empty());
  EXPECT_LT(world.body(box).linearVelocity.z(), 0.0);
}

TEST(Contact, ConveyorSurfaceCarriesTheBox) {
  // ODE's motion1: the surface moves at 1 m/s along the first friction
  // direction; a box on it is carried at that speed.
  World world;
  world.setSettings(SolverSettings::subStepped(4));
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.25), 1.0, Vec3(0.5, 0.5, 0.5)));
  for (int i = 0; i < 120; ++i) {
    ContactManifold m = groundContact(world, box, 0.25);
    m.surface.frictionDir1 = Vec3::UnitX();
    m.surface.motion1 = 1.0;
    world.addContact(m);
    world.step(1.0 / 60.0);
  }
  EXPECT_NEAR(world.body(box).linearVelocity.x(), 1.0, 1e-3);
  EXPECT_NEAR(world.body(box).linearVelocity.y(), 0.0, 1e-3);
}

TEST(Contact, ForceDependentSlipMovesInProportionToTheForce) {
  // ODE's slip1/slip2 make the tangent rows a damper: pushed with F the
  // box slides at slip * F / points (each of the four points' rows takes
  // its share of F; friction high enough never to saturate).
  for (double force : {2.0, 4.0}) {
    World world;
    SolverSettings s = SolverSettings::paper(20);
    s.warmStarting = true;
    world.setSettings(s);
    const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.25), 1.0, Vec3(0.5, 0.5, 0.5)));
    const double slip = 0.05;
    for (int i = 0; i < 240; ++i) {
      ContactManifold m = groundContact(world, box, 0.25);
      m.surface.mu = 100.0;
      m.surface.slip1 = m.surface.slip2 = slip;
      world.addContact(m);
      world.addForce(box, Vec3(force, 0, 0));
      world.step(1.0 / 60.0);
    }
    const double expected = slip * force / 4.0;
    EXPECT_NEAR(world.body(box).linearVelocity.x(), expected, 0.02 * expected);
  }
}

TEST(Contact, RollingResistanceStopsARollingBall) {
  // Rolling resistance torque <= rolling * N about the tangents: a ball
  // rolling at 1 m/s stops; without it, it keeps rolling.
  auto speedAfter = [](double rolling) {
    World world;
    world.setSettings(SolverSettings::subStepped(4));
    world.collisionSettings().surface.rolling = rolling;
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const double r = 0.1;
    const BodyId ball = world.createBody(test::sphereBody(Vec3(0, 0, r), 1.0, r));
    world.addShape(Shape::sphere(ball, r));
    world.setLinearVelocity(ball, Vec3(1, 0, 0));
    world.setAngularVelocity(ball, Vec3(0, 1.0 / r, 0));
    test::stepN(world, 180, 1.0 / 60.0);
    return world.body(ball).linearVelocity.norm();
  };
  EXPECT_GT(speedAfter(0.0), 0.99);
  // Deceleration of a rolling solid ball: (5/7) g rolling / r = 3.5 m/s^2
  // with rolling = 0.05 m, so 1 m/s is gone well within 3 s.
  EXPECT_LT(speedAfter(0.05), 1e-3);
}

TEST(Contact, WarmStartingCutsTheSweepsTheTenBoxStackNeeds) {
  // The sub-stepped solver, up to 30 sweeps per sub-step until every
  // residual is below 1 mm/s. Gauss-Seidel over the manifolds (no contact
  // island block): warm started the stack needs a couple per sub-step,
  // cold it never gets there. Its island as one block: one, either way.
  auto sweeps = [](bool warm, int contactIslandRows = 0) {
    scenes::Scene scene;
    scenes::makeScene("stack", scene);
    SolverSettings s = SolverSettings::subStepped(20);
    s.iterations = 30;
    s.tolerance = 1e-3;
    s.warmStarting = warm;
    s.contactIslandRows = contactIslandRows;
    scene.world.setSettings(s);
    int total = 0;
    for (int f = 0; f < 180; ++f) {
      scene.world.step(scene.frameStep);
      if (f >= 120) total += scene.world.lastStepStats().iterations;
    }
    return total / (60.0 * 20.0);
  };
  const double warm = sweeps(true), cold = sweeps(false);
  std::printf("10-box stack, sweeps per sub-step to 1e-3: warm %.1f, cold %.1f\n", warm, cold);
  EXPECT_LT(warm, 4.0);
  EXPECT_GT(cold, 20.0);
  const int rows = SolverSettings::kContactIslandRows;
  const double blockWarm = sweeps(true, rows), blockCold = sweeps(false, rows);
  std::printf("as one contact block: warm %.1f, cold %.1f\n", blockWarm, blockCold);
  EXPECT_EQ(blockWarm, 1.0);
  EXPECT_EQ(blockCold, 1.0);
}

// SCENES.md's stack and pyramid, 2000 frames (33 s) under the sub-stepped
// solver with 20 sub-steps: the top box moves less than 1 mm.
double topDrift(const std::string& name, int substeps = 20) {
  scenes::Scene scene;
  scenes::makeScene(name, scene);
  scene.world.setSettings(SolverSettings::subStepped(substeps));
  double drift = 0.0;
  for (int f = 0; f < 2000; ++f) {
    scene.world.step(scene.frameStep);
    drift = std::max(drift, scenes::measure(scene).drift);
  }
  std::printf("%s, %d sub-steps: top box drift over 2000 frames %.3f mm\n", name.c_str(), substeps,
              1e3 * drift);
  return drift;
}

TEST(Contact, StackOfTenStandsFor2000Frames) {
  EXPECT_LT(topDrift("stack"), 1e-3);
}

// SCENES.md's target at quickstep 20's cost: one sub-step a frame. The
// stack is one contact island, its normals exact in one sweep
// (contact by contact it fell at one sub-step).
TEST(Contact, StackOfTenStandsFor2000FramesAtOneSubstep) {
  EXPECT_LT(topDrift("stack", 1), 1e-3);
}

TEST(Contact, PyramidStandsFor2000Frames) {
  EXPECT_LT(topDrift("pyramid"), 1e-3);
}

TEST(Contact, SpheresAndBoxesMeetWhereGeometrySays) {
  // A sphere on a sphere, a sphere on a box, and a box standing on its
  // edge across another box's edge (edge-edge contact): each lands at the
  // height the shapes allow.
  World world;
  world.setSettings(SolverSettings::subStepped(4));
  world.collisionSettings().surface.slop = 0.0;
  const double r = 0.2;
  BodyDesc fixed;
  fixed.type = BodyType::Static;
  fixed.position = Vec3(0, 0, 0);
  const BodyId base = world.createBody(fixed);
  world.addShape(Shape::sphere(base, r));
  const BodyId top = world.createBody(test::sphereBody(Vec3(0, 0, 2 * r + 0.05), 1.0, r));
  world.addShape(Shape::sphere(top, r));

  fixed.position = Vec3(2, 0, 0);
  const BodyId table = world.createBody(fixed);
  world.addShape(Shape::box(table, Vec3(0.5, 0.5, 0.1)));
  const BodyId ball = world.createBody(test::sphereBody(Vec3(2, 0, 0.1 + r + 0.05), 1.0, r));
  world.addShape(Shape::sphere(ball, r));

  // The static block is turned 45 degrees about y (its top is an edge
  // along y), the falling box 45 degrees about x (its bottom is an edge
  // along x): the edges cross.
  fixed.position = Vec3(4, 0, 0);
  fixed.orientation = Quat(Eigen::AngleAxisd(kPi / 4, Vec3::UnitY()));
  const BodyId block = world.createBody(fixed);
  world.addShape(Shape::box(block, Vec3(0.5, 0.5, 0.5)));
  const double edgeHeight = 0.5 * std::sqrt(2.0) + 0.25 * std::sqrt(2.0);
  BodyDesc d = boxBody(Vec3(4, 0, edgeHeight + 0.02), 1.0, Vec3(0.5, 0.5, 0.5));
  d.orientation = Quat(Eigen::AngleAxisd(kPi / 4, Vec3::UnitX()));
  const BodyId tilted = world.createBody(d);
  world.addShape(Shape::box(tilted, Vec3(0.25, 0.25, 0.25)));

  test::stepN(world, 30, 1.0 / 60.0);
  // Only the first half second: the sphere on a sphere and the box on its
  // edge are unstable balances, but they must first land where they touch.
  EXPECT_NEAR(world.body(top).position.z(), 2 * r, 1e-3);
  EXPECT_NEAR(world.body(ball).position.z(), 0.1 + r, 1e-3);
  EXPECT_NEAR(world.body(tilted).position.z(), edgeHeight, 2e-3);
  bool edgeContact = false;  // one point from the edge-edge branch of the SAT
  for (const ContactManifold& m : world.contacts()) {
    if (m.bodyA == tilted || m.bodyB == tilted) {
      edgeContact = m.pointCount == 1 && m.points[0].feature >= 100;
    }
  }
  EXPECT_TRUE(edgeContact);
}

TEST(Contact, SurfaceNormalVelocityAndCorrectionCap) {
  // motionN = 0.5 m/s: a resting box is pushed off the surface at that
  // speed. A box starting 5 cm deep comes out no faster than the cap.
  {
    World world;
    world.setGravity(Vec3::Zero());
    const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.25), 1.0, Vec3(0.5, 0.5, 0.5)));
    ContactManifold m = groundContact(world, box, 0.25);
    m.surface.motionN = 0.5;
    world.addContact(m);
    world.step(1.0 / 60.0);
    EXPECT_NEAR(world.body(box).linearVelocity.z(), 0.5, 1e-4);  // less CFM's give
  }
  {
    World world;
    world.setGravity(Vec3::Zero());
    const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.2), 1.0, Vec3(0.5, 0.5, 0.5)));
    ContactManifold m = groundContact(world, box, 0.25);
    m.surface.softness = Softness::erpCfm(1.0, 0.0);  // would remove all 5 cm in one step
    m.surface.maxCorrectingVelocity = 0.3;
    world.addContact(m);
    world.step(1.0 / 60.0);
    EXPECT_NEAR(world.body(box).linearVelocity.z(), 0.3, 1e-6);
  }
}

// One manifold whose points push along different normals (a ball landing
// in a V groove, walls 20 degrees off level) is one block: one sweep
// stops the fall on both walls at once and leaves no sideways velocity.
// Point by point, the wall solved first would throw the ball sideways.
TEST(Contact, PointsAlongDifferentNormalsAreSolvedTogether) {
  const double tilt = 20.0 * kPi / 180.0, r = 0.4;
  World world;
  SolverSettings s = SolverSettings::paper(1);  // one sweep, no relax
  s.warmStarting = false;
  world.setSettings(s);
  BodyDesc d = test::sphereBody(Vec3(0, 0, r / std::cos(tilt)), 1.0, r);
  d.linearVelocity = Vec3(0, 0, -3.0);
  const BodyId ball = world.createBody(d);
  ContactManifold m;
  m.bodyB = ball;
  m.normal = Vec3::UnitZ();
  m.pointCount = 2;
  m.surface.mu = 0.0;
  m.surface.softness = Softness::erpCfm(0.2, 0.0);
  for (int k = 0; k < 2; ++k) {
    const Vec3 n(0.0, (k == 0 ? 1.0 : -1.0) * std::sin(tilt), std::cos(tilt));
    m.points[k].normal = n;
    m.points[k].position = world.body(ball).position - r * n;
  }
  world.addContact(m);
  world.step(1.0 / 60.0);
  const Vec3 v = world.body(ball).linearVelocity;
  EXPECT_NEAR(v.y(), 0.0, 1e-9) << "a symmetric landing pushes both walls alike";
  EXPECT_NEAR(v.z(), 0.0, 1e-9) << "both walls stop the fall in one sweep";
  // Closed form: two equal pushes along the walls' normals carry the
  // ball's 3 N s and the step's weight.
  const double carried = 3.0 + 9.81 / 60.0;
  for (int k = 0; k < 2; ++k)
    EXPECT_NEAR(world.contacts()[0].points[k].stepNormalImpulse, carried / (2.0 * std::cos(tilt)),
                1e-9);
}

// A surface moving along its normal (ODE motionN: a lift the caller moves
// each step) keeps moving through the sub-steps: a box riding it moves at
// its speed and stays on it. The gap measured from where the collision
// left the surface let the box fall back within each step: it rode
// 1.1 mm deep at 0.2426 of 0.25 m/s with 10 sub-steps.
TEST(Contact, BodyRidesASurfaceMovingAlongItsNormal) {
  const double speed = 0.25, h = 0.02, half = 0.15;
  World world;
  world.setGravity(Vec3(0, 0, -0.5));
  world.setSettings(SolverSettings::subStepped(10));
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, half), 0.3, Vec3(0.3, 0.3, 0.3)));
  double lift = 0.0;  // the surface's height
  for (int k = 0; k < 100; ++k) {
    ContactManifold m = groundContact(world, box, half);
    for (int i = 0; i < 4; ++i)
      m.points[i].separation -= lift;
    m.surface.motionN = speed;
    world.addContact(m);
    world.step(h);
    lift += speed * h;
  }
  const Body& b = world.body(box);
  EXPECT_NEAR(b.linearVelocity.z(), speed, 1e-4);
  EXPECT_NEAR(b.position.z() - half, lift, 5e-4);
}

// Restitution off a moving surface reverses the speed relative to it, as
// ODE defines it: a box meeting a lift rising at 0.25 m/s at 1 m/s leaves
// at 0.25 + 0.25 (1 + 0.25) = 0.5625 m/s (relative to the ground it met
// the lift at 1 m/s and would leave at 0.5).
TEST(Contact, BounceOffAMovingSurfaceIsRelativeToIt) {
  for (int substeps : {1, 10}) {
    World world;
    world.setGravity(Vec3::Zero());
    world.setSettings(SolverSettings::subStepped(substeps));
    BodyDesc d = boxBody(Vec3(0, 0, 0.25), 1.0, Vec3(0.5, 0.5, 0.5));
    d.linearVelocity = Vec3(0, 0, -1.0);
    const BodyId box = world.createBody(d);
    ContactManifold m = groundContact(world, box, 0.25);
    m.surface.motionN = 0.25;
    m.surface.restitution = 0.25;
    m.surface.restitutionThreshold = 0.01;
    world.addContact(m);
    world.step(1.0 / 60.0);
    EXPECT_NEAR(world.body(box).linearVelocity.z(), 0.5625, 1e-4) << substeps << " sub-steps";
  }
}

// A half-metre box `gap` above the ground, moving at vz, stepped once.
BodyId stepBoxAboveGround(World& world, double gap, double vz) {
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const BodyId box = addBox(world, Vec3(0, 0, 0.25 + gap), 1.0, Vec3(0.25, 0.25, 0.25));
  world.setLinearVelocity(box, Vec3(0, 0, vz));
  world.step(1.0 / 60.0);
  return box;
}

TEST(Contact, SpeculativeContactsNeverPull) {
  // A box above the ground gets contact points when it can reach the
  // ground within the step (its speed times the step, plus the 4 mm
  // resting margin), but moves freely until it touches: exactly g for
  // the first step, approaching (12 mm up at 0.5 m/s: it reaches 12.3 mm
  // and falls 9.7) or leaving (3 mm up, rising), and it lands without
  // bouncing or sticking above the ground.
  for (const double vz : {-0.5, 0.5}) {
    World world;
    const BodyId box = stepBoxAboveGround(world, vz < 0.0 ? 0.012 : 0.003, vz);
    ASSERT_EQ(world.contacts().size(), 1u) << vz;
    EXPECT_NEAR(world.body(box).linearVelocity.z(), vz - 9.81 / 60.0, 1e-12) << vz;
    for (int k = 0; k < 4; ++k)
      EXPECT_EQ(world.contacts()[0].points[k].normalImpulse, 0.0) << vz;
    test::stepN(world, 60, 1.0 / 60.0);
    EXPECT_NEAR(world.body(box).position.z(), 0.25, 0.005 + 1e-4) << "rests within the slop";
  }
}

// The reach follows motion: a box at rest 10 mm above the ground (it
// falls 2.7 mm in the step) gets no speculative points, where a fixed
// 20 mm margin gave it four; thrown down at 1 m/s from 18 mm up (17 mm a
// step) it gets them, and stops at the ground within the step.
TEST(Contact, SpeculativeReachIsHowFarTheBodyCanMove) {
  for (const double vz : {0.0, -1.0}) {
    World world;
    const BodyId box = stepBoxAboveGround(world, vz < 0.0 ? 0.018 : 0.010, vz);
    EXPECT_EQ(world.contacts().size(), vz < 0.0 ? 1u : 0u) << vz;
    if (vz < 0.0) {
      EXPECT_GT(world.body(box).position.z(), 0.25 - 0.001) << "stopped at the ground";
    }
  }
}

// What a collider that reports one deepest point does (ODE's cylinder-
// plane for a coin, its convex-convex): the lowest bottom corner of a box
// on the ground, alone.
ContactManifold deepestCorner(const World& world, BodyId box, double half, double mu) {
  ContactManifold all = groundContact(world, box, half);
  int deepest = 0;
  for (int k = 1; k < 4; ++k)
    if (all.points[k].separation < all.points[deepest].separation) deepest = k;
  ContactManifold m = all;
  m.pointCount = 1;
  m.points[0] = all.points[deepest];
  m.points[0].feature = 0;  // no ids, as ODE gives none
  m.surface.mu = mu;
  return m;
}

// Contact persistence (World::setContactPersistence) against a collider
// that gives one point a step: the box, tipped 3 degrees, must come to
// rest flat on its face (the points of earlier steps carried), and
// carrying must not add friction (a box slides v^2 / (2 mu g)). A ball's
// single point holds it alone and is never carried.
TEST(Contact, PersistenceRestsABoxGivenOnlyItsDeepestCorner) {
  for (const double persistence : {0.0, 0.02}) {
    World world;
    world.setContactPersistence(persistence);
    BodyDesc d = boxBody(Vec3(0, 0, 0.52), 2.0, Vec3(1, 1, 1));
    d.orientation = Quat(Eigen::AngleAxisd(3.0 * kPi / 180.0, Vec3(1, 1, 0).normalized()));
    const BodyId box = world.createBody(d);
    double lastRotation = 0.0;
    for (int i = 0; i < 300; ++i) {
      if (deepestCorner(world, box, 0.5, 0.6).points[0].separation < 0.01)
        world.addContact(deepestCorner(world, box, 0.5, 0.6));
      world.step(1.0 / 60.0);
      lastRotation = rotationDegrees(world.body(box).orientation);
    }
    std::printf("  persistence %.2f m: tilt after 5 s %.3f deg, height %.4f m, %d points\n",
                persistence, lastRotation, world.body(box).position.z(),
                world.contacts().empty() ? 0 : world.contacts()[0].pointCount);
    if (persistence == 0.0) continue;
    EXPECT_LT(lastRotation, 0.2);
    EXPECT_NEAR(world.body(box).position.z(), 0.5, 2e-3);
    ASSERT_EQ(world.contacts().size(), 1u);
    EXPECT_EQ(world.contacts()[0].pointCount, 4);
    int carried = 0;
    for (int k = 0; k < 4; ++k)
      carried += world.contacts()[0].points[k].carried;
    EXPECT_EQ(carried, 3);
  }
  {
    World world;
    world.setContactPersistence(0.02);
    const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0.5), 2.0, Vec3(1, 1, 1)));
    world.setLinearVelocity(box, Vec3(3.0, 0.0, 0.0));
    for (int i = 0; i < 120; ++i) {
      world.addContact(deepestCorner(world, box, 0.5, 0.3));
      world.step(1.0 / 60.0);
    }
    const double analytic = 3.0 * 3.0 / (2.0 * 0.3 * 9.81);
    EXPECT_NEAR(world.body(box).position.x(), analytic, 0.02 * analytic);
  }
  {
    World world;
    world.setContactPersistence(0.02);
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const BodyId ball = world.createBody(test::sphereBody(Vec3(0, 0, 0.5), 1.0, 0.5));
    world.addShape(Shape::sphere(ball, 0.5));
    world.setLinearVelocity(ball, Vec3(1.0, 0.0, 0.0));
    world.setAngularVelocity(ball, Vec3(0.0, 2.0, 0.0));
    for (int i = 0; i < 60; ++i) {
      world.step(1.0 / 60.0);
      ASSERT_EQ(world.contacts().size(), 1u);
      EXPECT_EQ(world.contacts()[0].pointCount, 1);
    }
  }
}

// Each contact point says how round its two surfaces are there
// (ContactPoint::radiusA): sub-steps follow a round surface's centre.
TEST(Contact, PointsSayHowRoundTheirSurfacesAre) {
  World world;
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  auto add = [&](const Shape& shape, const Vec3& at, const Quat& q) {
    BodyDesc d = test::boxBody(at, 1.0, Vec3(0.2, 0.2, 0.2));
    d.orientation = q;
    Shape s = shape;
    s.body = world.createBody(d);
    world.addShape(s);
    return s.body;
  };
  const Quat lying(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));
  const BodyId sphere = add(Shape::sphere(0, 0.1), Vec3(0, 0, 0.099), Quat::Identity());
  const BodyId capsule = add(Shape::capsule(0, 0.1, 0.3), Vec3(1, 0, 0.099), lying);
  const BodyId wheel = add(Shape::cylinder(0, 0.2, 0.1), Vec3(2, 0, 0.199), lying);
  const BodyId drum = add(Shape::cylinder(0, 0.2, 0.1), Vec3(3, 0, 0.049), Quat::Identity());
  const BodyId box = add(Shape::box(0, Vec3(0.1, 0.1, 0.1)), Vec3(4, 0, 0.099), Quat::Identity());
  world.step(1.0 / 60.0);
  const std::map<BodyId, double> expected = {
      {sphere, 0.1}, {capsule, 0.1}, {wheel, 0.2}, {drum, 0.0}, {box, 0.0}};
  int points = 0;
  for (const ContactManifold& m : world.contacts()) {
    ASSERT_EQ(m.bodyA, kWorldBody);
    for (int i = 0; i < m.pointCount; ++i, ++points) {
      EXPECT_EQ(m.points[i].radiusA, 0.0) << "the plane";
      EXPECT_DOUBLE_EQ(m.points[i].radiusB, expected.at(m.bodyB)) << "body " << m.bodyB;
    }
  }
  EXPECT_GE(points, 5);
}

// A capsule (the ragdoll's head: 5 kg, r 8 cm, 14 cm long) on a ball joint
// at one end, its other end on the ground, rolling round the joint at 30
// rad/s about the line from the joint to the contact. Rolling without
// slipping gives the system no energy, so it may keep its energy or lose
// some, not gain. Before the contact followed the end cap's centre through
// the sub-steps and a held body's gyroscopic step turned with the rate the
// solve leaves, it gained 65 J at 1 sub-step, 533 J at 4 and 1,094 J at 10
// in 10 s colliding once a step (from 16 J of kinetic energy), and 5,723 J
// at 10 colliding every sub-step; ODE's steppers on the same head lose
// about half of it in 20 s. Bounded here at 1% of
// the kinetic energy: colliding every sub-step at 10 sub-steps it still
// gains 0.05 J in 10 s, steadily (and more with more sweeps a sub-step:
// README, Contacts).
TEST(Contact, CapsuleRollingRoundABallJointAtItsEndGainsNoEnergy) {
  const double r = 0.08, length = 0.14, w0 = 30.0;
  const Vec3 neck(0, 0, 0.219);
  const double reach = length + r;  // the joint to the far cap's centre
  const Vec3 axis =
      Vec3(-std::sqrt(reach * reach - (neck.z() - r) * (neck.z() - r)), 0.0, r - neck.z())
          .normalized();
  const Vec3 touching = neck + reach * axis - Vec3(0, 0, r);
  for (const bool everySubstep : {false, true}) {
    for (const int substeps : {1, 4, 10}) {
      World world;
      SolverSettings settings = SolverSettings::subStepped(substeps);
      settings.maxTurnPerSubstep = 0.0;  // the count asked for
      settings.gyroscopic = true;
      world.setSettings(settings);
      CollisionSettings& collision = world.collisionSettings();
      collision.everySubstep = everySubstep;
      collision.surfaceFromShapes = false;
      collision.surface.mu = 1.0;
      collision.surface.slop = 0.0;  // the load on the surface, not a layer below it
      world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
      BodyDesc d;
      d.position = neck + (0.5 * length + r) * axis;
      d.orientation = Quat::FromTwoVectors(Vec3::UnitZ(), axis);
      const MassProperties m = capsuleMass(5.0, r, length);
      d.mass = m.mass;
      d.inertia = m.inertia;
      d.angularVelocity = w0 * (touching - neck).normalized();
      d.linearVelocity = d.angularVelocity.cross(d.position - neck);
      const BodyId head = world.createBody(d);
      world.addShape(Shape::capsule(head, r, length));
      BallJointDesc ball;
      ball.common.bodyB = head;
      ball.anchor = neck;
      world.createJoint(ball);
      auto energy = [&] {
        const Body& b = world.body(head);
        const Mat3 R = b.orientation.toRotationMatrix();
        return 0.5 * b.mass * b.linearVelocity.squaredNorm() +
               0.5 * b.angularVelocity.dot(R * m.inertia * R.transpose() * b.angularVelocity) +
               b.mass * 9.81 * b.position.z();
      };
      const double start = energy();
      const Mat3 R0 = d.orientation.toRotationMatrix();
      const double kinetic =
          0.5 * d.angularVelocity.dot(R0 * m.inertia * R0.transpose() * d.angularVelocity) +
          0.5 * m.mass * d.linearVelocity.squaredNorm();
      double most = 0.0;
      for (int frame = 0; frame < 600; ++frame) {  // 10 s
        world.step(1.0 / 60.0);
        most = std::max(most, energy() - start);
      }
      const double spin = world.body(head).angularVelocity.norm();
      std::printf(
          "  %2d sub-steps, colliding %s: most energy gained %.4f J, %.1f rad/s after 10 s\n",
          substeps, everySubstep ? "every sub-step" : "once a step", most, spin);
      EXPECT_LT(most, 0.01 * kinetic) << substeps << " sub-steps";
      EXPECT_GT(spin, 10.0) << "it rolls on";
    }
  }
}

}  // namespace
}  // namespace blockstep

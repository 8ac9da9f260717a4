// The broad phase, and capsules, cylinders and hulls resting in a world.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "core/collision/broadphase.h"
#include "core/collision/narrowphase.h"
#include "core/collision/support.h"
#include "support/landing_load.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

Shape randomShape(std::mt19937& rng, BodyId body) {
  std::uniform_real_distribution<double> size(0.05, 0.4);
  switch (rng() % 5) {
    case 0:
      return Shape::sphere(body, size(rng));
    case 1:
      return Shape::capsule(body, size(rng) / 2, size(rng));
    case 2:
      return Shape::cylinder(body, size(rng) / 2, size(rng));
    case 3:
      return Shape::box(body, Vec3(size(rng), size(rng), size(rng)) / 2);
    default: {
      std::vector<Vec3> points;
      std::normal_distribution<double> gauss(0.0, 0.1);
      for (int i = 0; i < 12; ++i)
        points.push_back(Vec3(gauss(rng), gauss(rng), gauss(rng)));
      return Shape::convex(body,
                           std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points)));
    }
  }
}

TEST(BroadPhase, AllPairsAndSweepAndPruneFindTheSamePairsAsEveryBoxTestedWithEvery) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> place(-3.0, 3.0), angle(-kPi, kPi);
  std::vector<Shape> shapes;
  std::vector<ShapePose> poses;
  for (int i = 0; i < 1000; ++i) {
    shapes.push_back(randomShape(rng, 0));
    const Quat q(Eigen::AngleAxisd(angle(rng), Vec3(place(rng), place(rng), 1.0).normalized()));
    poses.push_back(ShapePose{Vec3(place(rng), place(rng), place(rng)), q.toRotationMatrix()});
  }
  shapes.push_back(Shape::plane(Vec3::UnitZ(), 0.0));
  poses.push_back(ShapePose{Vec3::Zero(), Mat3::Identity()});
  shapes[17].alive = false;
  BroadPhase allPairs, sweep;
  std::vector<Aabb> boxes(shapes.size());
  std::vector<std::pair<int, int>> expected, a, b;
  std::size_t total = 0;
  for (int step = 0; step < 5; ++step) {
    for (std::size_t i = 0; i < shapes.size(); ++i)
      boxes[i] = shapeAabb(shapes[i], poses[i], 0.01);
    expected.clear();
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
      for (int j = i + 1; j < static_cast<int>(boxes.size()); ++j)
        if (boxes[i].overlaps(boxes[j])) expected.emplace_back(i, j);
    allPairs.findPairs(boxes, BroadPhaseMethod::AllPairs, a);
    sweep.findPairs(boxes, BroadPhaseMethod::SweepAndPrune, b);
    EXPECT_EQ(a, expected);
    EXPECT_EQ(b, expected) << "step " << step;
    total += expected.size();
    // Move everything a little, as a step would: the sweep keeps its order.
    for (ShapePose& p : poses)
      p.position += Vec3(place(rng), place(rng), place(rng)) * 0.05;
  }
  EXPECT_GT(total, 5000u);  // the plane alone meets about half the shapes each step
}

// Sweep and prune sweeps along the axis that leaves the fewest boxes to
// test, reviewed every kAxisReview calls: a column 30 m tall is swept
// along z, the same boxes laid 60 m wide along x along x. The pairs are
// every box tested with every other's on every call, before and after the
// axis turns.
TEST(BroadPhase, SweepTakesTheAxisWithFewestTestsAndFindsTheSamePairs) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> across(-0.5, 0.5), along(0.0, 30.0), jiggle(-0.01, 0.01);
  std::vector<Shape> shapes;
  std::vector<ShapePose> poses;
  for (int i = 0; i < 600; ++i) {
    shapes.push_back(randomShape(rng, 0));
    poses.push_back(ShapePose{Vec3(across(rng), across(rng), along(rng)), Mat3::Identity()});
  }
  shapes.push_back(Shape::plane(Vec3::UnitZ(), -1.0));
  poses.push_back(ShapePose{Vec3::Zero(), Mat3::Identity()});
  BroadPhase sweep;
  std::vector<Aabb> boxes(shapes.size());
  std::vector<std::pair<int, int>> expected, found;
  // kAxisReview calls, the shapes moved a little before each.
  auto run = [&](int axis, const char* what) {
    for (int call = 0; call < BroadPhase::kAxisReview; ++call) {
      for (std::size_t i = 0; i + 1 < shapes.size(); ++i) {
        poses[i].position += Vec3(jiggle(rng), jiggle(rng), jiggle(rng));
        boxes[i] = shapeAabb(shapes[i], poses[i], 0.01);
      }
      boxes.back() = shapeAabb(shapes.back(), poses.back(), 0.01);
      expected.clear();
      for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
        for (int j = i + 1; j < static_cast<int>(boxes.size()); ++j)
          if (boxes[i].overlaps(boxes[j])) expected.emplace_back(i, j);
      sweep.findPairs(boxes, BroadPhaseMethod::SweepAndPrune, found);
      ASSERT_EQ(found, expected) << what << ", call " << call;
      ASSERT_GT(expected.size(), 600u) << what;  // the plane meets every shape
    }
    EXPECT_EQ(sweep.sweepAxis(), axis) << what;
  };
  run(2, "standing");
  for (ShapePose& p : poses)
    p.position = Vec3(2.0 * p.position.z(), p.position.x(), p.position.y());
  run(0, "laid along x");
  for (ShapePose& p : poses)
    p.position = Vec3(p.position.y(), p.position.x(), p.position.z());
  run(1, "turned along y");
}

TEST(BroadPhase, BoxesHoldTheirShapes) {
  // Every support point of a shape, in any direction, lies in its box.
  std::mt19937 rng(3);
  std::normal_distribution<double> gauss;
  for (int i = 0; i < 200; ++i) {
    const Shape s = randomShape(rng, 0);
    const Quat q = Quat(gauss(rng), gauss(rng), gauss(rng), gauss(rng)).normalized();
    const ShapePose pose{Vec3(gauss(rng), gauss(rng), gauss(rng)), q.toRotationMatrix()};
    const Aabb box = shapeAabb(s, pose, 0.0);
    const PosedConvex c(s, pose);
    for (int k = 0; k < 50; ++k) {
      const Vec3 d = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
      const Vec3 p = c.coreSupport(d) + c.radius * d;
      EXPECT_TRUE((p.array() >= box.lo.array() - 1e-12).all() &&
                  (p.array() <= box.hi.array() + 1e-12).all())
          << "shape kind " << static_cast<int>(s.kind);
    }
  }
}

// A body resting on the ground plane from `shape`, with mass from `mass`.
struct Resting {
  World world;
  BodyId body;
};

void dropOnGround(Resting& r, const Shape& shape, const MassProperties& mass, const Vec3& position,
                  const Quat& q) {
  r.world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  BodyDesc d;
  d.position = position;
  d.orientation = q;
  d.mass = mass.mass;
  d.inertia = mass.inertia;
  r.body = r.world.createBody(d);
  Shape s = shape;
  s.body = r.body;
  r.world.addShape(s);
}

TEST(ConvexWorld, CapsuleLyingDownAndCylinderStandingUpRestWithoutRolling) {
  Resting capsule;
  dropOnGround(capsule, Shape::capsule(0, 0.1, 0.6), capsuleMass(2.0, 0.1, 0.6), Vec3(0, 0, 0.1),
               Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY())));
  Resting cylinder;
  dropOnGround(cylinder, Shape::cylinder(0, 0.2, 0.5), cylinderMass(3.0, 0.2, 0.5),
               Vec3(0, 0, 0.25), Quat::Identity());
  for (Resting* r : {&capsule, &cylinder}) {
    const Vec3 start = r->world.body(r->body).position;
    test::stepN(r->world, 600, 1.0 / 60.0);  // 10 s
    const Body& b = r->world.body(r->body);
    EXPECT_LT((b.position - start).norm(), 5e-3);
    EXPECT_LT(b.linearVelocity.norm(), 1e-3);
    EXPECT_LT(b.angularVelocity.norm(), 1e-3);
    ASSERT_EQ(r->world.contacts().size(), 1u);
    EXPECT_EQ(r->world.contacts()[0].pointCount, r == &capsule ? 2 : 4);
  }
}

TEST(ConvexWorld, BadShapesAreRefusedAndLeaveTheWorldAsItWas) {
  World world;
  const BodyId b = world.createBody(test::sphereBody(Vec3::Zero(), 1.0, 0.1));
  EXPECT_THROW(world.addShape(Shape::capsule(b, -0.1, 1.0)), Error);
  EXPECT_THROW(world.addShape(Shape::capsule(b, 0.1, std::nan(""))), Error);
  EXPECT_THROW(world.addShape(Shape::cylinder(b, 0.1, 0.0)), Error);
  EXPECT_THROW(world.addShape(Shape::convex(b, nullptr)), Error);
  // A capsule of length 0 is a sphere, and is accepted.
  EXPECT_EQ(world.addShape(Shape::capsule(b, 0.1, 0.0)), 0);
}

TEST(ConvexWorld, CylinderOnItsSideRollsDownAnIncline) {
  // A solid cylinder rolling without slipping accelerates at 2/3 g sin.
  World world;
  const double slope = 10.0 * kPi / 180.0;
  const Quat tilt(Eigen::AngleAxisd(slope, Vec3::UnitX()));
  Shape ground = Shape::plane(tilt * Vec3::UnitZ(), 0.0);
  ground.friction = 1.0;
  world.addShape(ground);
  BodyDesc d;
  const MassProperties m = cylinderMass(1.0, 0.1, 0.3);
  d.mass = m.mass;
  d.inertia = m.inertia;
  d.orientation = tilt * Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()));  // axis across the slope
  d.position = tilt * Vec3(0, 0, 0.1);
  const BodyId b = world.createBody(d);
  Shape s = Shape::cylinder(b, 0.1, 0.3);
  s.friction = 1.0;
  world.addShape(s);
  test::stepN(world, 60, 1.0 / 60.0);  // 1 s
  const double expected = 2.0 / 3.0 * 9.81 * std::sin(slope);
  EXPECT_NEAR(world.body(b).linearVelocity.norm(), expected, 0.05 * expected);
}

// A box-like hull whose bottom is a shallow pyramid: four corners at
// z = 0 and a centre vertex 20 mm below them.
std::shared_ptr<const ConvexHull> pointedBottomHull() {
  std::vector<Vec3> points = {Vec3(0, 0, -0.02)};
  for (int c = 0; c < 8; ++c)
    points.push_back(Vec3(c & 1 ? 0.1 : -0.1, c & 2 ? 0.1 : -0.1, c & 4 ? 0.1 : 0.0));
  return std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points));
}

TEST(ConvexWorld, AHullOnAVertexTouchesTheGroundWithEveryVertexWithinTheMargin) {
  // Standing on its centre vertex, corners 10 mm up: the centre (the
  // deepest, first) and three corners, where the support vertex alone let
  // a hull rock from one vertex to another.
  const Shape ground = Shape::plane(Vec3::UnitZ(), 0.0);
  const Shape hull = Shape::convex(0, pointedBottomHull());
  ContactManifold m;
  ASSERT_EQ(
      collideConvexPlane(ground, hull, ShapePose{Vec3(0, 0, 0.0199), Mat3::Identity()}, 0.02, m),
      4);
  EXPECT_NEAR(m.points[0].separation, -1e-4, 1e-12);
  for (int k = 1; k < 4; ++k)
    EXPECT_NEAR(m.points[k].separation, 0.0199, 1e-12);
}

TEST(ConvexWorld, AHullPressedInOnItsDeepestVertexIsPushedOut) {
  // The same hull at rest with its centre vertex 23 mm deep and its corners
  // 3 mm deep: five points within the margin, kept as four with the
  // deepest first, and the push-out lifts it back to the slop.
  World world;
  world.setSettings(SolverSettings::subStepped(4));
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const MassProperties mass = hullMass(*pointedBottomHull(), 500.0);
  std::vector<Vec3> centred = pointedBottomHull()->vertices();
  for (Vec3& v : centred)
    v -= mass.centre;  // the body's origin at the centre of mass
  const auto hull = std::make_shared<const ConvexHull>(ConvexHull::fromPoints(centred));
  BodyDesc d;
  d.position = Vec3(0, 0, -0.003) - mass.centre;
  d.mass = mass.mass;
  d.inertia = mass.inertia;
  const BodyId b = world.createBody(d);
  world.addShape(Shape::convex(b, hull));
  test::stepN(world, 60, 1.0 / 60.0);
  double lowest = kInf;
  for (const Vec3& v : hull->vertices())
    lowest = std::min(lowest, (world.body(b).position + world.body(b).orientation * v).z());
  EXPECT_GT(lowest, -0.006) << "the slop is 5 mm";
}

// A hundred random hulls (10 points each, about 0.2 m across) dropped in
// a heap, three heaps, under the sub-stepped preset (4 sub-steps, warm
// started): after 8 s every body rests. Before a hull's ground contact
// held every vertex within the margin, a hull tipping between two of its
// faces got its support vertex alone, rocked from one vertex to the other
// each step 14 mm deep, and one heap in five never came to rest.
TEST(ConvexWorld, PileOfHundredHullsSettlesAndRestsOnContactsAtTheirTrueDepth) {
  for (unsigned seed : {2u, 5u, 8u}) {
    World world;
    world.setSettings(SolverSettings::subStepped(4));
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, 0.06);
    std::uniform_real_distribution<double> place(-0.6, 0.6);
    std::vector<BodyId> bodies;
    std::vector<std::shared_ptr<const ConvexHull>> hulls;
    for (int i = 0; i < 100; ++i) {
      std::vector<Vec3> points;
      for (int k = 0; k < 10; ++k)
        points.push_back(Vec3(gauss(rng), gauss(rng), gauss(rng)));
      auto hull = std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points));
      const MassProperties m = hullMass(*hull, 500.0);
      // The body's origin at the hull's centre of mass.
      std::vector<Vec3> centred = hull->vertices();
      for (Vec3& v : centred)
        v -= m.centre;
      hull = std::make_shared<const ConvexHull>(ConvexHull::fromPoints(centred));
      BodyDesc d;
      d.position = Vec3(place(rng), place(rng), 0.2 + 0.15 * i / 4);
      d.mass = m.mass;
      d.inertia = m.inertia;
      const BodyId b = world.createBody(d);
      world.addShape(Shape::convex(b, hull));
      bodies.push_back(b);
      hulls.push_back(hull);
    }
    test::stepN(world, 480, 1.0 / 60.0);  // 8 s
    double fastest = 0.0, meanSpeed = 0.0;
    for (BodyId b : bodies) {
      fastest = std::max(fastest, world.body(b).linearVelocity.norm());
      meanSpeed += world.body(b).linearVelocity.norm() / bodies.size();
    }
    std::printf("heap %u after 8 s: mean speed %.2g m/s, fastest %.2g m/s\n", seed, meanSpeed,
                fastest);
    EXPECT_LT(meanSpeed, 2e-4) << "heap " << seed << " still moves";
    EXPECT_LT(fastest, 5e-3) << "heap " << seed;
    // Each body's ground contact reports the depth of its lowest vertex
    // (measured after the step moved it by at most a few tenths of a mm).
    int grounded = 0;
    for (const ContactManifold& m : world.contacts()) {
      if (m.bodyA != kWorldBody) continue;
      const std::size_t i = static_cast<std::size_t>(m.bodyB - bodies.front());
      const Body& body = world.body(m.bodyB);
      double lowest = kInf, reported = kInf;
      for (const Vec3& v : hulls[i]->vertices())
        lowest = std::min(lowest, (body.position + body.orientation * v).z());
      for (int k = 0; k < m.pointCount; ++k)
        reported = std::min(reported, m.points[k].separation);
      EXPECT_NEAR(reported, lowest, 5e-4) << "body " << m.bodyB;
      // The depth left is the solver's under a load (the slop is 5 mm).
      EXPECT_GT(lowest, -0.0075) << "heap " << seed << ", body " << m.bodyB;
      ++grounded;
    }
    EXPECT_GT(grounded, 40);
  }
}

// A ball thrown at 6 m/s against a wall moves 0.1 m a frame at 60 Hz,
// five times the 20 mm margin: colliding once a frame, it is 80 mm off the
// wall at one frame's start (no contact yet) and 20 mm inside it by the
// next. Colliding every sub-step (10 mm each) the speculative contact
// stops it at the wall.
double deepestIntoWall(bool everySubstep) {
  World world;
  world.setGravity(Vec3::Zero());
  SolverSettings settings = world.settings();
  settings.substeps = 10;
  world.setSettings(settings);
  world.collisionSettings().everySubstep = everySubstep;
  const double face = 0.33;  // the wall's face, x
  Shape wall = Shape::box(kWorldBody, Vec3(0.1, 1.0, 1.0));
  wall.localPosition = Vec3(face + 0.1, 0, 0);
  world.addShape(wall);
  const double r = 0.05;
  const BodyId ball = world.createBody(test::sphereBody(Vec3::Zero(), 1.0, r));
  world.addShape(Shape::sphere(ball, r));
  world.setLinearVelocity(ball, Vec3(6.0, 0, 0));
  double deepest = 0.0;
  for (int frame = 0; frame < 30; ++frame) {
    world.step(1.0 / 60.0);
    deepest = std::max(deepest, world.body(ball).position.x() + r - face);
  }
  EXPECT_LT(world.body(ball).linearVelocity.x(), 0.05) << "the ball should stop at the wall";
  EXPECT_GT(world.body(ball).linearVelocity.x(), -0.5) << "and not bounce off it";
  return deepest;
}

TEST(ConvexWorld, CollidingEverySubstepStopsAFastBallAtTheWall) {
  EXPECT_GT(deepestIntoWall(false), 0.015);
  EXPECT_LT(deepestIntoWall(true), 1e-3);
}

TEST(ConvexWorld, CollidingEverySubstepAppliesForcesOverTheWholeStep) {
  World world;
  world.setGravity(Vec3(0, 0, -9.81));
  SolverSettings settings = world.settings();
  settings.substeps = 4;
  world.setSettings(settings);
  world.collisionSettings().everySubstep = true;
  world.addShape(Shape::plane(Vec3::UnitZ(), -10.0));
  const BodyId b = world.createBody(test::sphereBody(Vec3(0, 0, 1), 2.0, 0.1));
  world.addShape(Shape::sphere(b, 0.1));
  world.addForce(b, Vec3(3.0, 0, 0));
  const double h = 0.02;
  world.step(h);
  EXPECT_NEAR(world.body(b).linearVelocity.x(), 3.0 / 2.0 * h, 1e-12);
  EXPECT_NEAR(world.body(b).linearVelocity.z(), -9.81 * h, 1e-12);
  EXPECT_TRUE(world.body(b).force.isZero()) << "cleared once the step is over";
  EXPECT_EQ(world.lastStepStats().substeps, 4);
}

// lastStepStats().deepestFound: the deepest point the world's own
// collision found in the step, at any part. Two balls pressed 8 and 12 mm
// into the ground (past the 5 mm slop), no gravity: each step's collision
// at its start finds the deeper ball exactly where it is (a ball against a
// plane is exact), the later parts only shallower as the contacts push
// out, so the step reports its start depth; pushed out, it reports less.
TEST(ConvexWorld, TheStepReportsTheDeepestContactItsCollisionFound) {
  for (const bool everySubstep : {false, true}) {
    SCOPED_TRACE(everySubstep ? "colliding every sub-step" : "colliding once a step");
    World world;
    world.setSettings(SolverSettings::subStepped(4));
    world.collisionSettings().everySubstep = everySubstep;
    world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
    const double r = 0.1;
    std::vector<BodyId> balls;
    for (const double depth : {0.008, 0.012}) {
      balls.push_back(world.createBody(test::sphereBody(Vec3(balls.size(), 0, r - depth), 1.0, r)));
      world.addShape(Shape::sphere(balls.back(), r));
    }
    EXPECT_EQ(world.lastStepStats().deepestFound, 0.0) << "nothing found before a step";
    double expected = 0.0;
    for (int step = 0; step < 6; ++step) {
      expected = 0.0;
      for (BodyId b : balls)
        expected = std::max(expected, r - world.body(b).position.z());
      world.step(1.0 / 60.0);
      EXPECT_NEAR(world.lastStepStats().deepestFound, expected, 1e-12) << "step " << step;
    }
    EXPECT_LT(expected, 0.012 - 1e-4) << "the balls should have been pushed out meanwhile";
  }
}

// Colliding every sub-step, a step takes shorter parts (down to
// maxSubstepFactor times) while a touching body turns its surface more
// than maxTurnPerSubstep a part: the contacts found at a part's start are
// solved linearized there, and a body turning far before the next
// collision brings other points of its surface into what it touches (in
// the 1,000-shape pile a light cylinder tumbling between two balls went
// 41 mm deep). A ball's turn moves none of its surface. Returns the most
// parts a step took and the deepest the body went below the ground.
struct TumbleRun {
  int mostParts = 0;
  double deepest = 0.0;
};
TumbleRun tumbleOnTheGround(bool ball) {
  World world;
  world.setSettings(SolverSettings::subStepped(10));
  world.collisionSettings().everySubstep = true;
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const Vec3 half(0.2, 0.02, 0.02);
  const double r = 0.05;
  BodyDesc d = ball ? test::sphereBody(Vec3(0, 0, r), 1.0, r)
                    : test::boxBody(Vec3(0, 0, 0.25), 1.0, 2.0 * half);
  d.angularVelocity = Vec3(0.0, 100.0, 0.0);               // 0.17 rad a sub-step
  if (ball) d.linearVelocity = Vec3(100.0 * r, 0.0, 0.0);  // rolling
  const BodyId b = world.createBody(d);
  world.addShape(ball ? Shape::sphere(b, r) : Shape::box(b, half));
  TumbleRun run;
  for (int frame = 0; frame < 30; ++frame) {
    world.step(1.0 / 60.0);
    run.mostParts = std::max(run.mostParts, world.lastStepStats().substeps);
    const Body& body = world.body(b);
    const Mat3 R = body.orientation.toRotationMatrix();
    for (int c = 0; c < 8; ++c) {
      const Vec3 corner(c & 1 ? half.x() : -half.x(), c & 2 ? half.y() : -half.y(),
                        c & 4 ? half.z() : -half.z());
      const double z = ball ? body.position.z() - r : (body.position + R * corner).z();
      run.deepest = std::max(run.deepest, -z);
    }
  }
  return run;
}

TEST(ConvexWorld, CollidingEverySubstepTakesShorterPartsWhileATouchingBodyTumbles) {
  const TumbleRun plank = tumbleOnTheGround(false);
  EXPECT_GT(plank.mostParts, 10);
  EXPECT_LE(plank.mostParts, 40);
  EXPECT_LT(plank.deepest, 0.005);
  const TumbleRun ball = tumbleOnTheGround(true);
  EXPECT_EQ(ball.mostParts, 10);
  EXPECT_LT(ball.deepest, 0.001);
}

// A part also holds how far a touching body's turn moves its shape's
// features (maxSurfaceTravelPerSubstep; World::surfaceTurnRate): 0.1 rad
// is 10 mm at the end of a 0.2 m cylinder. A 1 m plank spinning on
// frictionless ground at 9 rad/s about the vertical (0.015 rad a 1/600 s
// sub-step, well within the turn) moves its corners 0.5004 m x 9 / 600 =
// 7.5 mm a sub-step, which takes two parts of 5 mm; stood on its end, the
// same spin moves its corners 0.028 m x 9 / 600 = 0.42 mm, which takes
// one. Returns the most parts a step took after the first (which has no
// contacts to go by).
int partsSpinningOnIce(bool standing, double maxTravel) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(10);
  settings.maxSurfaceTravelPerSubstep = maxTravel;
  world.setSettings(settings);
  world.collisionSettings().everySubstep = true;
  Shape ground = Shape::plane(Vec3::UnitZ(), 0.0);
  ground.friction = 0.0;
  world.addShape(ground);
  const Vec3 half = standing ? Vec3(0.02, 0.02, 0.5) : Vec3(0.5, 0.02, 0.02);
  BodyDesc d = test::boxBody(Vec3(0, 0, half.z()), 1.0, 2.0 * half);
  d.angularVelocity = Vec3(0.0, 0.0, 9.0);
  const BodyId b = world.createBody(d);
  Shape plank = Shape::box(b, half);
  plank.friction = 0.0;
  world.addShape(plank);
  int mostParts = 0;
  for (int frame = 0; frame < 10; ++frame) {
    world.step(1.0 / 60.0);
    if (frame > 0) mostParts = std::max(mostParts, world.lastStepStats().substeps);
  }
  EXPECT_NEAR(world.body(b).angularVelocity.z(), 9.0, 1e-6) << "on ice nothing slows the spin";
  EXPECT_LT(std::abs(world.body(b).position.z() - half.z()), 1e-3) << "it rests on the ground";
  return mostParts;
}

TEST(ConvexWorld, CollidingEverySubstepHoldsATurningShapesTravelPerPart) {
  EXPECT_EQ(partsSpinningOnIce(false, SolverSettings::kMaxSurfaceTravelPerSubstep), 20);
  EXPECT_EQ(partsSpinningOnIce(false, 0.0), 10);  // the turn only
  EXPECT_EQ(partsSpinningOnIce(true, SolverSettings::kMaxSurfaceTravelPerSubstep), 10);
}

// The deepest point of the contacts the world's last collision found (m).
double deepestContact(const World& world) {
  double deepest = 0.0;
  for (const ContactManifold& m : world.contacts())
    for (int k = 0; k < m.pointCount; ++k)
      deepest = std::max(deepest, -m.points[k].separation);
  return deepest;
}

// A contact on a body a joint holds gives under the load it carries no
// more than under its own weight (SolverSettings::loadRelativeContacts).
// A 0.1 kg foot glued under a 10 kg block rests on the ground; its
// contacts' spring (the drop-in's, omega h = 0.4 a sub-step) relative to
// the foot's own mass gives gamma P under the block's load, and rests
// where the push-out rate beta / h (Solver::penetrationRate) meets it:
// a depth gamma P h / beta proportional to the load. Relative to the load
// it carries, the depth is what the foot's own weight alone would give:
// 0.1 / 10.1 of it. Returns the deepest contact of the last half second.
double footUnderABlock(bool loadRelative) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(10);
  settings.loadRelativeContacts = loadRelative;
  test::collidingEverySubstepOnSprings(world, settings);
  world.collisionSettings().surface.slop = 0.0;
  const Vec3 footHalf(0.05, 0.05, 0.05), blockHalf(0.1, 0.1, 0.1);
  const BodyId foot =
      world.createBody(test::boxBody(Vec3(0, 0, footHalf.z()), 0.1, 2.0 * footHalf));
  world.addShape(Shape::box(foot, footHalf));
  const BodyId block = world.createBody(
      test::boxBody(Vec3(0, 0, 2.0 * footHalf.z() + blockHalf.z()), 10.0, 2.0 * blockHalf));
  FixedJointDesc glue;
  glue.common.bodyA = foot;
  glue.common.bodyB = block;
  world.createJoint(glue);
  double deepest = 0.0;
  for (int frame = 0; frame < 60; ++frame) {
    world.step(1.0 / 60.0);
    if (frame < 30) continue;
    deepest = std::max(deepest, deepestContact(world));
  }
  return deepest;
}

TEST(ConvexWorld, AFootUnderAHeavyBlockGivesNoMoreUnderItsLoadThanUnderItsWeight) {
  const double ownMass = footUnderABlock(false);
  const double load = footUnderABlock(true);
  std::printf(
      "  0.1 kg foot under 10 kg: rests %.3f mm deep (spring relative to its own mass), "
      "%.4f mm (to its load)\n",
      ownMass * 1e3, load * 1e3);
  EXPECT_GT(ownMass, 1e-3);
  EXPECT_LT(load, 2.0 * ownMass * 0.1 / 10.1) << "about the foot's own weight's give";
}

// A 4 kg box landing at 3.5 m/s on a column of two 3 kg boxes standing on
// one end of a 30 kg plank, another such column on its other end (the
// pile's 3.9 kg box on a 3.4 kg one on a 2.9 kg one). The island has more
// points (24) than the contact island limit here (16), so each manifold
// is its own block: with one sweep a sub-step the landing's impulse goes
// down one contact a sweep, and the load goes on into the column. With
// impactDepth the landing's contact (closing 5.8 mm in the 1/600 s
// sub-step) and the manifolds around it, its path to the ground first,
// up to the limit, are one exact group: the load, the column and the
// plank stop together in that sub-step, and stay stopped: warm started
// with the landing's whole impulse, the next sub-step threw the load back
// up at 0.65 m/s (ContactIslands::capImpactImpulses). Returns, after the
// frame's two sub-steps, the fastest any body of the load's column still
// closes on the one under it, and the fastest any of them moves up or
// down (m/s).
struct AfterLanding {
  double closing = 0.0;
  double fastest = 0.0;
};
AfterLanding afterALanding(double impactDepth) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(2);
  settings.contactIslandRows = 16;
  settings.impactDepth = impactDepth;
  settings.sinkingDepth = 0.0;  // the impact groups alone (sinking groups stop the column too)
  test::collidingEverySubstepOnSprings(world, settings);
  const Vec3 plankHalf(1.0, 0.1, 0.05), half(0.1, 0.1, 0.1);
  std::vector<BodyId> column{
      world.createBody(test::boxBody(Vec3(0, 0, plankHalf.z()), 30.0, 2.0 * plankHalf))};
  world.addShape(Shape::box(column[0], plankHalf));
  for (const double x : {-0.8, 0.8}) {
    for (int k = 0; k < 2; ++k) {
      const Vec3 at(x, 0, 2 * plankHalf.z() + half.z() * (2 * k + 1));
      const BodyId b = world.createBody(test::boxBody(at, 3.0, 2.0 * half));
      world.addShape(Shape::box(b, half));
      if (x < 0.0) column.push_back(b);
    }
  }
  const double h = 1.0 / 300.0;
  for (int frame = 0; frame < 300; ++frame)  // settled first
    world.step(h);
  const Vec3 top = world.body(column.back()).position;
  BodyDesc load = test::boxBody(top + Vec3(0, 0, 2 * half.z() + 0.002), 4.0, 2.0 * half);
  load.linearVelocity = Vec3(0, 0, -3.5);
  const BodyId landing = world.createBody(load);
  world.addShape(Shape::box(landing, half));
  column.push_back(landing);
  world.step(h);
  AfterLanding after;
  after.closing = -world.body(column[0]).linearVelocity.z();
  for (std::size_t k = 0; k < column.size(); ++k) {
    const double vz = world.body(column[k]).linearVelocity.z();
    after.fastest = std::max(after.fastest, std::abs(vz));
    if (k > 0)
      after.closing = std::max(after.closing, world.body(column[k - 1]).linearVelocity.z() - vz);
  }
  return after;
}

TEST(ConvexWorld, ABoxLandingOnAColumnStopsWithItInOneSubstepSolvedAsOneGroup) {
  const AfterLanding perManifold = afterALanding(0.0);
  const AfterLanding grouped = afterALanding(SolverSettings::kImpactDepth);
  std::printf(
      "  4 kg landing at 3.5 m/s on a column: closing %.3f m/s, fastest %.3f m/s after the "
      "frame (per manifold); %.3f and %.3f m/s (impact group)\n",
      perManifold.closing, perManifold.fastest, grouped.closing, grouped.fastest);
  EXPECT_GT(perManifold.closing, 0.05);
  EXPECT_LT(grouped.closing, 0.02);
  EXPECT_LT(grouped.fastest, 0.02) << "stopped, not thrown back up";
}

// A 2 kg box carrying a 10 kg one lands at 2.2 m/s on a 0.73 kg box
// resting on the ground beside a 0.5 kg box (the pile's 0.73 kg hull under
// a 2 kg body with 9.8 kg on it). The island has more points (20) than
// the contact island limit here (16) and no impact groups, so the light
// box's ground contact is its own block: its soft rows give under the
// load after every sub-step's sweeps. (The soft contacts throw the load
// back up at 0.65 m/s; it lands again at 0.5 m/s in frame 8.) With
// sinkingDepth the ground contact, still sinking after the sweeps, is
// solved again with the manifolds around it, rigid. Returns the deepest
// the light box's ground contact and any contact went over the landings
// (m).
struct UnderALoad {
  double ground = 0.0;
  double deepest = 0.0;
};
UnderALoad underALandingLoad(double sinkingDepth) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(10);
  settings.contactIslandRows = 16;
  settings.impactDepth = 0.0;
  settings.sinkingDepth = sinkingDepth;
  test::collidingEverySubstepOnSprings(world, settings);
  const BodyId light = test::landingOnALightBox(world).light;
  UnderALoad run;
  for (int frame = 0; frame < 30; ++frame) {
    world.step(1.0 / 60.0);
    run.deepest = std::max(run.deepest, deepestContact(world));
    for (const ContactManifold& m : world.contacts()) {
      if (m.bodyA != light && m.bodyB != light) continue;
      if (m.bodyA != kWorldBody && m.bodyB != kWorldBody) continue;
      for (int k = 0; k < m.pointCount; ++k)
        run.ground = std::max(run.ground, -m.points[k].separation);
    }
  }
  return run;
}

TEST(ConvexWorld, ALightBodyUnderALandingLoadIsStoppedFromSinkingAfterTheSweeps) {
  const UnderALoad sinking = underALandingLoad(0.0);
  const UnderALoad stopped = underALandingLoad(SolverSettings::kSinkingDepth);
  std::printf(
      "  12 kg landing on a 0.73 kg box: its ground contact %.2f mm deep, any %.2f mm (sweeps "
      "alone); %.2f and %.2f mm (sinking contacts solved again)\n",
      sinking.ground * 1e3, sinking.deepest * 1e3, stopped.ground * 1e3, stopped.deepest * 1e3);
  EXPECT_GT(sinking.ground, 0.0015);
  EXPECT_LT(stopped.ground, 0.0002);
  EXPECT_LT(stopped.deepest, 0.001);
}

// A 5 kg ball landing at 4 m/s on the edge of a 0.1 kg, 50 mm cube on the
// ground (the pile's 87 g cylinder under a 7.3 kg ball) spins the cube up
// within one part. Returns the parts taken again and the deepest contact
// the world found over the landing.
struct SpunUp {
  int retaken = 0;
  double deepest = 0.0;
};
SpunUp cubeStruckOnItsEdge(bool retake) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(10);
  settings.retakeTurningParts = retake;
  world.setSettings(settings);
  world.collisionSettings().everySubstep = true;
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const Vec3 half(0.025, 0.025, 0.025);
  world.addShape(
      Shape::box(world.createBody(test::boxBody(Vec3(0, 0, half.z()), 0.1, 2.0 * half)), half));
  const double r = 0.1;
  BodyDesc ball = test::sphereBody(Vec3(0.03, 0, 2 * half.z() + r + 0.002), 5.0, r);
  ball.linearVelocity = Vec3(0, 0, -4.0);
  world.addShape(Shape::sphere(world.createBody(ball), r));
  SpunUp run;
  for (int frame = 0; frame < 20; ++frame) {
    world.step(1.0 / 60.0);
    run.retaken += world.lastStepStats().retakenParts;
    run.deepest = std::max(run.deepest, deepestContact(world));
  }
  return run;
}

TEST(ConvexWorld, APartThatSpinsATouchingBodyUpIsTakenAgainShorter) {
  const SpunUp kept = cubeStruckOnItsEdge(false);
  const SpunUp retaken = cubeStruckOnItsEdge(true);
  std::printf(
      "  5 kg ball on a 0.1 kg cube's edge: deepest %.2f mm (parts kept), %.2f mm (%d "
      "taken again)\n",
      kept.deepest * 1e3, retaken.deepest * 1e3, retaken.retaken);
  EXPECT_EQ(kept.retaken, 0);
  EXPECT_GT(kept.deepest, 0.002);
  EXPECT_GT(retaken.retaken, 0);
  EXPECT_LT(retaken.deepest, 0.001);
}

// A 10 kg ball at 12 m/s strikes a 0.1 kg ball 8 mm short of a third, in
// the first 1/600 s part of a step: the light ball leaves the strike at
// 11.9 m/s and goes 20 mm in the part, farther than it reached when the
// part collided (half the resting margin: it stood still). Returns the gap left between
// the light ball and the third after each of the first two steps, and the
// parts taken again.
struct Struck {
  double gapAfterStrike = 0.0, gapAfterNext = 0.0;
  int retaken = 0;
};
Struck ballStruckTowardAnother(bool retake) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(2);
  settings.retakeTurningParts = retake;
  world.setSettings(settings);
  world.setGravity(Vec3::Zero());
  world.collisionSettings().everySubstep = true;
  const double big = 0.1, small = 0.05, gap = 0.008;
  BodyDesc striker = test::sphereBody(Vec3(-big - small - 0.001, 0, 0), 10.0, big);
  striker.linearVelocity = Vec3(12.0, 0, 0);
  world.addShape(Shape::sphere(world.createBody(striker), big));
  const BodyId light = world.createBody(test::sphereBody(Vec3::Zero(), 0.1, small));
  world.addShape(Shape::sphere(light, small));
  const BodyId third = world.createBody(test::sphereBody(Vec3(2 * small + gap, 0, 0), 1.0, small));
  world.addShape(Shape::sphere(third, small));
  auto gapNow = [&] {
    return (world.body(third).position - world.body(light).position).norm() - 2 * small;
  };
  Struck run;
  world.step(1.0 / 300.0);
  run.gapAfterStrike = gapNow();
  run.retaken += world.lastStepStats().retakenParts;
  world.step(1.0 / 300.0);
  run.gapAfterNext = gapNow();
  run.retaken += world.lastStepStats().retakenParts;
  return run;
}

TEST(ConvexWorld, APartWhoseSolveSendsABodyPastItsReachIsTakenAgainReachingFarther) {
  const Struck kept = ballStruckTowardAnother(false);
  const Struck retaken = ballStruckTowardAnother(true);
  std::printf(
      "  light ball struck toward another 8 mm away: gap after the strike %.2f mm (part kept), "
      "%.2f mm (%d taken again)\n",
      kept.gapAfterStrike * 1e3, retaken.gapAfterStrike * 1e3, retaken.retaken);
  EXPECT_EQ(kept.retaken, 0);
  EXPECT_LT(kept.gapAfterStrike, -0.008);  // 20 mm travelled into an 8 mm gap
  EXPECT_EQ(retaken.retaken, 1);
  // Taken again, the light ball's contact with the third came in ahead of
  // it: it stops at the third, and the next part finds nothing to take again.
  EXPECT_GT(retaken.gapAfterStrike, -0.0005);
  EXPECT_GT(retaken.gapAfterNext, -0.0005);
}
// With SolverSettings::recordStageEnergy each sub-step reports the bodies'
// energy after its five stages, in order. A ball starting 8 mm into the
// ground at rest: gravity gives it (g h)^2 / 2 per kilogram; the sweeps
// stop that and send it up out of the ground (position correction); the
// position update lifts it at that speed; and relax takes the speed
// back, so the push-out becomes height, not motion (the point of the
// relax stage, as in Box2D v3's soft step).
TEST(ConvexWorld, EachSubstepReportsItsStagesEnergyAndRelaxTakesBackThePushOut) {
  World world;
  SolverSettings settings = SolverSettings::subStepped(4);
  settings.recordStageEnergy = true;
  world.setSettings(settings);
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  const double r = 0.1, m = 2.0, z0 = r - 0.008, h = 1.0 / 240.0, g = 9.81;
  const BodyId ball = world.createBody(test::sphereBody(Vec3(0, 0, z0), m, r));
  world.addShape(Shape::sphere(ball, r));
  world.step(4 * h);
  const std::vector<StageEnergySample>& e = world.lastStepStats().stageEnergy;
  ASSERT_EQ(e.size(), 24u);
  using After = StageEnergySample::After;
  for (std::size_t k = 0; k < e.size(); ++k) {
    EXPECT_EQ(e[k].substep, static_cast<int>(k / 6)) << k;
    EXPECT_EQ(e[k].substeps, 4) << k;
    EXPECT_EQ(e[k].after, k % 6 == 0 ? After::Start : static_cast<After>(k % 6 - 1)) << k;
  }
  EXPECT_EQ(e[0].kinetic, 0.0) << "at rest when the step starts";
  EXPECT_NEAR(e[1].kinetic, 0.5 * m * (g * h) * (g * h), 1e-12);
  EXPECT_NEAR(e[1].potential, m * g * z0, 1e-12);
  for (int sub = 0; sub < 4; ++sub) {
    SCOPED_TRACE(sub);
    if (sub > 0) {
      EXPECT_EQ(e[6 * sub].kinetic, e[6 * sub - 1].kinetic) << "it starts where relax left it";
      EXPECT_EQ(e[6 * sub].potential, e[6 * sub - 1].potential);
    }
    const StageEnergySample* s = &e[6 * sub + 1];
    EXPECT_EQ(s[0].potential, s[2].potential) << "nothing moves before the position update";
    // The speed the position update lifted the ball at is the one the
    // sweeps left it: the push-out, straight up.
    const double up = (s[3].potential - s[2].potential) / (m * g * h);
    EXPECT_GT(up, 0.01) << "m/s";
    EXPECT_NEAR(s[2].kinetic, 0.5 * m * up * up, 1e-9);
    EXPECT_EQ(s[3].kinetic, s[2].kinetic) << "moving does not change the velocities";
    EXPECT_LT(s[4].kinetic, 1e-6 * s[2].kinetic) << "relax took the push-out's speed back";
    EXPECT_EQ(s[4].potential, s[3].potential) << "relax moves nothing";
  }
  const double z = world.body(ball).position.z();
  EXPECT_NEAR(e.back().potential, m * g * z, 1e-12);
  EXPECT_GT(z, z0 + 1e-4) << "pushed out";
  // Off, nothing is recorded.
  settings.recordStageEnergy = false;
  world.setSettings(settings);
  world.step(4 * h);
  EXPECT_TRUE(world.lastStepStats().stageEnergy.empty());
}

}  // namespace
}  // namespace blockstep

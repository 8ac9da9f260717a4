// blockstep's own collision for ODE programs (dWorldSetBlockCollision):
// the program makes geoms and never calls dSpaceCollide; blockstep
// collides the space's geoms itself, every step or every sub-step.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 60.0;

// A cube of half side 0.25 as ODE's convex geom wants it: planes
// (n, d), points, and polygons (count, then indices, counter-clockwise
// seen from outside).
const dReal kCubePlanes[] = {1, 0,  0, 0.25, -1, 0, 0, 0.25, 0, 1, 0,  0.25,
                             0, -1, 0, 0.25, 0,  0, 1, 0.25, 0, 0, -1, 0.25};
const dReal kCubePoints[] = {-0.25, -0.25, -0.25, 0.25,  -0.25, -0.25, 0.25, 0.25,
                             -0.25, -0.25, 0.25,  -0.25, -0.25, -0.25, 0.25, 0.25,
                             -0.25, 0.25,  0.25,  0.25,  0.25,  -0.25, 0.25, 0.25};
const unsigned kCubePolygons[] = {4, 1, 2, 6, 5, 4, 0, 4, 7, 3, 4, 2, 3, 7, 6,
                                  4, 0, 1, 5, 4, 4, 4, 5, 6, 7, 4, 0, 3, 2, 1};

struct CollidedScene {
  OdeScene scene;
  dSpaceID space = dHashSpaceCreate(0);
  dSurfaceParameters surface{};

  CollidedScene() {
    dCreatePlane(space, 0, 0, 1, 0);
    surface.mode = dContactApprox1;
    surface.mu = 0.6;
    dWorldSetBlockSubsteppedSolver(scene.world, 10);
  }
  ~CollidedScene() { dSpaceDestroy(space); }
  dBodyID body(double x, double y, double z, dGeomID geom, double mass = 1.0) {
    dBodyID b = scene.box(x, y, z, mass, 0.5);
    dGeomSetBody(geom, b);
    return b;
  }
  void run(int frames, double h = kStep) {
    for (int f = 0; f < frames; ++f)
      ASSERT_EQ(dWorldBlockStep(scene.world, h), 1) << dWorldGetBlockStepMessage(scene.world);
  }
};

double tiltDegrees(dBodyID b) {
  const dReal* R = dBodyGetRotation(b);  // row major 3x4: R[10] is z.z
  return std::acos(std::min(1.0, std::abs(double(R[10])))) * 180.0 / M_PI;
}

TEST(OdeBlockCollision, BoxAndConvexCubeRestFlatOnTheGroundWithoutDSpaceCollide) {
  CollidedScene c;
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, 0);
  const dBodyID box = c.body(0, 0, 0.26, dCreateBox(c.space, 0.5, 0.5, 0.5));
  const dBodyID hull =
      c.body(2, 0, 0.26, dCreateConvex(c.space, kCubePlanes, 6, kCubePoints, 8, kCubePolygons));
  c.run(300);
  for (dBodyID b : {box, hull}) {
    EXPECT_NEAR(dBodyGetPosition(b)[2], 0.25, 3e-3);
    EXPECT_LT(tiltDegrees(b), 0.1);
    const dReal* v = dBodyGetLinearVel(b);
    EXPECT_LT(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1e-3);
  }
  dBlockStepStats stats;
  ASSERT_EQ(dWorldGetBlockStepStats(c.scene.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperBlockstep);
  EXPECT_GT(stats.collideSeconds, 0.0);
}

TEST(OdeBlockCollision, CategoryAndCollideBitsAndSwitchingOffAsOdeHasThem) {
  CollidedScene c;
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, 0);
  dGeomID ghostGeom = dCreateSphere(c.space, 0.1);
  dGeomSetCategoryBits(ghostGeom, 2);
  dGeomSetCollideBits(ghostGeom, 2);  // the plane is category ~0: it collides with it
  dGeomID passGeom = dCreateSphere(c.space, 0.1);
  dGeomSetCategoryBits(passGeom, 0);
  dGeomSetCollideBits(passGeom, 0);  // collides with nothing
  const dBodyID resting = c.body(0, 0, 0.1, ghostGeom);
  const dBodyID falling = c.body(1, 0, 0.1, passGeom);
  c.run(60);
  EXPECT_NEAR(dBodyGetPosition(resting)[2], 0.1, 2e-3);
  EXPECT_NEAR(dBodyGetPosition(falling)[2], 0.1 - 0.5 * 9.81 * 1.0, 0.05);
  // Off: the resting sphere falls through the ground too.
  dWorldSetBlockCollision(c.scene.world, nullptr, nullptr, 0);
  c.run(30);
  EXPECT_LT(dBodyGetPosition(resting)[2], -0.5);
}

TEST(OdeBlockCollision, GeomsWithoutACoreShapeAreLeftOutAndTheWorldSteps) {
  CollidedScene c;
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, 0);
  dCreateRay(c.space, 1.0);
  const dBodyID ball = c.body(0, 0, 0.1, dCreateSphere(c.space, 0.1));
  c.run(30);
  EXPECT_NEAR(dBodyGetPosition(ball)[2], 0.1, 2e-3);
  EXPECT_STREQ(dWorldGetBlockStepMessage(c.scene.world), "");
}

TEST(OdeBlockCollision, BadArgumentsAreRefusedAndChangeNothing) {
  CollidedScene c;
  dWorldSetBlockCollision(c.scene.world, c.space, nullptr, 0);        // no surface
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, 0x40);  // unknown flag
  const dBodyID ball = c.body(0, 0, 0.1, dCreateSphere(c.space, 0.1));
  c.run(30);
  EXPECT_LT(dBodyGetPosition(ball)[2], 0.0) << "collision stayed off";
}

// The surface reaches every contact blockstep makes: a box on a 20-degree
// slope (tan 20 = 0.364) slides with mu 0.3 and holds with mu 0.45.
double slideOnSlope(double mu) {
  CollidedScene c;
  dSpaceDestroy(c.space);  // without the flat ground
  c.space = dHashSpaceCreate(0);
  const double slope = 20.0 * M_PI / 180.0;
  dCreatePlane(c.space, 0, -std::sin(slope), std::cos(slope), 0);
  c.surface.mu = mu;
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, 0);
  const dBodyID box = c.body(0, -0.25 * std::sin(slope), 0.25 * std::cos(slope),
                             dCreateBox(c.space, 0.5, 0.5, 0.5));
  dMatrix3 R;
  dRFromAxisAndAngle(R, 1, 0, 0, slope);
  dBodySetRotation(box, R);
  c.run(60);
  const dReal* v = dBodyGetLinearVel(box);
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

TEST(OdeBlockCollision, TheSurfacesFrictionHoldsABoxOnASlopeOrLetsItSlide) {
  const double g = 9.81, slope = 20.0 * M_PI / 180.0;
  // Sliding: a = g (sin - mu cos), 1 s.
  EXPECT_NEAR(slideOnSlope(0.3), g * (std::sin(slope) - 0.3 * std::cos(slope)), 0.05);
  EXPECT_LT(slideOnSlope(0.45), 1e-3);
}

// A ball thrown at 6 m/s at a wall moves 0.1 m a frame, five times the
// 20 mm speculative margin: collided once a frame it is found 20 mm deep,
// collided every sub-step it stops at the wall.
double deepestIntoWall(int flags) {
  CollidedScene c;
  dWorldSetGravity(c.scene.world, 0, 0, 0);
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, flags);
  const double face = 0.33;
  dGeomID wall = dCreateBox(c.space, 0.2, 2.0, 2.0);
  dGeomSetPosition(wall, face + 0.1, 0, 1.0);
  const dBodyID ball = c.body(0, 0, 1.0, dCreateSphere(c.space, 0.05));
  dBodySetLinearVel(ball, 6.0, 0, 0);
  double deepest = 0.0;
  for (int f = 0; f < 30; ++f) {
    c.run(1);
    deepest = std::max(deepest, dBodyGetPosition(ball)[0] + 0.05 - face);
  }
  EXPECT_LT(std::abs(dBodyGetLinearVel(ball)[0]), 0.5) << "stopped at the wall";
  return deepest;
}

TEST(OdeBlockCollision, CollidingEverySubstepStopsAFastBallAtTheWall) {
  EXPECT_GT(deepestIntoWall(0), 0.015);
  EXPECT_LT(deepestIntoWall(dBlockCollideEverySubstep), 1e-3);
}

// dWorldGetBlockDeepestContact: the deepest point blockstep's own
// collision found in the last step. A ball 8 mm into the ground, no
// gravity: the step's first collision finds it exactly that deep.
TEST(OdeBlockCollision, TheDeepestContactFoundInAStepIsReported) {
  CollidedScene c;
  dWorldSetGravity(c.scene.world, 0, 0, 0);
  dWorldSetBlockCollision(c.scene.world, c.space, &c.surface, dBlockCollideEverySubstep);
  c.body(0, 0, 0.1 - 0.008, dCreateSphere(c.space, 0.1));
  EXPECT_EQ(dWorldGetBlockDeepestContact(c.scene.world), 0.0) << "not stepped yet";
  c.run(1);
  EXPECT_NEAR(dWorldGetBlockDeepestContact(c.scene.world), 0.008, 1e-9);
  EXPECT_EQ(dWorldGetBlockDeepestContact(nullptr), 0.0);
}

// dWorldSetBlockRecordStageEnergy: each sub-step's energy at its start
// and after its five stages. A box falling free under semi-implicit Euler
// (section 3): it starts sub-step k at g h k, after its forces it moves
// at g h (k + 1), and after its position
// update it has fallen g h^2 (k + 1)(k + 2) / 2; no other stage changes
// anything.
TEST(OdeBlockCollision, EachSubstepsEnergyAfterEveryStageIsReported) {
  OdeScene scene;
  dWorldSetBlockSubsteppedSolver(scene.world, 4);
  const double m = 3.0, z0 = 2.0, g = 9.81, h = kStep / 4;
  scene.box(0, 0, z0, m);
  EXPECT_EQ(dWorldGetBlockStageEnergy(scene.world, nullptr, nullptr, nullptr, nullptr, 0), 0)
      << "not stepped yet";
  dWorldSetBlockRecordStageEnergy(scene.world, 1);
  ASSERT_EQ(dWorldBlockStep(scene.world, kStep), 1);
  const int n = dWorldGetBlockStageEnergy(scene.world, nullptr, nullptr, nullptr, nullptr, 0);
  ASSERT_EQ(n, 24);
  std::vector<int> substep(n), stage(n);
  std::vector<dReal> kinetic(n), potential(n);
  ASSERT_EQ(dWorldGetBlockStageEnergy(scene.world, substep.data(), stage.data(), kinetic.data(),
                                      potential.data(), n),
            n);
  for (int i = 0; i < n; ++i) {
    const int k = i / 6;
    EXPECT_EQ(substep[i], k);
    EXPECT_EQ(stage[i], i % 6 == 0 ? dBlockStageStart : i % 6 - 1) << "the start first";
    const double v = g * h * (stage[i] == dBlockStageStart ? k : k + 1);
    EXPECT_NEAR(kinetic[i], 0.5 * m * v * v, 1e-9) << i;
    const bool moved = stage[i] == dBlockStagePositions || stage[i] == dBlockStageRelax;
    const int moves = moved ? k + 1 : k;
    const double fallen = 0.5 * g * h * h * moves * (moves + 1);
    EXPECT_NEAR(potential[i], m * g * (z0 - fallen), 1e-9) << i;
  }
  // Room for fewer: the first ones only, and how many there were.
  int stages[3] = {-1, -1, -1};
  EXPECT_EQ(dWorldGetBlockStageEnergy(scene.world, nullptr, stages, nullptr, nullptr, 2), n);
  EXPECT_EQ(stages[0], dBlockStageStart);
  EXPECT_EQ(stages[1], dBlockStageForces);
  EXPECT_EQ(stages[2], -1);
  dWorldSetBlockRecordStageEnergy(scene.world, 0);
  ASSERT_EQ(dWorldBlockStep(scene.world, kStep), 1);
  EXPECT_EQ(dWorldGetBlockStageEnergy(scene.world, nullptr, nullptr, nullptr, nullptr, 0), 0)
      << "recording off";
  EXPECT_EQ(dWorldGetBlockStageEnergy(nullptr, nullptr, nullptr, nullptr, nullptr, 0), 0);
}

// dBlockSetColliders: ODE's own dCollide, with the core's collision for
// pairs with a convex geom or a cylinder. The colliders stay in ODE's
// table for the process (until dCloseODE), so the checks run in a child
// process of their own and report what failed through its exit.
int contactsOf(dGeomID a, dGeomID b, dContactGeom* out) {
  return dCollide(a, b, 8, out, sizeof(dContactGeom));
}

std::string checkCoreColliders() {
  std::string failed;
  auto check = [&](bool ok, const char* what) {
    if (!ok) failed += std::string(what) + "; ";
  };
  auto near = [](double a, double b) { return std::abs(a - b) < 1e-9; };
  dSpaceID space = dSimpleSpaceCreate(0);
  dGeomID ground = dCreateBox(space, 4, 4, 1);
  dGeomSetPosition(ground, 0, 0, -0.5);  // top face at z = 0
  dGeomID hull = dCreateConvex(space, kCubePlanes, 6, kCubePoints, 8, kCubePolygons);
  dGeomSetPosition(hull, 0.3, 0, 0.25 - 0.004);  // 4 mm deep
  dGeomID cylinder = dCreateCylinder(space, 0.2, 0.5);
  dGeomSetPosition(cylinder, -1, 0, 0.25 - 0.002);
  dContactGeom c[8];
  const int odeHull = contactsOf(hull, ground, c);
  const int odeCylinder = contactsOf(cylinder, ground, c);
  check(dBlockSetColliders(1) == 1, "dBlockSetColliders(1) failed");
  const int count = contactsOf(hull, ground, c);
  check(count == 4, "the hull should touch on 4 points");
  for (int i = 0; i < count; ++i) {
    check(near(c[i].depth, 0.004), "depth");
    check(near(c[i].normal[2], 1.0), "the normal should push the hull (o1) up");
    check(near(std::abs(c[i].pos[0] - 0.3), 0.25) && near(std::abs(c[i].pos[1]), 0.25),
          "the points should be the cube's corners");
    check(c[i].g1 == hull && c[i].g2 == ground, "g1, g2");
  }
  // The pair the other way round: ODE flips the normals for o1 = ground.
  check(contactsOf(ground, hull, c) == 4 && near(c[0].normal[2], -1.0) && c[0].g1 == ground,
        "reversed pair");
  const int rim = contactsOf(cylinder, ground, c);
  check(rim == 4, "the cylinder should stand on 4 points of its rim");
  for (int i = 0; i < rim; ++i)
    check(near(c[i].depth, 0.002), "cylinder depth");
  dGeomSetPosition(hull, 0.3, 0, 0.3);
  check(contactsOf(hull, ground, c) == 0, "apart: no contact");
  std::fprintf(stderr, "ODE's collider: hull %d point(s), cylinder %d; blockstep's: %d and %d\n",
               odeHull, odeCylinder, count, rim);
  dSpaceDestroy(space);
  return failed;
}

TEST(OdeBlockColliders, ConvexCubeAndCylinderOnABoxGetFourPointsInOdesConvention) {
  EXPECT_EXIT(
      {
        const std::string failed = checkCoreColliders();
        std::fprintf(stderr, "%s\n", failed.empty() ? "all held" : failed.c_str());
        std::exit(failed.empty() ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "all held");
}

}  // namespace
}  // namespace blockstep::test

// Contacts made the ODE way (geoms, dSpaceCollide, contact joints in a
// group) and stepped by dWorldBlockStep: a stack rests, and bounce,
// friction, soft_cfm and motion1 behave as ODE's direct solver has them.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 60.0;

// A world with a ground plane and box or sphere geoms; every step collides
// them into a contact group with one surface.
struct ContactScene {
  OdeScene scene;
  dSpaceID space = dHashSpaceCreate(0);
  dJointGroupID contacts = dJointGroupCreate(0);
  dSurfaceParameters surface{};
  std::vector<dGeomID> geoms;

  ContactScene() {
    geoms.push_back(dCreatePlane(space, 0, 0, 1, 0));
    surface.mode = dContactApprox1;
    surface.mu = 0.6;
  }
  ~ContactScene() {
    dJointGroupDestroy(contacts);
    dSpaceDestroy(space);
  }
  dBodyID box(double x, double y, double z, double side, double mass = 1.0) {
    dBodyID b = scene.box(x, y, z, mass, side);
    dGeomID g = dCreateBox(space, side, side, side);
    dGeomSetBody(g, b);
    geoms.push_back(g);
    return b;
  }
  dBodyID sphere(double x, double y, double z, double radius) {
    dBodyID b = dBodyCreate(scene.world);
    dMass m;
    dMassSetSphereTotal(&m, 1.0, radius);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, y, z);
    scene.bodies.push_back(b);
    dGeomID g = dCreateSphere(space, radius);
    dGeomSetBody(g, b);
    geoms.push_back(g);
    return b;
  }

  static void nearCallback(void* data, dGeomID a, dGeomID b) {
    auto* self = static_cast<ContactScene*>(data);
    dContact contact[4];
    const int n = dCollide(a, b, 4, &contact[0].geom, sizeof(dContact));
    for (int i = 0; i < n; ++i) {
      contact[i].surface = self->surface;
      dJointID j = dJointCreateContact(self->scene.world, self->contacts, &contact[i]);
      dJointAttach(j, dGeomGetBody(a), dGeomGetBody(b));
    }
  }
  void step(Stepper s, double h = kStep) {
    dSpaceCollide(space, this, &nearCallback);
    stepWith(s, scene.world, h);
    dJointGroupEmpty(contacts);
  }
};

TEST(OdeContacts, BoxStackRests) {
  ContactScene c;
  const double side = 0.5;
  std::vector<dBodyID> boxes;
  for (int i = 0; i < 6; ++i)
    boxes.push_back(c.box(0.0, 0.0, side * (i + 0.5), side));
  for (int f = 0; f < 300; ++f)
    c.step(Stepper::Block);
  const dReal* top = dBodyGetPosition(boxes.back());
  const double drift = std::hypot(top[0], top[1]);
  const double sink = side * 5.5 - top[2];
  std::printf("  6-box stack after 5 s: top drift %.3g mm, sink %.3g mm\n", drift * 1e3,
              sink * 1e3);
  EXPECT_LT(drift, 1e-3);
  EXPECT_LT(std::abs(sink), 5e-3);
  for (dBodyID b : boxes) {
    const dReal* v = dBodyGetLinearVel(b);
    EXPECT_LT(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1e-2);
  }
  dBlockStepStats stats;
  ASSERT_EQ(dWorldGetBlockStepStats(c.scene.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperBlockstep);
}

// Boxes set 1 mm into the ground stand on four contact points each (ODE
// gives three at exact touching), and the push out of the ground must not
// travel up the stack: with the sub-step's correction rate these stacks
// jumped apart (metres) at 10 and 20 sub-steps. Every sub-step count the
// program's quickstep iterations can ask for keeps them standing for 2000
// frames; at one sub-step (quickstep 2) one friction pass a sweep let the
// stack sway off by 100 mm.
TEST(OdeContacts, StackOnFourPointsRestsAtAnySubstepCount) {
  for (const int substeps : {1, 2, 5, 10, 20}) {
    ContactScene c;
    const double side = 0.5, depth = 1e-3;
    std::vector<dBodyID> boxes;
    for (int i = 0; i < 10; ++i)
      boxes.push_back(c.box(0.0, 0.0, side * (i + 0.5) - depth, side));
    dWorldSetBlockSubsteppedSolver(c.scene.world, substeps);
    double drift = 0.0;
    for (int f = 0; f < 2000; ++f) {
      c.step(Stepper::Block);
      const dReal* top = dBodyGetPosition(boxes.back());
      drift = std::max(drift, std::hypot(top[0], top[1]));
    }
    const double rise = dBodyGetPosition(boxes.back())[2] - (side * 9.5 - depth);
    std::printf("  10 boxes 1 mm deep, %d sub-steps: top drift %.3g mm, top %+.3g mm\n", substeps,
                drift * 1e3, rise * 1e3);
    EXPECT_LT(drift, 1e-3);
    // The stack is one contact island, solved exactly: the bottom box is
    // pushed out of the ground and every contact rests 10 um deep, so the
    // top rises 1 mm less 0.1 mm. (Contact by contact, the contacts
    // settled under the load at their sub-step compliance: the top sank
    // 7.6 mm at 5 sub-steps, 1.2 mm at 20; quickstep 20 sinks six boxes
    // 4.2 mm: preload test.)
    EXPECT_NEAR(rise, depth - 10 * 1e-5, 0.05e-3);
    for (dBodyID b : boxes) {
      const dReal* v = dBodyGetLinearVel(b);
      EXPECT_LT(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1e-2);
    }
  }
}

// The compare runner's plank_load without its load: two static supports
// (0.2 x 0.4 x 0.5 m at x = -0.8 and 0.8) and a 1 kg plank (2 x 0.3 x 0.05
// m) across them, all exactly touching. Returns the plank; a load on it
// rests at z = 0.55 + its half height.
dBodyID plankOnTwoSupports(ContactScene& c) {
  for (double x : {-0.8, 0.8}) {
    dGeomID support = dCreateBox(c.space, 0.2, 0.4, 0.5);
    dGeomSetPosition(support, x, 0.0, 0.25);
  }
  dBodyID plank = dBodyCreate(c.scene.world);
  dMass m;
  dMassSetBoxTotal(&m, 1.0, 2.0, 0.3, 0.05);
  dBodySetMass(plank, &m);
  dBodySetPosition(plank, 0.0, 0.0, 0.525);
  dGeomSetBody(dCreateBox(c.space, 2.0, 0.3, 0.05), plank);
  return plank;
}

// A 1000 kg block on a 1 kg plank laid across two static supports, all
// exactly touching (the compare runner's plank_load): dWorldStep holds it
// (one LCP for the island); Gauss-Seidel contact by contact passes the
// plank only its own share of the load a sweep, and the plank went
// through the supports under every sub-stepped setting. As one contact
// island the default holds it as dWorldStep does, at 1 and 10 sub-steps.
TEST(OdeContacts, TonneOnAOneKilogramPlankRestsAsDirectSolver) {
  auto drop = [](Stepper stepper, int substeps, int contactRows) {
    ContactScene c;
    plankOnTwoSupports(c);
    const dBodyID block = c.box(0.0, 0.0, 0.75, 0.4, 1000.0);
    dWorldSetBlockSubsteppedSolver(c.scene.world, substeps);
    dWorldSetBlockContactIslandRows(c.scene.world, contactRows);
    for (int f = 0; f < 300; ++f)
      c.step(stepper);
    return 0.75 - dBodyGetPosition(block)[2];
  };
  const double direct = drop(Stepper::Direct, 1, 64);
  std::printf("  block drop after 5 s: dWorldStep %.3g mm", 1e3 * direct);
  for (int substeps : {1, 10}) {
    const double island = drop(Stepper::Block, substeps, 64);
    const double manifolds = drop(Stepper::Block, substeps, 0);
    std::printf(", %d sub-steps %.3g mm (contact by contact %.0f mm)", substeps, 1e3 * island,
                1e3 * manifolds);
    EXPECT_NEAR(island, direct, 1e-4) << substeps;
    EXPECT_GT(manifolds, 0.01) << substeps;  // what the island block is for
  }
  std::printf("\n");
  EXPECT_LT(std::abs(direct), 1e-4);
}

// Two tonnes stacked on the 1 kg plank make an island larger than the
// contact island limit set here (12 points): it keeps one block per
// contact, except the plank, a light body under a heavy one, whose
// contacts (both supports and the block) are one exact group
// (dWorldSetBlockLightBodyGroups, on by default sub-stepped). The plank
// then rests as under dWorldStep; contact by contact it is squeezed out
// from under the blocks (which way depends on the contacts' order).
TEST(OdeContacts, LightPlankInALargerIslandRestsAsDirectSolver) {
  auto drop = [](Stepper stepper, int lightGroups) {
    ContactScene c;
    const dBodyID plank = plankOnTwoSupports(c);
    c.box(0.0, 0.0, 0.75, 0.4, 1000.0);
    c.box(0.0, 0.0, 1.15, 0.4, 1000.0);
    dWorldSetBlockSubsteppedSolver(c.scene.world, 10);
    EXPECT_EQ(dWorldGetBlockLightBodyGroups(c.scene.world), 1);  // the sub-stepped default
    dWorldSetBlockContactIslandRows(c.scene.world, 12);
    dWorldSetBlockLightBodyGroups(c.scene.world, lightGroups);
    EXPECT_EQ(dWorldGetBlockLightBodyGroups(c.scene.world), lightGroups);
    for (int f = 0; f < 300; ++f)
      c.step(stepper);
    const dReal* p = dBodyGetPosition(plank);
    return std::sqrt(p[0] * p[0] + p[1] * p[1] + (p[2] - 0.525) * (p[2] - 0.525));
  };
  const double direct = drop(Stepper::Direct, 1);
  const double grouped = drop(Stepper::Block, 1);
  const double manifolds = drop(Stepper::Block, 0);
  std::printf(
      "  plank moved after 5 s: dWorldStep %.3g mm, light-body group %.3g mm, contact by "
      "contact %.0f mm\n",
      1e3 * direct, 1e3 * grouped, 1e3 * manifolds);
  EXPECT_LT(direct, 1e-4);
  EXPECT_LT(grouped, 1e-4);
  EXPECT_GT(manifolds, 0.01);  // what the group is for
}

// Load-relative contacts (dWorldSetBlockLoadRelativeContacts) follow the
// solver until set: on sub-stepped, off in the paper preset, then as set
// whichever solver follows. CompareRuns measures what they do.
TEST(OdeContacts, LoadRelativeContactsFollowTheSolverUntilSet) {
  ContactScene c;
  dWorldSetBlockSubsteppedSolver(c.scene.world, 10);
  EXPECT_EQ(dWorldGetBlockLoadRelativeContacts(c.scene.world), 1);
  dWorldSetBlockPaperSolver(c.scene.world, 50);
  EXPECT_EQ(dWorldGetBlockLoadRelativeContacts(c.scene.world), 0);
  dWorldSetBlockLoadRelativeContacts(c.scene.world, 1);
  EXPECT_EQ(dWorldGetBlockLoadRelativeContacts(c.scene.world), 1);
  dWorldSetBlockSubsteppedSolver(c.scene.world, 10);
  dWorldSetBlockLoadRelativeContacts(c.scene.world, 0);
  EXPECT_EQ(dWorldGetBlockLoadRelativeContacts(c.scene.world), 0);
}

// Runs the contact scene built by `build` with dWorldStep and with
// blockstep, and returns probe() of both after `steps` steps. Blockstep
// runs the paper's solver here (one step, ODE's own ERP and CFM rows,
// enough sweeps to converge), the configuration that solves the problem
// dWorldStep solves; the sub-stepped default damps contacts differently
// (README, solver notes).
template <class Build, class Probe>
std::pair<double, double> twinContacts(Build build, Probe probe, int steps, double h = kStep) {
  double out[2];
  int i = 0;
  for (Stepper s : {Stepper::Direct, Stepper::Block}) {
    ContactScene c;
    build(c);
    if (s == Stepper::Block) dWorldSetBlockPaperSolver(c.scene.world, 50);
    for (int f = 0; f < steps; ++f)
      c.step(s, h);
    out[i++] = probe(c);
  }
  return {out[0], out[1]};
}

// A ball dropped 0.9 m onto bounce 0.6 rises to 0.6^2 0.9 = 0.324 m. The
// apex is taken over the whole second flight (1.2 s), by dWorldStep, the
// paper preset, and the sub-stepped default.
TEST(OdeContacts, BounceHeightAsDirectSolver) {
  double apex[3] = {0.0, 0.0, 0.0};
  int i = 0;
  for (const int mode : {0, 1, 2}) {
    ContactScene c;
    c.surface.mode = dContactApprox1 | dContactBounce;
    c.surface.bounce = 0.6;
    c.surface.bounce_vel = 0.1;
    dBodyID ball = c.sphere(0.0, 0.0, 1.0, 0.1);
    if (mode == 1) dWorldSetBlockPaperSolver(c.scene.world, 50);
    bool bounced = false;
    for (int f = 0; f < 288; ++f) {
      c.step(mode == 0 ? Stepper::Direct : Stepper::Block, 1.0 / 240.0);
      const double vz = dBodyGetLinearVel(ball)[2];
      if (vz > 0.0) bounced = true;
      if (bounced) apex[i] = std::max(apex[i], dBodyGetPosition(ball)[2] - 0.1);
    }
    ++i;
  }
  std::printf(
      "  bounce apex: dWorldStep %.4f m, paper preset %.4f m, sub-stepped %.4f m "
      "(analytic 0.324 m)\n",
      apex[0], apex[1], apex[2]);
  EXPECT_NEAR(apex[1], apex[0], 0.01 * apex[0]);
  EXPECT_NEAR(apex[2], apex[0], 0.02 * apex[0]);
  EXPECT_NEAR(apex[2], 0.324, 0.02 * 0.324);
}

TEST(OdeContacts, FrictionSlideAsDirectSolver) {
  // A box pushed at 3 m/s slides to a stop at a = mu g; mu = 0.3.
  auto build = [](ContactScene& c) {
    c.surface.mu = 0.3;
    dBodyID b = c.box(0.0, 0.0, 0.25, 0.5);
    dBodySetLinearVel(b, 3.0, 0.0, 0.0);
  };
  auto probe = [](ContactScene& c) { return dBodyGetPosition(c.scene.bodies[0])[0]; };
  const auto [direct, block] = twinContacts(build, probe, 90);
  const double analytic = 3.0 * 3.0 / (2.0 * 0.3 * 9.81);
  std::printf("  slide distance: dWorldStep %.4f m, blockstep %.4f m, mu g analytic %.4f m\n",
              direct, block, analytic);
  EXPECT_NEAR(block, direct, 0.02 * direct);
  EXPECT_NEAR(block, analytic, 0.03 * analytic);
}

TEST(OdeContacts, SoftCfmSinksAsDirectSolver) {
  // soft_cfm 1e-3 m/N with soft_erp 0.2 at h = 1/60 s is a spring of
  // k = ERP / (h CFM) = 12 kN/m per contact point: a resting 10 kg box on
  // four points sinks m g / (4 k) = 2.04 mm.
  auto build = [](ContactScene& c) {
    c.surface.mode = dContactApprox1 | dContactSoftCFM | dContactSoftERP;
    c.surface.soft_cfm = 1e-3;
    c.surface.soft_erp = 0.2;
    c.box(0.0, 0.0, 0.25, 0.5, 10.0);
  };
  auto probe = [](ContactScene& c) { return 0.25 - dBodyGetPosition(c.scene.bodies[0])[2]; };
  const auto [direct, block] = twinContacts(build, probe, 180);
  std::printf("  soft contact sink: dWorldStep %.4f m, blockstep %.4f m\n", direct, block);
  EXPECT_NEAR(direct, 10.0 * 9.81 / (4.0 * 12000.0), 1e-4);
  EXPECT_NEAR(block, direct, 0.02 * direct);
}

TEST(OdeContacts, Motion1DrivesLikeAConveyor) {
  auto build = [](ContactScene& c) {
    c.surface.mode = dContactApprox1 | dContactMotion1 | dContactFDir1;
    c.surface.motion1 = 0.5;
    c.box(0.0, 0.0, 0.25, 0.5);
  };
  // fdir1 is set per contact: the near callback gives +x.
  struct Conveyor {
    static void nearCallback(void* data, dGeomID a, dGeomID b) {
      auto* self = static_cast<ContactScene*>(data);
      dContact contact[4];
      const int n = dCollide(a, b, 4, &contact[0].geom, sizeof(dContact));
      for (int i = 0; i < n; ++i) {
        contact[i].surface = self->surface;
        contact[i].fdir1[0] = 1.0;
        contact[i].fdir1[1] = 0.0;
        contact[i].fdir1[2] = 0.0;
        dJointID j = dJointCreateContact(self->scene.world, self->contacts, &contact[i]);
        dJointAttach(j, dGeomGetBody(a), dGeomGetBody(b));
      }
    }
  };
  double speed[2];
  int i = 0;
  for (Stepper s : {Stepper::Direct, Stepper::Block}) {
    ContactScene c;
    build(c);
    for (int f = 0; f < 60; ++f) {
      dSpaceCollide(c.space, &c, &Conveyor::nearCallback);
      stepWith(s, c.scene.world, kStep);
      dJointGroupEmpty(c.contacts);
    }
    speed[i++] = dBodyGetLinearVel(c.scene.bodies[0])[0];
  }
  std::printf("  conveyor: box speed dWorldStep %.4f m/s, blockstep %.4f m/s\n", speed[0],
              speed[1]);
  EXPECT_NEAR(std::abs(speed[1]), 0.5, 0.01);
  EXPECT_NEAR(speed[1], speed[0], 0.01);
}

// dJointFeedback on contact joints: the contact forces under a resting
// 3 kg box add up to its weight, on the box (f1, node 0, whether the box
// is the contact's body1 or its body2 with the normal flipped), as with
// dWorldStep.
TEST(OdeContacts, ContactFeedbackCarriesTheWeight) {
  for (const bool boxIsBody2 : {false, true}) {
    for (Stepper stepper : {Stepper::Direct, Stepper::Block}) {
      ContactScene c;
      dBodyID box = c.box(0.0, 0.0, 0.25, 0.5, 3.0);
      std::vector<dJointFeedback> feedback(8);
      double up = 0.0, sideX = 0.0, sideY = 0.0;
      for (int frame = 0; frame < 60; ++frame) {
        dContact contact[8];
        const int n = dCollide(c.geoms[1], c.geoms[0], 8, &contact[0].geom, sizeof(dContact));
        up = sideX = sideY = 0.0;
        for (int i = 0; i < n; ++i) {
          contact[i].surface = c.surface;
          if (boxIsBody2) {
            for (int k = 0; k < 3; ++k)
              contact[i].geom.normal[k] *= -1;
          }
          dJointID j = dJointCreateContact(c.scene.world, c.contacts, &contact[i]);
          dJointAttach(j, boxIsBody2 ? nullptr : box, boxIsBody2 ? box : nullptr);
          dJointSetFeedback(j, &feedback[i]);
        }
        stepWith(stepper, c.scene.world, kStep);
        for (int i = 0; i < n; ++i) {
          up += feedback[i].f1[2];
          sideX += feedback[i].f1[0];
          sideY += feedback[i].f1[1];
        }
        dJointGroupEmpty(c.contacts);
      }
      std::printf("  %s, box as body%d: contact feedback on the box %.4f N (weight %.4f N)\n",
                  stepper == Stepper::Direct ? "dWorldStep" : "blockstep", boxIsBody2 ? 2 : 1, up,
                  3.0 * 9.81);
      std::printf("    net sideways %.3g N\n", std::hypot(sideX, sideY));
      EXPECT_NEAR(up, 3.0 * 9.81, 0.01 * 3.0 * 9.81);
      // Nothing pushes the box sideways. (The sub-stepped solver once let
      // its relax pass drive loaded contacts to a creep speed that
      // friction answered with 1.3 N.)
      EXPECT_LT(std::hypot(sideX, sideY), 1e-3);
    }
  }
}

// The default (sub-stepped, damped rigid contacts) against physics rather
// than against dWorldStep: it solves a softer contact problem, so it is
// held to the analytic answers with the margins measured (README).
TEST(OdeContacts, SubSteppedDefaultSlidesAndSinksAsPhysicsSays) {
  {
    ContactScene c;
    c.surface.mu = 0.3;
    dBodyID b = c.box(0.0, 0.0, 0.25, 0.5);
    dBodySetLinearVel(b, 3.0, 0.0, 0.0);
    for (int f = 0; f < 90; ++f)
      c.step(Stepper::Block);
    const double analytic = 3.0 * 3.0 / (2.0 * 0.3 * 9.81);
    const double slide = dBodyGetPosition(b)[0];
    std::printf("  sub-stepped slide %.4f m, analytic %.4f m\n", slide, analytic);
    // Friction decelerates at mu g (the relax pass's friction bound was
    // once the solve pass's normals, push included: 6% short).
    EXPECT_NEAR(slide, analytic, 0.01 * analytic);
  }
  {
    // soft_cfm as ODE's spring at any sub-step: m g / (4 k) = 2.04 mm.
    ContactScene c;
    c.surface.mode = dContactApprox1 | dContactSoftCFM | dContactSoftERP;
    c.surface.soft_cfm = 1e-3;
    c.surface.soft_erp = 0.2;
    dBodyID b = c.box(0.0, 0.0, 0.25, 0.5, 10.0);
    for (int f = 0; f < 180; ++f)
      c.step(Stepper::Block);
    const double sink = 0.25 - dBodyGetPosition(b)[2];
    std::printf("  sub-stepped soft contact sink %.4f m\n", sink);
    EXPECT_NEAR(sink, 10.0 * 9.81 / (4.0 * 12000.0), 0.02 * sink);
  }
}

// A ball dropped into a V groove (walls 10 degrees off level, the groove
// running 10 degrees downhill, the surface of ODE's demo_tracks): both walls
// must catch it at once, so it lands on the groove's line and stays there,
// then rolls down at the closed form for rolling on two lines of contact,
// a = g sin(incline) / (1 + (2/5) / cos^2(wall)) (the contact points lie
// r cos(wall) from the rolling axis). Solved wall by wall, the wall taken
// first kicked the ball sideways and it rocked across the groove.
TEST(OdeContacts, BallInAGrooveLandsOnItsLineAndRollsAsTheClosedForm) {
  const double wall = 10.0 * M_PI / 180.0, incline = 10.0 * M_PI / 180.0, r = 0.4;
  auto run = [&](Stepper stepper, double& accel, double& sideways, double& offWall) {
    ContactScene s;
    dGeomDestroy(s.geoms[0]);  // no ground: the groove's walls instead
    for (double side : {1.0, -1.0}) {
      dCreatePlane(s.space, -std::sin(incline) * std::cos(wall), side * std::sin(wall),
                   std::cos(incline) * std::cos(wall), 0.0);
    }
    s.surface.mode = dContactApprox1 | dContactBounce | dContactSoftERP;  // demo_tracks' surface
    s.surface.mu = 10.0;
    s.surface.bounce = 0.2;
    s.surface.soft_erp = 1e-3;
    const double lift = r / std::cos(wall) + 0.5;  // 0.5 m above the resting height
    dBodyID ball = s.sphere(-std::sin(incline) * lift, 0.0, std::cos(incline) * lift, r);
    dMass m;
    dMassSetSphere(&m, 0.1, r);  // the demo's density: 27 g
    dBodySetMass(ball, &m);
    double x[3];
    sideways = 0.0;
    for (int k = 1; k <= 150; ++k) {  // 50 Hz, as the demo
      s.step(stepper, 0.02);
      sideways = std::max(sideways, std::abs(dBodyGetPosition(ball)[1]));
      if (k % 50 == 0) x[k / 50 - 1] = dBodyGetPosition(ball)[0];
    }
    accel = (x[2] - 2.0 * x[1] + x[0]);  // over 1 s intervals
    // Height above the groove's line against resting on both walls.
    const dReal* p = dBodyGetPosition(ball);
    const double above = -std::sin(incline) * p[0] + std::cos(incline) * p[2];
    offWall = std::abs(above * std::cos(wall) - r);
  };
  const double expected = -9.81 * std::sin(incline) /
                          (1.0 + 0.4 / (std::cos(wall) * std::cos(wall))) * std::cos(incline);
  double aBlock, yBlock, dBlock, aQuick, yQuick, dQuick;
  run(Stepper::Block, aBlock, yBlock, dBlock);
  run(Stepper::Quick, aQuick, yQuick, dQuick);
  std::printf(
      "  rolling down: a_x %.4f m/s^2 (closed form %.4f, quickstep %.4f); largest sideways "
      "offset %.2g m (quickstep %.2g); off the walls at 3 s %.2g m (quickstep %.2g)\n",
      aBlock, expected, aQuick, yBlock, yQuick, dBlock, dQuick);
  EXPECT_NEAR(aBlock, expected, 0.005 * std::abs(expected));
  EXPECT_LT(yBlock, 1e-3) << "a symmetric landing must not push the ball sideways";
  EXPECT_LT(dBlock, 1e-3);
}

// demo_motion's lift: a platform geom the program moves up at 0.25 m/s
// (and sideways), its contacts carrying that speed as motionN, motion1 and
// motion2. A box riding it moves with it and stays on its surface, as with
// ODE's steppers (closed form: the platform's velocity, no penetration).
TEST(OdeContacts, BoxRidesALiftingPlatformAtItsSpeed) {
  const double vel[3] = {0.2, 0.1, 0.25}, h = 0.02;
  OdeScene s;
  dWorldSetGravity(s.world, 0, 0, -0.5);
  dSpaceID space = dSimpleSpaceCreate(0);
  dJointGroupID group = dJointGroupCreate(0);
  dGeomID platform = dCreateBox(space, 4, 4, 1);
  dBodyID box = s.box(0.0, 0.0, 0.5 + 0.15 + 0.01, 0.3, 0.3);
  dGeomSetBody(dCreateBox(space, 0.3, 0.3, 0.3), box);
  struct Lift {
    dWorldID world;
    dJointGroupID group;
    dGeomID platform;
    const double* vel;
  } lift{s.world, group, platform, vel};
  auto collide = [](void* data, dGeomID o1, dGeomID o2) {
    const auto* l = static_cast<Lift*>(data);
    dContact c[4];
    const int n = dCollide(o1, o2, 4, &c[0].geom, sizeof(dContact));
    for (int i = 0; i < n; ++i) {
      dSurfaceParameters& f = c[i].surface;
      f.mode = dContactBounce | dContactMotionN | dContactMotion1 | dContactMotion2 | dContactFDir1;
      f.mu = 1.0;
      f.bounce = 0.25;
      f.bounce_vel = 0.01;
      dVector3 d1, d2;
      dPlaneSpace(c[i].geom.normal, d1, d2);
      for (int k = 0; k < 3; ++k)
        c[i].fdir1[k] = d1[k];
      const double sign = c[i].geom.g1 == l->platform ? -1.0 : 1.0;
      f.motion1 = dCalcVectorDot3(l->vel, d1);
      f.motion2 = sign * dCalcVectorDot3(l->vel, d2);
      f.motionN = sign * dCalcVectorDot3(l->vel, c[i].geom.normal);
      dJointAttach(dJointCreateContact(l->world, l->group, c + i), dGeomGetBody(o1),
                   dGeomGetBody(o2));
    }
  };
  for (int k = 1; k <= 100; ++k) {
    dSpaceCollide(space, &lift, collide);
    dGeomSetPosition(platform, vel[0] * k * h, vel[1] * k * h, vel[2] * k * h);
    stepWith(Stepper::Block, s.world, h);
    dJointGroupEmpty(group);
  }
  const double depth = 0.5 + 0.15 + vel[2] * 100 * h - dBodyGetPosition(box)[2];
  const double vz = dBodyGetLinearVel(box)[2];
  std::printf("  riding: %.4f m/s up (platform 0.25), %.2g m into it\n", vz, depth);
  EXPECT_NEAR(vz, vel[2], 1e-3);
  EXPECT_LT(depth, 5e-4);
  dJointGroupDestroy(group);
  dSpaceDestroy(space);
}

// ODE's demo_moving_convex world: g 0.5, contacts with mu infinite,
// bounce 0.1 above 0.1 m/s and soft_cfm 0.01 (stepped at 20 Hz).
void useMovingConvexDemo(ContactScene& c) {
  dWorldSetGravity(c.scene.world, 0, 0, -0.5);
  c.surface.mode = dContactBounce | dContactSoftCFM;
  c.surface.mu = dInfinity;
  c.surface.bounce = 0.1;
  c.surface.bounce_vel = 0.1;
  c.surface.soft_cfm = 0.01;
}

// A body's geom, added to the scene's space and collided with the rest.
void addGeom(ContactScene& c, dBodyID body, dGeomID geom) {
  c.scene.bodies.push_back(body);
  dGeomSetBody(geom, body);
  c.geoms.push_back(geom);
}

// ODE finds contacts once a frame, so where a landing corner is found
// depends on the frame's phase: 1 mm above the ground one frame, 90 mm
// deep the next (1.85 m/s at 20 Hz). Pushing it out is position
// correction, not a spring's release. Taken as the spring soft_cfm makes
// (k = ERP / (h CFM) 400 N/m, d = (1 - ERP) / CFM 80 N s/m, pushing at
// k x / d) it threw demo_moving_convex's box (0.218 x 0.239 x 0.510 m,
// g 0.5, mu infinite, bounce 0.1, soft_cfm 0.01) off its landing corner
// with 36% more energy than ODE converged: it tumbled onto another face
// or was still rolling 5 s later, depending on the drop height. ODE
// (both steppers, and converged) lays it on the same face from any
// height; so must blockstep.
TEST(OdeContacts, BoxLandingOnACornerSettlesOnOneFaceWhateverTheFramePhase) {
  const double sides[3] = {0.21803398644971522, 0.23928345431091344, 0.50976688007585869};
  const dMatrix3 R = {0.2598237759323565,   0.88640441851245699,  0.38311723049459095, 0,
                      -0.83852329757429855, 0.010332042685487153, 0.54476777467015214, 0,
                      0.47892617895180573,  -0.46279634369292311, 0.74595526633913156, 0};
  for (const double lift : {0.0, 0.003, 0.0063, 0.02, 0.05}) {
    ContactScene c;
    useMovingConvexDemo(c);
    dBodyID box = dBodyCreate(c.scene.world);
    dMass m;
    dMassSetBox(&m, 5.0, sides[0], sides[1], sides[2]);
    dBodySetMass(box, &m);
    dBodySetRotation(box, R);
    dBodySetPosition(box, 0.0, 0.0, 1.3803668979247719 + lift);
    dBodySetLinearVel(box, 0.0, 0.0, -1.5);
    addGeom(c, box, dCreateBox(c.space, sides[0], sides[1], sides[2]));
    for (int f = 0; f < 150; ++f)
      c.step(Stepper::Block, 0.05);
    const double height = dBodyGetPosition(box)[2];
    const double speed =
        std::hypot(std::hypot(dBodyGetLinearVel(box)[0], dBodyGetLinearVel(box)[1]),
                   std::hypot(dBodyGetLinearVel(box)[2],
                              std::hypot(dBodyGetAngularVel(box)[0], dBodyGetAngularVel(box)[1])));
    std::printf("  dropped %.4f m higher: rests at %.4f m (ODE 0.1090), speed %.2g\n", lift, height,
                speed);
    EXPECT_NEAR(height, 0.5 * sides[0], 1e-3) << "on its largest face";
    EXPECT_LT(speed, 1e-2);
  }
}

// ODE's cylinder-plane collider gives a nearly flat coin one point a
// frame, its deepest rim point (demo_moving_convex's coin: radius 0.27 m,
// 0.092 m thick, mu infinite, bounce 0.1, soft_cfm 0.01, g 0.5, 20 Hz).
// ODE rocks it between opposite rim points 10 mm deep; converged it lies
// flat. With contact persistence (the default) it lies flat on four
// points, at rest; without, sub-stepping rocked it into a growing wobble.
TEST(OdeContacts, CoinGivenOneRimPointAFrameLiesFlat) {
  for (const double persistence : {0.0, 0.005}) {
    ContactScene c;
    useMovingConvexDemo(c);
    dWorldSetBlockContactPersistence(c.scene.world, persistence);
    dBodyID coin = dBodyCreate(c.scene.world);
    dMass m;
    dMassSetCylinder(&m, 5.0, 3, 0.27, 0.092);
    dBodySetMass(coin, &m);
    dMatrix3 R;
    dRFromAxisAndAngle(R, 1, 0.3, 0, 0.9);
    dBodySetRotation(coin, R);
    dBodySetPosition(coin, 0, 0, 0.5);
    addGeom(c, coin, dCreateCylinder(c.space, 0.27, 0.092));
    double lowest = 1.0, speed = 0.0;
    for (int f = 0; f < 400; ++f) {
      c.step(Stepper::Block, 0.05);
      if (f >= 300) {
        lowest = std::min(lowest, dBodyGetPosition(coin)[2]);
        speed = std::max(
            speed, std::hypot(dBodyGetLinearVel(coin)[2], std::hypot(dBodyGetAngularVel(coin)[0],
                                                                     dBodyGetAngularVel(coin)[1])));
      }
    }
    const double tilt = std::acos(std::min(1.0, dBodyGetRotation(coin)[10])) * 180.0 / M_PI;
    std::printf("  coin, persistence %.2f m: tilt %.2f deg, lowest centre %.4f m (flat 0.046)\n",
                persistence, tilt, lowest);
    if (persistence == 0.0) continue;
    EXPECT_LT(tilt, 0.1);
    EXPECT_NEAR(lowest, 0.046, 1e-3);
    EXPECT_LT(speed, 1e-3) << "at rest";
  }
}

// A wheel rolling on level ground keeps its speed (no rolling resistance
// asked for). ODE's cylinder-plane collider gives a wheel lying on its
// side two rim points; contact persistence (the default) carries last
// frame's, which stand for material points rolling up off the ground.
// Given ODE's friction force (mu = dInfinity, whatever the load) such a
// point held its material point still and braked the wheel: from 1.5 to
// 2.5 m/s it lost 2% to 10% of its speed in 2 s (slower, the new points
// stand for the old; faster, the old rise beyond the persistence distance
// and are dropped). In demo_moving_convex the same
// held a landing capsule's rolling end cap and flung the capsule 0.94 m
// from where ODE, plain and converged, lays it. A carried point takes
// friction only from its own load.
TEST(OdeContacts, WheelRollingOnItsCarriedPointsKeepsItsSpeed) {
  const int modes[2] = {0, dContactApprox1};
  for (const int mode : modes) {
    for (const double speed : {1.0, 1.5, 2.0, 2.5, 3.0}) {
      ContactScene c;
      c.surface.mode = mode;
      c.surface.mu = mode == 0 ? dInfinity : 0.8;
      dBodyID wheel = dBodyCreate(c.scene.world);
      dMass m;
      dMassSetCylinder(&m, 5.0, 3, 0.2, 0.3);
      dBodySetMass(wheel, &m);
      dMatrix3 R;
      dRFromAxisAndAngle(R, 1, 0, 0, M_PI / 2);  // the axis along y
      dBodySetRotation(wheel, R);
      dBodySetPosition(wheel, 0, 0, 0.2);
      dBodySetLinearVel(wheel, speed, 0, 0);
      dBodySetAngularVel(wheel, 0, speed / 0.2, 0);
      addGeom(c, wheel, dCreateCylinder(c.space, 0.2, 0.3));
      for (int f = 0; f < 120; ++f)
        c.step(Stepper::Block);
      const double v = dBodyGetLinearVel(wheel)[0];
      std::printf("  %s, %.1f m/s: after 2 s %.4f m/s, %.3f m on (closed form %.3f)\n",
                  mode == 0 ? "mu dInfinity" : "Approx1 mu 0.8", speed, v,
                  dBodyGetPosition(wheel)[0], 2.0 * speed);
      EXPECT_NEAR(v, speed, 1e-3 * speed);
      EXPECT_NEAR(dBodyGetPosition(wheel)[0], 2.0 * speed, 2e-3 * speed);
      EXPECT_NEAR(dBodyGetPosition(wheel)[2], 0.2, 1e-3);
    }
  }
}

// Issue 14's rolling cases through ODE's collision, once per frame: a 1 m
// ball rolling at 1 m/s reached 1.67 m/s in 10 s and 2.77 m/s in 30 s, at
// 25 m/s it sank 67 mm, and a marble nudged at 1 mm/s reached 0.41 m/s.
// Rolling dissipates nothing here, so the speed stays; a ball set sliding
// without spin ends rolling at 5/7 of its speed (a solid sphere: friction
// takes m v (1 - 5/7) and gives it to the spin), whatever the solver preset.
TEST(OdeContacts, RollingBallsKeepTheirSpeedAndSlidingOnesEndAtFiveSevenths) {
  struct Case {
    double radius, speed, seconds;
    bool spinning;
  };
  const Case cases[] = {{0.5, 1.0, 30.0, true},
                        {0.5, 25.0, 3.0, true},
                        {0.5, 1.0, 10.0, false},
                        {0.01, 0.001, 10.0, false}};
  for (const char* preset : {"default", "paper"}) {
    for (const Case& k : cases) {
      ContactScene c;
      c.surface.mode = 0;
      c.surface.mu = 1.0;
      dBodyID ball = c.sphere(0, 0, k.radius, k.radius);
      dWorldSetAutoDisableFlag(c.scene.world, 0);
      if (std::string(preset) == "paper") dWorldSetBlockPaperSolver(c.scene.world, 20);
      dBodySetLinearVel(ball, k.speed, 0, 0);
      if (k.spinning) dBodySetAngularVel(ball, 0, k.speed / k.radius, 0);
      double lowest = k.radius;
      const int frames = static_cast<int>(k.seconds * 60);
      for (int f = 0; f < frames; ++f) {
        c.step(Stepper::Block);
        lowest = std::min(lowest, double(dBodyGetPosition(ball)[2]));
      }
      const dReal* v = dBodyGetLinearVel(ball);
      const double expected = k.spinning ? k.speed : k.speed * 5.0 / 7.0;
      std::printf(
          "  %s, r %.2f m at %g m/s %s: %.6g m/s after %g s (expected %.6g), %.3f mm deep\n",
          preset, k.radius, k.speed, k.spinning ? "rolling" : "sliding", std::hypot(v[0], v[1]),
          k.seconds, expected, 1e3 * (k.radius - lowest));
      EXPECT_NEAR(std::hypot(v[0], v[1]), expected, 2e-3 * expected);
      EXPECT_LT(k.radius - lowest, 5e-4);
    }
  }
}

// The ragdoll's head (a 5 kg capsule, r 8 cm, 14 cm long) on a ball joint
// at one end, its other end on the ground, rolling round the joint at 30
// rad/s, through ODE's collision once a frame. Rolling gives it no
// energy. Before blockstep knew the capsule's end is round (the contact
// kept the step's first lever arm through the sub-steps) and turned held
// bodies with the midpoint gyroscopic rate, it gained 11.5 J in 10 s here
// (from 9.5 J), and in the ragdoll scene the head, come to rest on the
// ground, spun up to 24 rad/s and kept spinning. dWorldStep loses 7.3 J.
TEST(OdeContacts, HeadRollingRoundItsNeckGainsNoEnergy) {
  const double r = 0.08, length = 0.14, w0 = 30.0, neckZ = 0.219;
  // The capsule's axis, from the neck down to the far cap's centre at
  // height r, in the x-z plane; the far cap touches the ground below it.
  const double reach = length + r, drop = neckZ - r;
  const double ax = -std::sqrt(reach * reach - drop * drop) / reach, az = -drop / reach;
  const double centre[3] = {(0.5 * length + r) * ax, 0.0, neckZ + (0.5 * length + r) * az};
  const double line[3] = {reach * ax, 0.0, reach * az - r};  // the neck to the contact
  const double lineLength = std::hypot(line[0], line[2]);
  const double w[3] = {w0 * line[0] / lineLength, 0.0, w0 * line[2] / lineLength};
  const double arm[3] = {centre[0], 0.0, centre[2] - neckZ};
  const double v[3] = {w[1] * arm[2] - w[2] * arm[1], w[2] * arm[0] - w[0] * arm[2],
                       w[0] * arm[1] - w[1] * arm[0]};
  for (const Stepper stepper : {Stepper::Block, Stepper::Direct}) {
    ContactScene c;
    dBodyID head = dBodyCreate(c.scene.world);
    dMass m;
    dMassSetCapsuleTotal(&m, 5.0, 3, r, length);
    dBodySetMass(head, &m);
    dBodySetPosition(head, centre[0], centre[1], centre[2]);
    dMatrix3 R;
    dRFromZAxis(R, ax, 0.0, az);
    dBodySetRotation(head, R);
    dBodySetAngularVel(head, w[0], w[1], w[2]);
    dBodySetLinearVel(head, v[0], v[1], v[2]);
    addGeom(c, head, dCreateCapsule(c.space, r, length));
    dJointID ball = dJointCreateBall(c.scene.world, nullptr);
    dJointAttach(ball, head, nullptr);
    dJointSetBallAnchor(ball, 0.0, 0.0, neckZ);
    auto energy = [&] {
      const dReal* lv = dBodyGetLinearVel(head);
      const dReal* av = dBodyGetAngularVel(head);
      const dReal* rot = dBodyGetRotation(head);
      // The angular velocity in the body frame, then w . I w.
      double wb[3];
      for (int i = 0; i < 3; ++i)
        wb[i] = rot[i] * av[0] + rot[4 + i] * av[1] + rot[8 + i] * av[2];
      double spin = 0.0;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          spin += wb[i] * m.I[4 * i + j] * wb[j];
      return 0.5 * m.mass * (lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]) + 0.5 * spin +
             m.mass * 9.81 * dBodyGetPosition(head)[2];
    };
    const double start = energy();
    const double kinetic = start - m.mass * 9.81 * centre[2];
    double most = 0.0;
    for (int f = 0; f < 600; ++f) {
      c.step(stepper);
      most = std::max(most, energy() - start);
    }
    std::printf("  %s: most energy gained %.4f J of %.1f J, %.2f J in the end\n",
                stepper == Stepper::Block ? "blockstep" : "dWorldStep", most, kinetic,
                energy() - start);
    if (stepper == Stepper::Block) {
      EXPECT_LT(most, 0.01 * kinetic);
      EXPECT_GT(energy() - start, -0.5 * kinetic) << "it rolls on (a stopped head gains nothing)";
    }
  }
}

// Newton's cradle: five 1 kg balls of 5 cm radius hanging 0.5 m below
// hinges, touching in a row, elastic (bounce 1) and frictionless; the
// first raised 30 degrees. Elastic collisions keep the energy, so no step
// may add any. (The last ball should swing out as high as the first fell;
// solved at once through balls at rest against one another, the impulse
// spreads along the row instead: here it rises 26 mm of 67, under
// quickstep 20 33 mm, and dWorldStep throws it 0.6 m.) A contact's impact
// impulse, warm started into the next sub-step, pushed the balls apart
// once more: the drop-in gained 0.57 J in 5 s and the balls met 29 mm
// deep.
TEST(OdeContacts, NewtonsCradleKeepsItsEnergy) {
  constexpr int kBalls = 5;
  constexpr double r = 0.05, length = 0.5, pivotZ = 1.0, raised = M_PI / 6;
  ContactScene c;
  dGeomDestroy(c.geoms.front());  // no ground
  c.geoms.erase(c.geoms.begin());
  c.surface.mode = dContactBounce;
  c.surface.mu = 0.0;
  c.surface.bounce = 1.0;
  c.surface.bounce_vel = 0.0;
  std::vector<dBodyID> balls;
  for (int i = 0; i < kBalls; ++i) {
    const double px = (i - 0.5 * (kBalls - 1)) * 2 * r;
    const double swing = i == 0 ? -raised : 0.0;
    dBodyID b = dBodyCreate(c.scene.world);
    dMass m;
    dMassSetSphereTotal(&m, 1.0, r);
    dBodySetMass(b, &m);
    dBodySetPosition(b, px + length * std::sin(swing), 0.0, pivotZ - length * std::cos(swing));
    addGeom(c, b, dCreateSphere(c.space, r));
    dJointID h = dJointCreateHinge(c.scene.world, nullptr);
    dJointAttach(h, b, nullptr);
    dJointSetHingeAnchor(h, px, 0.0, pivotZ);
    dJointSetHingeAxis(h, 0, 1, 0);
    balls.push_back(b);
  }
  auto energy = [&] {
    double e = 0.0;
    for (dBodyID b : balls) {
      const dReal* v = dBodyGetLinearVel(b);
      e += 0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 9.81 * dBodyGetPosition(b)[2];
    }
    return e;  // spheres on hinges through their centres turn not at all
  };
  const double start = energy();
  const double drop = length * (1.0 - std::cos(raised));  // the first ball's height
  double most = 0.0, highest = 0.0;
  for (int f = 0; f < 300; ++f) {
    c.step(Stepper::Block);
    most = std::max(most, energy() - start);
    highest = std::max(highest, dBodyGetPosition(balls.back())[2] - (pivotZ - length));
  }
  std::printf("  most energy gained %.4f J of %.3f J of swing; last ball rose %.1f mm of %.1f\n",
              most, 9.81 * drop, highest * 1e3, drop * 1e3);
  EXPECT_LT(most, 1e-3 * 9.81 * drop);
  EXPECT_GT(highest, 0.25 * drop) << "the last ball swings out";
}

}  // namespace
}  // namespace blockstep::test

// Body state as ODE defines it, under dWorldBlockStep: damping with its
// thresholds, auto-disable and waking, kinematic bodies, gravity mode.
#include <algorithm>
#include <cmath>
#include <utility>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 60.0;

// ODE scales a velocity above its threshold by (1 - scale) after each step.
TEST(OdeBodies, DampingAsOdeDefinesIt) {
  OdeScene s;
  dWorldSetGravity(s.world, 0, 0, 0);
  dBodyID b = s.box(0.0, 0.0, 0.0);
  dBodySetLinearVel(b, 2.0, 0.0, 0.0);
  dBodySetAngularVel(b, 0.0, 0.0, 4.0);
  dBodySetLinearDamping(b, 0.1);
  dBodySetAngularDamping(b, 0.2);
  dBodySetLinearDampingThreshold(b, 1.0);  // below 1 m/s: no more damping
  dBodySetAngularDampingThreshold(b, 0.0);
  s.add(dJointCreateNull(s.world, 0), b, nullptr);
  for (int k = 0; k < 3; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_NEAR(dBodyGetLinearVel(b)[0], 2.0 * std::pow(0.9, 3), 1e-12);
  EXPECT_NEAR(dBodyGetAngularVel(b)[2], 4.0 * std::pow(0.8, 3), 1e-12);
  for (int k = 0; k < 20; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  // 2 * 0.9^7 = 0.957 < 1: damping stopped at the seventh step.
  EXPECT_NEAR(dBodyGetLinearVel(b)[0], 2.0 * std::pow(0.9, 7), 1e-12);
}

// A body resting with auto-disable on is disabled after ODE's idle steps,
// and a body hitting it wakes it, as with dWorldStep.
TEST(OdeBodies, AutoDisableAndWakeAsDirectSolver) {
  int disabledAt[2] = {-1, -1};
  int i = 0;
  for (Stepper stepper : {Stepper::Direct, Stepper::Block}) {
    OdeScene s;
    dSpaceID space = dHashSpaceCreate(0);
    dJointGroupID contacts = dJointGroupCreate(0);
    dCreatePlane(space, 0, 0, 1, 0);
    dBodyID b = s.box(0.0, 0.0, 0.1, 1.0, 0.2);
    dGeomSetBody(dCreateBox(space, 0.2, 0.2, 0.2), b);
    dBodySetAutoDisableFlag(b, 1);
    dBodySetAutoDisableSteps(b, 20);
    dBodySetAutoDisableTime(b, 0.0);
    struct Ctx {
      dWorldID w;
      dJointGroupID g;
    } ctx{s.world, contacts};
    auto near = [](void* data, dGeomID g1, dGeomID g2) {
      auto* c = static_cast<Ctx*>(data);
      dContact contact[4];
      const int n = dCollide(g1, g2, 4, &contact[0].geom, sizeof(dContact));
      for (int k = 0; k < n; ++k) {
        contact[k].surface.mode = dContactApprox1;
        contact[k].surface.mu = 0.5;
        dJointAttach(dJointCreateContact(c->w, c->g, &contact[k]), dGeomGetBody(g1),
                     dGeomGetBody(g2));
      }
    };
    dBodyID ball = nullptr;
    bool woke = false;
    for (int f = 0; f < 120; ++f) {
      if (f == 80) {  // drop a ball on it
        ball = dBodyCreate(s.world);
        dMass m;
        dMassSetSphereTotal(&m, 1.0, 0.05);
        dBodySetMass(ball, &m);
        dBodySetPosition(ball, 0.0, 0.0, 0.3);
        dGeomSetBody(dCreateSphere(space, 0.05), ball);
      }
      dSpaceCollide(space, &ctx, near);
      stepWith(stepper, s.world, kStep);
      dJointGroupEmpty(contacts);
      if (disabledAt[i] < 0 && !dBodyIsEnabled(b)) disabledAt[i] = f;
      if (f > 80 && dBodyIsEnabled(b)) woke = true;
      if (f == 79) {
        EXPECT_FALSE(dBodyIsEnabled(b));
        EXPECT_EQ(dBodyGetLinearVel(b)[2], 0.0);  // ODE zeroes a disabled body's velocity
      }
    }
    // Hit by the ball, the box woke up; it keeps resting on the ground.
    EXPECT_TRUE(woke);
    EXPECT_NEAR(dBodyGetPosition(b)[2], 0.1, 2e-3);
    dJointGroupDestroy(contacts);
    dSpaceDestroy(space);
    ++i;
  }
  std::printf("  disabled after frame: dWorldStep %d, blockstep %d\n", disabledAt[0],
              disabledAt[1]);
  ASSERT_GE(disabledAt[0], 0);
  EXPECT_NEAR(disabledAt[1], disabledAt[0], 3);
}

TEST(OdeBodies, WokenByATouchingBody) {
  OdeScene s;
  dBodyID a = s.box(0.0, 0.0, 1.0);
  dBodyID b = s.box(0.3, 0.0, 1.0);
  dJointID j = s.add(dJointCreateBall(s.world, 0), a, b);
  dJointSetBallAnchor(j, 0.15, 0.0, 1.0);
  dBodyDisable(b);
  ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  // The enabled body's joint woke the disabled one, and both fell.
  EXPECT_TRUE(dBodyIsEnabled(b));
  EXPECT_LT(dBodyGetLinearVel(b)[2], 0.0);
}

TEST(OdeBodies, KinematicAndGravityModes) {
  OdeScene s;
  dBodyID k = s.box(0.0, 0.0, 0.0);
  dBodySetKinematic(k);
  dBodySetLinearVel(k, 1.0, 0.0, 0.0);
  dBodyID floating = s.box(2.0, 0.0, 0.0);
  dBodySetGravityMode(floating, 0);
  dBodyID pulled = s.box(0.0, 0.5, 0.0);
  dJointID j = s.add(dJointCreateSlider(s.world, 0), pulled, k);  // follows the kinematic body
  dJointSetSliderAxis(j, 0.0, 0.0, 1.0);
  for (int f = 0; f < 60; ++f)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_NEAR(dBodyGetPosition(k)[0], 1.0, 1e-9);  // moved by its velocity only
  EXPECT_NEAR(dBodyGetPosition(k)[2], 0.0, 1e-12);
  EXPECT_NEAR(dBodyGetPosition(floating)[2], 0.0, 1e-12);
  EXPECT_NEAR(dBodyGetPosition(pulled)[0], 1.0, 1e-3);  // carried along x
  EXPECT_LT(dBodyGetPosition(pulled)[2], -1.0);         // free to fall along z
}

// ODE's per-body rotation settings: finite rotation (exact, also about an
// axis only) for a fast spinner, and the gyroscopic mode turned off for
// one body while another keeps it: as with dWorldStep.
TEST(OdeBodies, FiniteRotationAndGyroscopicModes) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID spinner = s.box(0.0, 0.0, 0.0);
    dBodySetAngularVel(spinner, 0.0, 0.0, 100.0);  // 1.67 rad a step
    dBodySetFiniteRotationMode(spinner, 1);
    dBodySetGyroscopicMode(spinner, 0);
    dBodyID wheel = s.box(2.0, 0.0, 0.0);
    dBodySetAngularVel(wheel, 0.0, 80.0, 0.0);
    dBodySetFiniteRotationMode(wheel, 1);
    dBodySetFiniteRotationAxis(wheel, 0.0, 1.0, 0.0);
    dBodySetGyroscopicMode(wheel, 0);
    dBodyID tumbler = s.box(4.0, 0.0, 0.0);
    dMass m;
    dMassSetBoxTotal(&m, 1.0, 0.2, 0.6, 1.0);
    dBodySetMass(tumbler, &m);
    dBodySetAngularVel(tumbler, 0.3, 6.0, 0.4);
    dBodySetGyroscopicMode(tumbler, 0);
    dBodyID gyro = s.box(6.0, 0.0, 0.0);  // keeps ODE's default: the world's term is on
    dBodySetAngularVel(gyro, 0.0, 0.0, 1.0);
  };
  auto probe = [](OdeScene& s) {
    std::vector<double> out;
    for (int i = 0; i < 2; ++i) {
      const dReal* q = dBodyGetQuaternion(s.bodies[i]);
      out.insert(out.end(), {q[0], q[1], q[2], q[3]});
    }
    const dReal* w = dBodyGetAngularVel(s.bodies[2]);
    out.insert(out.end(), {w[0], w[1], w[2]});
    return out;
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep);
  // Exact rotations compose exactly over blockstep's sub-steps; the
  // tumbler's first-order turn would not, so its rate is compared.
  double worst = 0.0;
  for (int i = 0; i < 11; ++i)
    worst = std::max(worst, run.maxDifference(i));
  std::printf("  spinner and wheel quaternions, tumbler rate: max |blockstep - dWorldStep| %.3g\n",
              worst);
  EXPECT_LT(worst, 1e-9);
  EXPECT_NEAR(run.block.back()[8], 0.3, 1e-12) << "no gyroscopic term for the tumbler";
}

// A torque-free symmetric top (demo_gyroscopic's: 1 kg, radius 1 m,
// 0.25 m thick, spinning at 7 rad/s about its axis with 1 rad/s across
// it) against the closed form: R(t) = Rot(L, |L| t / I1) R0
// Rot(e3, (1 - I3 / I1) w3 t). ODE's first-order implicit gyroscopic term
// (Lacoursiere 2006) bleeds spin energy, which the midpoint rule keeps;
// the demo's top ends 0.15 m from plain ODE for this reason.
TEST(OdeBodies, GyroscopicTopFollowsTheClosedForm) {
  constexpr double kTopStep = 0.02;  // the demo's
  constexpr int kSteps = 120;        // its 2.4 s of flight before landing
  const double w0[3] = {1.0, 0.0, 7.0};
  dMass m;
  dMassSetCylinderTotal(&m, 1.0, 3, 1.0, 0.25);
  const double I1 = m.I[0], I3 = m.I[10];
  const double L[3] = {I1 * w0[0], I1 * w0[1], I3 * w0[2]};  // R0 = identity
  const double Lnorm = std::sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
  const double T = kSteps * kTopStep;
  dMatrix3 precession, spin, exact;
  dRFromAxisAndAngle(precession, L[0], L[1], L[2], Lnorm * T / I1);
  dRFromAxisAndAngle(spin, 0.0, 0.0, 1.0, (1.0 - I3 / I1) * w0[2] * T);
  dMultiply0_333(exact, precession, spin);
  const double energy0 = 0.5 * (I1 * w0[0] * w0[0] + I3 * w0[2] * w0[2]);

  struct Result {
    double axisError;   // angle between the body's axis and the exact one
    double spinError;   // angle between its x axes (the spin phase)
    double energyLoss;  // relative
  };
  auto run = [&](Stepper stepper) {
    OdeScene s;
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID top = dBodyCreate(s.world);
    dBodySetMass(top, &m);
    dBodySetAngularVel(top, w0[0], w0[1], w0[2]);
    for (int k = 0; k < kSteps; ++k)
      stepWith(stepper, s.world, kTopStep);
    const dReal* R = dBodyGetRotation(top);
    auto column = [](const dReal* M, int c, int r) { return M[r * 4 + c]; };
    auto angle = [&](int c) {
      double dot = 0.0;
      for (int r = 0; r < 3; ++r)
        dot += column(R, c, r) * column(exact, c, r);
      return std::acos(std::min(1.0, dot));
    };
    const dReal* w = dBodyGetAngularVel(top);
    double wb[3] = {0, 0, 0};  // body-frame rate
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        wb[c] += column(R, c, r) * w[r];
    const double energy = 0.5 * (I1 * (wb[0] * wb[0] + wb[1] * wb[1]) + I3 * wb[2] * wb[2]);
    return Result{angle(2), angle(0), 1.0 - energy / energy0};
  };
  const Result ode = run(Stepper::Direct);
  const Result block = run(Stepper::Block);
  std::printf(
      "  after %.1f s: axis off the closed form by %.3g rad (dWorldStep %.3g), spin phase "
      "%.3g rad (%.3g), energy lost %.3g (%.3g)\n",
      T, block.axisError, ode.axisError, block.spinError, ode.spinError, block.energyLoss,
      ode.energyLoss);
  EXPECT_LT(block.axisError, 0.25 * ode.axisError);
  EXPECT_LT(block.spinError, 0.25 * ode.spinError);
  EXPECT_LT(std::abs(block.energyLoss), 1e-9);
}

// dBodySetMovedCallback: called once per step for each moved body, after
// the step, with the new pose already written; a callback may change the
// world (here it destroys another body) without harm.
struct MovedLog {
  int calls = 0;
  double z = 0.0;
  dBodyID victim = nullptr;
};
MovedLog movedLog;

void onMoved(dBodyID b) {
  ++movedLog.calls;
  movedLog.z = dBodyGetPosition(b)[2];
  if (movedLog.victim) {
    dBodyDestroy(movedLog.victim);
    movedLog.victim = nullptr;
  }
}

TEST(OdeBodies, MovedCallbackRunsAfterEachStep) {
  OdeScene s;
  dBodyID falling = s.box(0.0, 0.0, 1.0);
  dBodyID other = s.box(1.0, 0.0, 1.0);
  dBodySetMovedCallback(falling, onMoved);
  dBodySetMovedCallback(other, onMoved);
  movedLog = MovedLog{};
  for (int k = 0; k < 3; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_EQ(movedLog.calls, 6);
  EXPECT_EQ(movedLog.z, dBodyGetPosition(other)[2]) << "the pose after the step";
  EXPECT_LT(movedLog.z, 1.0);
  movedLog.victim = other;  // the first callback of the next step destroys it
  s.bodies.pop_back();
  movedLog.calls = 0;
  ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_EQ(movedLog.calls, 1) << "a body destroyed by a callback gets none";
  ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_EQ(movedLog.calls, 2);
}

// Auto-disable samples a body's motion over blockstep's last step. It
// took the pose after the step for the pose before it, so every jointed
// body counted as idle and froze in mid-air after ODE's 10 idle steps: a
// pendulum stopped mid-swing, a car hung in the air before landing (issue
// 14's car "never coming to rest" was judged by such frozen bodies).
TEST(OdeBodies, AutoDisableLeavesAMovingJointedBodyAwake) {
  for (const Stepper stepper : {Stepper::Quick, Stepper::Block}) {
    OdeScene s;
    dWorldSetAutoDisableFlag(s.world, 1);
    dBodyID bob = s.box(0.5, 0.0, 1.0);
    dJointID hinge = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
    dJointSetHingeAnchor(hinge, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(hinge, 0.0, 1.0, 0.0);
    for (int k = 0; k < 30; ++k)
      stepWith(stepper, s.world, 1.0 / 60.0);
    EXPECT_TRUE(dBodyIsEnabled(bob)) << (stepper == Stepper::Block ? "blockstep" : "quickstep");
    EXPECT_GT(std::abs(dJointGetHingeAngle(hinge)), 1.0);  // half a second into the swing
  }
}

// A 2,700 kg car on four 4 kg hinge2 wheels (rear ones held straight by
// stops, front ones free to steer) dropped 0.3 m onto the ground, ODE's
// auto-disable on: under dWorldStep replaced by blockstep it lands, hops
// and comes to rest as ODE's own dWorldStep does, its free wheels not
// steering themselves.
struct CarRun {
  double hop = 0.0, restAt = -1.0, height = 0.0, steer = 0.0;
};

void carNear(void* data, dGeomID a, dGeomID b) {
  auto* world = static_cast<std::pair<dWorldID, dJointGroupID>*>(data);
  const dBodyID b1 = dGeomGetBody(a), b2 = dGeomGetBody(b);
  if (b1 && b2 && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;  // wheel and chassis
  dContact c[4];
  const int n = dCollide(a, b, 4, &c[0].geom, sizeof(dContact));
  for (int i = 0; i < n; ++i) {
    c[i].surface.mode = dContactApprox1;
    c[i].surface.mu = 1.0;
    dJointAttach(dJointCreateContact(world->first, world->second, &c[i]), b1, b2);
  }
}

CarRun dropCar() {
  OdeScene s;
  dWorldSetAutoDisableFlag(s.world, 1);
  dSpaceID space = dHashSpaceCreate(0);
  dJointGroupID contacts = dJointGroupCreate(0);
  std::pair<dWorldID, dJointGroupID> data{s.world, contacts};
  dCreatePlane(space, 0, 0, 1, 0);
  const double radius = 0.35, drop = 0.3, z0 = drop + radius + 0.4;
  dBodyID chassis = s.box(0.0, 0.0, z0, 2700.0, 1.0);
  dMass m;
  dMassSetBoxTotal(&m, 2700.0, 4.5, 1.8, 0.8);
  dBodySetMass(chassis, &m);
  dGeomID body = dCreateBox(space, 4.5, 1.8, 0.8);
  dGeomSetBody(body, chassis);
  dJointID hinges[4];
  for (int i = 0; i < 4; ++i) {
    const double x = (i < 2 ? 1.5 : -1.5), y = (i % 2 ? 1.1 : -1.1);
    dBodyID wheel = dBodyCreate(s.world);
    dMassSetSphereTotal(&m, 4.0, radius);
    dBodySetMass(wheel, &m);
    dBodySetPosition(wheel, x, y, z0 - 0.4);
    dGeomID g = dCreateSphere(space, radius);
    dGeomSetBody(g, wheel);
    hinges[i] = s.add(dJointCreateHinge2(s.world, 0), chassis, wheel);
    dJointSetHinge2Anchor(hinges[i], x, y, z0 - 0.4);
    const dReal steer[3] = {0, 0, 1}, axle[3] = {0, 1, 0};
    dJointSetHinge2Axes(hinges[i], steer, axle);
    dJointSetHinge2Param(hinges[i], dParamSuspensionERP, 0.4);
    if (i >= 2) {
      dJointSetHinge2Param(hinges[i], dParamLoStop, 0.0);
      dJointSetHinge2Param(hinges[i], dParamHiStop, 0.0);
    }
  }
  CarRun run;
  double lowest = 1e9;
  bool landed = false;
  for (int k = 0; k < 180; ++k) {
    dSpaceCollide(space, &data, carNear);
    dWorldStep(s.world, 1.0 / 60.0);
    dJointGroupEmpty(contacts);
    const double z = dBodyGetPosition(chassis)[2];
    landed |= dBodyGetLinearVel(chassis)[2] > 0.0;
    if (landed) {
      lowest = std::min(lowest, z);
      run.hop = std::max(run.hop, z - lowest);
    }
    for (int i = 0; i < 2; ++i)
      run.steer = std::max(run.steer, std::abs(double(dJointGetHinge2Angle1(hinges[i]))));
    if (run.restAt < 0 && !dBodyIsEnabled(chassis)) run.restAt = (k + 1) / 60.0;
  }
  run.height = dBodyGetPosition(chassis)[2];
  dJointGroupDestroy(contacts);
  dSpaceDestroy(space);
  return run;
}

TEST(OdeBodies, HeavyCarOnLightWheelsLandsAndRestsAsDirectSolver) {
  const CarRun ode = dropCar();
  dBlockStepSetReplace("step");
  const CarRun block = dropCar();
  dBlockStepSetReplace("none");
  std::printf(
      "  hop %.4f / %.4f m, at rest at %.2f / %.2f s, height %.4f / %.4f m, steer %.3g / "
      "%.3g rad (dWorldStep / blockstep)\n",
      ode.hop, block.hop, ode.restAt, block.restAt, ode.height, block.height, ode.steer,
      block.steer);
  ASSERT_GT(ode.restAt, 0.3);  // the case: it lands and settles within the 3 s
  EXPECT_NEAR(block.hop, ode.hop, 0.01);
  EXPECT_GT(block.restAt, 0.3);
  EXPECT_NEAR(block.restAt, ode.restAt, 0.2);
  EXPECT_NEAR(block.height, ode.height, 0.01);
  EXPECT_LT(block.steer, 0.01);
}

}  // namespace
}  // namespace blockstep::test

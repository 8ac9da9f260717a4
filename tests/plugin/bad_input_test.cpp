// Bad input through ODE's API: a clear message, no crash, and a world that
// still steps. Unsupported content: said once, and ODE steps that world.
#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 60.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A pendulum that must still swing correctly after the bad call.
struct Pendulum {
  OdeScene s;
  dBodyID bob = s.box(0.5, 0.0, 1.0);
  dJointID hinge = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
  Pendulum() {
    dJointSetHingeAnchor(hinge, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(hinge, 0.0, 1.0, 0.0);
  }
  void expectSwingsOnItsHinge(int steps = 60) {
    for (int k = 0; k < steps; ++k)
      ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
    dVector3 a1, a2;
    dJointGetHingeAnchor(hinge, a1);
    dJointGetHingeAnchor2(hinge, a2);
    EXPECT_LT(distance(a1, a2), 1e-3);
    EXPECT_GT(std::abs(dJointGetHingeAngle(hinge)), 0.1);
    const dReal* p = dBodyGetPosition(bob);
    for (int i = 0; i < 3; ++i)
      EXPECT_TRUE(std::isfinite(p[i]));
  }
};

TEST(OdeBadInput, JointAttachingABodyToItselfIsRefused) {
  Pendulum p;
  dJointID ball = dJointCreateBall(p.s.world, 0);
  testing::internal::CaptureStderr();
  dJointAttach(ball, p.bob, p.bob);  // ODE itself aborts here
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("cannot attach a body to itself"), std::string::npos) << err;
  EXPECT_EQ(dJointGetBody(ball, 0), nullptr);
  p.expectSwingsOnItsHinge();
}

TEST(OdeBadInput, NanOrNegativeMassIsRefused) {
  Pendulum p;
  dMass before;
  dBodyGetMass(p.bob, &before);
  dMass bad = before;
  bad.mass = kNaN;
  testing::internal::CaptureStderr();
  dBodySetMass(p.bob, &bad);  // ODE would take it and step into NaN
  bad.mass = -1.0;
  dBodySetMass(p.bob, &bad);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("mass nan is not positive and finite"), std::string::npos) << err;
  EXPECT_NE(err.find("mass -1 is not positive"), std::string::npos) << err;
  dMass after;
  dBodyGetMass(p.bob, &after);
  EXPECT_EQ(after.mass, before.mass);
  p.expectSwingsOnItsHinge();
}

// A NaN damping wrote NaN velocities at the next step (issue 14).
TEST(OdeBadInput, NanDampingIsRefused) {
  Pendulum p;
  testing::internal::CaptureStderr();
  dBodySetLinearDamping(p.bob, kNaN);
  dBodySetAngularDamping(p.bob, kNaN);
  dBodySetDamping(p.bob, 0.01, kNaN);
  dWorldSetLinearDamping(p.s.world, kNaN);
  dBodySetMaxAngularSpeed(p.bob, kNaN);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("dBodySetLinearDamping(nan): the value must be finite; call ignored"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetLinearDamping(nan)"), std::string::npos) << err;
  EXPECT_NE(err.find("dBodySetMaxAngularSpeed(nan): the value must be a number"), std::string::npos)
      << err;
  EXPECT_EQ(dBodyGetLinearDamping(p.bob), 0.0);
  EXPECT_EQ(dBodyGetAngularDamping(p.bob), 0.0);
  EXPECT_EQ(dWorldGetLinearDamping(p.s.world), 0.0);
  EXPECT_TRUE(std::isinf(dBodyGetMaxAngularSpeed(p.bob)));
  dBodySetMaxAngularSpeed(p.bob, dInfinity);  // allowed: no limit
  p.expectSwingsOnItsHinge();
}

TEST(OdeBadInput, ZeroOrNonFiniteAxisIsRefused) {
  Pendulum p;
  testing::internal::CaptureStderr();
  dJointSetHingeAxis(p.hinge, 0.0, 0.0, 0.0);  // ODE itself aborts here
  dJointSetHingeAxis(p.hinge, kNaN, 0.0, 1.0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("dJointSetHingeAxis(0, 0, 0): the axis must be finite and non-zero"),
            std::string::npos)
      << err;
  dVector3 axis;
  dJointGetHingeAxis(p.hinge, axis);
  EXPECT_NEAR(axis[1], 1.0, 1e-12);
  p.expectSwingsOnItsHinge();
}

TEST(OdeBadInput, NonFiniteStateRefusesTheStepAndKeepsTheWorld) {
  Pendulum p;
  dBodyID other = p.s.box(3.0, 0.0, 1.0);
  dBodySetLinearVel(other, kNaN, 0.0, 0.0);
  const dReal* x = dBodyGetPosition(p.bob);
  const double before[3] = {x[0], x[1], x[2]};
  testing::internal::CaptureStderr();
  EXPECT_EQ(dWorldBlockStep(p.s.world, kStep), 0);
  EXPECT_EQ(dWorldBlockStep(p.s.world, kStep), 0);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("non-finite position, orientation, velocity"), std::string::npos) << err;
  // Said once per world, not once per step.
  EXPECT_EQ(err.find("non-finite", err.find("non-finite") + 1), std::string::npos) << err;
  EXPECT_NE(std::string(dWorldGetBlockStepMessage(p.s.world)).find("non-finite"),
            std::string::npos);
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(x[i], before[i]);
  // Fixed by the program, the world steps again.
  dBodySetLinearVel(other, 0.0, 0.0, 0.0);
  p.expectSwingsOnItsHinge();
}

TEST(OdeBadInput, AbsurdStepSizesAreRefused) {
  Pendulum p;
  testing::internal::CaptureStderr();
  EXPECT_EQ(dWorldBlockStep(p.s.world, 0.0), 0);
  EXPECT_EQ(dWorldBlockStep(p.s.world, -kStep), 0);
  EXPECT_EQ(dWorldBlockStep(p.s.world, kNaN), 0);
  EXPECT_EQ(dWorldBlockStep(p.s.world, 16.0), 0);  // milliseconds given as seconds
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("step size"), std::string::npos) << err;
  p.expectSwingsOnItsHinge();
}

// dWorldSetBlockIterations(w, 1e9) threw std::bad_alloc through the C API
// at the next step and killed the program (issue 14): absurd counts are
// refused with a message and the world keeps its settings.
TEST(OdeBadInput, AbsurdSolverCountsAreRefusedAndTheWorldKeepsItsSettings) {
  Pendulum p;
  dWorldSetBlockSubsteppedSolver(p.s.world, 4);
  const int iterations = dWorldGetBlockIterations(p.s.world);
  testing::internal::CaptureStderr();
  dWorldSetBlockIterations(p.s.world, 1000000000);
  dWorldSetBlockSubsteps(p.s.world, 5000);
  dWorldSetBlockRelaxIterations(p.s.world, -1);
  dWorldSetBlockPaperSolver(p.s.world, 0);
  const dReal refreshTurn = dWorldGetBlockRefreshTurn(p.s.world);
  dWorldSetBlockRefreshTurn(p.s.world, -0.5);
  dWorldSetBlockRefreshTurn(p.s.world, std::nan(""));
  const dReal impactDepth = dWorldGetBlockImpactDepth(p.s.world);
  dWorldSetBlockImpactDepth(p.s.world, -0.001);
  dWorldSetBlockImpactDepth(p.s.world, INFINITY);
  const dReal sinkingDepth = dWorldGetBlockSinkingDepth(p.s.world);
  dWorldSetBlockSinkingDepth(p.s.world, -0.001);
  dWorldSetBlockSinkingDepth(p.s.world, std::nan(""));
  const dReal maxTravel = dWorldGetBlockMaxTravel(p.s.world);
  dWorldSetBlockMaxTravel(p.s.world, -0.002);
  dWorldSetBlockMaxTravel(p.s.world, INFINITY);
  const int projections = dWorldGetBlockProjections(p.s.world);
  dWorldSetBlockProjections(p.s.world, -1);
  dWorldSetBlockProjections(p.s.world, 17);
  const dReal projectionTolerance = dWorldGetBlockProjectionTolerance(p.s.world);
  dWorldSetBlockProjectionTolerance(p.s.world, -1e-3);
  dWorldSetBlockProjectionTolerance(p.s.world, std::nan(""));
  dWorldSetBlockProjectionTolerance(p.s.world, INFINITY);
  const int contactRows = dWorldGetBlockContactIslandRows(p.s.world);
  dWorldSetBlockContactIslandRows(p.s.world, -3);
  dWorldSetBlockContactIslandRows(p.s.world, 100000);
  dWorldSetBlockIslandContacts(p.s.world, 3);
  const int exactJoint = dWorldGetBlockExactJointSubsteps(p.s.world);
  const int exactContact = dWorldGetBlockExactContactSubsteps(p.s.world);
  dWorldSetBlockExactJointSubsteps(p.s.world, -1);
  dWorldSetBlockExactContactSubsteps(p.s.world, 1001);
  const int calm = dWorldGetBlockCalmSubsteps(p.s.world);
  const dReal calmSpeed = dWorldGetBlockCalmSpeed(p.s.world);
  dWorldSetBlockCalmSubsteps(p.s.world, -2);
  dWorldSetBlockCalmSpeed(p.s.world, -0.1);
  dWorldSetBlockCalmSpeed(p.s.world, std::nan(""));
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(calm, 0);  // off unless the program asks
  EXPECT_EQ(dWorldGetBlockCalmSubsteps(p.s.world), 0);
  EXPECT_EQ(calmSpeed, 0.3);
  EXPECT_EQ(dWorldGetBlockCalmSpeed(p.s.world), calmSpeed);
  for (const char* said : {"dWorldSetBlockCalmSubsteps(-2): expected 0 to 1000; call ignored",
                           "dWorldSetBlockCalmSpeed(-0.1): expected a speed >= 0",
                           "dWorldSetBlockCalmSpeed(nan): expected a speed >= 0"})
    EXPECT_NE(err.find(said), std::string::npos) << err;
  dWorldSetBlockCalmSubsteps(p.s.world, 2);
  EXPECT_EQ(dWorldGetBlockCalmSubsteps(p.s.world), 2);
  EXPECT_EQ(exactJoint, 0);    // off unless the program asks
  EXPECT_EQ(exactContact, 0);  // the sub-stepped preset's: every island its N
  EXPECT_EQ(dWorldGetBlockExactJointSubsteps(p.s.world), 0);
  EXPECT_EQ(dWorldGetBlockExactContactSubsteps(p.s.world), 0);
  {
    Pendulum dropIn;  // following quickstep: exact islands at one sub-step
    EXPECT_EQ(dWorldGetBlockExactContactSubsteps(dropIn.s.world), 1);
    EXPECT_EQ(dWorldGetBlockExactJointSubsteps(dropIn.s.world), 1);
  }
  for (const char* said : {"dWorldSetBlockExactJointSubsteps(-1): expected 0 to 1000; call ignored",
                           "dWorldSetBlockExactContactSubsteps(1001): expected 0"})
    EXPECT_NE(err.find(said), std::string::npos) << err;
  dWorldSetBlockExactJointSubsteps(p.s.world, 2);
  EXPECT_EQ(dWorldGetBlockExactJointSubsteps(p.s.world), 2);
  EXPECT_EQ(contactRows, 128);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockContactIslandRows(p.s.world), contactRows);
  EXPECT_NE(err.find("dWorldSetBlockContactIslandRows(-3): expected 0 to 4096"), std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockContactIslandRows(100000): expected 0 to 4096"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockRefreshTurn(-0.5): expected an angle >= 0"), std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockRefreshTurn(nan): expected an angle >= 0"), std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockImpactDepth(-0.001): expected a depth >= 0"), std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockImpactDepth(inf): expected a depth >= 0"), std::string::npos)
      << err;
  EXPECT_EQ(impactDepth, 0.001);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockImpactDepth(p.s.world), impactDepth);
  EXPECT_NE(err.find("dWorldSetBlockSinkingDepth(-0.001): expected a depth >= 0"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockSinkingDepth(nan): expected a depth >= 0"), std::string::npos)
      << err;
  EXPECT_EQ(sinkingDepth, 0.00025);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockSinkingDepth(p.s.world), sinkingDepth);
  EXPECT_NE(err.find("dWorldSetBlockMaxTravel(-0.002): expected a distance >= 0"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockMaxTravel(inf): expected a distance >= 0"), std::string::npos)
      << err;
  EXPECT_EQ(maxTravel, 0.005);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockMaxTravel(p.s.world), maxTravel);
  EXPECT_NE(err.find("dWorldSetBlockProjections(-1): expected 0 to 16; call ignored"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockProjections(17): expected 0 to 16"), std::string::npos) << err;
  EXPECT_EQ(projections, 1);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockProjections(p.s.world), projections);
  dWorldSetBlockProjections(p.s.world, 2);
  EXPECT_EQ(dWorldGetBlockProjections(p.s.world), 2);
  for (const char* said : {"dWorldSetBlockProjectionTolerance(-0.001): expected an error >= 0",
                           "dWorldSetBlockProjectionTolerance(nan): expected an error >= 0",
                           "dWorldSetBlockProjectionTolerance(inf): expected an error >= 0"})
    EXPECT_NE(err.find(said), std::string::npos) << err;
  EXPECT_EQ(projectionTolerance, 0.001);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockProjectionTolerance(p.s.world), projectionTolerance);
  dWorldSetBlockProjectionTolerance(p.s.world, 5e-4);
  EXPECT_EQ(dWorldGetBlockProjectionTolerance(p.s.world), 5e-4);
  EXPECT_NE(err.find("dWorldSetBlockIslandContacts(3): expected 0 to 2"), std::string::npos) << err;
  EXPECT_EQ(dWorldGetBlockIslandContacts(p.s.world), 2);  // the sub-stepped preset's: at impacts
  dWorldSetBlockIslandContacts(p.s.world, 1);
  EXPECT_EQ(dWorldGetBlockIslandContacts(p.s.world), 1);
  dWorldSetBlockIslandContacts(p.s.world, 0);
  EXPECT_EQ(dWorldGetBlockIslandContacts(p.s.world), 0);
  EXPECT_EQ(dWorldGetBlockRetakeTurns(p.s.world), 1);  // the sub-stepped preset's
  dWorldSetBlockRetakeTurns(p.s.world, 0);
  EXPECT_EQ(dWorldGetBlockRetakeTurns(p.s.world), 0);
  EXPECT_EQ(refreshTurn, 0.001);  // the sub-stepped preset's
  EXPECT_EQ(dWorldGetBlockRefreshTurn(p.s.world), refreshTurn);
  EXPECT_NE(err.find("dWorldSetBlockIterations(1000000000): expected 1 to 100000; call ignored"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("dWorldSetBlockSubsteps(5000): expected 1 to 1000"), std::string::npos);
  EXPECT_NE(err.find("dWorldSetBlockRelaxIterations(-1): expected 0 to 100000"), std::string::npos);
  EXPECT_NE(err.find("dWorldSetBlockPaperSolver(0): expected 1 to 100000"), std::string::npos);
  EXPECT_EQ(dWorldGetBlockIterations(p.s.world), iterations);
  EXPECT_EQ(dWorldGetBlockSubsteps(p.s.world), 4);
  p.expectSwingsOnItsHinge();
}

// Inputs ODE steps, which blockstep used to refuse at every step: a
// drop-in program never checks the return value, so its world froze
// (issue 14). Each is now taken into range, said once, and the world steps.
TEST(OdeBadInput, InputsOdeStepsAreClampedSaidOnceAndStepped) {
  struct Case {
    const char* what;
    std::function<void(Pendulum&)> apply;
    const char* message;  // nullptr: taken as it is, nothing to say
  };
  auto stops = [](Pendulum& p) {
    dJointSetHingeParam(p.hinge, dParamLoStop, -0.5);
    dJointSetHingeParam(p.hinge, dParamHiStop, 0.5);
  };
  const std::vector<Case> cases = {
      {"world ERP 2", [](Pendulum& p) { dWorldSetERP(p.s.world, 2.0); }, "an ERP outside [0, 1]"},
      {"world CFM -1e-3", [](Pendulum& p) { dWorldSetCFM(p.s.world, -1e-3); }, "a negative CFM"},
      {"stop bounce 1.5",
       [&](Pendulum& p) {
         stops(p);
         dJointSetHingeParam(p.hinge, dParamBounce, 1.5);
       },
       "a joint stop's bounce outside [0, 1]"},
      {"stop ERP -1",
       [&](Pendulum& p) {
         stops(p);
         dJointSetHingeParam(p.hinge, dParamStopERP, -1.0);
       },
       "an ERP outside [0, 1]"},
      {"5000 quickstep iterations",
       [](Pendulum& p) { dWorldSetQuickStepNumIterations(p.s.world, 5000); },
       "more than 2000 quickstep iterations are followed as 1000 sub-steps"},
      {"max angular speed 0", [](Pendulum& p) { dBodySetMaxAngularSpeed(p.bob, 0.0); }, nullptr},
      {"motor with infinite FMax",
       [](Pendulum& p) {
         dJointSetHingeParam(p.hinge, dParamVel, 1.5);
         dJointSetHingeParam(p.hinge, dParamFMax, dInfinity);
       },
       nullptr},
      {"hand-set inertia (1, 1, 5)",
       [](Pendulum& p) {
         dMass m;
         dBodyGetMass(p.bob, &m);
         dMassSetParameters(&m, 1.0, 0, 0, 0, 0.01, 0.01, 0.05, 0, 0, 0);
         dBodySetMass(p.bob, &m);
       },
       nullptr},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    Pendulum p;
    c.apply(p);
    testing::internal::CaptureStderr();
    for (int k = 0; k < 60; ++k)
      ASSERT_EQ(dWorldBlockStep(p.s.world, kStep), 1) << dWorldGetBlockStepMessage(p.s.world);
    const std::string err = testing::internal::GetCapturedStderr();
    if (c.message) {
      const std::size_t first = err.find(c.message);
      EXPECT_NE(first, std::string::npos) << err;
      EXPECT_EQ(err.find(c.message, first + 1), std::string::npos) << "said twice: " << err;
    } else {
      EXPECT_EQ(err, "");
    }
    // The bob swings on its hinge, which holds.
    dVector3 a1, a2;
    dJointGetHingeAnchor(p.hinge, a1);
    dJointGetHingeAnchor2(p.hinge, a2);
    EXPECT_LT(distance(a1, a2), 5e-3);
    EXPECT_LT(dBodyGetPosition(p.bob)[2], 0.95);
  }
}

// A contact with bounce 1.5 (ODE adds energy at each bounce) is taken as
// bounce 1: a ball dropped from 0.5 m comes back up to about 0.5 m, no
// higher, and the world never freezes.
TEST(OdeBadInput, ContactBounceAboveOneBouncesAsOne) {
  OdeScene s;
  dBodyID ball = s.box(0.0, 0.0, 0.6, 1.0, 0.2);
  dJointGroupID group = dJointGroupCreate(0);
  testing::internal::CaptureStderr();
  double highestAfterBounce = 0.0;
  bool bounced = false;
  for (int k = 0; k < 120; ++k) {
    dJointGroupEmpty(group);
    const dReal* p = dBodyGetPosition(ball);
    if (p[2] < 0.1 + 0.02) {
      dContact c{};
      c.surface.mode = dContactBounce;
      c.surface.bounce = 1.5;
      c.surface.bounce_vel = 0.01;
      c.geom.pos[0] = p[0];
      c.geom.pos[1] = p[1];
      c.geom.normal[2] = 1.0;
      c.geom.depth = 0.1 - p[2];
      dJointAttach(dJointCreateContact(s.world, group, &c), ball, nullptr);
    }
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1) << dWorldGetBlockStepMessage(s.world);
    bounced |= dBodyGetLinearVel(ball)[2] > 0.5;
    if (bounced)
      highestAfterBounce = std::max(highestAfterBounce, double(dBodyGetPosition(ball)[2]));
  }
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("a contact's bounce outside [0, 1]"), std::string::npos) << err;
  EXPECT_TRUE(bounced);
  EXPECT_GT(highestAfterBounce, 0.5);
  EXPECT_LT(highestAfterBounce, 0.62);
  dJointGroupDestroy(group);
}

TEST(OdeBadInput, BodyDestroyedMidRunLeavesItsJointDetached) {
  OdeScene s;
  dBodyID a = s.box(0.3, 0.0, 1.0);
  dBodyID b = s.box(0.6, 0.0, 1.0);
  dJointID top = s.add(dJointCreateHinge(s.world, 0), a, nullptr);
  dJointSetHingeAnchor(top, 0.0, 0.0, 1.0);
  dJointSetHingeAxis(top, 0.0, 1.0, 0.0);
  dJointID mid = s.add(dJointCreateBall(s.world, 0), a, b);
  dJointSetBallAnchor(mid, 0.45, 0.0, 1.0);
  for (int k = 0; k < 30; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  dBodyDestroy(b);  // ODE detaches `mid` from it
  for (int k = 0; k < 30; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  // `a` swings on alone: its hinge holds.
  dVector3 a1, a2;
  dJointGetHingeAnchor(top, a1);
  dJointGetHingeAnchor2(top, a2);
  EXPECT_LT(distance(a1, a2), 1e-3);
  dBlockStepStats stats;
  ASSERT_EQ(dWorldGetBlockStepStats(s.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperBlockstep);
  // Reattached to the world, the ball joint pins `a` where its anchor is.
  dJointAttach(mid, a, nullptr);
  dJointSetBallAnchor(mid, dBodyGetPosition(a)[0], 0.0, dBodyGetPosition(a)[2]);
  for (int k = 0; k < 30; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  dJointGetBallAnchor(mid, a1);
  dJointGetBallAnchor2(mid, a2);
  EXPECT_LT(distance(a1, a2), 1e-3);
}

// ODE's dJointDestroy leaves a joint in a group alone (its group frees
// it): the pendulum keeps swinging on its hinge, as under ODE's stepper.
// blockstep used to forget the joint, and the bob fell (issue 14).
TEST(OdeBadInput, DestroyingAGroupedJointKeepsItAsOdeDoes) {
  dJointGroupID group = dJointGroupCreate(0);
  double swing[2] = {0.0, 0.0};
  for (int useOde = 0; useOde < 2; ++useOde) {
    OdeScene s;
    dBodyID bob = s.box(0.5, 0.0, 1.0);
    dJointID hinge = s.add(dJointCreateHinge(s.world, group), bob, nullptr);
    dJointSetHingeAnchor(hinge, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(hinge, 0.0, 1.0, 0.0);
    dJointDestroy(hinge);  // a no-op in ODE
    for (int k = 0; k < 60; ++k)
      stepWith(useOde ? Stepper::Direct : Stepper::Block, s.world, kStep);
    dVector3 a1, a2;
    dJointGetHingeAnchor(hinge, a1);
    dJointGetHingeAnchor2(hinge, a2);
    EXPECT_LT(distance(a1, a2), useOde ? 5e-3 : 1e-3) << (useOde ? "ODE" : "blockstep");
    swing[useOde] = dJointGetHingeAngle(hinge);
    dJointGroupEmpty(group);  // frees the hinge
  }
  // A second into the swing from horizontal (the hinge angle is the swing
  // from hanging plus pi / 2): the bob swung on its hinge, as near the
  // pendulum's equation of motion as ODE's direct solver (2.922 rad; ODE
  // 2.860 at this step, blockstep 2.894).
  const double exact = pendulumSwing(cubePendulumRate(1.0, 0.2, 0.5), -M_PI / 2, 0.0, -dInfinity,
                                     dInfinity, kStep, 1.0)
                           .back() +
                       M_PI / 2;
  std::printf("  hinge angle after 1 s: blockstep %.4f, dWorldStep %.4f, equation of motion %.4f\n",
              swing[0], swing[1], exact);
  EXPECT_GT(std::abs(swing[1]), 0.5);
  EXPECT_LE(std::abs(swing[0] - exact), std::abs(swing[1] - exact));
  dJointGroupDestroy(group);
}

TEST(OdeBadInput, WorldDestroyedWithGroupedJointsIsForgotten) {
  dJointGroupID group = dJointGroupCreate(0);
  {
    OdeScene s;
    dBodyID b = s.box(0.0, 0.0, 1.0);
    dJointID j = dJointCreateBall(s.world, group);
    dJointAttach(j, b, nullptr);
    dJointSetBallAnchor(j, 0.0, 0.0, 1.5);
    for (int k = 0; k < 10; ++k)
      ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  }  // dWorldDestroy with a grouped joint alive
  dJointGroupEmpty(group);
  dJointGroupDestroy(group);
  Pendulum p;  // a new world may reuse the addresses
  p.expectSwingsOnItsHinge();
}

// A joint kind without a mapping is said once, and that world steps with
// ODE's quickstep; the stats say so.
TEST(OdeBadInput, UnsupportedJointFallsBackToOdeOnce) {
  Pendulum p;
  // Plane2D between two bodies: ODE constrains body1 alone; no mapping.
  dJointID motor = dJointCreatePlane2D(p.s.world, 0);
  dJointAttach(motor, p.bob, p.s.box(2.0, 0.0, 1.0));
  testing::internal::CaptureStderr();
  for (int k = 0; k < 5; ++k)
    ASSERT_EQ(dWorldBlockStep(p.s.world, kStep), 1);
  const std::string err = testing::internal::GetCapturedStderr();
  const std::string said = "ODE plane2d joint";
  EXPECT_NE(err.find(said), std::string::npos) << err;
  EXPECT_EQ(err.find(said, err.find(said) + 1), std::string::npos) << "said more than once";
  EXPECT_NE(err.find("stepped by ODE"), std::string::npos) << err;
  dBlockStepStats stats;
  ASSERT_EQ(dWorldGetBlockStepStats(p.s.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperOde);
  // Once the motor is gone, blockstep steps again.
  dJointDestroy(motor);
  ASSERT_EQ(dWorldBlockStep(p.s.world, kStep), 1);
  ASSERT_EQ(dWorldGetBlockStepStats(p.s.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperBlockstep);
}

// A transmission needs two bodies (ODE aborts on attaching one): the
// attach is refused with a message, and the world steps on.
TEST(OdeBadInput, TransmissionOnOneBodyIsRefused) {
  Pendulum p;
  dJointID gear = dJointCreateTransmission(p.s.world, 0);
  testing::internal::CaptureStderr();
  dJointAttach(gear, p.bob, nullptr);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("a transmission joint needs two bodies"), std::string::npos) << err;
  EXPECT_EQ(dJointGetBody(gear, 0), nullptr);
  p.expectSwingsOnItsHinge();
}

}  // namespace
}  // namespace blockstep::test

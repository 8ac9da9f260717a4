// Each ODE joint kind, stepped by dWorldBlockStep, follows the trajectory
// ODE's direct solver (dWorldStep) gives, in ODE's own coordinates (the
// angles and positions its getters report), and keeps the joint at least
// as tight as quickstep with the same iteration count.
#include <algorithm>
#include <array>
#include <cmath>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 240.0;
constexpr double kSeconds = 2.0;

// Blockstep at high effort: the reference comparisons ask for agreement
// with the direct solver, not for the default cost.
void highEffort(OdeScene& s) {
  dWorldSetBlockSubsteppedSolver(s.world, 20);
}

TEST(OdeJoints, HingePendulumFollowsDirectSolver) {
  auto build = [](OdeScene& s) {
    dBodyID bob = s.box(0.0, 0.0, 1.0 - 0.7);
    dBodySetLinearVel(bob, 1.5, 0.0, 0.0);
    dJointID j = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
    dJointSetHingeAnchor(j, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(j, 0.0, 1.0, 0.0);
  };
  auto probe = [](OdeScene& s) {
    dVector3 a1, a2;
    dJointGetHingeAnchor(s.joints[0], a1);
    dJointGetHingeAnchor2(s.joints[0], a2);
    return std::vector<double>{dJointGetHingeAngle(s.joints[0]), distance(a1, a2)};
  };
  const TwinRun run = runTwin(build, probe, kSeconds, kStep, 20, highEffort);
  run.report("hinge angle (rad)", 0);
  run.reportError("anchor gap (m)", 1);
  // The pendulum swings about 0.9 rad; the trajectories stay within 0.02 rad.
  EXPECT_GT(TwinRun::maxOf(run.direct, 0), 0.5);
  EXPECT_LT(run.maxDifference(0), 0.02);
  EXPECT_LE(TwinRun::maxOf(run.block, 1), TwinRun::maxOf(run.quick, 1) + 1e-6);
}

// Two hinges in series (a double pendulum), the lower one between two
// bodies, the upper one attached with the body as ODE's body2 (reversed).
TEST(OdeJoints, DoubleHingeAndReversedAttachment) {
  auto build = [](OdeScene& s) {
    dBodyID upper = s.box(0.5, 0.0, 1.0);
    dBodyID lower = s.box(1.0, 0.0, 1.0, 0.5);
    dJointID top = s.add(dJointCreateHinge(s.world, 0), nullptr, upper);
    dJointSetHingeAnchor(top, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(top, 0.0, 1.0, 0.0);
    dJointID mid = s.add(dJointCreateHinge(s.world, 0), upper, lower);
    dJointSetHingeAnchor(mid, 0.5, 0.0, 1.0);
    dJointSetHingeAxis(mid, 0.0, 1.0, 0.0);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetHingeAngle(s.joints[0]), dJointGetHingeAngle(s.joints[1])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("upper hinge angle (rad)", 0);
  run.report("lower hinge angle (rad)", 1);
  EXPECT_GT(TwinRun::maxOf(run.direct, 0), 0.5);
  // A double pendulum is chaotic; over 1 s the two solvers stay together.
  EXPECT_LT(run.maxDifference(0), 0.03);
  EXPECT_LT(run.maxDifference(1), 0.05);
}

// Stops mean what they mean in ODE: the zero angle is the pose at
// dJointSetHingeAxis, here with the bob already turned by 0.4 rad, and
// bounce 0 is an inelastic stop ("not bouncy at all", ODE's manual). The
// pendulum's equation of motion is the reference (pendulumSwing; the bob,
// 0.7 m below the hinge, swings by minus the hinge angle; the joint turns
// its 2 m/s into a turn about the pivot, keeping its angular momentum
// about it). ODE's own dWorldStep pushes a stop's
// penetration out with ERP and throws the bob back (0.10 rad off the
// closed form at 240 Hz, 0.017 still at 240 kHz). With bounce, blockstep
// runs the paper's solver (one step, ODE's own ERP and CFM rows), which
// follows dWorldStep: the sub-stepped solver's damped rows take up part
// of an impulsive rebound in the joint (see the README's solver notes).
TEST(OdeJoints, HingeStopsUseOdesZeroAngle) {
  const double lo = -0.3, hi = 0.25;
  for (const double bounce : {0.0, 0.5}) {
    auto build = [bounce, lo, hi](OdeScene& s) {
      dBodyID bob = s.box(0.0, 0.0, 0.3);
      dMatrix3 r;
      dRFromAxisAndAngle(r, 0, 1, 0, 0.4);
      dBodySetRotation(bob, r);
      dBodySetLinearVel(bob, 2.0, 0.0, 0.0);
      dJointID j = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
      dJointSetHingeAnchor(j, 0.0, 0.0, 1.0);
      dJointSetHingeAxis(j, 0.0, 1.0, 0.0);
      dJointSetHingeParam(j, dParamLoStop, lo);
      dJointSetHingeParam(j, dParamHiStop, hi);
      dJointSetHingeParam(j, dParamBounce, bounce);
    };
    auto probe = [](OdeScene& s) { return std::vector<double>{dJointGetHingeAngle(s.joints[0])}; };
    auto configure = [bounce](OdeScene& s) {
      if (bounce > 0.0) {
        dWorldSetBlockPaperSolver(s.world, 50);
      } else {
        highEffort(s);
      }
    };
    const TwinRun run = runTwin(build, probe, kSeconds, kStep, 20, configure);
    double lowest = 0.0, highest = 0.0;
    for (const auto& v : run.block) {
      lowest = std::min(lowest, v[0]);
      highest = std::max(highest, v[0]);
    }
    std::printf("  blockstep range [%.4f, %.4f], stops [%.2f, %.2f]\n", lowest, highest, lo, hi);
    EXPECT_GT(lowest, lo - 0.01);
    EXPECT_LT(highest, hi + 0.01);
    EXPECT_GT(highest, hi - 0.05);  // it does reach the upper stop
    if (bounce > 0.0) {
      run.report("hinge angle, stops with bounce 0.5 (rad)", 0);
      EXPECT_LT(run.maxDifference(0), 0.05);
      continue;
    }
    const double mass = 1.0, side = 0.2, lever = 0.7;
    const double turnRate = mass * lever * 2.0 / cubePivotInertia(mass, side, lever);
    const std::vector<double> swing = pendulumSwing(cubePendulumRate(mass, side, lever), 0.0,
                                                    turnRate, -hi, -lo, kStep, kSeconds);
    double blockOff = 0.0, odeOff = 0.0;
    for (std::size_t k = 0; k < swing.size(); ++k) {
      blockOff = std::max(blockOff, std::abs(run.block[k][0] + swing[k]));
      odeOff = std::max(odeOff, std::abs(run.direct[k][0] + swing[k]));
    }
    std::printf(
        "  hinge angle, inelastic stops (rad): max off the equation of motion: blockstep %.3g, "
        "dWorldStep %.3g\n",
        blockOff, odeOff);
    EXPECT_LT(blockOff, 0.02);
  }
}

// A velocity motor with a force limit, no gravity: the hinge spins up to
// dParamVel, as fast as FMax allows.
TEST(OdeJoints, HingeMotorReachesItsSpeed) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID wheel = s.box(0.0, 0.0, 0.0, 2.0, 0.5);
    dJointID j = s.add(dJointCreateHinge(s.world, 0), wheel, nullptr);
    dJointSetHingeAnchor(j, 0.0, 0.0, 0.0);
    dJointSetHingeAxis(j, 0.0, 0.0, 1.0);
    dJointSetHingeParam(j, dParamVel, 3.0);
    dJointSetHingeParam(j, dParamFMax, 0.5);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetHingeAngleRate(s.joints[0])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("motor speed (rad/s)", 0);
  // I = 2 * 0.5^2 / 6 = 1/12 kg m^2; 0.5 N m takes 0.5 s to reach 3 rad/s.
  EXPECT_NEAR(run.block[59][0], 0.5 / (1.0 / 12.0) * 0.25, 0.02);
  EXPECT_NEAR(run.block.back()[0], 3.0, 1e-3);
  EXPECT_LT(run.maxDifference(0), 0.01);
}

// A motor told to hold a pendulum still (Vel 0) with a compliant row
// (dParamCFM 0.5 rad/s per N m) is a damper: the pendulum sinks at up to
// CFM times the gravity torque (2.45 rad/s level), as with dWorldStep.
// Without the CFM it would not move.
TEST(OdeJoints, HingeMotorCfmLetsThePendulumSink) {
  auto build = [](OdeScene& s) {
    dBodyID bob = s.box(0.5, 0.0, 1.0);
    dJointID j = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
    dJointSetHingeAnchor(j, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(j, 0.0, 1.0, 0.0);
    dJointSetHingeParam(j, dParamVel, 0.0);
    dJointSetHingeParam(j, dParamFMax, 100.0);
    dJointSetHingeParam(j, dParamCFM, 0.5);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetHingeAngle(s.joints[0]),
                               dJointGetHingeAngleRate(s.joints[0])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("angle (rad)", 0);
  run.report("rate (rad/s)", 1);
  EXPECT_GT(TwinRun::maxOf(run.direct, 0), 0.5);
  EXPECT_LT(run.maxDifference(0), 0.01);
  EXPECT_LT(run.maxDifference(1), 0.02);
}

// A slider on a 45 degree incline with a stop 0.2 m down and a motor
// pushing up on a second run.
TEST(OdeJoints, SliderStopAndMotor) {
  for (const bool motor : {false, true}) {
    auto build = [motor](OdeScene& s) {
      dBodyID block = s.box(0.0, 0.0, 0.0);
      dJointID j = s.add(dJointCreateSlider(s.world, 0), block, nullptr);
      dJointSetSliderAxis(j, 1.0, 0.0, 1.0);
      dJointSetSliderParam(j, dParamLoStop, -0.2);
      if (motor) {
        dJointSetSliderParam(j, dParamVel, 0.5);
        dJointSetSliderParam(j, dParamFMax, 20.0);
      }
    };
    auto probe = [](OdeScene& s) {
      return std::vector<double>{dJointGetSliderPosition(s.joints[0])};
    };
    const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
    run.report(motor ? "slider position, motor (m)" : "slider position, stop (m)", 0);
    // ODE's stop is soft (StopERP 0.2 per step): it sinks 6 mm past it,
    // blockstep's about 0.1 mm.
    EXPECT_LT(run.maxDifference(0), 0.01);
    if (motor) {
      EXPECT_NEAR(run.block.back()[0], 0.5 * 1.0, 0.02);
    } else {
      EXPECT_NEAR(run.block.back()[0], -0.2, 0.005);
    }
  }
}

// Stops set with lo > hi (demo_feedback sets a slider's to 0 and -0.2):
// ODE's setters take them, and its joints test their stops only when
// lo <= hi, so the axis is free: as with dWorldStep, at the closed form.
TEST(OdeJoints, SliderStopsGivenTheWrongWayRoundAreIgnored) {
  for (const double push : {9.81, -9.81}) {
    auto build = [push](OdeScene& s) {
      dWorldSetGravity(s.world, push, 0.0, 0.0);
      dBodyID block = s.box(0.0, 0.0, 0.0);
      dJointID j = s.add(dJointCreateSlider(s.world, 0), block, nullptr);
      dJointSetSliderAxis(j, 1.0, 0.0, 0.0);
      dJointSetSliderParam(j, dParamLoStop, 0.0);
      dJointSetSliderParam(j, dParamHiStop, -0.2);
    };
    auto probe = [](OdeScene& s) {
      return std::vector<double>{dJointGetSliderPosition(s.joints[0])};
    };
    const TwinRun run = runTwin(build, probe, 1.0, kStep);
    run.report(push > 0 ? "pushed up past lo (m)" : "pushed down below lo (m)", 0);
    // Free fall along the axis: 1/2 g t^2 = 4.905 m after 1 s (ODE's
    // semi-implicit Euler at 60 Hz adds 1/2 g h t = 0.08 m, blockstep's
    // sub-steps a tenth of that).
    EXPECT_GT(TwinRun::maxOf(run.direct, 0), 4.9) << "ODE lets it fall free";
    EXPECT_NEAR(TwinRun::maxOf(run.block, 0), 4.905, 0.01);
  }
}

// Ball joints: a double pendulum swinging out of plane.
TEST(OdeJoints, BallDoublePendulum) {
  auto build = [](OdeScene& s) {
    dBodyID a = s.box(0.4, 0.0, 1.0);
    dBodyID b = s.box(0.8, 0.0, 1.0);
    dBodySetLinearVel(b, 0.0, 1.0, 0.0);
    dJointID top = s.add(dJointCreateBall(s.world, 0), a, nullptr);
    dJointSetBallAnchor(top, 0.0, 0.0, 1.0);
    dJointID mid = s.add(dJointCreateBall(s.world, 0), a, b);
    dJointSetBallAnchor(mid, 0.4, 0.0, 1.0);
  };
  auto probe = [](OdeScene& s) {
    const dReal* p = dBodyGetPosition(s.bodies[1]);
    dVector3 a1, a2;
    dJointGetBallAnchor(s.joints[1], a1);
    dJointGetBallAnchor2(s.joints[1], a2);
    return std::vector<double>{p[0], p[1], p[2], distance(a1, a2)};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("lower bob x (m)", 0);
  run.report("lower bob y (m)", 1);
  run.report("lower bob z (m)", 2);
  run.reportError("lower anchor gap (m)", 3);
  for (int i = 0; i < 3; ++i)
    EXPECT_LT(run.maxDifference(i), 0.02);
  EXPECT_LE(TwinRun::maxOf(run.block, 3), TwinRun::maxOf(run.quick, 3));
}

// The universal joint below as generalized coordinates: the bob (ODE's
// body1, a 1 kg cube of side 0.2 m, 0.5 m below the anchor) turns by t2
// about the world's y (axis2, fixed in the world) and then by t1 about its
// own x (axis1): position L (-cos t1 sin t2, sin t1, -cos t1 cos t2), turn
// rate squared t1'^2 + t2'^2, so with I0 the cube's inertia
//   (m L^2 + I0) t1'' = -m L^2 c1 s1 t2'^2 - m g L s1 c2,
//   (m L^2 c1^2 + I0) t2'' = 2 m L^2 c1 s1 t1' t2' - m g L c1 s2.
// The mass matrix is diagonal and the stop's impulse acts along t2 alone,
// so an inelastic stop sets t2' = 0. Integrated by RK4 at 1/1000 of h;
// the start velocity (0.8, 0.6, 0) m/s is projected onto the joint's
// motion as the joint's first impulse does (momentum kept along it).
std::vector<std::array<double, 4>> universalWithInelasticStop2(double stop, double h,
                                                               double seconds) {
  const double m = 1.0, L = 0.5, I0 = m * 0.2 * 0.2 / 6.0, g = 9.81;
  const double start = m * L / (m * L * L + I0);  // turn per unit start speed
  return integrateRk4<4>(
      {0.0, 0.0, 0.6 * start, -0.8 * start},  // t1, t2, t1', t2'
      [&](const std::array<double, 4>& q) {
        const double c1 = std::cos(q[0]), s1 = std::sin(q[0]), c2 = std::cos(q[1]),
                     s2 = std::sin(q[1]);
        return std::array<double, 4>{
            q[2], q[3],
            (-m * L * L * c1 * s1 * q[3] * q[3] - m * g * L * s1 * c2) / (m * L * L + I0),
            (2.0 * m * L * L * c1 * s1 * q[2] * q[3] - m * g * L * c1 * s2) /
                (m * L * L * c1 * c1 + I0)};
      },
      [stop](std::array<double, 4>& q) {
        if (std::abs(q[1]) > stop) {
          q[1] = std::clamp(q[1], -stop, stop);
          q[3] = 0.0;
        }
      },
      h, seconds);
}

// Universal joint: a body hanging below it, spun about both axes, with an
// inelastic stop on the second angle, against the equations of motion
// above. ODE's dWorldStep throws the bob back off the stop (ERP pushes the
// stop's penetration out as a rebound; it does not vanish with h).
TEST(OdeJoints, UniversalAnglesAndStops) {
  const double stop = 0.25;
  auto build = [stop](OdeScene& s) {
    dBodyID bob = s.box(0.0, 0.0, 0.5);
    dBodySetLinearVel(bob, 0.8, 0.6, 0.0);
    dJointID j = s.add(dJointCreateUniversal(s.world, 0), bob, nullptr);
    dJointSetUniversalAnchor(j, 0.0, 0.0, 1.0);
    dJointSetUniversalAxis1(j, 1.0, 0.0, 0.0);
    dJointSetUniversalAxis2(j, 0.0, 1.0, 0.0);
    dJointSetUniversalParam(j, dParamLoStop2, -stop);
    dJointSetUniversalParam(j, dParamHiStop2, stop);
  };
  auto probe = [](OdeScene& s) {
    dVector3 a1, a2;
    dJointGetUniversalAnchor(s.joints[0], a1);
    dJointGetUniversalAnchor2(s.joints[0], a2);
    return std::vector<double>{dJointGetUniversalAngle1(s.joints[0]),
                               dJointGetUniversalAngle2(s.joints[0]), distance(a1, a2)};
  };
  const TwinRun run = runTwin(build, probe, kSeconds, kStep, 20, highEffort);
  run.reportError("anchor gap (m)", 2);
  const auto exact = universalWithInelasticStop2(stop, kStep, kSeconds);
  for (int i = 0; i < 2; ++i) {
    double blockOff = 0.0, odeOff = 0.0;
    for (std::size_t k = 0; k < exact.size(); ++k) {
      blockOff = std::max(blockOff, std::abs(run.block[k][i] - exact[k][i]));
      odeOff = std::max(odeOff, std::abs(run.direct[k][i] - exact[k][i]));
    }
    std::printf(
        "  universal angle %d (rad): max off the equations of motion: blockstep %.3g, dWorldStep "
        "%.3g\n",
        i + 1, blockOff, odeOff);
    EXPECT_LT(blockOff, 0.01);
  }
  EXPECT_GT(TwinRun::maxOf(run.direct, 0), 0.2);
  EXPECT_LT(TwinRun::maxOf(run.block, 1), stop + 0.01);
  EXPECT_LE(TwinRun::maxOf(run.block, 2), TwinRun::maxOf(run.quick, 2));
}

// Hinge2, a car's front wheel: the chassis is held by a fixed joint, the
// wheel hangs on a soft suspension along the steering axis, is steered
// by a motor toward a stop and driven about its axle.
TEST(OdeJoints, Hinge2SteersSpringsAndDrives) {
  auto build = [](OdeScene& s) {
    dBodyID chassis = s.box(0.0, 0.0, 1.0, 20.0, 0.5);
    dBodyID wheel = s.box(0.0, 0.4, 1.0, 2.0, 0.3);
    dJointID weld = s.add(dJointCreateFixed(s.world, 0), chassis, nullptr);
    dJointSetFixed(weld);
    dJointID j = s.add(dJointCreateHinge2(s.world, 0), chassis, wheel);
    dJointSetHinge2Anchor(j, 0.0, 0.4, 1.0);
    const dReal steer[3] = {0.0, 0.0, 1.0}, axle[3] = {0.0, 1.0, 0.0};
    dJointSetHinge2Axes(j, steer, axle);
    dJointSetHinge2Param(j, dParamSuspensionERP, 0.4);
    dJointSetHinge2Param(j, dParamSuspensionCFM, 1e-2);
    dJointSetHinge2Param(j, dParamVel, 1.0);
    dJointSetHinge2Param(j, dParamFMax, 50.0);
    dJointSetHinge2Param(j, dParamLoStop, -0.3);
    dJointSetHinge2Param(j, dParamHiStop, 0.3);
    dJointSetHinge2Param(j, dParamVel2, 6.0);
    dJointSetHinge2Param(j, dParamFMax2, 20.0);
  };
  auto probe = [](OdeScene& s) {
    dVector3 a1, a2;
    dJointGetHinge2Anchor(s.joints[1], a1);
    dJointGetHinge2Anchor2(s.joints[1], a2);
    return std::vector<double>{dJointGetHinge2Angle1(s.joints[1]),
                               dJointGetHinge2Angle2Rate(s.joints[1]), a1[2] - a2[2]};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("steering angle (rad)", 0);
  run.report("axle speed (rad/s)", 1);
  run.report("suspension sag (m)", 2);
  EXPECT_NEAR(run.block.back()[0], 0.3, 0.01);  // steered onto its stop
  EXPECT_NEAR(run.block.back()[1], 6.0, 0.05);  // driven at the motor's speed
  EXPECT_LT(run.maxDifference(0), 0.02);
  EXPECT_LT(run.maxDifference(1), 0.1);
  // The sag is the spring's: ODE's value within 5%.
  EXPECT_GT(run.direct.back()[2], 1e-3);
  EXPECT_NEAR(run.block.back()[2], run.direct.back()[2], 0.05 * run.direct.back()[2]);
}

// Piston: a body slides down a tilted rod onto a stop while a motor turns
// it about the rod.
TEST(OdeJoints, PistonSlidesToItsStopAndTurns) {
  auto build = [](OdeScene& s) {
    dBodyID body = s.box(0.0, 0.0, 1.0);
    dJointID j = s.add(dJointCreatePiston(s.world, 0), body, nullptr);
    dJointSetPistonAnchor(j, 0.0, 0.0, 1.0);
    dJointSetPistonAxis(j, 1.0, 0.0, 1.0);
    dJointSetPistonParam(j, dParamLoStop, -0.25);
    dJointSetPistonParam(j, dParamVel2, 2.0);
    dJointSetPistonParam(j, dParamFMax2, 5.0);
  };
  auto probe = [](OdeScene& s) {
    dVector3 a1, a2;
    dJointGetPistonAnchor(s.joints[0], a1);
    dJointGetPistonAnchor2(s.joints[0], a2);
    return std::vector<double>{dJointGetPistonPosition(s.joints[0]),
                               dJointGetPistonAngleRate(s.joints[0])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("piston position (m)", 0);
  run.report("piston turn rate (rad/s)", 1);
  EXPECT_NEAR(run.block.back()[0], -0.25, 0.005);
  EXPECT_NEAR(run.block.back()[1], 2.0, 0.01);
  EXPECT_LT(run.maxDifference(0), 0.01);
  EXPECT_LT(run.maxDifference(1), 0.05);
}

// Each of the piston's stops has its own softness: the turn is driven
// (1 N m) into a soft stop (StopERP2 0.2, StopCFM2 1: a 48 N m/rad spring
// at this step) that gives 0.02 rad, while the slide stop stays rigid.
TEST(OdeJoints, PistonStopsHaveTheirOwnSoftness) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID body = s.box(0.0, 0.0, 1.0);
    dJointID j = s.add(dJointCreatePiston(s.world, 0), body, nullptr);
    dJointSetPistonAnchor(j, 0.0, 0.0, 1.0);
    dJointSetPistonAxis(j, 0.0, 0.0, 1.0);
    dJointSetPistonParam(j, dParamHiStop2, 0.5);
    dJointSetPistonParam(j, dParamStopCFM2, 1.0);
    dJointSetPistonParam(j, dParamVel2, 2.0);
    dJointSetPistonParam(j, dParamFMax2, 1.0);
    dJointSetPistonParam(j, dParamHiStop, 0.1);
    dJointSetPistonParam(j, dParamVel, 1.0);
    dJointSetPistonParam(j, dParamFMax, 1.0);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetPistonAngle(s.joints[0]),
                               dJointGetPistonPosition(s.joints[0])};
  };
  const TwinRun run = runTwin(build, probe, 2.0, kStep, 20, highEffort);
  run.report("piston angle (rad)", 0);
  run.report("piston position (m)", 1);
  EXPECT_NEAR(run.direct.back()[0], 0.5 + 1.0 / 48.0, 0.003);
  EXPECT_NEAR(run.block.back()[0], run.direct.back()[0], 0.002);
  EXPECT_NEAR(run.block.back()[1], 0.1, 1e-3) << "the slide stop stays rigid";
}

// AMotor (user mode), no gravity: a motor about the body's own z axis
// spins it up to dParamVel within FMax, while a second axis (global x,
// zero speed, large FMax) stops the tumbling it started with; as
// dWorldStep has it.
TEST(OdeJoints, AMotorDrivesAndHolds) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID body = s.box(0.0, 0.0, 0.0);
    dBodySetAngularVel(body, 2.0, 0.0, 0.0);
    dJointID motor = s.add(dJointCreateAMotor(s.world, 0), body, nullptr);
    dJointSetAMotorMode(motor, dAMotorUser);
    dJointSetAMotorNumAxes(motor, 2);
    dJointSetAMotorAxis(motor, 0, 1, 0.0, 0.0, 1.0);  // fixed in the body
    dJointSetAMotorAxis(motor, 1, 0, 1.0, 0.0, 0.0);  // global x
    dJointSetAMotorParam(motor, dParamVel, 3.0);
    dJointSetAMotorParam(motor, dParamFMax, 0.02);
    dJointSetAMotorParam(motor, dParamVel2, 0.0);
    dJointSetAMotorParam(motor, dParamFMax2, 100.0);
  };
  auto probe = [](OdeScene& s) {
    const dReal* w = dBodyGetAngularVel(s.bodies[0]);
    dVector3 spin;
    dJointGetAMotorAxis(s.joints[0], 0, spin);
    return std::vector<double>{w[0] * spin[0] + w[1] * spin[1] + w[2] * spin[2], w[0]};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("spin about the body's z (rad/s)", 0);
  run.report("tumble about global x (rad/s)", 1);
  // I = m s^2 / 6 = 1/150 kg m^2: 0.02 N m gives 3 rad/s^2, 3 rad/s at 1 s.
  EXPECT_NEAR(run.block[119][0], 1.5, 0.01);
  EXPECT_NEAR(run.block.back()[1], 0.0, 1e-6);
  EXPECT_LT(run.maxDifference(0), 0.01);
  EXPECT_LT(run.maxDifference(1), 0.01);
}

// AMotor in Euler mode on a ball joint (a ragdoll shoulder): the axes as
// ODE's Euler mode has them (0 fixed in the upper body, 2 in the lower);
// its angles and reference vectors are rebuilt from what the program set.
void buildEulerShoulder(OdeScene& s, double swing, double spin) {
  dBodyID upper = s.box(0.0, 0.0, 1.0, 2.0);
  dBodyID lower = s.box(0.0, 0.0, 0.6);
  dBodySetAngularVel(lower, swing, 0.0, spin);
  dBodySetLinearVel(lower, 0.0, -0.2 * swing, 0.0);  // consistent with the anchor at z = 0.8
  dJointID weld = s.add(dJointCreateFixed(s.world, 0), upper, nullptr);
  dJointSetFixed(weld);
  dJointID ball = s.add(dJointCreateBall(s.world, 0), upper, lower);
  dJointSetBallAnchor(ball, 0.0, 0.0, 0.8);
  dJointID motor = s.add(dJointCreateAMotor(s.world, 0), upper, lower);
  dJointSetAMotorMode(motor, dAMotorEuler);
  dJointSetAMotorAxis(motor, 0, 1, 1.0, 0.0, 0.0);
  dJointSetAMotorAxis(motor, 2, 2, 0.0, 0.0, 1.0);
}

// The swing about x meets a stop on the first Euler angle and stops there
// (no bounce), as with dWorldStep.
TEST(OdeJoints, AMotorEulerStopHoldsTheSwing) {
  auto build = [](OdeScene& s) {
    buildEulerShoulder(s, 3.0, 0.0);
    dJointSetAMotorParam(s.joints[2], dParamLoStop, -0.3);
    dJointSetAMotorParam(s.joints[2], dParamHiStop, 0.3);
  };
  auto probe = [](OdeScene& s) {
    const dReal* p = dBodyGetPosition(s.bodies[1]);
    return std::vector<double>{std::atan2(p[1], 0.8 - p[2])};  // the swing angle
  };
  const TwinRun run = runTwin(build, probe, 0.5, kStep, 20, highEffort);
  run.report("swing angle (rad)", 0);
  // Free, 3 rad/s would swing it to 1.2 rad; the stop takes it at 0.3.
  EXPECT_NEAR(TwinRun::maxOf(run.direct, 0), 0.3, 0.02);
  EXPECT_NEAR(TwinRun::maxOf(run.block, 0), 0.3, 0.02);
  // Off the stop the swings part by up to 0.044 rad (ODE's stop is the
  // softer one, ERP 0.2 per step).
  EXPECT_LT(run.maxDifference(0), 0.05);
}

// A motor on the third Euler angle spins the lower body up, as with
// dWorldStep.
// Attached as (0, body), ODE's Euler mode keeps the public roles (axis 0
// in the world, axis 2 in the body). A motor on angle 0 and a stop on
// angle 2: the motions agree until the stop is reached; there ODE's stop
// pushes the wrong way (its reversed rows; the body is spun up past
// 100 rad/s within 0.4 s), while blockstep's holds at the stop.
TEST(OdeJoints, AMotorEulerAttachedToTheWorldFirst) {
  auto build = [](OdeScene& s) {
    buildEulerShoulder(s, 2.0, 1.0);
    dJointID motor = s.joints[2];
    dJointAttach(motor, nullptr, s.bodies[1]);
    dJointSetAMotorAxis(motor, 0, 1, 1.0, 0.0, 0.0);
    dJointSetAMotorAxis(motor, 2, 2, 0.0, 0.0, 1.0);
    dJointSetAMotorParam(motor, dParamVel, -1.0);
    dJointSetAMotorParam(motor, dParamFMax, 0.05);
    dJointSetAMotorParam(motor, dParamLoStop3, -0.2);
    dJointSetAMotorParam(motor, dParamHiStop3, 0.2);
  };
  auto probe = [](OdeScene& s) {
    const dReal* q = dBodyGetQuaternion(s.bodies[1]);
    const dReal* w = dBodyGetAngularVel(s.bodies[1]);
    return std::vector<double>{q[1], q[2], q[3], dJointGetAMotorAngle(s.joints[2], 2),
                               std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.reportError("spin (rad/s)", 4);
  const int beforeStop = 40;  // 1/6 s: angle 2 reaches -0.17 rad
  for (int k = 0; k < beforeStop; ++k) {
    for (int i = 0; i < 4; ++i)
      ASSERT_NEAR(run.block[k][i], run.direct[k][i], 0.01) << "step " << k << " quantity " << i;
  }
  EXPECT_LT(run.direct[beforeStop][3], -0.15);
  for (const auto& b : run.block) {
    EXPECT_GT(b[3], -0.2 - 0.01) << "blockstep's stop holds";
    EXPECT_LT(b[4], 3.0) << "and stays calm";
  }
}

TEST(OdeJoints, AMotorEulerMotorSpins) {
  auto build = [](OdeScene& s) {
    buildEulerShoulder(s, 0.0, 0.0);
    dJointSetAMotorParam(s.joints[2], dParamVel3, 2.0);
    dJointSetAMotorParam(s.joints[2], dParamFMax3, 0.05);
  };
  auto probe = [](OdeScene& s) { return std::vector<double>{dBodyGetAngularVel(s.bodies[1])[2]}; };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("spin (rad/s)", 0);
  EXPECT_GT(TwinRun::maxOf(run.direct, 0), 1.0);
  EXPECT_LT(run.maxDifference(0), 0.02);
}

// LMotor: a force-limited linear motor along global x pulls a free body
// up to its speed (a = FMax / m), as dWorldStep has it.
TEST(OdeJoints, LMotorPullsUpToSpeed) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, 0, 0);
    dBodyID body = s.box(0.0, 0.0, 0.0, 2.0);
    dJointID motor = s.add(dJointCreateLMotor(s.world, 0), body, nullptr);
    dJointSetLMotorNumAxes(motor, 1);
    dJointSetLMotorAxis(motor, 0, 0, 1.0, 0.0, 0.0);
    dJointSetLMotorParam(motor, dParamVel, 1.0);
    dJointSetLMotorParam(motor, dParamFMax, 4.0);
  };
  auto probe = [](OdeScene& s) { return std::vector<double>{dBodyGetLinearVel(s.bodies[0])[0]}; };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("LMotor speed (m/s)", 0);
  EXPECT_NEAR(run.block[59][0], 4.0 / 2.0 * 0.25, 1e-6);  // a = 2 m/s^2 for 0.25 s
  EXPECT_NEAR(run.block.back()[0], 1.0, 1e-6);
  EXPECT_LT(run.maxDifference(0), 1e-6);
}

// Plane2D: a body on the plane z = 0 under gravity along -y (in the
// plane) and a tilting push out of it, with a motor along x and about z;
// it stays in the plane, turns only about z, and follows dWorldStep.
TEST(OdeJoints, Plane2DKeepsTheBodyInThePlane) {
  auto build = [](OdeScene& s) {
    dWorldSetGravity(s.world, 0, -9.81, 0);
    dBodyID body = s.box(0.0, 0.0, 0.0);
    dBodySetAngularVel(body, 1.0, 0.0, 0.0);  // would tip it out of the plane
    dBodySetLinearVel(body, 0.0, 2.0, 0.5);
    dJointID j = s.add(dJointCreatePlane2D(s.world, 0), body, nullptr);
    dJointSetPlane2DXParam(j, dParamVel, 1.0);
    dJointSetPlane2DXParam(j, dParamFMax, 10.0);
    dJointSetPlane2DAngleParam(j, dParamVel, 2.0);
    dJointSetPlane2DAngleParam(j, dParamFMax, 10.0);
  };
  auto probe = [](OdeScene& s) {
    const dReal* x = dBodyGetPosition(s.bodies[0]);
    const dReal* w = dBodyGetAngularVel(s.bodies[0]);
    return std::vector<double>{x[0], x[1], x[2], w[2], std::hypot(w[0], w[1])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("x (m)", 0);
  run.report("y (m)", 1);
  run.report("spin about z (rad/s)", 3);
  run.reportError("|z| (m)", 2);
  run.reportError("tilt rate (rad/s)", 4);
  // The fall along y differs by ODE's own integration error, g h t / 2
  // (0.02 m at h = 1/240 s, t = 1 s); blockstep's fall is semi-implicit Euler's over
  // sub-steps h_s exactly: 2 t - g t^2 / 2 - g h_s t / 2.
  EXPECT_LT(run.maxDifference(0), 3e-3);
  EXPECT_LT(run.maxDifference(1), 0.5 * 9.81 * kStep * 1.0 + 1e-3);
  EXPECT_NEAR(run.block.back()[1], 2.0 - 0.5 * 9.81 - 0.5 * 9.81 * (kStep / 20.0), 1e-9);
  EXPECT_NEAR(run.block.back()[3], 2.0, 1e-3);
  EXPECT_LT(TwinRun::maxOf(run.block, 2), 1e-3);
  EXPECT_LT(TwinRun::maxOf(run.block, 4), 1e-3);
}

// PR: a carriage (body2) hangs from a rail (body1, welded to the world)
// on a prismatic stage along x with a stop, and swings about the rotoide
// axis y; a motor pushes the stage.
TEST(OdeJoints, PRSlidesAndSwings) {
  auto build = [](OdeScene& s) {
    dBodyID rail = s.box(0.0, 0.0, 1.0, 5.0, 0.2);
    dBodyID carriage = s.box(0.0, 0.0, 0.6);
    dBodySetLinearVel(carriage, 0.0, 0.0, 0.0);
    dJointID weld = s.add(dJointCreateFixed(s.world, 0), rail, nullptr);
    dJointSetFixed(weld);
    dJointID j = s.add(dJointCreatePR(s.world, 0), rail, carriage);
    dJointSetPRAnchor(j, 0.0, 0.0, 1.0);
    dJointSetPRAxis1(j, 1.0, 0.0, 0.0);
    dJointSetPRAxis2(j, 0.0, 1.0, 0.0);
    dJointSetPRParam(j, dParamLoStop, -0.3);
    dJointSetPRParam(j, dParamHiStop, 0.3);
    dJointSetPRParam(j, dParamVel, -1.0);
    dJointSetPRParam(j, dParamFMax, 3.0);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetPRPosition(s.joints[1]), dJointGetPRAngle(s.joints[1])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("PR position (m)", 0);
  run.report("PR angle (rad)", 1);
  EXPECT_GT(TwinRun::maxOf(run.direct, 1), 0.05);  // it does swing
  // ODE's stop is soft (it sinks 9 mm past -0.3); blockstep's holds.
  EXPECT_LT(run.maxDifference(0), 0.01);
  EXPECT_LT(run.maxDifference(1), 0.03);
  EXPECT_LT(TwinRun::maxOf(run.block, 0), 0.3 + 0.005);
}

// PU: a body hangs on a universal joint whose anchor slides along a
// tilted rail (a stop and a motor on the slide), swinging about both axes.
TEST(OdeJoints, PUSlidesAndSwings) {
  auto build = [](OdeScene& s) {
    dBodyID bob = s.box(0.0, 0.0, 0.6);
    dBodySetLinearVel(bob, 0.5, 0.8, 0.0);
    dJointID j = s.add(dJointCreatePU(s.world, 0), bob, nullptr);
    dJointSetPUAnchor(j, 0.0, 0.0, 1.0);
    dJointSetPUAxis1(j, 1.0, 0.0, 0.0);
    dJointSetPUAxis2(j, 0.0, 1.0, 0.0);
    dJointSetPUAxis3(j, 0.0, 0.0, 1.0);  // the slide: vertical
    dJointSetPUParam(j, dParamLoStop3, -0.2);
    dJointSetPUParam(j, dParamHiStop3, 0.2);
  };
  auto probe = [](OdeScene& s) {
    return std::vector<double>{dJointGetPUPosition(s.joints[0]), dJointGetPUAngle1(s.joints[0]),
                               dJointGetPUAngle2(s.joints[0])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("PU position (m)", 0);
  run.report("PU angle 1 (rad)", 1);
  run.report("PU angle 2 (rad)", 2);
  EXPECT_GT(TwinRun::maxOf(run.direct, 1), 0.1);
  EXPECT_GT(TwinRun::maxOf(run.direct, 2), 0.1);
  EXPECT_NEAR(run.block.back()[0], -0.2, 0.005);  // resting on the lower stop
  EXPECT_LT(run.maxDifference(0), 0.01);
  EXPECT_LT(run.maxDifference(1), 0.03);
  EXPECT_LT(run.maxDifference(2), 0.03);
}

// DHinge: a rod hinged at both ends about parallel axes (y): a body hangs
// from a pivot body on a 0.5 m link, and the pair swings in the x-z plane.
TEST(OdeJoints, DHingeSwingsLikeARod) {
  auto build = [](OdeScene& s) {
    dBodyID pivot = s.box(0.0, 0.0, 1.0);
    dBodyID bob = s.box(0.5, 0.0, 1.0);
    dBodySetLinearVel(bob, 0.0, 0.5, 0.0);  // pushed out of the plane: the joint stops it
    dJointID top = s.add(dJointCreateHinge(s.world, 0), pivot, nullptr);
    dJointSetHingeAnchor(top, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(top, 0.0, 1.0, 0.0);
    dJointID j = s.add(dJointCreateDHinge(s.world, 0), pivot, bob);
    dJointSetDHingeAxis(j, 0.0, 1.0, 0.0);
    dJointSetDHingeAnchor1(j, 0.0, 0.0, 1.0);
    dJointSetDHingeAnchor2(j, 0.5, 0.0, 1.0);
  };
  auto probe = [](OdeScene& s) {
    const dReal* p = dBodyGetPosition(s.bodies[1]);
    dVector3 a1, a2;
    dJointGetDHingeAnchor1(s.joints[1], a1);
    dJointGetDHingeAnchor2(s.joints[1], a2);
    return std::vector<double>{p[0], p[2], std::abs(distance(a1, a2) - 0.5), std::abs(p[1])};
  };
  const TwinRun run = runTwin(build, probe, 1.0, kStep, 20, highEffort);
  run.report("bob x (m)", 0);
  run.report("bob z (m)", 1);
  run.reportError("rod length error (m)", 2);
  run.reportError("out of plane (m)", 3);
  EXPECT_GT(TwinRun::maxOf(run.direct, 1), 0.2);
  EXPECT_LT(run.maxDifference(0), 0.02);
  EXPECT_LT(run.maxDifference(1), 0.02);
  EXPECT_LE(TwinRun::maxOf(run.block, 2), TwinRun::maxOf(run.quick, 2) + 1e-6);
  // The out-of-plane push gives at most 0.16 mm (the damped rigid rows
  // give a little under an impulse; quickstep 20 gives 1.1 mm).
  EXPECT_LT(TwinRun::maxOf(run.block, 3), 5e-4);
  EXPECT_LE(TwinRun::maxOf(run.block, 3), TwinRun::maxOf(run.quick, 3));
}

// A fixed joint welds a second body under a ball-jointed first one: the
// pair swings as one rigid pendulum.
TEST(OdeJoints, FixedWeldSwingsAsOneBody) {
  auto build = [](OdeScene& s) {
    dBodyID a = s.box(0.3, 0.0, 1.0);
    dBodyID b = s.box(0.6, 0.0, 1.0, 3.0);
    dJointID top = s.add(dJointCreateBall(s.world, 0), a, nullptr);
    dJointSetBallAnchor(top, 0.0, 0.0, 1.0);
    dJointID weld = s.add(dJointCreateFixed(s.world, 0), a, b);
    dJointSetFixed(weld);
  };
  auto probe = [](OdeScene& s) {
    const dReal* pa = dBodyGetPosition(s.bodies[0]);
    const dReal* pb = dBodyGetPosition(s.bodies[1]);
    return std::vector<double>{pb[2], std::abs(distance(pa, pb) - 0.3)};
  };
  const TwinRun run = runTwin(build, probe, kSeconds, kStep, 20, highEffort);
  run.report("welded body z (m)", 0);
  run.reportError("weld stretch (m)", 1);
  EXPECT_LT(run.maxDifference(0), 0.02);
  EXPECT_LE(TwinRun::maxOf(run.block, 1), TwinRun::maxOf(run.quick, 1));
}

// DBall keeps two anchors at their distance: a pendulum on a rod.
TEST(OdeJoints, DBallRodPendulum) {
  auto build = [](OdeScene& s) {
    dBodyID bob = s.box(0.6, 0.0, 0.8);
    dJointID j = s.add(dJointCreateDBall(s.world, 0), bob, nullptr);
    dJointSetDBallAnchor1(j, 0.6, 0.0, 0.8);
    dJointSetDBallAnchor2(j, 0.0, 0.0, 1.0);
  };
  auto probe = [](OdeScene& s) {
    const dReal* p = dBodyGetPosition(s.bodies[0]);
    dVector3 a1, a2;
    dJointGetDBallAnchor1(s.joints[0], a1);
    dJointGetDBallAnchor2(s.joints[0], a2);
    return std::vector<double>{p[0], p[2],
                               std::abs(distance(a1, a2) - dJointGetDBallDistance(s.joints[0]))};
  };
  const TwinRun run = runTwin(build, probe, kSeconds, kStep, 20, highEffort);
  run.report("bob x (m)", 0);
  run.report("bob z (m)", 1);
  run.reportError("rod length error (m)", 2);
  EXPECT_LT(run.maxDifference(0), 0.02);
  EXPECT_LT(run.maxDifference(1), 0.02);
  EXPECT_LE(TwinRun::maxOf(run.block, 2), TwinRun::maxOf(run.quick, 2));
}

// A null joint constrains nothing: the body is a projectile.
TEST(OdeJoints, NullJointLeavesAProjectile) {
  OdeScene s;
  dBodyID b = s.box(0.0, 0.0, 0.0);
  dBodySetLinearVel(b, 1.0, 0.0, 4.0);
  s.add(dJointCreateNull(s.world, 0), b, nullptr);
  const int steps = 240;
  for (int k = 0; k < steps; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  const dReal* p = dBodyGetPosition(b);
  const double t = steps * kStep;
  // Semi-implicit Euler over sub-steps h: z = v t - g t^2 / 2 - g h t / 2.
  const double h = kStep / dWorldGetBlockSubsteps(s.world);
  EXPECT_EQ(dWorldGetBlockSubsteps(s.world), 10);  // ODE's 20 iterations / 2
  EXPECT_NEAR(p[0], 1.0 * t, 1e-9);
  EXPECT_NEAR(p[2], 4.0 * t - 0.5 * 9.81 * t * t - 0.5 * 9.81 * h * t, 1e-9);
  dBlockStepStats stats;
  ASSERT_EQ(dWorldGetBlockStepStats(s.world, &stats), 1);
  EXPECT_EQ(stats.stepper, dBlockStepperBlockstep);
}

// dJointFeedback: a 2 kg mass hanging at rest on a hinge feels m g up.
// Transmission: a pendulum (body1, its wheel on the hinge axis) drives a
// second wheel on its own hinge through the joint in each ODE mode. The
// wheels' hinge angles follow dWorldStep's, and so do the transmission
// angles ODE's getters report (blockstep answers them from its own state).
struct GearScene {
  int mode;
  double backlash = 0.0;
  double bevelHeight = -0.3;  // of the horizontal bevel wheel's centre
};

void buildGears(OdeScene& s, const GearScene& g) {
  // Pendulum wheel: hinge at (0.4, 0, 0) about y, bob 0.3 m below. The
  // scene sits at height 0: ODE reflects a chain's contact points across a
  // plane through the origin, right only when the line of centres lies in
  // it (elsewhere ODE's contact points land far from the sprockets).
  dBodyID pendulum = s.box(0.4, 0.0, -0.3);
  dBodySetAngularVel(pendulum, 0.0, 2.0, 0.0);
  dBodySetLinearVel(pendulum, 0.6, 0.0, 0.0);
  dJointID h1 = s.add(dJointCreateHinge(s.world, 0), pendulum, nullptr);
  dJointSetHingeAnchor(h1, 0.4, 0.0, 0.0);
  dJointSetHingeAxis(h1, 0.0, 1.0, 0.0);
  // Driven wheel: a heavier box turning about its centre; for bevel gears
  // a horizontal wheel whose rim meets the pendulum wheel's at
  // (0.4, 0, bevelHeight).
  const bool bevel = g.mode == dTransmissionIntersectingAxes;
  const double c[3] = {bevel ? 0.4 : 0.0, bevel ? 0.3 : 0.0, bevel ? g.bevelHeight : 0.0};
  dBodyID wheel = s.box(c[0], c[1], c[2], 3.0, 0.3);
  dJointID h2 = s.add(dJointCreateHinge(s.world, 0), wheel, nullptr);
  dJointSetHingeAnchor(h2, c[0], c[1], c[2]);
  dJointSetHingeAxis(h2, 0.0, bevel ? 0.0 : 1.0, bevel ? 1.0 : 0.0);
  dJointID t = s.add(dJointCreateTransmission(s.world, 0), pendulum, wheel);
  dJointSetTransmissionMode(t, g.mode);
  dJointSetTransmissionAnchor1(t, 0.4, 0.0, 0.0);
  dJointSetTransmissionAnchor2(t, c[0], c[1], c[2]);
  if (bevel) {
    dJointSetTransmissionAxis1(t, 0.0, 1.0, 0.0);
    dJointSetTransmissionAxis2(t, 0.0, 0.0, 1.0);
  } else {
    dJointSetTransmissionAxis(t, 0.0, 1.0, 0.0);
  }
  if (g.mode == dTransmissionParallelAxes) dJointSetTransmissionRatio(t, 1.0 / 3.0);
  if (g.mode == dTransmissionChainDrive) {
    dJointSetTransmissionRadius1(t, 0.1);
    dJointSetTransmissionRadius2(t, 0.2);
  }
  dJointSetTransmissionBacklash(t, g.backlash);
}

// Quantities 0-3: hinge angles and transmission angles; 4: how far the
// rims' arcs part beyond the backlash (ODE's delta: r1 a1 + r2 a2 for
// gears, r1 a1 - r2 a2 for a chain), the joint's own error; 5: the ratio.
TwinRun runGears(const GearScene& g) {
  auto probe = [g](OdeScene& s) {
    const dJointID t = s.joints[2];
    const double a1 = dJointGetTransmissionAngle1(t), a2 = dJointGetTransmissionAngle2(t);
    const double r1 = dJointGetTransmissionRadius1(t), r2 = dJointGetTransmissionRadius2(t);
    const double delta = g.mode == dTransmissionChainDrive ? r1 * a1 - r2 * a2 : r1 * a1 + r2 * a2;
    return std::vector<double>{dJointGetHingeAngle(s.joints[0]),
                               dJointGetHingeAngle(s.joints[1]),
                               a1,
                               a2,
                               std::max(0.0, std::abs(delta) - g.backlash),
                               dJointGetTransmissionRatio(t)};
  };
  return runTwin([&g](OdeScene& s) { buildGears(s, g); }, probe, kSeconds, kStep, 20, highEffort);
}

TEST(OdeJoints, TransmissionGearsChainAndBevel) {
  const struct {
    const char* name;
    GearScene scene;
    double tolerance;  // rad, on the hinge angles
  } cases[] = {{"spur gears, ratio 1/3", {dTransmissionParallelAxes}, 0.002},
               {"chain, radii 0.1 and 0.2", {dTransmissionChainDrive}, 0.002},
               {"bevel gears at right angles", {dTransmissionIntersectingAxes}, 0.002},
               {"spur gears with 2 cm backlash", {dTransmissionParallelAxes, 0.02}, 0.02}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    std::printf("%s\n", c.name);
    const TwinRun run = runGears(c.scene);
    run.report("pendulum angle (rad)", 0);
    run.report("wheel angle (rad)", 1);
    run.report("transmission angle 1 (rad)", 2);
    run.report("transmission angle 2 (rad)", 3);
    EXPECT_GT(TwinRun::maxOf(run.direct, 1), 0.1) << "the wheel must turn";
    EXPECT_LT(run.maxDifference(0), c.tolerance);
    EXPECT_LT(run.maxDifference(1), c.tolerance);
    // ODE reports the angles it measured at the start of its last step,
    // blockstep those of its last sub-step: they differ by up to w h, on
    // top of the trajectories' own difference (the hinge tolerance).
    EXPECT_LT(run.maxDifference(2), std::max(0.01, c.tolerance));
    EXPECT_LT(run.maxDifference(3), std::max(0.01, c.tolerance));
    run.reportError("rim arc error (m)", 4);
    EXPECT_LE(TwinRun::maxOf(run.block, 4), TwinRun::maxOf(run.quick, 4) + 1e-6);
    EXPECT_NEAR(run.block.back()[5], run.direct.back()[5], 1e-5) << "the ratio ODE reports";
  }
}

// With the bevel wheel above the pendulum's axis ODE's position correction
// for intersecting axes acts against the motion (its arc signs are fixed,
// not taken from the geometry): dWorldStep's pendulum climbs from 0.26 rad
// to 1.4 rad. Blockstep's stays within its initial swing.
TEST(OdeJoints, TransmissionBevelAboveKeepsItsEnergy) {
  GearScene above{dTransmissionIntersectingAxes};
  above.bevelHeight = 0.3;
  const TwinRun run = runGears(above);
  run.reportError("pendulum swing (rad)", 0);
  EXPECT_LT(TwinRun::maxOf(run.block, 0), 0.3);
  EXPECT_GT(TwinRun::maxOf(run.block, 0), 0.2);
  EXPECT_NEAR(TwinRun::maxOf(run.block, 1), TwinRun::maxOf(run.block, 0), 0.01)
      << "equal radii: the wheel turns as far as the pendulum";
}

TEST(OdeJoints, HingeFeedbackIsWeight) {
  OdeScene s;
  dBodyID bob = s.box(0.0, 0.0, 0.5, 2.0);
  dJointID j = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
  dJointSetHingeAnchor(j, 0.0, 0.0, 1.0);
  dJointSetHingeAxis(j, 1.0, 0.0, 0.0);
  dJointFeedback fb{};
  dJointSetFeedback(j, &fb);
  for (int k = 0; k < 120; ++k)
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1);
  EXPECT_NEAR(fb.f1[2], 2.0 * 9.81, 0.01 * 2.0 * 9.81);
  EXPECT_NEAR(fb.f1[0], 0.0, 1e-3);
  EXPECT_NEAR(fb.f1[1], 0.0, 1e-3);
  // Torque about the body's centre: the force acts 0.5 m above it.
  EXPECT_NEAR(std::hypot(fb.t1[0], fb.t1[1]), 0.0, 1e-3);
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(fb.f2[i], 0.0);  // no body2
}

}  // namespace
}  // namespace blockstep::test

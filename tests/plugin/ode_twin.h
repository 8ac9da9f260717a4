// The same ODE scene built in several worlds and stepped by different
// steppers: ODE's direct solver (dWorldStep) as the reference, ODE's
// quickstep, and blockstep (dWorldBlockStep), all through ODE's own API.
#pragma once

#include <gtest/gtest.h>
#include <ode/ode.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "blockstep/blockstep_ode.h"

namespace blockstep::test {

class OdeLibrary : public ::testing::Environment {
 public:
  void SetUp() override {
    dInitODE2(0);
    dBlockStepSetReplace("none");  // dWorldStep / dWorldQuickStep stay ODE's own
  }
  void TearDown() override { dCloseODE(); }
};

struct OdeScene {
  dWorldID world = nullptr;
  std::vector<dBodyID> bodies;
  std::vector<dJointID> joints;
  std::vector<dJointFeedback> feedback = std::vector<dJointFeedback>(8);

  OdeScene() {
    world = dWorldCreate();
    dWorldSetGravity(world, 0, 0, -9.81);
  }
  ~OdeScene() { dWorldDestroy(world); }
  OdeScene(const OdeScene&) = delete;
  OdeScene& operator=(const OdeScene&) = delete;

  // A box-shaped body of `mass` kg and side `size` at (x, y, z).
  dBodyID box(double x, double y, double z, double mass = 1.0, double size = 0.2) {
    dBodyID b = dBodyCreate(world);
    dMass m;
    dMassSetBoxTotal(&m, mass, size, size, size);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, y, z);
    bodies.push_back(b);
    return b;
  }
  dJointID add(dJointID j, dBodyID b1, dBodyID b2) {
    dJointAttach(j, b1, b2);
    joints.push_back(j);
    return j;
  }
};

enum class Stepper { Direct, Quick, Block };

inline void stepWith(Stepper s, dWorldID w, double h) {
  switch (s) {
    case Stepper::Direct:
      dWorldStep(w, h);
      break;
    case Stepper::Quick:
      dWorldQuickStep(w, h);
      break;
    case Stepper::Block:
      ASSERT_EQ(dWorldBlockStep(w, h), 1) << dWorldGetBlockStepMessage(w);
      break;
  }
}

// Builds the scene once per stepper, steps each for `seconds` and records
// probe(scene) after every step.
struct TwinRun {
  std::vector<std::vector<double>> direct, quick, block;
  double maxDifference(int i) const {  // blockstep vs dWorldStep, quantity i
    double d = 0.0;
    for (std::size_t k = 0; k < direct.size(); ++k) {
      d = std::max(d, std::abs(direct[k][i] - block[k][i]));
    }
    return d;
  }
  // Prints the figures a test checks, for the record.
  void report(const char* what, int i) const {
    std::printf("  %s: max |blockstep - dWorldStep| %.3g, range %.3g\n", what, maxDifference(i),
                maxOf(direct, i));
  }
  void reportError(const char* what, int i) const {
    std::printf("  %s: max over the run: dWorldStep %.3g, quickstep %.3g, blockstep %.3g\n", what,
                maxOf(direct, i), maxOf(quick, i), maxOf(block, i));
  }
  static double maxOf(const std::vector<std::vector<double>>& series, int i) {
    double m = 0.0;
    for (const auto& s : series)
      m = std::max(m, std::abs(s[i]));
    return m;
  }
};

inline TwinRun runTwin(const std::function<void(OdeScene&)>& build,
                       const std::function<std::vector<double>(OdeScene&)>& probe, double seconds,
                       double h, int iterations = 20,
                       const std::function<void(OdeScene&)>& configureBlock = nullptr) {
  TwinRun run;
  const int steps = static_cast<int>(std::lround(seconds / h));
  for (Stepper s : {Stepper::Direct, Stepper::Quick, Stepper::Block}) {
    OdeScene scene;
    dWorldSetQuickStepNumIterations(scene.world, iterations);
    build(scene);
    if (s == Stepper::Block && configureBlock) configureBlock(scene);
    auto& out = s == Stepper::Direct ? run.direct : s == Stepper::Quick ? run.quick : run.block;
    for (int k = 0; k < steps; ++k) {
      stepWith(s, scene.world, h);
      out.push_back(probe(scene));
    }
    if (s == Stepper::Block) {
      // Blockstep itself stepped the world, not ODE's stepper as a fallback.
      dBlockStepStats stats;
      EXPECT_EQ(dWorldGetBlockStepStats(scene.world, &stats), 1);
      EXPECT_EQ(stats.stepper, dBlockStepperBlockstep) << dWorldGetBlockStepMessage(scene.world);
    }
  }
  return run;
}

// y integrated over `seconds` by RK4 at h / 1000, sampled every h:
// y' = rates(y); stop(y) runs after each RK4 step (an inelastic stop sets
// a coordinate's rate to 0). The equations-of-motion references the
// joint tests hold blockstep and ODE's own steppers to.
template <std::size_t N, class Rates, class Stop>
std::vector<std::array<double, N>> integrateRk4(std::array<double, N> y, Rates rates, Stop stop,
                                                double h, double seconds) {
  auto moved = [](std::array<double, N> q, const std::array<double, N>& d, double t) {
    for (std::size_t i = 0; i < N; ++i)
      q[i] += t * d[i];
    return q;
  };
  const int per = 1000;
  const double dt = h / per;
  std::vector<std::array<double, N>> out;
  for (int step = 0; step < static_cast<int>(std::lround(seconds / h)); ++step) {
    for (int i = 0; i < per; ++i) {
      const auto k1 = rates(y);
      const auto k2 = rates(moved(y, k1, 0.5 * dt));
      const auto k3 = rates(moved(y, k2, 0.5 * dt));
      const auto k4 = rates(moved(y, k3, dt));
      for (std::size_t j = 0; j < N; ++j)
        y[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
      stop(y);
    }
    out.push_back(y);
  }
  return out;
}

// A rigid pendulum's swing from hanging, theta'' = -k sin theta (k = m g
// r / I about the pivot), from theta0 at rate0, sampled every h, with
// inelastic stops at [lo, hi] (each takes the whole speed into it, ODE's
// bounce 0).
inline std::vector<double> pendulumSwing(double k, double theta0, double rate0, double lo,
                                         double hi, double h, double seconds) {
  const auto states = integrateRk4<2>(
      {theta0, rate0},
      [k](const std::array<double, 2>& y) {
        return std::array<double, 2>{y[1], -k * std::sin(y[0])};
      },
      [lo, hi](std::array<double, 2>& y) {
        if (y[0] < lo || y[0] > hi) y = {std::clamp(y[0], lo, hi), 0.0};
      },
      h, seconds);
  std::vector<double> swing;
  for (const auto& y : states)
    swing.push_back(y[0]);
  return swing;
}

// The inertia about a pivot at lever r of a cube-shaped bob (ODE's box,
// side `side`).
inline double cubePivotInertia(double mass, double side, double lever) {
  return mass * side * side / 6.0 + mass * lever * lever;
}

// k = m g r / I of that pendulum.
inline double cubePendulumRate(double mass, double side, double lever) {
  return mass * 9.81 * lever / cubePivotInertia(mass, side, lever);
}

inline double distance(const dVector3 a, const dVector3 b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

}  // namespace blockstep::test

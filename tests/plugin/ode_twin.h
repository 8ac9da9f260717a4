// The same ODE scene built in several worlds and stepped by different
// steppers: ODE's direct solver (dWorldStep) as the reference, ODE's
// quickstep, and blockstep (dWorldBlockStep), all through ODE's own API.
#pragma once

#include <gtest/gtest.h>
#include <ode/ode.h>

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

inline double distance(const dVector3 a, const dVector3 b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

}  // namespace blockstep::test

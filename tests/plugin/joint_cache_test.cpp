// The bridge reads an ODE joint again only when one of its setters ran or
// the world's ERP, CFM or step changed (WorldBridge::readAll): every
// setter of ODE's API must therefore reach the plugin, and whatever a
// program sets between steps must still take effect at the next step.
#include <dlfcn.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

// The joint setters ODE's installed header declares: every dJointSet*,
// and dJointAttach, but for the two that do not touch the joint's rows.
std::set<std::string> odeJointSetters() {
  std::ifstream in(ODE_OBJECTS_HEADER);
  std::stringstream text;
  text << in.rdbuf();
  const std::string header = text.str();
  const std::regex declaration(R"(ODE_API\s+void\s+(dJoint(Set[A-Za-z0-9]+|Attach))\s*\()");
  std::set<std::string> names;
  for (auto it = std::sregex_iterator(header.begin(), header.end(), declaration);
       it != std::sregex_iterator(); ++it) {
    const std::string name = (*it)[1];
    if (name != "dJointSetData" && name != "dJointSetFeedback") names.insert(name);
  }
  return names;
}

TEST(PluginJointCache, EverySetterOfOdesApiIsCounted) {
  const std::set<std::string> setters = odeJointSetters();
  // ODE 0.16 declares 72 of them; far fewer means the header was not read.
  ASSERT_GT(setters.size(), 60u) << ODE_OBJECTS_HEADER;
  for (const std::string& name : setters) {
    void* found = dlsym(RTLD_DEFAULT, name.c_str());
    ASSERT_NE(found, nullptr) << name;
    Dl_info info{};
    ASSERT_NE(dladdr(found, &info), 0) << name;
    EXPECT_NE(std::string(info.dli_fname).find("libblockstep_ode"), std::string::npos)
        << name << " resolves to " << info.dli_fname
        << ": the bridge would not see the program set it";
  }
}

// A wheel on a hinge along z, out of gravity's plane: only its motor and
// its stops turn it.
struct Wheel {
  OdeScene scene;
  dBodyID body;
  dJointID hinge;
  static constexpr double kStep = 1.0 / 60.0;

  Wheel() {
    body = scene.box(0.0, 0.0, 1.0, 1.0, 0.4);
    hinge = scene.add(dJointCreateHinge(scene.world, 0), body, nullptr);
    dJointSetHingeAnchor(hinge, 0.0, 0.0, 1.0);
    dJointSetHingeAxis(hinge, 0.0, 0.0, 1.0);
    dJointSetHingeParam(hinge, dParamFMax, 100.0);
    dWorldSetGravity(scene.world, 0.0, 0.0, 0.0);
  }
  void steps(int n) {
    for (int i = 0; i < n; ++i)
      dWorldBlockStep(scene.world, kStep);
  }
};

TEST(PluginJointCache, MotorAndStopsSetBetweenStepsTakeEffectAtTheNextStep) {
  Wheel w;
  w.steps(10);  // read once, then unchanged
  EXPECT_NEAR(dJointGetHingeAngleRate(w.hinge), 0.0, 1e-9);

  dJointSetHingeParam(w.hinge, dParamVel, 2.0);
  w.steps(1);
  EXPECT_NEAR(dJointGetHingeAngleRate(w.hinge), 2.0, 1e-3);
  w.steps(20);
  EXPECT_NEAR(dJointGetHingeAngleRate(w.hinge), 2.0, 1e-3);

  // A stop just ahead of the wheel: it stops there, the motor pushing on.
  // (The angle stands still within 2 mrad past the stop; the rate the body
  // reports there is the relax pass's creep into the soft stop, 0.38 rad/s,
  // which the next step's solve takes back: see the README's "Stops and
  // motors".)
  const double stop = dJointGetHingeAngle(w.hinge) + 0.1;
  dJointSetHingeParam(w.hinge, dParamHiStop, stop);
  w.steps(20);
  const double held = dJointGetHingeAngle(w.hinge);
  EXPECT_LT(held, stop + 0.003);
  EXPECT_GT(held, stop - 0.01);
  w.steps(10);
  EXPECT_NEAR(dJointGetHingeAngle(w.hinge), held, 1e-4);

  // The motor reversed turns it back off the stop.
  dJointSetHingeParam(w.hinge, dParamVel, -1.0);
  w.steps(5);
  EXPECT_NEAR(dJointGetHingeAngleRate(w.hinge), -1.0, 1e-3);
}

TEST(PluginJointCache, AnAxisSetBetweenStepsTurnsTheWheelAboutIt) {
  Wheel w;
  dJointSetHingeParam(w.hinge, dParamVel, 1.0);
  w.steps(10);
  const dReal* spin = dBodyGetAngularVel(w.body);
  EXPECT_NEAR(spin[2], 1.0, 1e-3);
  // The axis moved to x: the motor now turns the wheel about x, and the
  // old turn about z is held by the hinge.
  dJointSetHingeAxis(w.hinge, 1.0, 0.0, 0.0);
  w.steps(10);
  spin = dBodyGetAngularVel(w.body);
  EXPECT_NEAR(spin[0], 1.0, 1e-3);
  EXPECT_NEAR(spin[2], 0.0, 1e-3);
}

// The world's CFM is part of every hinge's rows: made soft between steps,
// a pendulum's hinge stretches under its bob at once.
TEST(PluginJointCache, TheWorldsCfmSetBetweenStepsSoftensTheJoints) {
  OdeScene s;
  dBodyID bob = s.box(0.5, 0.0, 1.0);
  dJointID hinge = s.add(dJointCreateHinge(s.world, 0), bob, nullptr);
  dJointSetHingeAnchor(hinge, 0.0, 0.0, 1.0);
  dJointSetHingeAxis(hinge, 0.0, 1.0, 0.0);
  auto gap = [&] {
    dVector3 a1, a2;
    dJointGetHingeAnchor(hinge, a1);
    dJointGetHingeAnchor2(hinge, a2);
    return distance(a1, a2);
  };
  double rigid = 0.0, soft = 0.0;
  for (int i = 0; i < 30; ++i) {
    dWorldBlockStep(s.world, 1.0 / 60.0);
    rigid = std::max(rigid, gap());
  }
  dWorldSetCFM(s.world, 1e-2);
  for (int i = 0; i < 30; ++i) {
    dWorldBlockStep(s.world, 1.0 / 60.0);
    soft = std::max(soft, gap());
  }
  EXPECT_LT(rigid, 1e-3);
  EXPECT_GT(soft, 10.0 * rigid + 1e-3);
}

}  // namespace
}  // namespace blockstep::test

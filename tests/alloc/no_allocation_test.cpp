// Nothing allocates on the heap inside World::step once a scene has been
// stepped once. Counted with a replaced global operator new, so this suite
// is its own binary.

#include "compare/native/scenes.h"
#include "support/allocation_counter.h"
#include "support/landing_load.h"
#include "support/test_world.h"
#include "support/two_islands.h"

namespace blockstep {
namespace {

// Heap allocations in 20 steps of a scene after 60 steps of warm-up
// (workspaces grow to the scene's high-water mark; with contacts, until
// the bodies have landed and the contact set settles).
long allocationsAfterWarmUp(const std::string& name, const SolverSettings& settings) {
  scenes::Scene scene;
  scenes::makeScene(name, scene);
  scene.world.setSettings(settings);
  for (int i = 0; i < 60; ++i)
    scene.world.step(scene.frameStep);
  const long before = test::allocationCount();
  for (int i = 0; i < 20; ++i)
    scene.world.step(scene.frameStep);
  return test::allocationCount() - before;
}

TEST(NoAllocation, StepAllocatesNothingAfterWarmUp) {
  for (const std::string& name : scenes::sceneNames()) {
    SCOPED_TRACE(name);
    SolverSettings projected = SolverSettings::subStepped(1);
    projected.positionProjections = 2;
    projected.islandBlockContacts = true;
    for (SolverSettings s : {SolverSettings::paper(10), SolverSettings::subStepped(4), projected}) {
      s.recordResiduals = true;
      EXPECT_EQ(allocationsAfterWarmUp(name, s), 0);
    }
  }
}

// The same with two threads sweeping islands and sharing out the bodies
// and blocks (TBB's tasks come from its own pools once warmed up).
TEST(NoAllocation, StepOnTwoThreadsAllocatesNothingAfterWarmUp) {
  for (const std::string& name : scenes::sceneNames()) {
    SCOPED_TRACE(name);
    SolverSettings s = SolverSettings::subStepped(4);
    s.threads = 2;
    s.positionProjections = 1;     // islands projected on the two threads too
    s.islandBlockContacts = true;  // and their contact normals coupled there
    EXPECT_EQ(allocationsAfterWarmUp(name, s), 0);
  }
}

// Islands that take different sub-step counts are stepped class by
// class, each with its own island-block selection: none of it allocates
// once warmed up, on one thread or two.
TEST(NoAllocation, IslandsSteppedInClassesAllocateNothingAfterWarmUp) {
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    World world;
    SolverSettings s = SolverSettings::subStepped(10);
    s.threads = threads;
    world.setSettings(s);
    test::circlingBox(world);
    test::slowPendulum(world);
    for (int i = 0; i < 60; ++i)
      world.step(1.0 / 60.0);
    const long before = test::allocationCount();
    for (int i = 0; i < 20; ++i) {
      world.step(1.0 / 60.0);
      EXPECT_EQ(world.lastStepStats().substeps, 25);  // the two classes: 10 and 25
    }
    EXPECT_EQ(test::allocationCount() - before, 0);
  }
}

// A light body's contacts solved as one group inside a larger island
// (SolverSettings::lightBodyGroups): two tonnes on a 1 kg plank across two
// supports, an island of 16 points over a limit of 12, regrouped every
// sub-step.
TEST(NoAllocation, LightBodyGroupsAllocateNothingAfterWarmUp) {
  World world;
  SolverSettings s = SolverSettings::subStepped(10);
  s.contactIslandRows = 12;
  world.setSettings(s);
  const BodyId plank = test::plankOnTwoSupports(world);
  test::addBoxBody(world, Vec3(0, 0, 0.75), 1000.0, Vec3(0.2, 0.2, 0.2));
  test::addBoxBody(world, Vec3(0, 0, 1.15), 1000.0, Vec3(0.2, 0.2, 0.2));
  for (int i = 0; i < 60; ++i)
    world.step(1.0 / 60.0);
  const long before = test::allocationCount();
  for (int i = 0; i < 20; ++i)
    world.step(1.0 / 60.0);
  EXPECT_EQ(test::allocationCount() - before, 0);
  EXPECT_NEAR(world.body(plank).position.z(), 0.525, 1e-4);  // the group held it
}

// Sinking groups (SolverSettings::sinkingDepth) are formed after the
// sweeps wherever a contact still sinks, so their storage grows to the
// largest seen: a landing seen once allocates nothing when it comes again.
// 12 kg lands on a light box in an island over the contact island limit,
// without impact groups, so the sinking groups do the holding.
TEST(NoAllocation, SinkingGroupsAllocateNothingWhenALandingComesAgain) {
  World world;
  SolverSettings s = SolverSettings::subStepped(10);
  s.contactIslandRows = 16;
  s.impactDepth = 0.0;
  test::collidingEverySubstepOnSprings(world, s);
  const test::LandingOnALightBox landing = test::landingOnALightBox(world);
  for (int i = 0; i < 30; ++i)
    world.step(1.0 / 60.0);
  test::placeLanding(world, landing);
  const long before = test::allocationCount();
  int sinkingGroups = 0;
  for (int i = 0; i < 30; ++i) {
    world.step(1.0 / 60.0);
    sinkingGroups += world.lastStepStats().sinkingGroups;
  }
  EXPECT_EQ(test::allocationCount() - before, 0);
  EXPECT_GT(sinkingGroups, 0) << "the landing again was held by sinking groups";
}

TEST(NoAllocation, TheCounterSeesAllocations) {
  // Guards the test above against a counter that never counts.
  const long before = test::allocationCount();
  std::vector<int> v;
  v.reserve(100);
  EXPECT_GE(v.capacity(), 100u);  // used, so the allocation stays
  EXPECT_GE(test::allocationCount() - before, 1);
}

}  // namespace
}  // namespace blockstep

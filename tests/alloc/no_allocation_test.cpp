// Nothing allocates on the heap inside World::step once a scene has been
// stepped once. Counted with a replaced global operator new, so this suite
// is its own binary.

#include "compare/native/scenes.h"
#include "support/allocation_counter.h"
#include "support/test_world.h"

namespace blockstep {
namespace {

TEST(NoAllocation, StepAllocatesNothingAfterWarmUp) {
  for (const std::string& name : scenes::sceneNames()) {
    for (const SolverSettings& settings :
         {SolverSettings::paper(10), SolverSettings::subStepped(4)}) {
      SCOPED_TRACE(name);
      scenes::Scene scene;
      scenes::makeScene(name, scene);
      SolverSettings s = settings;
      s.recordResiduals = true;
      scene.world.setSettings(s);
      // Warm-up: workspaces grow to the scene's high-water mark (with
      // contacts, until the bodies have landed and the contact set settles).
      for (int i = 0; i < 60; ++i)
        scene.world.step(scene.frameStep);
      const long before = test::allocationCount();
      for (int i = 0; i < 20; ++i)
        scene.world.step(scene.frameStep);
      EXPECT_EQ(test::allocationCount() - before, 0);
    }
  }
}

// The same with two threads sweeping islands and sharing out the bodies
// and blocks (TBB's tasks come from its own pools once warmed up).
TEST(NoAllocation, StepOnTwoThreadsAllocatesNothingAfterWarmUp) {
  for (const std::string& name : scenes::sceneNames()) {
    SCOPED_TRACE(name);
    scenes::Scene scene;
    scenes::makeScene(name, scene);
    SolverSettings s = SolverSettings::subStepped(4);
    s.threads = 2;
    scene.world.setSettings(s);
    for (int i = 0; i < 60; ++i)
      scene.world.step(scene.frameStep);
    const long before = test::allocationCount();
    for (int i = 0; i < 20; ++i)
      scene.world.step(scene.frameStep);
    EXPECT_EQ(test::allocationCount() - before, 0);
  }
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

// Nothing allocates on the heap inside World::step once a scene has been
// stepped once. Counted with a replaced global operator new, so this suite
// is its own binary.
#include <atomic>
#include <cstdlib>
#include <new>

#include "compare/native/scenes.h"
#include "support/test_world.h"

namespace {
std::atomic<long> allocations{0};
}

void* operator new(std::size_t n) {
  ++allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

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
      const long before = allocations.load();
      for (int i = 0; i < 20; ++i)
        scene.world.step(scene.frameStep);
      EXPECT_EQ(allocations.load() - before, 0);
    }
  }
}

TEST(NoAllocation, TheCounterSeesAllocations) {
  // Guards the test above against a counter that never counts.
  const long before = allocations.load();
  auto* v = new std::vector<int>(100);
  delete v;
  EXPECT_GE(allocations.load() - before, 2);
}

}  // namespace
}  // namespace blockstep

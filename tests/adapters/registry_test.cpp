// The registry of ODE objects (adapters/ode/registry.h) with threads: each
// world has its own lock, so a world being stepped on one thread does not
// hold back another thread's world, from its first body to its
// destruction.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <mutex>

#include "adapters/ode/registry.h"
#include "adapters/ode/world_bridge.h"
#include "support/ode_library.h"

namespace blockstep::ode {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new test::OdeLibrary);

// Another thread's whole world life, told to the registry as the plugin's
// hooks tell it: a body resting on a contact, one step, then destruction.
// Returns the body's height after the step.
double anotherWorldsLife(Registry& registry) {
  dAllocateODEDataForThread(dAllocateMaskAll);
  dWorldID world = dWorldCreate();
  dWorldSetGravity(world, 0, 0, -9.81);
  dBodyID body = dBodyCreate(world);
  registry.bodyCreated(world, body);
  dMass m;
  dMassSetBoxTotal(&m, 1.0, 0.2, 0.2, 0.2);
  dBodySetMass(body, &m);
  dBodySetPosition(body, 0, 0, 1);
  dJointGroupID group = dJointGroupCreate(0);
  dContact c{};
  c.surface.mu = 1.0;
  c.geom.pos[2] = 0.9;
  c.geom.normal[2] = 1.0;
  dJointID contact = dJointCreateContact(world, group, &c);
  registry.jointCreated(world, group, contact, &c);
  dJointAttach(contact, body, nullptr);
  double height = 0.0;
  {
    const std::shared_ptr<WorldRecord> record = registry.world(world);
    std::lock_guard lock(record->mutex);
    record->bridge = std::make_unique<WorldBridge>(world);
    EXPECT_EQ(record->bridge->step(*record, 1.0 / 60.0), StepOutcome::Stepped)
        << record->bridge->message();
    height = dBodyGetPosition(body)[2];
  }
  dJointGroupEmpty(group);
  registry.groupEmptied(group);
  dJointGroupDestroy(group);
  registry.groupDestroyed(group);
  dWorldDestroy(world);
  registry.worldDestroyed(world);
  dCleanupODEAllDataForThread();
  return height;
}

TEST(RegistryThreads, AWorldBeingSteppedDoesNotHoldBackAnotherThreadsWorld) {
  Registry& registry = Registry::instance();
  dWorldID stepped = dWorldCreate();
  const std::shared_ptr<WorldRecord> record = registry.ensureWorld(stepped);
  std::unique_lock holding(record->mutex);  // as a long step of this world does

  auto other = std::async(std::launch::async, [&] { return anotherWorldsLife(registry); });
  // Bounded only so that a regression fails instead of hanging the suite.
  const bool finished = other.wait_for(std::chrono::seconds(30)) == std::future_status::ready;
  holding.unlock();
  EXPECT_TRUE(finished) << "the other world waited behind this one's lock";
  // The contact held the body up: it stayed within a millimetre of 1 m.
  EXPECT_NEAR(other.get(), 1.0, 1e-3);

  dWorldDestroy(stepped);
  registry.worldDestroyed(stepped);
  EXPECT_EQ(registry.world(stepped), nullptr);
}

}  // namespace
}  // namespace blockstep::ode

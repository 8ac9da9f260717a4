// Several threads, each with worlds of its own, as ODE allows (dInitODE2
// and dAllocateODEDataForThread): making, configuring, stepping and
// destroying worlds at once must give each world what it gets alone. The
// suite runs these under ThreadSanitizer too (scripts/test.sh). And a
// program's moved callback may step another world from inside a step.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "ode_twin.h"

namespace blockstep::test {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new OdeLibrary);

constexpr double kStep = 1.0 / 60.0;

// A 0.2 m box resting on the ground at z = 0, held by four contacts at its
// corners made afresh each step (into the group the caller empties).
// Four contacts of a 0.2 m box with a floor at `floor` (m) under it.
void addGroundContacts(dWorldID world, dJointGroupID group, dBodyID box, double mu,
                       double floor = 0.0) {
  const dReal* p = dBodyGetPosition(box);
  const double depth = floor + 0.1 - p[2];
  if (depth < -1e-3) return;
  for (int k = 0; k < 4; ++k) {
    dContact c{};
    c.surface.mode = 0;
    c.surface.mu = mu;
    c.geom.pos[0] = p[0] + (k & 1 ? 0.1 : -0.1);
    c.geom.pos[1] = p[1] + (k & 2 ? 0.1 : -0.1);
    c.geom.normal[2] = 1.0;
    c.geom.depth = depth;
    dJointAttach(dJointCreateContact(world, group, &c), box, nullptr);
  }
}

// A three-link hinge chain hanging from the world, with a box lying on the
// ground under it held by a contact made afresh each step (a joint group
// created, emptied and destroyed as programs do).
struct ChainAndBox {
  OdeScene s;
  std::vector<dJointID> hinges;
  dBodyID box = nullptr;
  dJointGroupID contacts = dJointGroupCreate(0);

  ChainAndBox() {
    dBodyID parent = nullptr;
    for (int i = 0; i < 3; ++i) {
      dBodyID link = s.box(0.3 * (i + 1), 0.0, 2.0, 1.0, 0.1);
      dJointID h = s.add(dJointCreateHinge(s.world, 0), link, parent);
      dJointSetHingeAnchor(h, 0.3 * i, 0.0, 2.0);
      dJointSetHingeAxis(h, 0.0, 1.0, 0.0);
      hinges.push_back(h);
      parent = link;
    }
    box = s.box(0.0, 0.0, 0.1, 1.0, 0.2);
  }
  ~ChainAndBox() { dJointGroupDestroy(contacts); }

  void step() {
    dJointGroupEmpty(contacts);
    addGroundContacts(s.world, contacts, box, 1.0);
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1) << dWorldGetBlockStepMessage(s.world);
  }

  // Every body's position and velocity, in order.
  std::vector<double> state() const {
    std::vector<double> out;
    for (dBodyID b : s.bodies) {
      out.insert(out.end(), dBodyGetPosition(b), dBodyGetPosition(b) + 3);
      out.insert(out.end(), dBodyGetLinearVel(b), dBodyGetLinearVel(b) + 3);
    }
    return out;
  }
};

constexpr int kSteps = 40;

std::vector<double> runAlone() {
  ChainAndBox scene;
  dWorldSetBlockSubsteps(scene.s.world, 4);
  for (int k = 0; k < kSteps; ++k)
    scene.step();
  return scene.state();
}

// The crash of issue 14: setters on one thread while others create, step
// and destroy their worlds (the registry's map of worlds grew and moved
// under a setter). Each world must end exactly as it does alone.
TEST(PluginThreads, WorldsMadeSteppedAndDestroyedOnSeveralThreadsEachEndAsAlone) {
  const std::vector<double> alone = runAlone();
  // The chain swings and the box rests: a scene where a lost joint or
  // contact shows.
  ASSERT_GT(std::abs(alone[0] - 0.3), 0.01);
  ASSERT_NEAR(alone[3 * 6 + 2], 0.1, 2e-3);

  constexpr int kThreads = 4, kRounds = 6;
  std::atomic<int> differing{0}, rounds{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      dAllocateODEDataForThread(dAllocateMaskAll);
      for (int r = 0; r < kRounds; ++r) {
        if (t == 0) {
          // The setter thread: many short-lived worlds, set up and dropped.
          for (int k = 0; k < 50; ++k) {
            dWorldID w = dWorldCreate();
            dWorldSetBlockIterations(w, 1 + k % 5);
            dWorldSetBlockSubsteps(w, 1 + k % 3);
            EXPECT_EQ(dWorldGetBlockSubsteps(w), 1 + k % 3);
            dWorldDestroy(w);
          }
        }
        if (runAlone() != alone) ++differing;
        ++rounds;
      }
      dCleanupODEAllDataForThread();
    });
  }
  for (std::thread& t : threads)
    t.join();
  EXPECT_EQ(rounds.load(), kThreads * kRounds);
  EXPECT_EQ(differing.load(), 0);
}

// dBodySetMovedCallback: a callback of one world that steps another world.
// The nested step's callbacks used to overwrite the outer step's list (one
// list per thread): the outer world's later bodies lost their callbacks.
struct NestedLog {
  dWorldID inner = nullptr;
  std::vector<dBodyID> called;
};
NestedLog nestedLog;

void logMoved(dBodyID b) {
  nestedLog.called.push_back(b);
}

void stepInnerWorld(dBodyID b) {
  logMoved(b);
  ASSERT_EQ(dWorldBlockStep(nestedLog.inner, kStep), 1);
}

TEST(PluginThreads, MovedCallbackSteppingAnotherWorldKeepsEveryCallback) {
  OdeScene outer, inner;
  nestedLog = NestedLog{inner.world, {}};
  std::vector<dBodyID> outerBodies, innerBodies;
  for (int i = 0; i < 3; ++i) {
    outerBodies.push_back(outer.box(i, 0, 5));
    dBodySetMovedCallback(outerBodies.back(), i == 0 ? stepInnerWorld : logMoved);
  }
  for (int i = 0; i < 5; ++i) {
    innerBodies.push_back(inner.box(i, 1, 5));
    dBodySetMovedCallback(innerBodies.back(), logMoved);
  }
  for (int k = 0; k < 3; ++k) {
    nestedLog.called.clear();
    ASSERT_EQ(dWorldBlockStep(outer.world, kStep), 1);
    // Each body of both worlds once: 3 outer and 5 inner callbacks.
    for (dBodyID b : outerBodies)
      EXPECT_EQ(std::count(nestedLog.called.begin(), nestedLog.called.end(), b), 1) << "step " << k;
    for (dBodyID b : innerBodies)
      EXPECT_EQ(std::count(nestedLog.called.begin(), nestedLog.called.end(), b), 1) << "step " << k;
  }
  // Both worlds fell as free bodies do: 3 steps of the outer, 3 of the inner.
  const double fallen = 5.0 - dBodyGetPosition(innerBodies[4])[2];
  EXPECT_NEAR(fallen, 0.5 * 9.81 * (3 * kStep) * (3 * kStep), 0.02);
}

// Islands swept on several threads (dWorldSetBlockThreads): 200 hinge
// chains of three links (enough bodies and blocks for their loops to be
// shared out too), each set swinging at its own rate (island
// blocks, one per chain, projected at each step's end), and 20 boxes
// dropped onto the ground, held by
// contacts made each step. The islands share no movable body, so every
// thread count must give the same bits as one thread.
struct ManyIslands {
  OdeScene s;
  std::vector<dBodyID> boxes, tips;
  dJointGroupID contacts = dJointGroupCreate(0);

  explicit ManyIslands(int threads) {
    for (int c = 0; c < 200; ++c) {
      dBodyID parent = nullptr;
      for (int i = 0; i < 3; ++i) {
        dBodyID link = s.box(0.3 * (i + 1), 2.0 * c, 3.0, 1.0, 0.1);
        dBodySetLinearVel(link, 0.0, 0.0, -0.005 * c * (i + 1));
        dJointID h = s.add(dJointCreateHinge(s.world, 0), link, parent);
        dJointSetHingeAnchor(h, 0.3 * i, 2.0 * c, 3.0);
        dJointSetHingeAxis(h, 0.0, 1.0, 0.0);
        parent = link;
      }
      if (c % 2 == 1) tips.push_back(parent);
    }
    for (int k = 0; k < 20; ++k) {
      boxes.push_back(s.box(-3.0, 2.0 * k, 0.1 + 0.01 * k, 1.0, 0.2));
      dBodySetAngularVel(boxes.back(), 0.0, 0.0, 0.1 * k);
    }
    dWorldSetBlockSubsteps(s.world, 4);
    dWorldSetBlockProjections(s.world, 1);  // each chain's last pose projected on its thread
    // Every other chain swings onto a floor 0.5 m below its pin: its
    // tip's normals are solved in the chain's null space on its thread.
    dWorldSetBlockIslandContacts(s.world, 1);
    dWorldSetBlockThreads(s.world, threads);
  }
  ~ManyIslands() { dJointGroupDestroy(contacts); }

  void step() {
    dJointGroupEmpty(contacts);
    for (dBodyID box : boxes)
      addGroundContacts(s.world, contacts, box, 0.5);
    for (dBodyID tip : tips)
      addGroundContacts(s.world, contacts, tip, 0.5, 2.5);
    ASSERT_EQ(dWorldBlockStep(s.world, kStep), 1) << dWorldGetBlockStepMessage(s.world);
  }

  std::vector<double> state() const {
    std::vector<double> out;
    for (dBodyID b : s.bodies) {
      for (const dReal* v : {dBodyGetPosition(b), dBodyGetLinearVel(b), dBodyGetAngularVel(b)})
        out.insert(out.end(), v, v + 3);
      out.insert(out.end(), dBodyGetQuaternion(b), dBodyGetQuaternion(b) + 4);
    }
    return out;
  }
};

std::vector<double> runIslands(int threads) {
  ManyIslands scene(threads);
  EXPECT_EQ(dWorldGetBlockThreads(scene.s.world), threads);
  for (int k = 0; k < 60; ++k)
    scene.step();
  return scene.state();
}

TEST(PluginThreads, IslandsSweptOnSeveralThreadsGiveTheBitsOfOne) {
  const std::vector<double> one = runIslands(1);
  // A scene that moved: the first chain, released horizontally with its
  // end link at x = +0.9, has swung through to the other side after its
  // second, and every box rests on its contacts (centre at 0.1 m).
  // 13 numbers a body; the 600 links come first, chain by chain, then
  // the boxes.
  EXPECT_LT(one[13 * 2], -0.5);
  for (int k = 0; k < 20; ++k)
    EXPECT_NEAR(one[13 * (600 + k) + 2], 0.1, 2e-3) << "box " << k;
  for (int threads : {2, 3, 0}) {
    const std::vector<double> many = runIslands(threads);
    ASSERT_EQ(many.size(), one.size());
    EXPECT_EQ(std::memcmp(many.data(), one.data(), one.size() * sizeof(double)), 0)
        << threads << " threads";
  }
}

TEST(PluginThreads, AThreadCountOutOfRangeIsRefused) {
  OdeScene s;
  testing::internal::CaptureStderr();
  dWorldSetBlockThreads(s.world, -1);
  dWorldSetBlockThreads(s.world, 100000);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_EQ(dWorldGetBlockThreads(s.world), 1);
  EXPECT_NE(said.find("dWorldSetBlockThreads(-1)"), std::string::npos) << said;
  EXPECT_NE(said.find("dWorldSetBlockThreads(100000)"), std::string::npos) << said;
}

}  // namespace
}  // namespace blockstep::test

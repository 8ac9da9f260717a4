// Google Benchmark of ODE worlds stepped three ways in one run: ODE's
// dWorldQuickStep (20 iterations), and blockstep through the plugin
// (dWorldBlockStep, following those 20 iterations: 10 sub-steps). The
// scenes are built with ODE's API; each benchmark reports the worst joint
// gap or the top box's drift it saw (counters), so speed is never read
// off a wrong answer. The ratio blockstep / quickstep is the plugin's cost
// including the adapter's reading and writing of the ODE world.
#include <benchmark/benchmark.h>
#include <ode/ode.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "blockstep/blockstep_ode.h"

namespace {

constexpr double kStep = 1.0 / 60.0;

struct Scene {
  dWorldID world = dWorldCreate();
  dSpaceID space = dHashSpaceCreate(0);
  dJointGroupID contacts = dJointGroupCreate(0);
  std::vector<dBodyID> bodies;
  std::vector<dJointID> joints;
  Scene() {
    dWorldSetGravity(world, 0, 0, -9.81);
    dWorldSetQuickStepNumIterations(world, 20);
    dCreatePlane(space, 0, 0, 1, 0);
  }
  ~Scene() {
    dJointGroupDestroy(contacts);
    dSpaceDestroy(space);
    dWorldDestroy(world);
  }
  dBodyID box(double x, double z, double mass, double side) {
    dBodyID b = dBodyCreate(world);
    dMass m;
    dMassSetBoxTotal(&m, mass, side, side, side);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, 0.0, z);
    bodies.push_back(b);
    return b;
  }
};

Scene* current = nullptr;

void nearCallback(void*, dGeomID a, dGeomID b) {
  dContact contact[4];
  const int n = dCollide(a, b, 4, &contact[0].geom, sizeof(dContact));
  for (int i = 0; i < n; ++i) {
    contact[i].surface.mode = dContactApprox1;
    contact[i].surface.mu = 0.6;
    dJointAttach(dJointCreateContact(current->world, current->contacts, &contact[i]),
                 dGeomGetBody(a), dGeomGetBody(b));
  }
}

// 20 hinge links of 0.1 kg with a 10 kg end, swinging from horizontal.
void buildChain(Scene& s) {
  dBodyID prev = nullptr;
  for (int i = 0; i < 20; ++i) {
    dBodyID link = s.box(0.1 * (i + 1), 5.0, i == 19 ? 10.0 : 0.1, 0.05);
    dJointID j = dJointCreateHinge(s.world, 0);
    dJointAttach(j, link, prev);
    dJointSetHingeAnchor(j, 0.1 * i, 0.0, 5.0);
    dJointSetHingeAxis(j, 0, 1, 0);
    s.joints.push_back(j);
    prev = link;
  }
}

// 10 half-metre boxes stacked on the ground.
void buildStack(Scene& s) {
  for (int i = 0; i < 10; ++i) {
    dGeomSetBody(dCreateBox(s.space, 0.5, 0.5, 0.5), s.box(0.0, 0.25 + 0.5 * i, 1.0, 0.5));
  }
}

double chainGap(const Scene& s) {
  double gap = 0.0;
  for (dJointID j : s.joints) {
    dVector3 a1, a2;
    dJointGetHingeAnchor(j, a1);
    dJointGetHingeAnchor2(j, a2);
    gap = std::max(gap,
                   std::sqrt((a1[0] - a2[0]) * (a1[0] - a2[0]) + (a1[1] - a2[1]) * (a1[1] - a2[1]) +
                             (a1[2] - a2[2]) * (a1[2] - a2[2])));
  }
  return gap;
}

template <bool kBlock, bool kStack>
void BM_Ode(benchmark::State& state) {
  dInitODE2(0);
  dBlockStepSetReplace("none");
  auto scene = std::make_unique<Scene>();
  current = scene.get();
  kStack ? buildStack(*scene) : buildChain(*scene);
  double worst = 0.0;
  int frame = 0;
  for (auto _ : state) {
    if (frame == 300) {  // start the scene over, outside the timing
      state.PauseTiming();
      scene = std::make_unique<Scene>();
      current = scene.get();
      kStack ? buildStack(*scene) : buildChain(*scene);
      frame = 0;
      state.ResumeTiming();
    }
    if (kStack) dSpaceCollide(scene->space, nullptr, &nearCallback);
    if (kBlock) {
      dWorldBlockStep(scene->world, kStep);
    } else {
      dWorldQuickStep(scene->world, kStep);
    }
    if (kStack) dJointGroupEmpty(scene->contacts);
    ++frame;
    state.PauseTiming();
    if (kStack) {
      const dReal* p = dBodyGetPosition(scene->bodies.back());
      worst = std::max(worst, std::hypot(p[0], p[1]));
    } else {
      worst = std::max(worst, chainGap(*scene));
    }
    state.ResumeTiming();
  }
  state.counters[kStack ? "top_drift_mm" : "max_gap_mm"] = worst * 1e3;
  scene.reset();
  dCloseODE();
}

// A world's teardown: an n x n sheet of boxes on ball joints, stepped once
// (so the plugin has mapped it), then its bodies destroyed one by one and
// the world. Only the destroying is timed; time per body should not grow
// with n (it grew as n^2 while each body's joints were looked up among
// all of the world's: 128 x 128 took 5 s).
template <bool kBlock>
void BM_Teardown(benchmark::State& state) {
  dInitODE2(0);
  dBlockStepSetReplace("none");
  const int n = static_cast<int>(state.range(0));
  for (auto _ : state) {
    state.PauseTiming();
    auto scene = std::make_unique<Scene>();
    std::vector<dBodyID> grid(n * n);
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j)
        grid[i * n + j] = scene->box(0.05 * i, 1.0 + 0.05 * j, 0.01, 0.04);
    }
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        for (int k = 0; k < 2; ++k) {
          if ((k == 0 ? i : j) + 1 == n) continue;
          dJointID joint = dJointCreateBall(scene->world, 0);
          dJointAttach(joint, grid[i * n + j], grid[k == 0 ? (i + 1) * n + j : i * n + j + 1]);
          dJointSetBallAnchor(joint, 0.05 * i + (k == 0 ? 0.025 : 0.0), 0.0,
                              1.0 + 0.05 * j + (k == 1 ? 0.025 : 0.0));
        }
      }
    }
    kBlock ? dWorldBlockStep(scene->world, kStep) : dWorldQuickStep(scene->world, kStep);
    state.ResumeTiming();
    for (dBodyID b : grid)
      dBodyDestroy(b);
    scene.reset();
  }
  state.counters["per_body"] =
      benchmark::Counter(static_cast<double>(n) * n, benchmark::Counter::kIsIterationInvariantRate |
                                                         benchmark::Counter::kInvert);
  dCloseODE();
}

// What a contact joint costs through the plugin: an ODE program makes
// and drops every contact of every step (dJointCreateContact,
// dJointAttach, dJointGroupEmpty), and the plugin's registry records each
// one (its dContact, for the step's read). 64 contacts between a box and
// the ground per iteration, the time given per contact; ODE's own
// allocation in its joint group is inside the figure.
void BM_ContactJoints(benchmark::State& state) {
  dInitODE2(0);
  dBlockStepSetReplace("none");
  auto scene = std::make_unique<Scene>();
  dBodyID box = scene->box(0.0, 0.25, 1.0, 0.5);
  dContact contact{};
  contact.surface.mode = dContactApprox1;
  contact.surface.mu = 0.6;
  contact.geom.normal[2] = 1.0;
  constexpr int kContacts = 64;
  for (auto _ : state) {
    for (int i = 0; i < kContacts; ++i) {
      contact.geom.pos[0] = 0.01 * i;
      dJointAttach(dJointCreateContact(scene->world, scene->contacts, &contact), box, nullptr);
    }
    dJointGroupEmpty(scene->contacts);
  }
  state.counters["per_contact"] = benchmark::Counter(
      kContacts, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  scene.reset();
  dCloseODE();
}
BENCHMARK(BM_ContactJoints)->Name("contact_joints/blockstep")->Unit(benchmark::kMicrosecond);

BENCHMARK(BM_Teardown<false>)
    ->Name("teardown/ode")
    ->Arg(32)
    ->Arg(128)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Teardown<true>)
    ->Name("teardown/blockstep")
    ->Arg(32)
    ->Arg(128)
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_Ode<false, false>)->Name("chain20_100to1/quickstep20")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Ode<true, false>)->Name("chain20_100to1/blockstep")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Ode<false, true>)->Name("stack10/quickstep20")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Ode<true, true>)->Name("stack10/blockstep")->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();

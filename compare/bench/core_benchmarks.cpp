// Google Benchmark over the native scenes: time per frame for the paper's
// solver and the sub-stepped solver. Each benchmark reports the worst
// joint separation it saw (counters), so speed is never read off a wrong
// answer. Compare with ODE's figures in ../shared/SCENES.md.
#include <benchmark/benchmark.h>

#include <algorithm>

#include "compare/native/scenes.h"
#include "core/solver/island_block.h"
#include "tests/support/ball_joint_rows.h"

namespace {

using namespace blockstep;

void runScene(benchmark::State& state, const char* name, SolverSettings settings) {
  scenes::Scene scene;
  scenes::makeScene(name, scene);
  scene.world.setSettings(settings);
  double worstSep = 0.0, worstAng = 0.0, worstDrift = 0.0;
  int frame = 0;
  for (auto _ : state) {
    if (frame == scene.frames) {  // start the scene over, outside the timing
      state.PauseTiming();
      scene = scenes::Scene{};
      scenes::makeScene(name, scene);
      scene.world.setSettings(settings);
      frame = 0;
      state.ResumeTiming();
    }
    scene.world.step(scene.frameStep);
    ++frame;
    state.PauseTiming();
    const scenes::Quality q = scenes::measure(scene);
    worstSep = std::max(worstSep, q.maxSeparation);
    worstAng = std::max(worstAng, q.maxAngle);
    worstDrift = std::max(worstDrift, q.drift);
    state.ResumeTiming();
  }
  state.counters["max_sep_mm"] = 1e3 * worstSep;
  state.counters["max_ang_deg"] = worstAng * 180.0 / kPi;
  state.counters["drift_mm"] = 1e3 * worstDrift;
}

#define SCENE_BENCH(scene)                                                               \
  BENCHMARK_CAPTURE(runScene, scene##_paper10, #scene, SolverSettings::paper(10))        \
      ->Unit(benchmark::kMillisecond);                                                   \
  BENCHMARK_CAPTURE(runScene, scene##_paper20, #scene, SolverSettings::paper(20))        \
      ->Unit(benchmark::kMillisecond);                                                   \
  BENCHMARK_CAPTURE(runScene, scene##_substep10, #scene, SolverSettings::subStepped(10)) \
      ->Unit(benchmark::kMillisecond);                                                   \
  BENCHMARK_CAPTURE(runScene, scene##_substep20, #scene, SolverSettings::subStepped(20)) \
      ->Unit(benchmark::kMillisecond);

// The island block's kernels alone: K of a chain of `joints` ball joints
// (3 rows each, hanging from the static body) formed and factored within
// its profile, and one solve with it (a sweep's), per (sub-)step. A star
// (every joint on one hub body) is the dense case: its profile is the
// whole lower triangle.
struct IslandKernel {
  std::vector<SolverBody> bodies;
  std::vector<ConstraintBlock> blocks;
  std::vector<ConstraintRow> rows;
  std::int32_t staticBody = 0;
  IslandBlocks islands;

  IslandKernel(int joints, bool star) {
    staticBody = joints + (star ? 1 : 0);
    bodies.resize(staticBody + 1);
    for (int i = 0; i < staticBody; ++i) {
      bodies[i].invMass = 1.0 / (0.1 + 0.05 * i);
      bodies[i].invI = Vec3(50.0, 40.0 + i, 30.0).asDiagonal();
      bodies[i].v = Vec3(0.1 * i, -0.05, 0.02);
    }
    for (int k = 0; k < joints; ++k) {
      test::addBallJointRows(bodies, staticBody, k, star ? joints : (k == 0 ? staticBody : k - 1),
                             k, Vec3(0.01 * k, 0.0, -0.05), Vec3(0.0, 0.0, 0.05), 1e-4, blocks,
                             rows);
    }
    islands.select(blocks, staticBody, {0, joints}, 1, 3 * joints);
  }
};

void islandFactor(benchmark::State& state, bool star) {
  IslandKernel k(static_cast<int>(state.range(0)), star);
  for (auto _ : state) {
    k.islands.factorAll(k.blocks, k.rows, k.bodies);
    benchmark::DoNotOptimize(k.rows.data());
  }
  state.counters["rows"] = static_cast<double>(k.rows.size());
  state.counters["factor_entries"] = static_cast<double>(k.islands.factorEntries());
}

void islandSolve(benchmark::State& state, bool star) {
  IslandKernel k(static_cast<int>(state.range(0)), star);
  k.islands.factorAll(k.blocks, k.rows, k.bodies);
  for (auto _ : state) {
    k.islands.solve(0, true, k.blocks, k.rows, k.bodies);
    benchmark::DoNotOptimize(k.bodies.data());
  }
  state.counters["rows"] = static_cast<double>(k.rows.size());
}

BENCHMARK_CAPTURE(islandFactor, chain, false)->Arg(6)->Arg(16)->Arg(50);
BENCHMARK_CAPTURE(islandSolve, chain, false)->Arg(6)->Arg(16)->Arg(50);
BENCHMARK_CAPTURE(islandFactor, star, true)->Arg(6)->Arg(16);
BENCHMARK_CAPTURE(islandSolve, star, true)->Arg(6)->Arg(16);

SCENE_BENCH(ragdoll)
SCENE_BENCH(chain)
SCENE_BENCH(chain_swing)
SCENE_BENCH(cloth32)
SCENE_BENCH(softcube)
SCENE_BENCH(stack)
SCENE_BENCH(pyramid)

}  // namespace

BENCHMARK_MAIN();

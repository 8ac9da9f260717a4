// Google Benchmark over the native scenes: time per frame for the paper's
// solver and the sub-stepped solver. Each benchmark reports the worst
// joint separation it saw (counters), so speed is never read off a wrong
// answer. Compare with ODE's figures in ../shared/SCENES.md.
#include <benchmark/benchmark.h>

#include <algorithm>

#include "compare/native/scenes.h"

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

SCENE_BENCH(ragdoll)
SCENE_BENCH(chain)
SCENE_BENCH(chain_swing)
SCENE_BENCH(cloth32)
SCENE_BENCH(softcube)
SCENE_BENCH(stack)
SCENE_BENCH(pyramid)

}  // namespace

BENCHMARK_MAIN();

// blockstep_demo: steps the native scenes of ../shared/SCENES.md under the
// paper's solver and the sub-stepped solver and prints one table: solve
// time per frame and the worst joint error over the run.
//
//   blockstep_demo [--frames N] [--scene NAME]...
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "compare/native/scenes.h"

namespace {

struct Mode {
  const char* name;
  blockstep::SolverSettings settings;
};

int usage(const char* message) {
  std::fprintf(stderr, "blockstep_demo: %s\nusage: blockstep_demo [--frames N] [--scene NAME]...\n",
               message);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace blockstep;
  int frames = -1;
  std::vector<std::string> names;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--frames" && i + 1 < argc) {
      char* end = nullptr;
      const long n = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || n < 1 || n > 1000000)
        return usage("--frames takes a whole number 1..1000000");
      frames = static_cast<int>(n);
    } else if (arg == "--scene" && i + 1 < argc) {
      names.push_back(argv[++i]);
    } else {
      return usage(("unknown argument '" + arg + "'").c_str());
    }
  }
  if (names.empty()) names = scenes::sceneNames();

  const std::vector<Mode> modes = {
      {"paper 10 it", SolverSettings::paper(10)},
      {"paper 20 it", SolverSettings::paper(20)},
      {"substep 10", SolverSettings::subStepped(10)},
      {"substep 20", SolverSettings::subStepped(20)},
  };

  std::printf("%-14s %-12s %8s %10s %14s %12s %11s %10s\n", "scene", "solver", "frames", "ms/frame",
              "max sep (mm)", "max ang (deg)", "drift (mm)", "pen (mm)");
  for (const std::string& name : names) {
    for (const Mode& mode : modes) {
      scenes::Scene scene;
      try {
        scenes::makeScene(name, scene);
      } catch (const Error& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
      }
      scene.world.setSettings(mode.settings);
      const int n = frames > 0 ? frames : scene.frames;
      double worstSep = 0.0, worstAng = 0.0, worstDrift = 0.0, worstPen = 0.0;
      double solveSeconds = 0.0;
      bool failed = false;
      for (int f = 0; f < n && !failed; ++f) {
        try {
          scene.world.step(scene.frameStep);
        } catch (const Error& e) {
          std::fprintf(stderr, "%s / %s: %s\n", name.c_str(), mode.name, e.what());
          failed = true;
        }
        solveSeconds += scene.world.lastStepStats().solveSeconds;
        const scenes::Quality q = scenes::measure(scene);
        worstSep = std::max(worstSep, q.maxSeparation);
        worstAng = std::max(worstAng, q.maxAngle);
        worstDrift = std::max(worstDrift, q.drift);
        worstPen = std::max(worstPen, q.penetration);
      }
      std::printf("%-14s %-12s %8d %10.3f %14.2f %12.2f %11.2f %10.2f%s\n", name.c_str(), mode.name,
                  n, 1e3 * solveSeconds / n, 1e3 * worstSep, worstAng * 180.0 / kPi,
                  1e3 * worstDrift, 1e3 * worstPen, failed ? "  FAILED" : "");
    }
  }
  return 0;
}

// blockstep-compare: the same ODE scenes stepped by ODE's quickstep (any
// iterations x sub-steps), ODE's dWorldStep and blockstep, one table, with
// ratios against quickstep 20, and CSV / JSON files for each run.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <stdexcept>

#include "blockstep/blockstep_ode.h"
#include "compare/ode/ab_file.h"
#include "compare/ode/convergence.h"
#include "compare/ode/runner.h"
#include "compare/ode/scene_file.h"

namespace {

using namespace blockstep::compare;

void writeCsv(const std::filesystem::path& path, const RunResult& r) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path.string());
  out << "frame,collide_ms,solve_ms,max_separation_m,rms_separation_m,max_angle_rad,"
         "penetration_m,contacts,kinetic_energy_j,potential_energy_j,handed_to_ode,"
         "held_penetration_m,found_penetration_m\n";
  for (std::size_t f = 0; f < r.frames.size(); ++f) {
    const FrameRecord& rec = r.frames[f];
    const double rms =
        rec.joints.joints > 0 ? std::sqrt(rec.joints.separationSumSq / rec.joints.joints) : 0.0;
    out << f << ',' << rec.collideSeconds * 1e3 << ',' << rec.solveSeconds * 1e3 << ','
        << rec.joints.separation << ',' << rms << ',' << rec.joints.angle << ',' << rec.penetration
        << ',' << rec.contacts << ',' << rec.kineticEnergy << ',' << rec.potentialEnergy << ','
        << rec.handedToOde << ',' << rec.heldPenetration << ',' << rec.foundPenetration << '\n';
  }
}

// The process's peak resident size (VmHWM), kB; 0 where /proc has none.
// Not getrusage's ru_maxrss: Linux counts in it the image of the process
// that forked this one before exec (a Python script's 12 to 100 MB).
long peakResidentKb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atol(line.c_str() + 6);
  }
  return 0;
}

nlohmann::json summary(const RunResult& r, double quickSolveMs) {
  nlohmann::json j;
  j["scene"] = r.scene;
  j["stepper"] = r.stepper;
  j["frames"] = r.framesRun;
  j["frames_asked"] = r.framesAsked;
  j["median_solve_ms"] = r.medianSolveMs;
  j["median_collide_ms"] = r.medianCollideMs;
  j["solve_ratio_to_quickstep20"] = quickSolveMs > 0.0 ? r.medianSolveMs / quickSolveMs : 0.0;
  j["max_separation_m"] = r.maxSeparation;
  j["rms_separation_m"] = r.rmsSeparation;
  j["max_angle_rad"] = r.maxAngle;
  j["max_penetration_m"] = r.maxPenetration;
  j["max_held_penetration_m"] = r.maxHeldPenetration;
  // blockstep's own collision only: the deepest it found within a frame.
  j["max_found_penetration_m"] = r.maxFoundPenetration;
  j["last_second_penetration_m"] = r.lastSecondPenetration;
  j["drift_m"] = r.drift;
  j["max_energy_gain_j"] = r.maxEnergyGain;
  j["max_energy_rise_j"] = r.maxEnergyRise;
  j["exploded"] = r.exploded;
  j["stopped_because"] = r.stoppedBecause;
  j["ode_messages"] = r.odeMessages;
  j["runaway_frames"] = r.runawayFrames;
  j["ode_stepped_frames"] = r.odeSteppedFrames;
  return j;
}

// Every setting of the error-versus-cost study: quickstep's iterations x
// sub-steps grid (the real rival at equal time) and blockstep's sub-steps,
// colliding once a frame (ODE's collider; projected past the preset's
// 1 mm), projected every step (projectionTolerance 0) and colliding every
// sub-step (its own).
std::vector<std::string> costGrid() {
  std::vector<std::string> grid;
  for (int it : {10, 20, 50})
    for (int sub : {1, 2, 4, 10})
      grid.push_back("quickstep:" + std::to_string(it) +
                     (sub > 1 ? "x" + std::to_string(sub) : ""));
  for (int n : {1, 2, 5, 10, 20, 40})
    grid.push_back("blockstep:substep:" + std::to_string(n));
  // With the step's last pose projected onto its rigid joints every step.
  for (int n : {1, 2, 5, 10})
    grid.push_back("blockstep:substep:" + std::to_string(n) + ",project=1,project_tol=0");
  // Colliding by itself every sub-step, as quickstep's sub-steps collide.
  for (int n : {1, 2, 5, 10})
    grid.push_back("blockstep:substep:" + std::to_string(n) + ",collision=substep");
  return grid;
}

// How many quickstep settings blockstep beats, at no more solve time and
// at no more solve and collision time (standing() says how).
void reportBeaten(const std::vector<RunResult>& results, const std::vector<Stepper>& steppers,
                  SceneError measure) {
  const Standing bySolve = standing(results, steppers, measure, false);
  const Standing byFrame = standing(results, steppers, measure, true);
  if (bySolve.quick > 0)
    std::printf(
        "%-12s %d of %d quickstep settings beaten by blockstep at no more solve time, %d at no "
        "more solve and collision time (lower %s, no deeper settled contact)\n",
        results.front().scene.c_str(), bySolve.beaten, bySolve.quick, byFrame.beaten,
        describe(measure));
}

// A built-in scene by name, or "file:PATH" read from a scene file.
std::unique_ptr<Scene> buildScene(const std::string& spec, int size) {
  if (spec.rfind("file:", 0) == 0) return loadSceneFile(spec.substr(5));
  return makeScene(spec, size);
}

std::string note(const RunResult& r) {
  std::string n = r.exploded ? "EXPLODED " : "";
  if (!r.stoppedBecause.empty() && !r.exploded) n += r.stoppedBecause + " ";
  if (r.runawayFrames > 0)
    n += "runaway guard fired in " + std::to_string(r.runawayFrames) + " frames ";
  if (r.odeSteppedFrames > 0)
    n += "ODE stepped " + std::to_string(r.odeSteppedFrames) + " frames (unsupported) ";
  if (r.odeMessages > 0) n += std::to_string(r.odeMessages) + " ODE messages";
  return n;
}

}  // namespace

// Where a run's files go: <prefix><scene>_<stepper><extension>, the
// stepper's colons made underscores.
std::filesystem::path runPath(const std::string& out, const std::string& scene,
                              const std::string& stepper, const char* prefix,
                              const char* extension) {
  std::string file = prefix + scene + "_" + stepper + extension;
  for (char& c : file)
    if (c == ':') c = '_';
  return std::filesystem::path(out) / file;
}

// The recorded poses for the report's replay: float32 values as
// RunResult::poses holds them (the scene's JSON gives the bodies).
void writePoses(const std::filesystem::path& path, const RunResult& r) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write " + path.string());
  out.write(reinterpret_cast<const char*>(r.poses.data()),
            static_cast<std::streamsize>(r.poses.size() * sizeof(float)));
}

// A run's results without its per-frame records, as a --jobs child hands
// them back.
nlohmann::json resultToJson(const RunResult& r) {
  return {{"scene", r.scene},
          {"stepper", r.stepper},
          {"frames_asked", r.framesAsked},
          {"frames_run", r.framesRun},
          {"exploded", r.exploded},
          {"runaway_frames", r.runawayFrames},
          {"ode_stepped_frames", r.odeSteppedFrames},
          {"stopped_because", r.stoppedBecause},
          {"ode_messages", r.odeMessages},
          {"median_solve_ms", r.medianSolveMs},
          {"median_collide_ms", r.medianCollideMs},
          {"max_separation", r.maxSeparation},
          {"rms_separation", r.rmsSeparation},
          {"max_angle", r.maxAngle},
          {"max_penetration", r.maxPenetration},
          {"max_held_penetration", r.maxHeldPenetration},
          {"max_found_penetration", r.maxFoundPenetration},
          {"last_second_penetration", r.lastSecondPenetration},
          {"drift", r.drift},
          {"start_energy", r.startEnergy},
          {"max_energy_gain", r.maxEnergyGain},
          {"max_energy_rise", r.maxEnergyRise}};
}

RunResult resultFromJson(const nlohmann::json& j) {
  RunResult r;
  r.scene = j.at("scene");
  r.stepper = j.at("stepper");
  r.framesAsked = j.at("frames_asked");
  r.framesRun = j.at("frames_run");
  r.exploded = j.at("exploded");
  r.runawayFrames = j.at("runaway_frames");
  r.odeSteppedFrames = j.at("ode_stepped_frames");
  r.stoppedBecause = j.at("stopped_because");
  r.odeMessages = j.at("ode_messages");
  r.medianSolveMs = j.at("median_solve_ms");
  r.medianCollideMs = j.at("median_collide_ms");
  r.maxSeparation = j.at("max_separation");
  r.rmsSeparation = j.at("rms_separation");
  r.maxAngle = j.at("max_angle");
  r.maxPenetration = j.at("max_penetration");
  r.maxHeldPenetration = j.value("max_held_penetration", 0.0);  // files from before it
  r.maxFoundPenetration = j.value("max_found_penetration", 0.0);
  r.lastSecondPenetration = j.at("last_second_penetration");
  r.drift = j.at("drift");
  r.startEnergy = j.at("start_energy");
  r.maxEnergyGain = j.at("max_energy_gain");
  r.maxEnergyRise = j.at("max_energy_rise");
  return r;
}

// Least, median and most of one measure over a job's runs (--seeds).
std::array<double, 3> spreadOf(const std::vector<RunResult>& runs, double RunResult::*measure) {
  std::vector<double> v;
  for (const RunResult& r : runs)
    v.push_back(r.*measure);
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  const double median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  return {v.front(), median, v.back()};
}

// The measures whose one run is one draw of a chaotic outcome.
constexpr std::pair<const char*, double RunResult::*> kSpreadMeasures[] = {
    {"max_separation_m", &RunResult::maxSeparation},
    {"max_penetration_m", &RunResult::maxPenetration},
    {"max_held_penetration_m", &RunResult::maxHeldPenetration},
    {"last_second_penetration_m", &RunResult::lastSecondPenetration},
    {"max_energy_rise_j", &RunResult::maxEnergyRise},
};

nlohmann::json spreadJson(const std::vector<RunResult>& runs) {
  nlohmann::json j;
  for (const auto& [name, measure] : kSpreadMeasures) {
    const auto s = spreadOf(runs, measure);
    j[name] = {s[0], s[1], s[2]};
  }
  return j;
}

// A row of the spread table: lengths in mm, the energy in J.
std::string spreadLine(const std::vector<RunResult>& runs, int labelWidth) {
  char buffer[512];
  std::string line;
  std::snprintf(buffer, sizeof buffer, "%-12s %-*s", runs.front().scene.c_str(), labelWidth,
                runs.front().stepper.c_str());
  line = buffer;
  for (const auto& [name, measure] : kSpreadMeasures) {
    const double unit = measure == &RunResult::maxEnergyRise ? 1.0 : 1e3;
    const auto s = spreadOf(runs, measure);
    std::snprintf(buffer, sizeof buffer, "%.4g [%.4g, %.4g]", unit * s[1], unit * s[0],
                  unit * s[2]);
    char cell[64];
    std::snprintf(cell, sizeof cell, " %26s", buffer);
    line += cell;
  }
  return line;
}

// One run of the comparison: a scene and a stepper.
struct Job {
  std::string scene;
  Stepper stepper;
  int seed = 0;  // RunOptions::perturbSeed
};

// One run on a freshly built scene, its CSV written when asked for (the
// scene as built only: perturbed runs add to the spread of the figures).
RunResult runOne(const Job& job, int size, const RunOptions& given, const std::string& out) {
  auto scene = buildScene(job.scene, size);
  RunOptions options = given;
  options.perturbSeed = job.seed;
  RunResult r = run(*scene, job.stepper, options);
  if (!out.empty() && job.seed == 0) {
    writeCsv(runPath(out, r.scene, r.stepper, "", ".csv"), r);
    if (!r.poses.empty()) writePoses(runPath(out, r.scene, r.stepper, "poses_", ".bin"), r);
  }
  return r;
}

// Every run, `jobs` at a time, each in a process of its own (a fork of
// this one, so it starts from the same ODE set-up): it steps its run,
// writes its CSV and hands its results back as JSON in a file of a
// temporary folder. A run whose process dies says so; the others go on.
// The results come back in the order the runs were asked for.
std::vector<RunResult> runInProcesses(const std::vector<Job>& all, int jobs, int size,
                                      const RunOptions& options, const std::string& out) {
  std::string dir = (std::filesystem::temp_directory_path() / "blockstep-compare-XXXXXX").string();
  if (!mkdtemp(dir.data())) throw std::runtime_error("cannot make a temporary folder");
  std::vector<RunResult> results(all.size());
  std::map<pid_t, std::size_t> running;
  auto resultFile = [&dir](std::size_t k) {
    return std::filesystem::path(dir) / (std::to_string(k) + ".json");
  };
  auto collect = [&] {
    int status = 0;
    const pid_t pid = wait(&status);
    if (pid < 0) throw std::runtime_error("lost a run's process");
    const std::size_t k = running.at(pid);
    running.erase(pid);
    std::ifstream in(resultFile(k));
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && in) {
      results[k] = resultFromJson(nlohmann::json::parse(in));
      return;
    }
    RunResult& r = results[k];
    r.scene = all[k].scene;
    r.stepper = all[k].stepper.label;
    r.framesAsked = options.frames;
    r.stoppedBecause =
        WIFSIGNALED(status)
            ? "its process died (signal " + std::to_string(WTERMSIG(status)) + ")"
            : "its process failed (exit " + std::to_string(WEXITSTATUS(status)) + ")";
  };
  for (std::size_t next = 0; next < all.size() || !running.empty();) {
    if (next < all.size() && static_cast<int>(running.size()) < jobs) {
      std::fflush(nullptr);  // nothing buffered is written twice
      const pid_t pid = fork();
      if (pid < 0) throw std::runtime_error("cannot start a run's process");
      if (pid == 0) {
        int code = 0;
        try {
          std::ofstream(resultFile(next)) << resultToJson(runOne(all[next], size, options, out));
        } catch (const std::exception& e) {
          std::fprintf(stderr, "blockstep-compare: %s %s: %s\n", all[next].scene.c_str(),
                       all[next].stepper.label.c_str(), e.what());
          code = 3;
        }
        std::fflush(nullptr);
        _exit(code);
      }
      running[pid] = next++;
      continue;
    }
    collect();
  }
  std::filesystem::remove_all(dir);
  return results;
}

// The convergence study of each scene (--residuals): a table of the
// error after n sweeps from the saved state, and convergence_<scene>.csv.
int runConvergence(const std::vector<std::string>& scenes, int size,
                   const ConvergenceOptions& options, const std::string& out) {
  for (const std::string& name : scenes) {
    auto scene = buildScene(name, size);
    const ConvergenceResult r = convergence(*scene, options);
    std::printf(
        "%s: one step of %.4g s from frame %d of quickstep 20 x 10 (largest joint separation "
        "%.3f mm, %d contacts); the largest body's speed off the converged step's (%s), "
        "m/s, and blockstep's residual, m/s:\n",
        r.scene.c_str(), options.dt, options.atFrame, r.startSeparation * 1e3, r.contacts,
        r.reference.c_str());
    std::printf("  %6s %12s %12s %14s %16s %14s\n", "sweeps", "quickstep", "blockstep",
                "blockstep rows", "blockstep island", "residual max");
    for (int n = 1; n <= options.maxSweeps; ++n) {
      if (n != 1 && n != 2 && n != 5 && n % 10 != 0 && n != options.maxSweeps) continue;
      const std::size_t k = n - 1;
      std::printf("  %6d %12.3g %12.3g %14.3g %16.3g %14.3g\n", n, r.quickstep[k], r.blockstep[k],
                  r.blockstepRows[k], r.blockstepIsland[k],
                  k < r.residualMax.size() ? r.residualMax[k] : 0.0);
    }
    if (out.empty()) continue;
    const auto path = std::filesystem::path(out) / ("convergence_" + r.scene + ".csv");
    std::ofstream csv(path);
    if (!csv) throw std::runtime_error("cannot write " + path.string());
    csv << "sweeps,quickstep_speed_error,blockstep_speed_error,blockstep_rows_speed_error,"
           "blockstep_island_speed_error,blockstep_residual_max,blockstep_residual_rms\n";
    for (std::size_t k = 0; k < r.quickstep.size(); ++k) {
      csv << k + 1 << ',' << r.quickstep[k] << ',' << r.blockstep[k] << ',' << r.blockstepRows[k]
          << ',' << r.blockstepIsland[k] << ',';
      if (k < r.residualMax.size())
        csv << r.residualMax[k] << ',' << r.residualRms[k];
      else
        csv << ',';
      csv << '\n';
    }
  }
  return 0;
}

// --ab: a program's A/B rows (BLOCKSTEP_AB) as a quickstep run and a
// blockstep run per world, printed, and with --out written as the runs
// are (a CSV each and summary.json) for the report.
int runAb(const std::string& file, const std::string& out) {
  const std::string name = std::filesystem::path(file).stem().string();
  const std::vector<AbWorld> worlds = readAbFile(file, name);
  nlohmann::json all = nlohmann::json::array();
  std::printf("%-22s %-34s %7s %10s %10s %12s %12s  %s\n", "world", "stepper", "steps", "solve ms",
              "x quick", "max sep mm", "rms sep mm", "note");
  for (const AbWorld& w : worlds) {
    const double quickMs = w.quickstep.medianSolveMs;
    for (const RunResult* r : {&w.quickstep, &w.blockstep}) {
      const bool block = r == &w.blockstep;
      std::printf("%-22s %-34s %7d %10.4f %10.2f %12.4f %12.4f  %s\n", r->scene.c_str(),
                  r->stepper.c_str(), r->framesRun, r->medianSolveMs,
                  quickMs > 0 ? r->medianSolveMs / quickMs : 0.0, r->maxSeparation * 1e3,
                  r->rmsSeparation * 1e3,
                  w.kept == (block ? "blockstep" : "quickstep")
                      ? "kept by the program"
                      : (w.kept == "dWorldStep" && block ? "(the program kept dWorldStep's)" : ""));
      nlohmann::json j = summary(*r, quickMs);
      j["kind"] = block ? "blockstep" : "quickstep";
      j["iterations"] = 0;
      j["substeps"] = 1;
      j["frame_dt"] = w.dt;
      j["error_m"] = r->maxSeparation;
      j["error_is"] = "max joint separation";
      j["ab_kept"] = w.kept;
      j["ab_max_speed_difference_m_s"] = w.maxSpeedDifference;
      j["csv_file"] = runPath("", r->scene, block ? "blockstep" : "quickstep", "", ".csv").string();
      all.push_back(j);
      if (!out.empty())
        writeCsv(runPath(out, r->scene, block ? "blockstep" : "quickstep", "", ".csv"), *r);
    }
    std::printf("%-22s the two steps' velocities ended up to %.4g m/s apart\n",
                w.quickstep.scene.c_str(), w.maxSpeedDifference);
  }
  if (!out.empty()) {
    std::filesystem::create_directories(out);
    std::ofstream(std::filesystem::path(out) / "summary.json") << all.dump(2) << '\n';
  }
  return 0;
}

// --help's list of scenes and steppers, a line each.
std::string helpFooter() {
  std::string text = "\nScenes (--scene; default: all but star and pile):\n";
  char line[200];
  for (const std::string& n : sceneNames()) {
    std::snprintf(line, sizeof line, "  %-22s %s\n", n.c_str(), sceneSummary(n).c_str());
    text += line;
  }
  text +=
      "\nSteppers (--stepper; default: quickstep:10, :20, :50, :20x4, :20x10, direct, "
      "blockstep, blockstep:substep:5 and :20, pbd:20, xpbd:1x20):\n"
      "  quickstep:IT[xSUB]     ODE's dWorldQuickStep, IT iterations, SUB sub-steps that each\n"
      "                         collide again (as a sub-stepping program does)\n"
      "  direct                 ODE's dWorldStep (its exact LCP), under the --cap wall time\n"
      "  blockstep              blockstep as a drop-in ODE program gets it (its default)\n"
      "  blockstep:substep:N    N sub-steps of one block sweep and one relax sweep each\n"
      "  blockstep:paper:IT     the paper's solver: one step, IT block iterations\n"
      "  pbd:IT[xSUB]           the paper's position-based baseline: a particle per body, a\n"
      "                         distance constraint per ball joint, IT iterations (ball-joint\n"
      "                         scenes whose bodies meet only static shapes: cloth, hair)\n"
      "  xpbd:IT[xSUB]          the same with XPBD's compliance (the joints' ERP and CFM as a\n"
      "                         spring): stiffness that does not depend on IT or SUB\n"
      "\nSettings (after a stepper as ,key=value, or --sweep key=v1,v2,...):\n";
  for (const auto& [key, meaning] : settingKeys()) {
    std::snprintf(line, sizeof line, "  %-22s %s\n", key.c_str(), meaning.c_str());
    text += line;
  }
  text +=
      "e.g. --stepper blockstep:substep:10,warm=0 --sweep sweeps=1,2,4 --sweep mode=block,row\n";
  return text;
}

int main(int argc, char** argv) {
  CLI::App app{
      "blockstep-compare: ODE scenes stepped by ODE's quickstep, ODE's dWorldStep and "
      "blockstep, measured the same way"};
  // The default comparison: the paper's four scenes, the field's, three
  // mass ratios (a 1000:1 chain hanging and whipped, a 1000 kg load on a
  // 1 kg plank) and the paper's self-colliding figures (a sheet rolled
  // up, hair whose strands touch);
  // quickstep at 10, 20 and 50 iterations and 20 with 4 and 10 sub-steps
  // (about blockstep's costs), dWorldStep under a wall-time cap,
  // blockstep's drop-in default and 5 and 20 sub-steps, 10 sub-steps
  // with its own collision every sub-step, and the paper's position-based
  // baseline where it can stand for the scene.
  std::vector<std::string> scenes = {
      "ragdoll",     "cloth",        "softcube",     "hair",        "chain",
      "chain_swing", "stack",        "pyramid",      "cradle",      "car",
      "bridge",      "ragdoll_pile", "hulls",        "chain_heavy", "chain_heavy_swing",
      "plank_load",  "cloth_roll",   "hair_touching"};
  std::vector<std::string> steppers = {"quickstep:10",
                                       "quickstep:20",
                                       "quickstep:50",
                                       "quickstep:20x4",
                                       "quickstep:20x10",
                                       "direct",
                                       "blockstep",
                                       "blockstep:substep:5",
                                       "blockstep:substep:20",
                                       "blockstep:substep:10,collision=substep",
                                       "pbd:20",
                                       "xpbd:1x20"};
  RunOptions options;
  options.capSeconds = 5.0;
  int size = 0;
  std::string out;
  std::string sceneHelp = "scene (repeatable):";
  for (const std::string& n : sceneNames())
    sceneHelp += " " + n;
  app.add_option("--scene", scenes, sceneHelp);
  std::vector<std::string> sceneFiles;
  app.add_option("--scene-file", sceneFiles,
                 "a scene of your own, a JSON file as --save-scenes writes (repeatable; "
                 "replaces the default scenes)");
  std::string saveScenes;
  app.add_option("--save-scenes", saveScenes,
                 "write each --scene as DIR/<name>.json (the scene file format) and stop");
  app.add_option("--stepper", steppers,
                 "stepper (repeatable): quickstep:IT[xSUB], direct, blockstep, "
                 "blockstep:substep:N, blockstep:paper:IT, pbd:IT[xSUB], xpbd:IT[xSUB]");
  app.add_option("--frames", options.frames, "frames per run")->check(CLI::Range(1, 1000000));
  app.add_option("--dt", options.dt, "frame step, s")->check(CLI::Range(1e-6, 1.0));
  app.add_option("--size", size, "cloth: cells per side (default 32)")->check(CLI::Range(0, 256));
  app.add_option("--cap", options.capSeconds, "wall-time cap of a dWorldStep run, s")
      ->check(CLI::Range(0.001, 86400.0));
  app.add_option("--out", out,
                 "folder for one CSV per run, summary.json, each scene's JSON and the recorded "
                 "poses of the report's replay");
  int replayStride = 2;
  app.add_option("--replay-stride", replayStride,
                 "with --out: record the bodies' poses every N frames for the report's 3D "
                 "replay (0: none)")
      ->check(CLI::Range(0, 1000000));
  double traceDepthMm = 0.0;
  app.add_option("--trace-depth", traceDepthMm,
                 "print every contact deeper than this (mm) at each frame's collision, with "
                 "both bodies' mass and motion, to stderr: where a deep contact came from")
      ->check(CLI::Range(0.0, 1e6));
  std::vector<int> traceEnergy;
  app.add_option("--trace-energy", traceEnergy,
                 "FIRST[,LAST]: print blockstep's kinetic and potential energy after each "
                 "stage of every sub-step of these frames to stderr, and what each stage changed "
                 "of the total: where a step gains energy")
      ->delimiter(',')
      ->expected(1, 2)
      ->check(CLI::Range(0, 1000000));
  int seeds = 1;
  app.add_option("--seeds", seeds,
                 "runs of each scene and stepper: the scene as built, then N-1 with every body's "
                 "start moved by 1e-6 m/s (seeds 1..N-1), for the spread (least, median, most) of "
                 "chaotic figures such as the deepest contact; the table's rows stay the first's")
      ->check(CLI::Range(1, 1000));
  bool grid = false;
  app.add_flag("--grid", grid,
               "error versus cost: quickstep 10/20/50 iterations x 1/2/4/10 sub-steps and "
               "blockstep 1/2/5/10/20/40 sub-steps (1/2/5/10 projected too, and colliding "
               "every sub-step), in place of --stepper");
  std::vector<std::string> sweeps;
  app.add_option("--sweep", sweeps,
                 "key=v1,v2,...: every stepper once per value, with ,key=value added "
                 "(repeatable: every combination; keys below)");
  int residualsFrame = -1;
  app.add_option("--residuals", residualsFrame,
                 "convergence study in place of the runs: from the state quickstep 20 x 10 "
                 "reaches at this frame, the error after one step given n = 1..--max-sweeps "
                 "sweeps (quickstep, blockstep block and row by row) and blockstep's residual "
                 "per sweep; writes convergence_<scene>.csv")
      ->check(CLI::Range(0, 1000000));
  ConvergenceOptions convergenceOptions;
  app.add_option("--max-sweeps", convergenceOptions.maxSweeps,
                 "the convergence study's largest sweep count (default 50)")
      ->check(CLI::Range(1, 10000));
  std::string abFile;
  app.add_option("--ab", abFile,
                 "in place of the runs: the rows an ODE program wrote under LD_PRELOAD with "
                 "BLOCKSTEP_AB=FILE (both steppers every step), as a run of each per world");
  bool report = false;
  app.add_flag("--report", report,
               "with --out: write the HTML report there too (compare/report/report.py)");
  int jobs = 1;
  app.add_option("--jobs", jobs,
                 "runs at a time, each in a process of its own (times then share the cores)")
      ->check(CLI::Range(1, 256));
  app.footer(helpFooter());
  CLI11_PARSE(app, argc, argv);
  if (grid) steppers = costGrid();
  options.traceDepth = 1e-3 * traceDepthMm;
  if (!traceEnergy.empty()) {
    options.traceEnergyFrom = traceEnergy.front();
    options.traceEnergyTo = traceEnergy.back();
  }

  dInitODE2(0);
  // quickstep and direct are ODE's own here, whatever BLOCKSTEP_REPLACE says.
  dBlockStepSetReplace("none");
  std::vector<Stepper> parsed;
  try {
    for (const std::string& sweep : sweeps)
      steppers = sweepLabels(steppers, sweep);
    for (const std::string& s : steppers)
      parsed.push_back(parseStepper(s));
    if (!sceneFiles.empty() && app.count("--scene") == 0) scenes.clear();
    for (const std::string& f : sceneFiles)
      scenes.push_back("file:" + f);
    for (const std::string& s : scenes)
      buildScene(s, size);  // names and files checked before anything runs
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "blockstep-compare: %s\n", e.what());
    dCloseODE();
    return 2;
  }
  if (!saveScenes.empty()) {
    std::filesystem::create_directories(saveScenes);
    for (const std::string& name : scenes) {
      auto scene = buildScene(name, size);
      const auto path = std::filesystem::path(saveScenes) / (scene->name() + ".json");
      saveSceneFile(*scene, path.string());
      std::printf("wrote %s\n", path.c_str());
    }
    dCloseODE();
    return 0;
  }
  if (!out.empty()) {
    std::filesystem::create_directories(out);
    options.poseStride = replayStride;
  }
  // The report, when asked for, once the results are written.
  auto writeReport = [&](int code) {
    if (code != 0 || !report || out.empty()) return code;
    const std::string command = "/usr/bin/python3 '" BLOCKSTEP_REPORT_SCRIPT "' '" + out + "'";
    return std::system(command.c_str()) == 0 ? 0 : 4;
  };
  if (!abFile.empty()) {
    int code = 0;
    try {
      code = runAb(abFile, out);
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "blockstep-compare: %s\n", e.what());
      code = 2;
    }
    dCloseODE();
    return writeReport(code);
  }
  if (residualsFrame >= 0) {
    convergenceOptions.atFrame = residualsFrame;
    convergenceOptions.dt = options.dt;
    const int code = runConvergence(scenes, size, convergenceOptions, out);
    dCloseODE();
    return writeReport(code);
  }

  nlohmann::json all = nlohmann::json::array();
  int labelWidth = 22;
  for (const std::string& label : steppers)
    labelWidth = std::max(labelWidth, static_cast<int>(label.size()));
  std::printf("%-12s %-*s %7s %10s %10s %9s %12s %12s %10s %10s %10s %10s %10s  %s\n", "scene",
              labelWidth, "stepper", "frames", "solve ms", "x qs20", "coll ms", "max sep mm",
              "rms sep mm", "pen mm", "held mm", "drift mm", "E gain J", "E rise J", "note");
  // A progress line on a terminal for runs longer than a second (one run
  // at a time only).
  const bool terminal = jobs == 1 && isatty(fileno(stderr)) != 0;
  double lastShown = 0.0;
  std::string running;
  if (terminal) {
    options.onFrame = [&](int done, double elapsed) {
      if (elapsed < 1.0 || elapsed - lastShown < 0.1) return;
      lastShown = elapsed;
      std::fprintf(stderr, "\r%s: frame %d of %d (%.0f s)   ", running.c_str(), done,
                   options.frames, elapsed);
    };
  }
  if (!out.empty() && replayStride > 0) {
    for (const std::string& name : scenes) {
      auto scene = buildScene(name, size);
      saveSceneFile(*scene,
                    (std::filesystem::path(out) / ("scene_" + scene->name() + ".json")).string());
    }
  }
  std::vector<Job> jobList;
  for (int seed = 0; seed < seeds; ++seed)
    for (const std::string& name : scenes)
      for (const Stepper& s : parsed)
        jobList.push_back({name, s, seed});
  std::vector<RunResult> results;
  if (jobs > 1) {
    results = runInProcesses(jobList, jobs, size, options, out);
  } else {
    for (const Job& job : jobList) {
      running = job.scene + " " + job.stepper.label;
      lastShown = 0.0;
      results.push_back(runOne(job, size, options, out));
      if (terminal && lastShown > 0.0) std::fprintf(stderr, "\r%*s\r", 70, "");
    }
  }
  // The scene as built first (the table), then each seed's runs in the
  // same order.
  const std::size_t perSeed = scenes.size() * parsed.size();
  std::vector<std::string> spreadLines;
  for (std::size_t first = 0; first < perSeed; first += parsed.size()) {
    const std::vector<RunResult> sceneResults(results.begin() + first,
                                              results.begin() + first + parsed.size());
    // Read against quickstep 20 when it was asked for (as it is, when
    // swept too).
    double quickSolveMs = 0.0;
    for (std::size_t k = 0; k < parsed.size(); ++k) {
      const Stepper& s = parsed[k];
      if (s.kind == Stepper::Kind::Quick && s.iterations == 20 && s.substeps == 1 &&
          (quickSolveMs == 0.0 || s.label == "quickstep:20"))
        quickSolveMs = sceneResults[k].medianSolveMs;
    }
    const SceneError measure = sceneErrorOf(*buildScene(jobList[first].scene, size));
    for (std::size_t k = 0; k < parsed.size(); ++k) {
      const RunResult& r = sceneResults[k];
      const double ratio = quickSolveMs > 0.0 ? r.medianSolveMs / quickSolveMs : 0.0;
      std::printf(
          "%-12s %-*s %7d %10.4f %10.2f %9.4f %12.3f %12.3f %10.3f %10.3f %10.3f %10.3g %10.3g  "
          "%s\n",
          r.scene.c_str(), labelWidth, r.stepper.c_str(), r.framesRun, r.medianSolveMs, ratio,
          r.medianCollideMs, r.maxSeparation * 1e3, r.rmsSeparation * 1e3, r.maxPenetration * 1e3,
          r.maxHeldPenetration * 1e3, r.drift * 1e3, r.maxEnergyGain, r.maxEnergyRise,
          note(r).c_str());
      nlohmann::json j = summary(r, quickSolveMs);
      const Stepper& st = parsed[k];
      j["kind"] = st.kind == Stepper::Kind::Quick       ? "quickstep"
                  : st.kind == Stepper::Kind::Direct    ? "direct"
                  : st.kind == Stepper::Kind::Particles ? (st.xpbd ? "xpbd" : "pbd")
                                                        : "blockstep";
      j["iterations"] = st.iterations;
      j["frame_dt"] = st.overrides.dt.value_or(options.dt);
      j["substeps"] = st.substeps;
      j["error_m"] = sceneError(r, measure);
      j["error_is"] = describe(measure);
      if (seeds > 1) {
        std::vector<RunResult> over;
        for (int seed = 0; seed < seeds; ++seed)
          over.push_back(results[seed * perSeed + first + k]);
        j["seeds"] = seeds;
        j["spread"] = spreadJson(over);
        spreadLines.push_back(spreadLine(over, labelWidth));
      }
      if (!out.empty() && replayStride > 0 && r.framesRun > 0) {
        j["replay_stride"] = replayStride;
        j["replay_file"] = runPath("", r.scene, r.stepper, "poses_", ".bin").string();
        j["csv_file"] = runPath("", r.scene, r.stepper, "", ".csv").string();
      }
      all.push_back(j);
    }
    reportBeaten(sceneResults, parsed, measure);
  }
  if (seeds > 1) {
    std::printf(
        "\nover %d runs (the scene as built, then %d with every body's start moved by %.0e m/s): "
        "median [least, most]\n",
        seeds, seeds - 1, kPerturbSpeed);
    std::printf("%-12s %-*s %26s %26s %26s %26s %26s\n", "scene", labelWidth, "stepper",
                "max sep mm", "pen mm", "held mm", "last s pen mm", "E rise J");
    for (const std::string& line : spreadLines)
      std::printf("%s\n", line.c_str());
  }
  if (jobs > 1)
    std::printf("(%d runs at a time: their solve times shared the machine's cores)\n", jobs);
  if (!out.empty()) {
    std::ofstream json(std::filesystem::path(out) / "summary.json");
    json << all.dump(2) << '\n';
    // This process's peak resident size (runs in processes of their own,
    // --jobs > 1, are not in it): compare/report/scaling.py reads it.
    std::ofstream(std::filesystem::path(out) / "process.json")
        << nlohmann::json{{"peak_resident_kb", peakResidentKb()}, {"jobs", jobs}}.dump(2) << '\n';
  }
  dCloseODE();
  return writeReport(0);
}

// Reading BLOCKSTEP_AB's rows (ab_file.h).
#include "compare/ode/ab_file.h"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace blockstep::compare {

namespace {

// The columns plugin/ab_mode.cpp writes, in its order.
const std::vector<std::string>& columns() {
  static const std::vector<std::string> names = {"world",
                                                 "step",
                                                 "h",
                                                 "kept",
                                                 "quickstep_ms",
                                                 "quickstep_max_separation_m",
                                                 "quickstep_rms_separation_m",
                                                 "quickstep_kinetic_j",
                                                 "blockstep_ms",
                                                 "blockstep_max_separation_m",
                                                 "blockstep_rms_separation_m",
                                                 "blockstep_kinetic_j",
                                                 "speed_difference_m_s",
                                                 "bodies",
                                                 "joints",
                                                 "contacts"};
  return names;
}

FrameRecord frame(double ms, double maxSep, double rmsSep, double kinetic, int joints,
                  int contacts) {
  FrameRecord f;
  f.solveSeconds = ms * 1e-3;
  f.joints.separation = maxSep;
  f.joints.separationSumSq = rmsSep * rmsSep * joints;
  f.joints.joints = joints;
  f.kineticEnergy = kinetic;
  f.contacts = contacts;
  return f;
}

}  // namespace

std::vector<AbWorld> readAbFile(const std::string& path, const std::string& name) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("A/B file " + path + ": cannot be read");
  std::string line;
  std::getline(in, line);
  std::string expected;
  for (const std::string& c : columns())
    expected += (expected.empty() ? "" : ",") + c;
  if (line != expected)
    throw std::invalid_argument("A/B file " + path + ": line 1 is not BLOCKSTEP_AB's header (" +
                                expected + ")");
  std::map<int, AbWorld> worlds;
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream split(line);
    for (std::string cell; std::getline(split, cell, ',');)
      cells.push_back(cell);
    const std::string where = "A/B file " + path + ": line " + std::to_string(number);
    if (cells.size() != columns().size())
      throw std::invalid_argument(where + ": " + std::to_string(cells.size()) + " columns, not " +
                                  std::to_string(columns().size()));
    std::vector<double> v(cells.size(), 0.0);
    for (std::size_t k = 0; k < cells.size(); ++k) {
      if (k == 3) continue;  // kept: a name
      char* end = nullptr;
      v[k] = std::strtod(cells[k].c_str(), &end);
      // speed_difference may be nan (a step that did not run both)
      if (end == cells[k].c_str() || *end || (k != 12 && !std::isfinite(v[k])))
        throw std::invalid_argument(where + ": " + columns()[k] + " '" + cells[k] +
                                    "' is not a number");
    }
    const int id = static_cast<int>(v[0]);
    if (id < 1 || !(v[2] > 0.0))
      throw std::invalid_argument(where + ": world must be >= 1 and h > 0");
    AbWorld& w = worlds[id];
    if (w.world == 0) {
      w.world = id;
      w.kept = cells[3];
      w.dt = v[2];
      const std::string scene = name + "_world" + std::to_string(id);
      w.quickstep.scene = w.blockstep.scene = scene;
      w.quickstep.stepper = "quickstep (program's iterations)";
      w.blockstep.stepper = "blockstep (program's settings)";
    }
    const int joints = static_cast<int>(v[14]), contacts = static_cast<int>(v[15]);
    w.quickstep.frames.push_back(frame(v[4], v[5], v[6], v[7], joints, contacts));
    w.blockstep.frames.push_back(frame(v[8], v[9], v[10], v[11], joints, contacts));
    if (std::isfinite(v[12])) w.maxSpeedDifference = std::max(w.maxSpeedDifference, v[12]);
  }
  std::vector<AbWorld> out;
  for (auto& [id, w] : worlds) {
    for (RunResult* r : {&w.quickstep, &w.blockstep}) {
      r->framesAsked = static_cast<int>(r->frames.size());
      summarizeFrames(*r, w.dt);
    }
    out.push_back(std::move(w));
  }
  if (out.empty()) throw std::invalid_argument("A/B file " + path + ": no steps in it");
  return out;
}

}  // namespace blockstep::compare

// Stepping a scene with one stepper, frame by frame.
#include "compare/ode/runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "blockstep/blockstep_ode.h"

namespace blockstep::compare {

namespace {

[[noreturn]] void reject(const std::string& text, const std::string& why) {
  throw std::invalid_argument(
      "stepper '" + text + "': " + why +
      " (accepted: quickstep:IT[xSUB], direct, blockstep, blockstep:substep:N, "
      "blockstep:paper:IT, pbd:IT[xSUB], xpbd:IT[xSUB]; IT 1..10000, N and SUB 1..1000)");
}

int number(const std::string& text, const std::string& digits, int lo, int hi) {
  if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos ||
      digits.size() > 6)
    reject(text, "'" + digits + "' is not a whole number");
  const int n = std::stoi(digits);
  if (n < lo || n > hi) reject(text, std::to_string(n) + " is out of range");
  return n;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// blockstep colliding the scene itself (collision=core or substep).
bool coreCollision(const Stepper& s) {
  return s.kind == Stepper::Kind::Block && s.overrides.collision &&
         *s.overrides.collision != Overrides::Collision::Ode;
}

void configure(Scene& scene, const Stepper& s) {
  const dWorldID w = scene.world();
  const Overrides& o = s.overrides;
  if (o.erp) dWorldSetERP(w, *o.erp);
  if (o.cfm) dWorldSetCFM(w, *o.cfm);
  // ODE's ball and fixed joints take the world's ERP and CFM when they are
  // made and keep them (hinges and contacts read the world's each step):
  // set on the world alone, a sweep over ERP changed nothing on a chain.
  for (const JointRecord& j : scene.joints()) {
    void (*setParam)(dJointID, int, dReal) = j.kind == JointKind::Ball    ? dJointSetBallParam
                                             : j.kind == JointKind::Fixed ? dJointSetFixedParam
                                                                          : nullptr;
    if (!setParam) continue;
    if (o.erp) setParam(j.joint, dParamERP, *o.erp);
    if (o.cfm) setParam(j.joint, dParamCFM, *o.cfm);
  }
  // The drop-in blockstep follows the quickstep iterations a program sets.
  const bool follows =
      s.kind == Stepper::Kind::Block && s.preset == Stepper::Preset::FollowQuickStep;
  dWorldSetQuickStepNumIterations(w, s.kind == Stepper::Kind::Quick || follows ? s.iterations : 20);
  if (s.kind != Stepper::Kind::Block) return;
  switch (s.preset) {
    case Stepper::Preset::FollowQuickStep:
      dWorldSetBlockFollowQuickStep(w);
      break;
    case Stepper::Preset::Substepped:
      dWorldSetBlockSubsteppedSolver(w, s.substeps);
      break;
    case Stepper::Preset::Paper:
      dWorldSetBlockPaperSolver(w, s.iterations);
      break;
  }
  // Each leaves follow-quickstep mode, from what the world runs now.
  if (o.sweeps) dWorldSetBlockIterations(w, *o.sweeps);
  if (o.relax) dWorldSetBlockRelaxIterations(w, *o.relax);
  if (o.warm) dWorldSetBlockWarmStarting(w, *o.warm ? 1 : 0);
  if (o.rowByRow) dWorldSetBlockMode(w, *o.rowByRow ? dBlockModeRowByRow : dBlockModeBlock);
  if (o.islandRows) dWorldSetBlockIslandBlockRows(w, *o.islandRows);
  if (o.chains) dWorldSetBlockChainBlocks(w, *o.chains ? 1 : 0);
  if (o.islandContacts) dWorldSetBlockIslandContacts(w, *o.islandContacts);
  if (o.lightGroups) dWorldSetBlockLightBodyGroups(w, *o.lightGroups ? 1 : 0);
  if (o.loadContacts) dWorldSetBlockLoadRelativeContacts(w, *o.loadContacts ? 1 : 0);
  if (o.impactDepth) dWorldSetBlockImpactDepth(w, *o.impactDepth);
  if (o.sinkingDepth) dWorldSetBlockSinkingDepth(w, *o.sinkingDepth);
  if (o.maxTravel) dWorldSetBlockMaxTravel(w, *o.maxTravel);
  if (o.retakeTurns) dWorldSetBlockRetakeTurns(w, *o.retakeTurns ? 1 : 0);
  if (o.contactRows) dWorldSetBlockContactIslandRows(w, *o.contactRows);
  if (o.maxTurn) dWorldSetBlockMaxTurn(w, *o.maxTurn);
  if (o.refreshTurn) dWorldSetBlockRefreshTurn(w, *o.refreshTurn);
  if (o.relaxDrift) dWorldSetBlockRelaxDrift(w, *o.relaxDrift ? 1 : 0);
  if (o.projections) dWorldSetBlockProjections(w, *o.projections);
  if (o.projectionTolerance) dWorldSetBlockProjectionTolerance(w, *o.projectionTolerance);
  if (o.threads) dWorldSetBlockThreads(w, *o.threads);
  if (o.exactJointSubsteps) dWorldSetBlockExactJointSubsteps(w, *o.exactJointSubsteps);
  if (o.calmSubsteps) dWorldSetBlockCalmSubsteps(w, *o.calmSubsteps);
  if (o.calmSpeed) dWorldSetBlockCalmSpeed(w, *o.calmSpeed);
  if (o.exactContactSubsteps) dWorldSetBlockExactContactSubsteps(w, *o.exactContactSubsteps);
  if (o.persistence) dWorldSetBlockContactPersistence(w, *o.persistence);
  if (o.tolerance) dWorldSetBlockTolerance(w, *o.tolerance);
  if (coreCollision(s)) {
    const int flags =
        *o.collision == Overrides::Collision::CoreEverySubstep ? dBlockCollideEverySubstep : 0;
    dWorldSetBlockCollision(w, scene.space(), &scene.contactSurface(), flags);
  }
}

// ODE's own messages (dWorldStep's "LCP internal error" on stacks) are
// counted per run instead of printed.
int odeMessages = 0;

void countMessage(int, const char*, va_list) {
  ++odeMessages;
}

bool finiteState(const Scene& scene) {
  for (dBodyID b : scene.bodies()) {
    const dReal* p = dBodyGetPosition(b);
    const dReal* v = dBodyGetLinearVel(b);
    const dReal* w = dBodyGetAngularVel(b);
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(p[k]) || !std::isfinite(v[k]) || !std::isfinite(w[k])) return false;
  }
  return true;
}

}  // namespace

int largestIslandRows(const Scene& scene) {
  const auto& bodies = scene.bodies();
  std::vector<int> parent(bodies.size()), rows(bodies.size(), 0);
  for (std::size_t i = 0; i < parent.size(); ++i)
    parent[i] = static_cast<int>(i);
  auto find = [&](int i) {
    while (parent[i] != i)
      i = parent[i] = parent[parent[i]];
    return i;
  };
  auto index = [&](dBodyID b) {
    return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin());
  };
  for (const JointRecord& j : scene.joints()) {
    const int n = j.kind == JointKind::Ball     ? 3
                  : j.kind == JointKind::Hinge  ? 5
                  : j.kind == JointKind::Hinge2 ? 4
                                                : 6;
    const int a = find(index(j.body1));
    if (j.body2) {
      const int b = find(index(j.body2));
      if (a != b) {
        parent[b] = a;
        rows[a] += rows[b];
      }
    }
    rows[a] += n;
  }
  int largest = 0;
  for (std::size_t i = 0; i < parent.size(); ++i)
    if (parent[i] == static_cast<int>(i)) largest = std::max(largest, rows[i]);
  return largest;
}

namespace {

// "erp, cfm, ...": what an error about a setting says is accepted.
std::string settingKeyList() {
  std::string keys;
  for (const auto& [key, meaning] : settingKeys())
    keys += (keys.empty() ? "" : ", ") + key;
  return keys;
}

[[noreturn]] void rejectSetting(const std::string& text, const std::string& why) {
  throw std::invalid_argument("stepper '" + text + "': " + why + " (settings: " + settingKeyList() +
                              ")");
}

double decimal(const std::string& text, const std::string& key, const std::string& value, double lo,
               double hi) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size() || !std::isfinite(v))
    rejectSetting(text, key + "='" + value + "' is not a number");
  if (v < lo || v > hi) {
    char range[120];
    std::snprintf(range, sizeof range, "%s=%s is out of range [%g, %g]", key.c_str(), value.c_str(),
                  lo, hi);
    rejectSetting(text, range);
  }
  return v;
}

int whole(const std::string& text, const std::string& key, const std::string& value, int lo,
          int hi) {
  const double v = decimal(text, key, value, lo, hi);
  if (v != std::floor(v)) rejectSetting(text, key + "='" + value + "' is not a whole number");
  return static_cast<int>(v);
}

bool flag(const std::string& text, const std::string& key, const std::string& value) {
  if (value == "1" || value == "on") return true;
  if (value == "0" || value == "off") return false;
  rejectSetting(text, key + "='" + value + "' is not 0/1 (or off/on)");
}

Stepper parseStepperName(const std::string& text, const std::string& name) {
  Stepper s;
  if (name == "direct") {
    s.kind = Stepper::Kind::Direct;
    return s;
  }
  if (name == "blockstep") {
    s.kind = Stepper::Kind::Block;
    return s;
  }
  // IT[xSUB] after a prefix: quickstep's and the particle steppers'.
  auto iterationsBySubsteps = [&](const std::string& prefix) {
    const std::string rest = name.substr(prefix.size());
    const std::size_t x = rest.find('x');
    s.iterations = number(text, rest.substr(0, x), 1, 10000);
    if (x != std::string::npos) s.substeps = number(text, rest.substr(x + 1), 1, 1000);
  };
  for (const char* prefix : {"quickstep:", "pbd:", "xpbd:"}) {
    if (name.rfind(prefix, 0) != 0) continue;
    iterationsBySubsteps(prefix);
    if (prefix[0] != 'q') {
      s.kind = Stepper::Kind::Particles;
      s.xpbd = prefix[0] == 'x';
    }
    return s;
  }
  s.kind = Stepper::Kind::Block;
  const std::string substep = "blockstep:substep:", paper = "blockstep:paper:";
  if (name.rfind(substep, 0) == 0) {
    s.preset = Stepper::Preset::Substepped;
    s.substeps = number(text, name.substr(substep.size()), 1, 1000);
    return s;
  }
  if (name.rfind(paper, 0) == 0) {
    s.preset = Stepper::Preset::Paper;
    s.iterations = number(text, name.substr(paper.size()), 1, 10000);
    return s;
  }
  reject(text, "unknown stepper");
}

bool isSettingKey(const std::string& key) {
  for (const auto& [k, meaning] : settingKeys())
    if (k == key) return true;
  return false;
}

// Why a stepper does not take a setting ("" when it does).
std::string whyNot(const Stepper& s, const std::string& key) {
  const bool block = s.kind == Stepper::Kind::Block;
  if (key == "erp" || key == "cfm" || key == "dt") return "";
  if (key == "iterations") {
    if (s.kind == Stepper::Kind::Direct) return "direct has no iterations";
    if (block && s.preset == Stepper::Preset::Substepped)
      return "blockstep:substep has no iterations of its own (use sweeps)";
    return "";
  }
  if (key == "substeps") {
    if (s.kind == Stepper::Kind::Direct) return "direct takes no sub-steps";
    if (block && s.preset != Stepper::Preset::Substepped)
      return "it takes no sub-steps (blockstep sub-steps: blockstep:substep:N)";
    return "";
  }
  return block ? "" : key + " is a blockstep setting";
}

// One ",key=value" item applied to a parsed stepper.
void applySetting(const std::string& text, const std::string& item, Stepper& s) {
  const std::size_t eq = item.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
    rejectSetting(text, "'" + item + "' is not key=value");
  const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
  if (!isSettingKey(key)) rejectSetting(text, "unknown setting '" + key + "'");
  if (const std::string why = whyNot(s, key); !why.empty()) rejectSetting(text, why);
  Overrides& o = s.overrides;
  if (key == "erp") {
    o.erp = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "cfm") {
    o.cfm = decimal(text, key, value, 0.0, 1e6);
  } else if (key == "dt") {
    o.dt = decimal(text, key, value, 1e-6, 1.0);
  } else if (key == "iterations") {
    // The name's own IT: quickstep's and the particle steppers'
    // iterations, the paper solver's sweeps, the quickstep iterations the
    // drop-in blockstep follows.
    s.iterations = whole(text, key, value, 1, 10000);
  } else if (key == "substeps") {
    s.substeps = whole(text, key, value, 1, 1000);
  } else if (key == "sweeps") {
    o.sweeps = whole(text, key, value, 1, 10000);
  } else if (key == "relax") {
    o.relax = whole(text, key, value, 0, 1000);
  } else if (key == "warm") {
    o.warm = flag(text, key, value);
  } else if (key == "mode") {
    if (value != "block" && value != "row")
      rejectSetting(text, "mode='" + value + "' is not block or row");
    o.rowByRow = value == "row";
  } else if (key == "island_rows") {
    o.islandRows = whole(text, key, value, 0, 1000000);
  } else if (key == "chains") {
    o.chains = flag(text, key, value);
  } else if (key == "island_contacts") {
    o.islandContacts = whole(text, key, value, 0, 2);
  } else if (key == "light_groups") {
    o.lightGroups = flag(text, key, value);
  } else if (key == "load_contacts") {
    o.loadContacts = flag(text, key, value);
  } else if (key == "impact_depth") {
    o.impactDepth = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "sinking_depth") {
    o.sinkingDepth = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "retake") {
    o.retakeTurns = flag(text, key, value);
  } else if (key == "contact_rows") {
    o.contactRows = whole(text, key, value, 0, 4096);
  } else if (key == "max_turn") {
    o.maxTurn = decimal(text, key, value, 0.0, 10.0);
  } else if (key == "max_travel") {
    o.maxTravel = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "refresh_turn") {
    o.refreshTurn = decimal(text, key, value, 0.0, 10.0);
  } else if (key == "exact_joint_substeps") {
    o.exactJointSubsteps = whole(text, key, value, 0, 1000);
  } else if (key == "calm_substeps") {
    o.calmSubsteps = whole(text, key, value, 0, 1000);
  } else if (key == "calm_speed") {
    o.calmSpeed = decimal(text, key, value, 0.0, 1000.0);
  } else if (key == "exact_contact_substeps") {
    o.exactContactSubsteps = whole(text, key, value, 0, 1000);
  } else if (key == "threads") {
    o.threads = whole(text, key, value, 0, 256);
  } else if (key == "relax_drift") {
    o.relaxDrift = flag(text, key, value);
  } else if (key == "project") {
    o.projections = whole(text, key, value, 0, 16);
  } else if (key == "project_tol") {
    o.projectionTolerance = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "persistence") {
    o.persistence = decimal(text, key, value, 0.0, 1.0);
  } else if (key == "tolerance") {
    o.tolerance = decimal(text, key, value, 0.0, 1e6);
  } else if (key == "collision") {
    if (value == "ode")
      o.collision = Overrides::Collision::Ode;
    else if (value == "core")
      o.collision = Overrides::Collision::Core;
    else if (value == "substep")
      o.collision = Overrides::Collision::CoreEverySubstep;
    else
      rejectSetting(text, "collision='" + value + "' is not ode, core or substep");
  }
}

}  // namespace

std::vector<std::pair<std::string, std::string>> settingKeys() {
  return {{"erp", "the world's ERP, 0..1 (every stepper)"},
          {"cfm", "the world's CFM (every stepper)"},
          {"dt", "the frame step, s"},
          {"iterations", "the name's IT: quickstep, pbd, xpbd, blockstep:paper, blockstep"},
          {"substeps", "the name's SUB: quickstep, pbd, xpbd, blockstep:substep (its N)"},
          {"sweeps", "blockstep: velocity sweeps per sub-step"},
          {"relax", "blockstep: relax sweeps per sub-step"},
          {"warm", "blockstep: warm starting, 0 or 1"},
          {"mode", "blockstep: block (one block per joint) or row (row by row)"},
          {"island_rows", "blockstep: island blocks up to this many joint rows, 0: off"},
          {"chains", "blockstep: larger islands cut into chains of that many rows, 0 or 1"},
          {"island_contacts",
           "blockstep: island blocks' contacts solved in the null space of their joints, 0, 1 "
           "or 2 (in steps with an impact)"},
          {"contact_rows",
           "blockstep: contact islands as one exact block up to this many points, 0: off"},
          {"light_groups",
           "blockstep: in larger contact islands, light bodies' contacts as exact groups, 0 or 1"},
          {"load_contacts",
           "blockstep: fresh contacts on jointed bodies give no more under their load than "
           "under their own weight, 0 or 1"},
          {"impact_depth",
           "blockstep: colliding every sub-step, contacts closing more than this a sub-step, m, "
           "solved with their neighbours as exact groups, 0: off"},
          {"sinking_depth",
           "blockstep: colliding every sub-step, contacts still sinking more than this a "
           "sub-step after the sweeps, m, solved with their neighbours as exact groups, 0: off"},
          {"retake",
           "blockstep: colliding every sub-step, a part that spins a touching body past max_turn "
           "taken again shorter, or that sends a body past its reach taken again reaching "
           "farther, 0 or 1"},
          {"max_turn", "blockstep: more sub-steps past this turn per sub-step, rad, 0: off"},
          {"max_travel",
           "blockstep: colliding every sub-step, more parts past this surface travel of a "
           "touching body's turn per part, m, 0: the turn only"},
          {"refresh_turn",
           "blockstep: sub-steps keep their rows until bodies turn this far, rad, 0: always "
           "prepare"},
          {"relax_drift", "blockstep: relax closes the joints' linearization drift, 0 or 1"},
          {"project",
           "blockstep: position projections of island blocks' rigid joint rows at each step's "
           "end, 0: off"},
          {"project_tol",
           "blockstep: with project, islands whose rigid joint rows are within this of closing "
           "(m or rad) are not projected, 0: always"},
          {"threads", "blockstep: threads sweeping independent islands, 0: one per core"},
          {"exact_joint_substeps",
           "blockstep: sub-steps of an island of joints solved exactly (an island block, "
           "projected, touching nothing), 0: the step's count"},
          {"calm_substeps",
           "blockstep: sub-steps of a calm island (joints one island block, touched, no "
           "contact closing faster than calm_speed), 0: the step's count"},
          {"calm_speed", "blockstep: with calm_substeps, the largest closing speed, m/s"},
          {"exact_contact_substeps",
           "blockstep: sub-steps of an island of contacts solved as one exact group, 0: the "
           "step's count"},
          {"persistence", "blockstep: contact persistence, m, 0: off"},
          {"tolerance", "blockstep: stop sweeping below this residual, m/s, 0: off"},
          {"collision",
           "blockstep: ode (the scene's dSpaceCollide, once a frame), core (blockstep's own, "
           "once a frame) or substep (blockstep's own, every sub-step)"}};
}

std::vector<std::string> sweepLabels(const std::vector<std::string>& labels,
                                     const std::string& sweep) {
  const std::size_t eq = sweep.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == sweep.size())
    throw std::invalid_argument("--sweep '" + sweep + "' is not key=v1,v2,...");
  const std::string key = sweep.substr(0, eq);
  std::vector<std::string> values;
  std::size_t at = eq + 1;
  while (at <= sweep.size()) {
    std::size_t comma = sweep.find(',', at);
    if (comma == std::string::npos) comma = sweep.size();
    if (comma == at) throw std::invalid_argument("--sweep '" + sweep + "' has an empty value");
    values.push_back(sweep.substr(at, comma - at));
    at = comma + 1;
  }
  if (!isSettingKey(key))
    throw std::invalid_argument("--sweep '" + sweep + "': unknown setting '" + key +
                                "' (settings: " + settingKeyList() + ")");
  // A stepper that does not take the setting runs once, as it is.
  std::vector<std::string> out;
  bool anyTakes = false;
  for (const std::string& label : labels) {
    if (!whyNot(parseStepper(label), key).empty()) {
      out.push_back(label);
      continue;
    }
    anyTakes = true;
    for (const std::string& v : values)
      out.push_back(label + "," + key + "=" + v);
  }
  if (!anyTakes)
    throw std::invalid_argument("--sweep '" + sweep + "': none of the steppers takes " + key);
  return out;
}

Stepper parseStepper(const std::string& text) {
  const std::size_t comma = text.find(',');
  Stepper s = parseStepperName(text, text.substr(0, comma));
  s.label = text;
  for (std::size_t at = comma; at != std::string::npos;) {
    const std::size_t next = text.find(',', at + 1);
    applySetting(text, text.substr(at + 1, next == std::string::npos ? next : next - at - 1), s);
    at = next;
  }
  return s;
}

void summarize(RunResult& r, const Scene& scene, const RunOptions& options) {
  summarizeFrames(r, options.dt);
  if (dBodyID p = scene.probe()) {
    const dReal* now = dBodyGetPosition(p);
    const dReal* s = scene.probeStart();
    r.drift = std::sqrt((now[0] - s[0]) * (now[0] - s[0]) + (now[1] - s[1]) * (now[1] - s[1]) +
                        (now[2] - s[2]) * (now[2] - s[2]));
  }
}

void summarizeFrames(RunResult& r, double dt) {
  std::vector<double> solve, collide;
  double sumSq = 0.0;
  long samples = 0;
  const int lastSecond = std::max(1, static_cast<int>(std::lround(1.0 / dt)));
  double lastPen = 0.0;
  int lastCount = 0;
  double lowestEnergy = r.startEnergy;
  for (std::size_t f = 0; f < r.frames.size(); ++f) {
    const FrameRecord& rec = r.frames[f];
    solve.push_back(rec.solveSeconds * 1e3);
    collide.push_back(rec.collideSeconds * 1e3);
    r.maxSeparation = std::max(r.maxSeparation, rec.joints.separation);
    r.maxAngle = std::max(r.maxAngle, rec.joints.angle);
    r.maxPenetration = std::max(r.maxPenetration, rec.penetration);
    r.maxHeldPenetration = std::max(r.maxHeldPenetration, rec.heldPenetration);
    r.maxFoundPenetration = std::max(r.maxFoundPenetration, rec.foundPenetration);
    const double energy = rec.kineticEnergy + rec.potentialEnergy;
    r.maxEnergyGain = std::max(r.maxEnergyGain, energy - r.startEnergy);
    lowestEnergy = std::min(lowestEnergy, energy);
    r.maxEnergyRise = std::max(r.maxEnergyRise, energy - lowestEnergy);
    sumSq += rec.joints.separationSumSq;
    r.runawayFrames += rec.handedToOde > 0;
    r.odeSteppedFrames += rec.steppedByOde;
    samples += rec.joints.joints;
    if (f + lastSecond >= r.frames.size()) {
      lastPen += rec.penetration;
      ++lastCount;
    }
  }
  r.framesRun = static_cast<int>(r.frames.size());
  r.medianSolveMs = median(solve);
  r.medianCollideMs = median(collide);
  r.rmsSeparation = samples > 0 ? std::sqrt(sumSq / samples) : 0.0;
  r.lastSecondPenetration = lastCount > 0 ? lastPen / lastCount : 0.0;
}

void recordPoses(const Scene& scene, int done, const RunOptions& options, RunResult& r) {
  if (options.poseStride <= 0 || done % options.poseStride != 0) return;
  r.poseStride = options.poseStride;
  for (dBodyID b : scene.bodies()) {
    const dReal* p = dBodyGetPosition(b);
    const dReal* q = dBodyGetQuaternion(b);
    r.poses.insert(r.poses.end(), {float(p[0]), float(p[1]), float(p[2]), float(q[0]), float(q[1]),
                                   float(q[2]), float(q[3])});
  }
}

namespace {

// RunOptions::traceDepth: the pairs deeper than `depth` at frame f's
// collision k (quickstep's sub-steps collide each), one line each.
void traceDeepPairs(const Scene& scene, const Stepper& stepper, int frame, int collision,
                    double depth) {
  for (const Scene::DeepPair& p : scene.pairsDeeperThan(depth)) {
    std::fprintf(stderr, "deep %s %s frame %d.%d: %.2f mm, %s; %s | %s\n", scene.name().c_str(),
                 stepper.label.c_str(), frame, collision, p.depth * 1e3, p.held ? "held" : "found",
                 Scene::describeGeom(p.a).c_str(), Scene::describeGeom(p.b).c_str());
  }
}

// RunOptions::traceEnergyFrom: the energy after each stage of every
// sub-step of frame f's step, and what the stage changed of the total,
// one line each.
void traceStageEnergy(dWorldID w, const Scene& scene, const Stepper& stepper, int frame) {
  static const char* const kStage[] = {"forces", "warm start", "sweeps",    "positions",
                                       "relax",  "start",      "projection"};
  const int n = dWorldGetBlockStageEnergy(w, nullptr, nullptr, nullptr, nullptr, 0);
  std::vector<int> substep(n), stage(n);
  std::vector<dReal> kinetic(n), potential(n);
  dWorldGetBlockStageEnergy(w, substep.data(), stage.data(), kinetic.data(), potential.data(), n);
  for (int i = 0; i < n; ++i) {
    const double total = kinetic[i] + potential[i];
    // From the sub-step's start on: islands stepped apart (their own
    // sub-step counts) each begin their sub-steps with a start.
    const bool start = stage[i] == dBlockStageStart || i == 0;
    const double change = start ? 0.0 : total - (kinetic[i - 1] + potential[i - 1]);
    const char* name = stage[i] >= 0 && stage[i] < 7 ? kStage[stage[i]] : "?";
    std::fprintf(stderr,
                 "energy %s %s frame %d sub-step %d %-10s kinetic %.6g J potential %.6g J "
                 "total %.6g J (%+.3g)\n",
                 scene.name().c_str(), stepper.label.c_str(), frame, substep[i], name, kinetic[i],
                 potential[i], total, change);
  }
}

}  // namespace

void perturbStart(Scene& scene, int seed) {
  std::mt19937 rng(static_cast<std::uint32_t>(seed));
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (dBodyID b : scene.bodies()) {
    if (dBodyIsKinematic(b)) continue;  // its motion is the scene's, not a state
    double d[3] = {gauss(rng), gauss(rng), gauss(rng)};
    const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(n > 0.0)) continue;
    const dReal* v = dBodyGetLinearVel(b);
    dBodySetLinearVel(b, v[0] + kPerturbSpeed * d[0] / n, v[1] + kPerturbSpeed * d[1] / n,
                      v[2] + kPerturbSpeed * d[2] / n);
  }
}

RunResult run(Scene& scene, const Stepper& stepper, const RunOptions& given) {
  RunOptions options = given;
  if (options.perturbSeed > 0) perturbStart(scene, options.perturbSeed);
  if (stepper.overrides.dt) options.dt = *stepper.overrides.dt;
  if (!(options.dt > 0.0) || options.dt > 1.0 || options.frames < 1)
    throw std::invalid_argument("a run needs frames >= 1 and 0 < dt <= 1 s");
  RunResult r;
  r.scene = scene.name();
  r.stepper = stepper.label;
  r.framesAsked = options.frames;
  r.frames.reserve(options.frames);
  r.startEnergy = scene.kineticEnergy() + scene.potentialEnergy();
  const dWorldID w = scene.world();
  if (stepper.kind == Stepper::Kind::Particles) {
    configure(scene, stepper);  // XPBD's compliance comes from the world's ERP and CFM
    return runParticles(scene, stepper, options);
  }
  const int jointRows = largestIslandRows(scene);
  if (stepper.kind == Stepper::Kind::Direct) {
    const int rows = jointRows;
    if (rows > options.directRowLimit) {
      r.stoppedBecause = "not run: an island of " + std::to_string(rows) +
                         " joint rows (dWorldStep takes 15-18 s a frame at 5952)";
      return r;
    }
  }
  configure(scene, stepper);
  odeMessages = 0;
  // Quickstep shuffles its rows with ODE's random numbers: every run
  // starts them alike, so a run repeats whatever ran before it.
  dRandSetSeed(0);
  dMessageFunction* previousHandler = dGetMessageHandler();
  dSetMessageHandler(&countMessage);
  recordPoses(scene, 0, options, r);
  const bool ownCollision = coreCollision(stepper);
  double ownCollideSeconds = 0.0;
  const auto start = Clock::now();
  for (int f = 0; f < options.frames; ++f) {
    FrameRecord rec;
    // Quickstep's sub-steps are whole steps of dt / SUB, each with its own
    // collision, as an ODE program sub-stepping does (contacts kept over
    // the sub-steps would push out their depth SUB times over).
    const int steps = stepper.kind == Stepper::Kind::Quick ? stepper.substeps : 1;
    const double h = options.dt / steps;
    int ok = 1;
    for (int k = 0; k < steps && ok; ++k) {
      const auto t0 = Clock::now();
      scene.collide();
      rec.contacts = scene.contactCount();
      // blockstep colliding itself: ODE's collision above only measures
      // the depth (the same measure for every stepper), and its contacts
      // go before the step; the collision time is blockstep's own.
      if (ownCollision) scene.clearContacts();
      const auto collided = Clock::now();
      // The measure, out of both times.
      rec.penetration = std::max(rec.penetration, scene.deepestContact());
      rec.heldPenetration = std::max(rec.heldPenetration, scene.deepestHeldContact());
      if (options.traceDepth > 0.0) traceDeepPairs(scene, stepper, f, k, options.traceDepth);
      const auto t1 = Clock::now();
      const double measureSeconds = seconds(collided, t1);
      switch (stepper.kind) {
        case Stepper::Kind::Quick:
          ok = dWorldQuickStep(w, h);
          break;
        case Stepper::Kind::Direct: {
          // Contacts add three rows each (normal and two friction
          // directions): a settled pyramid's 1660 contacts made one
          // dWorldStep take over three minutes.
          const int rows = jointRows + 3 * scene.contactCount();
          if (rows > options.directRowLimit) {
            char text[160];
            std::snprintf(text, sizeof text,
                          "stopped at frame %d: up to %d rows with its %d contacts (dWorldStep "
                          "is not run above %d)",
                          f, rows, scene.contactCount(), options.directRowLimit);
            r.stoppedBecause = text;
            ok = -1;
            break;
          }
          ok = dWorldStep(w, h);
          break;
        }
        case Stepper::Kind::Block: {
          // Only when asked: the call would count in the solve time.
          const bool tracing = options.traceEnergyFrom >= 0;
          const bool traceEnergy = tracing && f >= options.traceEnergyFrom &&
                                   f <= std::max(options.traceEnergyFrom, options.traceEnergyTo);
          if (tracing) dWorldSetBlockRecordStageEnergy(w, traceEnergy ? 1 : 0);
          ok = dWorldBlockStep(w, h);
          if (traceEnergy) traceStageEnergy(w, scene, stepper, f);
          dBlockStepStats stats;
          if (dWorldGetBlockStepStats(w, &stats)) {
            rec.handedToOde += stats.handedToOde;
            rec.steppedByOde |= stats.stepper == dBlockStepperOde;
            ownCollideSeconds = stats.collideSeconds;
          }
          if (ownCollision)
            rec.foundPenetration = std::max(rec.foundPenetration, dWorldGetBlockDeepestContact(w));
          break;
        }
        case Stepper::Kind::Particles:  // runParticles() steps these
          break;
      }
      const auto t2 = Clock::now();
      scene.clearContacts();
      if (ownCollision) {
        rec.collideSeconds += ownCollideSeconds;
        rec.solveSeconds += seconds(t1, t2) - ownCollideSeconds;
      } else {
        rec.collideSeconds += seconds(t0, t1) - measureSeconds;
        rec.solveSeconds += seconds(t1, t2);
      }
    }
    if (ok < 0) break;  // not stepped: stoppedBecause says why
    rec.joints = scene.jointError();
    rec.kineticEnergy = scene.kineticEnergy();
    rec.potentialEnergy = scene.potentialEnergy();
    r.frames.push_back(rec);
    recordPoses(scene, f + 1, options, r);
    if (options.onFrame) options.onFrame(f + 1, seconds(start, Clock::now()));
    if (!ok) {
      r.stoppedBecause =
          "the stepper refused frame " + std::to_string(f) +
          (stepper.kind == Stepper::Kind::Block ? std::string(": ") + dWorldGetBlockStepMessage(w)
                                                : std::string());
      break;
    }
    if (!finiteState(scene)) {
      r.exploded = true;
      r.stoppedBecause = "non-finite state at frame " + std::to_string(f);
      break;
    }
    // The cap is for dWorldStep, whose exact LCP takes seconds to minutes
    // a frame on cloth and lattices; the other steppers run every frame.
    if (stepper.kind == Stepper::Kind::Direct &&
        seconds(start, Clock::now()) > options.capSeconds && f + 1 < options.frames) {
      char text[120];
      std::snprintf(text, sizeof text, "wall-time cap of %g s reached after %d frames",
                    options.capSeconds, f + 1);
      r.stoppedBecause = text;
      break;
    }
  }

  dSetMessageHandler(previousHandler);
  r.odeMessages = odeMessages;
  summarize(r, scene, options);
  return r;
}

SceneError sceneErrorOf(const Scene& scene) {
  if (!scene.joints().empty()) return SceneError::JointSeparation;
  return scene.probe() ? SceneError::ProbeDrift : SceneError::HeldPenetration;
}

const char* describe(SceneError e) {
  switch (e) {
    case SceneError::JointSeparation:
      return "max joint separation";
    case SceneError::ProbeDrift:
      return "top-box drift";
    case SceneError::HeldPenetration:
      return "deepest held contact";
  }
  return "";
}

double sceneError(const RunResult& r, SceneError e) {
  switch (e) {
    case SceneError::JointSeparation:
      return r.maxSeparation;
    case SceneError::ProbeDrift:
      return r.drift;
    case SceneError::HeldPenetration:
      return r.maxHeldPenetration;
  }
  return 0.0;
}

Standing standing(const std::vector<RunResult>& results, const std::vector<Stepper>& steppers,
                  SceneError measure, bool withCollision) {
  auto error = [measure](const RunResult& r) { return sceneError(r, measure); };
  auto cost = [withCollision](const RunResult& r) {
    return r.medianSolveMs + (withCollision ? r.medianCollideMs : 0.0);
  };
  Standing out;
  for (std::size_t q = 0; q < results.size(); ++q) {
    const RunResult& Q = results[q];
    if (steppers[q].kind != Stepper::Kind::Quick || !Q.stoppedBecause.empty()) continue;
    ++out.quick;
    for (std::size_t b = 0; b < results.size(); ++b) {
      const RunResult& B = results[b];
      if (steppers[b].kind != Stepper::Kind::Block || !B.stoppedBecause.empty()) continue;
      if (cost(B) <= cost(Q) && error(B) < error(Q) &&
          B.lastSecondPenetration <= Q.lastSecondPenetration + 1e-4) {
        ++out.beaten;
        break;
      }
    }
  }
  return out;
}

}  // namespace blockstep::compare

// A preload for plain-ODE reference runs of ODE's demos: it tells how far
// a demo's end state moves when nothing but the stepper changes, so a
// blockstep run can be judged against ODE's own spread.
//
//   BSCOMPAT_STEPPER=swap      dWorldQuickStep runs dWorldStep and back
//   BSCOMPAT_STEP_SCALE=s      every step size is multiplied by s
//                              (1 +- 1e-9: is the demo chaotic?)
//   BSCOMPAT_REFINE=n          every step runs as n steps of dWorldStep
//                              (ODE's direct solver) of h / n: the forces
//                              the program added act on each, and damping
//                              (ODE scales velocities by 1 - d per step)
//                              becomes 1 - (1 - d)^(1/n) per step, so
//                              only the time resolution changes. This is
//                              ODE's own converged answer for a demo
//                              without contacts; contact joints would
//                              repeat their depth correction n times, so
//                              demos with contacts cannot be refined so.
//   BSCOMPAT_WHOLE_REFINE=n    the whole demo at a step n times finer,
//                              collision included: every step is h / n
//                              (with damping per step converted as
//                              above) and the headless drawstuff, told
//                              BSCOMPAT_STEPS_PER_FRAME=n, calls the
//                              demo's step function n times per frame.
//                              For demos with contacts whose step
//                              function does nothing but collide, step
//                              and move geoms without a body: such a geom
//                              (demo_motion's lift, placed at its speed
//                              times a clock the demo advances by its own
//                              step each call) is put where the demo had
//                              it at the same time, the position it asked
//                              for on call k / n when it asks on call k.
//   BSCOMPAT_RIGID_CONTACTS=v  contacts push out of penetration no faster
//                              than v m/s (dWorldSetContactMaxCorrectingVel
//                              before each step). At a fine step ODE's
//                              Baumgarte push-out of a contact found d deep
//                              is ERP d / h, about ERP times the impact
//                              speed however fine the step: a bounce the
//                              program never asked for. Limited, the
//                              refined answer is that of rigid contacts.
//   BSCOMPAT_RNG=split         ODE's own draws from its random generator
//                              (quickstep shuffles its rows with dRandInt)
//                              come from a stream of their own, so the
//                              program's draws (the random objects a demo
//                              drops) are the same whatever steps it:
//                              blockstep does not draw, and without this
//                              a demo would drop other objects under it.
#include <dlfcn.h>
#include <link.h>
#include <ode/ode.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <vector>

namespace {

using Stepper = int (*)(dWorldID, dReal);

template <typename F>
F real(const char* name) {
  const auto f = reinterpret_cast<F>(dlsym(RTLD_NEXT, name));
  if (!f) {
    std::fprintf(stderr, "stepper shim: ODE's %s not found\n", name);
    std::exit(2);
  }
  return f;
}

bool swapped() {
  const char* v = std::getenv("BSCOMPAT_STEPPER");
  return v && std::strcmp(v, "swap") == 0;
}

dReal scaled(dReal h) {
  const char* v = std::getenv("BSCOMPAT_STEP_SCALE");
  return v ? h * static_cast<dReal>(std::strtod(v, nullptr)) : h;
}

int refinement() {
  const char* v = std::getenv("BSCOMPAT_REFINE");
  return v ? std::max(1, std::atoi(v)) : 1;
}

// The bodies of each world, to carry forces and damping through the
// refined steps (ODE has no call that lists a world's bodies).
std::map<dWorldID, std::set<dBodyID>>& bodiesOf() {
  static std::map<dWorldID, std::set<dBodyID>> bodies;
  return bodies;
}

// Damping d per step of h as the same decay per step of h / n.
dReal finerDamping(dReal d, int n) {
  return d > 0 ? 1 - std::pow(1 - d, 1.0 / n) : d;
}

// While it lives, every body of a world damps per step of h / n as it
// did per step of h (ODE scales velocities by 1 - d per step).
class FinerDamping {
 public:
  FinerDamping(dWorldID w, int n) {
    for (dBodyID b : bodiesOf()[w]) {
      saved_.push_back({b, dBodyGetLinearDamping(b), dBodyGetAngularDamping(b)});
      dBodySetLinearDamping(b, finerDamping(dBodyGetLinearDamping(b), n));
      dBodySetAngularDamping(b, finerDamping(dBodyGetAngularDamping(b), n));
    }
  }
  ~FinerDamping() {
    for (const Saved& s : saved_) {
      dBodySetLinearDamping(s.body, s.linear);
      dBodySetAngularDamping(s.body, s.angular);
    }
  }
  FinerDamping(const FinerDamping&) = delete;
  FinerDamping& operator=(const FinerDamping&) = delete;

 private:
  struct Saved {
    dBodyID body;
    dReal linear, angular;
  };
  std::vector<Saved> saved_;
};

int refinedStep(dWorldID w, dReal h, int n) {
  static const auto directStep = real<Stepper>("dWorldStep");
  struct Forces {
    dBodyID body;
    dVector3 force, torque;
  };
  std::vector<Forces> forces;
  for (dBodyID b : bodiesOf()[w]) {
    Forces& f = forces.emplace_back();
    f.body = b;
    std::memcpy(f.force, dBodyGetForce(b), sizeof f.force);
    std::memcpy(f.torque, dBodyGetTorque(b), sizeof f.torque);
  }
  const FinerDamping damping(w, n);
  int ok = 1;
  for (int k = 0; k < n && ok; ++k) {
    for (std::size_t i = 0; i < forces.size() && k > 0; ++i) {
      const Forces& f = forces[i];
      dBodySetForce(f.body, f.force[0], f.force[1], f.force[2]);
      dBodySetTorque(f.body, f.torque[0], f.torque[1], f.torque[2]);
    }
    ok = directStep(w, h / n);
  }
  return ok;
}

int wholeRefinement() {
  const char* v = std::getenv("BSCOMPAT_WHOLE_REFINE");
  return v ? std::max(1, std::atoi(v)) : 1;
}

void limitContactPushOut(dWorldID w) {
  if (const char* v = std::getenv("BSCOMPAT_RIGID_CONTACTS"))
    dWorldSetContactMaxCorrectingVel(w, static_cast<dReal>(std::strtod(v, nullptr)));
}

// One step of h / n with each body's damping per step converted to the
// same decay over h, and the world's CFM scaled by 1 / n: ODE adds CFM / h
// to each row's K, so CFM / n keeps that regularization the same at the
// finer step (kept as it is, CFM / h grows n-fold: 1 at h / 1000 for the
// default 1e-5, as large as a light body's K). On demo_cylvssphere it
// moved the h / 1000 answer 2 mm of 14.5 m.
int finerStep(Stepper stepper, dWorldID w, dReal h, int n) {
  const dReal cfm = dWorldGetCFM(w);
  dWorldSetCFM(w, cfm / n);
  int ok = 0;
  {
    const FinerDamping damping(w, n);
    ok = stepper(w, h / n);
  }
  dWorldSetCFM(w, cfm);
  return ok;
}

// Per geom without a body the program places (under
// BSCOMPAT_WHOLE_REFINE): where it was before the first time, and every
// position asked for since.
std::map<dGeomID, std::vector<std::array<dReal, 3>>>& askedPositions() {
  static std::map<dGeomID, std::vector<std::array<dReal, 3>>> asked;
  return asked;
}

// A geom placed once before the first step and not again before the
// second was set up, not moved: it goes where it was asked to (the first
// step of h / n saw it 1 / n of the way there).
void placeSetUpGeoms() {
  static long steps = 0;
  if (++steps != 2) return;
  auto& asked = askedPositions();
  for (auto it = asked.begin(); it != asked.end();) {
    if (it->second.size() != 2) {
      ++it;
      continue;
    }
    const std::array<dReal, 3>& p = it->second.back();
    static const auto set = real<void (*)(dGeomID, dReal, dReal, dReal)>("dGeomSetPosition");
    set(it->first, p[0], p[1], p[2]);
    it = asked.erase(it);
  }
}

int step(dWorldID w, dReal h, const char* name) {
  placeSetUpGeoms();
  limitContactPushOut(w);
  const int n = refinement();
  if (n > 1) return refinedStep(w, scaled(h), n);
  static const auto quick = real<Stepper>("dWorldQuickStep");
  static const auto direct = real<Stepper>("dWorldStep");
  const Stepper stepper = std::strcmp(name, "dWorldStep") == 0 ? direct : quick;
  const int whole = wholeRefinement();
  if (whole > 1) return finerStep(stepper, w, scaled(h), whole);
  return stepper(w, scaled(h));
}

bool rngSplit() {
  const char* v = std::getenv("BSCOMPAT_RNG");
  return v && std::strcmp(v, "split") == 0;
}

// Where libode's code lies (found once: quickstep draws thousands of
// times per step).
struct CodeRange {
  std::uintptr_t begin = 0, end = 0;
};

CodeRange odeCode() {
  static const CodeRange range = [] {
    Dl_info info{};
    dladdr(reinterpret_cast<void*>(real<unsigned long (*)()>("dRand")), &info);
    CodeRange r;
    r.begin = reinterpret_cast<std::uintptr_t>(info.dli_fbase);
    dl_iterate_phdr(
        [](dl_phdr_info* object, std::size_t, void* data) {
          auto* found = static_cast<CodeRange*>(data);
          if (object->dlpi_addr != found->begin) return 0;
          for (int i = 0; i < object->dlpi_phnum; ++i) {
            const ElfW(Phdr)& segment = object->dlpi_phdr[i];
            if (segment.p_type == PT_LOAD)
              found->end = std::max<std::uintptr_t>(
                  found->end, object->dlpi_addr + segment.p_vaddr + segment.p_memsz);
          }
          return 1;
        },
        &r);
    return r;
  }();
  return range;
}

bool calledFromOde(const void* returnAddress) {
  const auto a = reinterpret_cast<std::uintptr_t>(returnAddress);
  const CodeRange r = odeCode();
  return a >= r.begin && a < r.end;
}

thread_local int drawDepth = 0;  // > 0 inside a draw (dRandReal calls dRand)
unsigned long odeSeed = 0;       // ODE's own stream

template <typename Result, typename... Args>
Result draw(Result (*realDraw)(Args...), const void* caller, Args... args) {
  ++drawDepth;
  if (drawDepth > 1 || !rngSplit() || !calledFromOde(caller)) {
    const Result r = realDraw(args...);
    --drawDepth;
    return r;
  }
  const unsigned long programSeed = dRandGetSeed();
  dRandSetSeed(odeSeed);
  const Result r = realDraw(args...);
  odeSeed = dRandGetSeed();
  dRandSetSeed(programSeed);
  --drawDepth;
  return r;
}

}  // namespace

extern "C" unsigned long dRand() {
  static const auto f = real<unsigned long (*)()>("dRand");
  return draw(f, __builtin_return_address(0));
}

extern "C" int dRandInt(int n) {
  static const auto f = real<int (*)(int)>("dRandInt");
  return draw(f, __builtin_return_address(0), n);
}

extern "C" dReal dRandReal() {
  static const auto f = real<dReal (*)()>("dRandReal");
  return draw(f, __builtin_return_address(0));
}

extern "C" dBodyID dBodyCreate(dWorldID w) {
  static const auto create = real<dBodyID (*)(dWorldID)>("dBodyCreate");
  dBodyID b = create(w);
  bodiesOf()[w].insert(b);
  return b;
}

extern "C" void dBodyDestroy(dBodyID b) {
  static const auto destroy = real<void (*)(dBodyID)>("dBodyDestroy");
  bodiesOf()[dBodyGetWorld(b)].erase(b);
  destroy(b);
}

extern "C" void dWorldDestroy(dWorldID w) {
  static const auto destroy = real<void (*)(dWorldID)>("dWorldDestroy");
  destroy(w);
  bodiesOf().erase(w);
}

// Under BSCOMPAT_WHOLE_REFINE a contact's own CFM is scaled as the
// world's is (see finerStep).
extern "C" dJointID dJointCreateContact(dWorldID w, dJointGroupID g, const dContact* c) {
  static const auto create =
      real<dJointID (*)(dWorldID, dJointGroupID, const dContact*)>("dJointCreateContact");
  const int n = wholeRefinement();
  if (n == 1 || !(c->surface.mode & dContactSoftCFM)) return create(w, g, c);
  dContact finer = *c;
  finer.surface.soft_cfm /= n;
  return create(w, g, &finer);
}

// Under BSCOMPAT_WHOLE_REFINE a geom without a body that the program
// places each step moves at the pace of the finer steps (see the top).
extern "C" void dGeomSetPosition(dGeomID g, dReal x, dReal y, dReal z) {
  static const auto set = real<void (*)(dGeomID, dReal, dReal, dReal)>("dGeomSetPosition");
  const int n = wholeRefinement();
  if (n == 1 || dGeomGetBody(g) || calledFromOde(__builtin_return_address(0)))
    return set(g, x, y, z);
  std::vector<std::array<dReal, 3>>& history = askedPositions()[g];
  if (history.empty()) {
    const dReal* p = dGeomGetPosition(g);
    history.push_back({p[0], p[1], p[2]});
  }
  history.push_back({x, y, z});
  const std::size_t call = history.size() - 1;
  const std::size_t before = call / n;
  const dReal t = dReal(call % n) / n;
  const std::array<dReal, 3>& a = history[before];
  const std::array<dReal, 3>& b = history[std::min(before + 1, call)];
  set(g, a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]));
}

// A body the program places while it moves one geom without a body is
// placed as far from where the program asked as that geom is: demo_motion
// drops its objects above where its clock says the lift is, n times
// further on than the lift is under BSCOMPAT_WHOLE_REFINE.
extern "C" void dBodySetPosition(dBodyID b, dReal x, dReal y, dReal z) {
  static const auto set = real<void (*)(dBodyID, dReal, dReal, dReal)>("dBodySetPosition");
  const auto& moved = askedPositions();
  if (wholeRefinement() == 1 || moved.size() != 1 || calledFromOde(__builtin_return_address(0)))
    return set(b, x, y, z);
  const dReal* at = dGeomGetPosition(moved.begin()->first);
  const std::array<dReal, 3>& asked = moved.begin()->second.back();
  set(b, x + at[0] - asked[0], y + at[1] - asked[1], z + at[2] - asked[2]);
}

extern "C" int dWorldQuickStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldStep" : "dWorldQuickStep");
}

extern "C" int dWorldStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldQuickStep" : "dWorldStep");
}

// State shared by the plugin's C API (api.cpp) and its interposed ODE
// entry points (interpose.cpp): the real ODE functions, what the
// BLOCKSTEP_* variables asked for, and one-time messages.
#pragma once

#include <ode/ode.h>

#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>
#include <exception>

#include "adapters/ode/world_bridge.h"
#include "core/constraints/joint.h"

namespace blockstep::plugin {

using blockstep::JointState;

// The next definition of `name` after this library: ODE's own.
template <class F>
F realOde(const char* name) {
  void* f = dlsym(RTLD_NEXT, name);
  if (!f) {
    std::fprintf(stderr,
                 "blockstep: cannot find ODE's %s after libblockstep_ode.so (link -lblockstep_ode "
                 "before -lode, or preload it); stopping\n",
                 name);
    std::abort();
  }
  return reinterpret_cast<F>(f);
}

// Declares and caches the real ODE function `name`.
#define BLOCKSTEP_REAL(name) \
  static const auto real_##name = ::blockstep::plugin::realOde<decltype(&::name)>(#name)

// The core's colliders in ODE (colliders.cpp): ODE's dInitODE and
// dCloseODE tell them when ODE's collider table is ready or gone.
void collidersAfterInit();
void collidersBeforeClose();
void setCollidersFromEnvironment(bool on);

struct Replace {
  bool quickStep = false;
  bool step = false;
};
Replace& replace();
bool quiet();

// Steps w with blockstep; for content blockstep cannot model, with
// `fallback` (ODE's own stepper). Returns ODE's convention: 1 stepped, 0 not.
// `stepper` is the ODE stepper the program called (it chooses the solver
// while the world follows ODE's settings).
int blockStep(dWorldID w, dReal h, int (*fallback)(dWorldID, dReal),
              ode::OdeStepper stepper = ode::OdeStepper::QuickStep);

// The core joint state of j when blockstep stepped its world last, else
// nullptr (ODE's own joint state is then the current one).
const JointState* steppedJointState(dJointID j);

// Prints "blockstep: <text>" on stderr unless BLOCKSTEP_QUIET is set.
void say(const char* format, ...) __attribute__((format(printf, 1, 2)));

// No exception may cross the C API (a program would die of it): a failure
// inside, which can only be running out of memory, is said and the call
// does nothing, giving back `failed`.
template <class F>
void guarded(const char* function, F&& f) noexcept {
  try {
    f();
  } catch (const std::exception& e) {
    say("%s: %s; call ignored", function, e.what());
  } catch (...) {
    say("%s: unknown failure; call ignored", function);
  }
}

template <class R, class F>
R guarded(const char* function, R failed, F&& f) noexcept {
  R result = failed;
  guarded(function, [&] { result = f(); });
  return result;
}

}  // namespace blockstep::plugin

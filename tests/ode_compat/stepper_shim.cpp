// A preload for plain-ODE reference runs of ODE's demos: it tells how far
// a demo's end state moves when nothing but the stepper changes, so a
// blockstep run can be judged against ODE's own spread.
//
//   BSCOMPAT_STEPPER=swap      dWorldQuickStep runs dWorldStep and back
//   BSCOMPAT_STEP_SCALE=s      every step size is multiplied by s
//                              (1 +- 1e-9: is the demo chaotic?)
//   BSCOMPAT_SUBSTEPS=k        every step is k steps of h / k, the body
//                              forces held over all of them: ODE's own
//                              answer converged in the step size
//
// The sub-steps read ODE's internal body list (its source is fetched for
// the compatibility suite); nothing here changes what ODE computes.
#include <dlfcn.h>
#include <ode/ode.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "objects.h"

namespace {

using Stepper = int (*)(dWorldID, dReal);

Stepper realStepper(const char* name) {
  const auto s = reinterpret_cast<Stepper>(dlsym(RTLD_NEXT, name));
  if (!s) {
    std::fprintf(stderr, "stepper shim: ODE's %s not found\n", name);
    std::exit(2);
  }
  return s;
}

bool swapped() {
  const char* v = std::getenv("BSCOMPAT_STEPPER");
  return v && std::strcmp(v, "swap") == 0;
}

dReal scaled(dReal h) {
  const char* v = std::getenv("BSCOMPAT_STEP_SCALE");
  return v ? h * static_cast<dReal>(std::strtod(v, nullptr)) : h;
}

int substeps() {
  const char* v = std::getenv("BSCOMPAT_SUBSTEPS");
  const int k = v ? std::atoi(v) : 1;
  return k > 1 ? k : 1;
}

int step(dWorldID w, dReal h, const char* name) {
  const Stepper real = realStepper(name);
  const int k = substeps();
  if (k == 1) return real(w, scaled(h));
  // ODE clears the accumulators after each step: hold them over all k.
  std::vector<dReal> forces;
  for (dxBody* b = w->firstbody; b; b = static_cast<dxBody*>(b->next)) {
    forces.insert(forces.end(), b->facc, b->facc + 3);
    forces.insert(forces.end(), b->tacc, b->tacc + 3);
  }
  int result = 1;
  for (int i = 0; i < k; ++i) {
    std::size_t at = 0;
    for (dxBody* b = w->firstbody; b; b = static_cast<dxBody*>(b->next), at += 6) {
      std::memcpy(b->facc, &forces[at], 3 * sizeof(dReal));
      std::memcpy(b->tacc, &forces[at + 3], 3 * sizeof(dReal));
    }
    result &= real(w, scaled(h) / k);
  }
  return result;
}

}  // namespace

extern "C" int dWorldQuickStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldStep" : "dWorldQuickStep");
}

extern "C" int dWorldStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldQuickStep" : "dWorldStep");
}

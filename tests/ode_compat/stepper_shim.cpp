// A preload for plain-ODE reference runs of ODE's demos: it tells how far
// a demo's end state moves when nothing but the stepper changes, so a
// blockstep run can be judged against ODE's own spread.
//
//   BSCOMPAT_STEPPER=swap      dWorldQuickStep runs dWorldStep and back
//   BSCOMPAT_STEP_SCALE=s      every step size is multiplied by s
//                              (1 +- 1e-9: is the demo chaotic?)
#include <dlfcn.h>
#include <ode/ode.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

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

int step(dWorldID w, dReal h, const char* name) {
  return realStepper(name)(w, scaled(h));
}

}  // namespace

extern "C" int dWorldQuickStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldStep" : "dWorldQuickStep");
}

extern "C" int dWorldStep(dWorldID w, dReal h) {
  return step(w, h, swapped() ? "dWorldQuickStep" : "dWorldStep");
}

// A drawstuff without a window, for running ODE's demo programs in tests.
//
// ODE's demos hand their simulation to dsSimulationLoop, which normally
// opens an X11 window and calls the demo's step function once per frame
// until the user closes it. This implementation runs a scripted number of
// frames with a fixed clock instead, presses scripted keys, and records
// what the last frame drew (the pose of every drawn object), so the same
// demo can be run plain and under blockstep and the end states compared.
//
// Environment (all optional):
//   BSCOMPAT_FRAMES  frames to run (default 600)
//   BSCOMPAT_KEYS    keys to press: "frame:key,frame:key", e.g. "0:a,120:s"
//   BSCOMPAT_POSES   file to write the last frame's drawn poses to
//   BSCOMPAT_STEPS_PER_FRAME  calls of the demo's step function per frame
//                    (default 1). With the stepper shim's step scaled by
//                    the inverse, the whole demo, collision included, runs
//                    at a finer time step: its converged answer.
#include <drawstuff/drawstuff.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

namespace {

// Every demo runs at this frame rate: dsElapsedTime answers it exactly.
constexpr double kFramePeriod = 1.0 / 60.0;
// The fixed clock's reading (ODE's demos seed their random numbers with it).
constexpr std::time_t kFixedTime = 1700000000;

struct DrawnPose {
  const char* kind;
  double size;  // radius, or a box's first side: tells markers from bodies
  double position[3];
  double rotation[9];  // row-major 3x3 (drawstuff's R is 3x4)
};

struct Loop {
  bool stopRequested = false;
  // Demos read the viewpoint back (demo_tracks offsets its contact lines
  // by it): kept as set, starting where drawstuff's window starts.
  float viewXyz[3] = {2.0f, 0.0f, 1.0f};
  float viewHpr[3] = {180.0f, 0.0f, 0.0f};
  std::vector<DrawnPose> frame;
};

Loop& loop() {
  static Loop instance;
  return instance;
}

template <typename Real>
void record(const char* kind, double size, const Real pos[3], const Real R[12]) {
  DrawnPose p{kind, size, {}, {}};
  for (int i = 0; i < 3; ++i)
    p.position[i] = double(pos[i]);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      p.rotation[3 * r + c] = R ? double(R[4 * r + c]) : (r == c);
  loop().frame.push_back(p);
}

template <typename Real>
void recordLine(const Real a[3], const Real b[3]) {
  DrawnPose p{"line", 0.0, {}, {}};
  for (int i = 0; i < 3; ++i) {
    p.position[i] = double(a[i]);
    p.rotation[i] = double(b[i]);  // the second end, in the rotation's first row
  }
  loop().frame.push_back(p);
}

long environmentNumber(const char* name, long fallback) {
  const char* text = std::getenv(name);
  if (!text || !*text) return fallback;
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (*end != '\0' || value < 0) {
    std::fprintf(stderr, "headless drawstuff: %s='%s' is not a whole number\n", name, text);
    std::exit(2);
  }
  return value;
}

struct KeyPress {
  long frame;
  int key;
};

// "frame:key,frame:key"; a key is one character.
std::vector<KeyPress> scriptedKeys() {
  std::vector<KeyPress> keys;
  const char* text = std::getenv("BSCOMPAT_KEYS");
  if (!text) return keys;
  std::string script = text;
  std::size_t at = 0;
  while (at < script.size()) {
    std::size_t comma = script.find(',', at);
    if (comma == std::string::npos) comma = script.size();
    const std::string item = script.substr(at, comma - at);
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos || colon + 2 != item.size() || colon == 0) {
      std::fprintf(stderr, "headless drawstuff: BSCOMPAT_KEYS item '%s' is not frame:key\n",
                   item.c_str());
      std::exit(2);
    }
    keys.push_back({std::atol(item.substr(0, colon).c_str()), item[colon + 1]});
    at = comma + 1;
  }
  return keys;
}

void writePoses(const char* path, long frames) {
  FILE* out = std::fopen(path, "w");
  if (!out) {
    std::fprintf(stderr, "headless drawstuff: cannot write %s\n", path);
    std::exit(2);
  }
  std::fprintf(out, "frames %ld objects %zu\n", frames, loop().frame.size());
  for (const DrawnPose& p : loop().frame) {
    std::fprintf(out, "%s %.9g", p.kind, p.size);
    for (double v : p.position)
      std::fprintf(out, " %.17g", v);
    for (double v : p.rotation)
      std::fprintf(out, " %.17g", v);
    std::fprintf(out, "\n");
  }
  std::fclose(out);
}

}  // namespace

// The demos seed their random numbers from the clock: a fixed one makes
// every run of a demo the same.
extern "C" std::time_t time(std::time_t* t) {
  if (t) *t = kFixedTime;
  return kFixedTime;
}

void dsSimulationLoop(int, char**, int, int, dsFunctions* fn) {
  const long frames = environmentNumber("BSCOMPAT_FRAMES", 600);
  const std::vector<KeyPress> keys = scriptedKeys();
  const long stepsPerFrame = std::max(1L, environmentNumber("BSCOMPAT_STEPS_PER_FRAME", 1));
  if (fn->start) fn->start();
  long frame = 0;
  for (; frame < frames && !loop().stopRequested; ++frame) {
    for (const KeyPress& k : keys)
      if (k.frame == frame && fn->command) fn->command(k.key);
    for (long k = 0; k < stepsPerFrame; ++k) {
      loop().frame.clear();
      if (fn->step) fn->step(0);
    }
  }
  if (fn->stop) fn->stop();
  if (const char* path = std::getenv("BSCOMPAT_POSES")) writePoses(path, frame);
}

void dsError(const char* msg, ...) {
  va_list args;
  va_start(args, msg);
  std::fprintf(stderr, "drawstuff error: ");
  std::vfprintf(stderr, msg, args);
  std::fprintf(stderr, "\n");
  va_end(args);
  std::exit(1);
}

void dsDebug(const char* msg, ...) {
  va_list args;
  va_start(args, msg);
  std::fprintf(stderr, "drawstuff internal error: ");
  std::vfprintf(stderr, msg, args);
  std::fprintf(stderr, "\n");
  va_end(args);
  std::abort();
}

void dsPrint(const char* msg, ...) {
  va_list args;
  va_start(args, msg);
  std::vfprintf(stdout, msg, args);
  va_end(args);
}

void dsSetViewpoint(float xyz[3], float hpr[3]) {
  for (int i = 0; i < 3; ++i) {
    if (xyz) loop().viewXyz[i] = xyz[i];
    if (hpr) loop().viewHpr[i] = hpr[i];
  }
}
void dsGetViewpoint(float xyz[3], float hpr[3]) {
  for (int i = 0; i < 3; ++i) {
    if (xyz) xyz[i] = loop().viewXyz[i];
    if (hpr) hpr[i] = loop().viewHpr[i];
  }
}
void dsStop() {
  loop().stopRequested = true;
}
double dsElapsedTime() {
  return kFramePeriod;
}
void dsSetTexture(int) {}
void dsSetColor(float, float, float) {}
void dsSetColorAlpha(float, float, float, float) {}
void dsSetSphereQuality(int) {}
void dsSetCapsuleQuality(int) {}
void dsSetDrawMode(int) {}

void dsDrawBox(const float pos[3], const float R[12], const float* sides) {
  record("box", sides[0], pos, R);
}
void dsDrawSphere(const float pos[3], const float R[12], float radius) {
  record("sphere", radius, pos, R);
}
void dsDrawTriangle(const float pos[3], const float R[12], const float*, const float*, const float*,
                    int) {
  record("triangle", 0.0, pos, R);
}
void dsDrawTriangles(const float pos[3], const float R[12], const float*, int, int) {
  record("triangles", 0.0, pos, R);
}
void dsDrawCylinder(const float pos[3], const float R[12], float, float radius) {
  record("cylinder", radius, pos, R);
}
void dsDrawCapsule(const float pos[3], const float R[12], float, float radius) {
  record("capsule", radius, pos, R);
}
void dsDrawLine(const float a[3], const float b[3]) {
  recordLine(a, b);
}
void dsDrawConvex(const float pos[3], const float R[12], const float*, unsigned int, const float*,
                  unsigned int, const unsigned int*) {
  record("convex", 0.0, pos, R);
}

void dsDrawBoxD(const double pos[3], const double R[12], const double* sides) {
  record("box", sides[0], pos, R);
}
void dsDrawSphereD(const double pos[3], const double R[12], float radius) {
  record("sphere", radius, pos, R);
}
void dsDrawTriangleD(const double pos[3], const double R[12], const double*, const double*,
                     const double*, int) {
  record("triangle", 0.0, pos, R);
}
void dsDrawTrianglesD(const double pos[3], const double R[12], const double*, int, int) {
  record("triangles", 0.0, pos, R);
}
void dsDrawCylinderD(const double pos[3], const double R[12], float, float radius) {
  record("cylinder", radius, pos, R);
}
void dsDrawCapsuleD(const double pos[3], const double R[12], float, float radius) {
  record("capsule", radius, pos, R);
}
void dsDrawLineD(const double a[3], const double b[3]) {
  recordLine(a, b);
}
void dsDrawConvexD(const double pos[3], const double R[12], const double*, unsigned int,
                   const double*, unsigned int, const unsigned int*) {
  record("convex", 0.0, pos, R);
}

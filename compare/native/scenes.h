// The benchmark scenes of ../shared/SCENES.md built with the native core
// API (no ODE, no collision yet), shared by tests, benchmarks and the demo.
// Where a scene needs collision (ragdoll on the ground, cloth on the cube)
// it runs without it until the collision module exists; the softcube hangs
// from one corner instead of landing.
#pragma once

#include <string>
#include <vector>

#include "core/world/world.h"

namespace blockstep::scenes {

struct Scene {
  std::string name;
  World world;
  std::vector<JointId> joints;
  int frames = 300;  // 5 s at 60 Hz
  double frameStep = 1.0 / 60.0;
  BodyId tracked = kWorldBody;  // the body whose drift is measured (the top box)
  Vec3 trackedStart = Vec3::Zero();
};

// Names accepted by makeScene, in SCENES.md order.
const std::vector<std::string>& sceneNames();
// Throws blockstep::Error for an unknown name.
void makeScene(const std::string& name, Scene& scene);

void ragdoll(Scene& s);
void chain(Scene& s, bool swing);          // 50 links, last one 100x heavier
void cloth(Scene& s, int n);               // n x n cells, two corner pins
void softcube(Scene& s, bool ballJoints);  // 5x5x5 cells, 300 joints, one corner pinned
void stack(Scene& s);                      // 10 boxes of 0.5 m on the ground
void pyramid(Scene& s, int base);          // base boxes at the bottom, 0.525 m apart

struct Quality {
  double maxSeparation = 0.0;  // m, worst joint anchor distance (and limit violation)
  double maxAngle = 0.0;       // rad, worst angular error of hinge/fixed rows
  double drift = 0.0;          // m, how far the tracked body is from its start
  double penetration = 0.0;    // m, deepest contact of the last step
};
Quality measure(const Scene& s);

}  // namespace blockstep::scenes

// A load landing on a light box (the pile's 0.73 kg hull under a 2 kg
// body carrying 9.8 kg), shared by the contact tests and the allocation
// test: the world colliding every sub-step on the drop-in's contact
// spring, and the landing, which can be put back to land again.
#pragma once

#include <utility>

#include "core/world/world.h"
#include "support/test_world.h"

namespace blockstep::test {

// The world's settings, its own collision every sub-step, contacts with
// the drop-in's spring (omega h = 0.4 a sub-step), and the ground.
inline void collidingEverySubstepOnSprings(World& world, const SolverSettings& settings) {
  world.setSettings(settings);
  world.collisionSettings().everySubstep = true;
  world.collisionSettings().surface.softness = Softness::stepSpring(0.4, 2.0);
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
}

// A 2 kg box carrying a 10 kg one, 2 mm above a 0.73 kg box resting on the
// ground beside a 0.5 kg box, falling at 2.2 m/s: 20 contact points once
// landed. Bodies in the order light, side, carrier, load.
struct LandingOnALightBox {
  BodyId light = -1, side = -1, carrier = -1, load = -1;
};

// Where each of the landing's bodies starts, and how fast.
inline void placeLanding(World& world, const LandingOnALightBox& l) {
  const Vec3 lightHalf(0.06, 0.06, 0.05), half(0.1, 0.1, 0.1);
  const double base = 2 * lightHalf.z() + 0.002;
  const std::pair<BodyId, Vec3> starts[] = {
      {l.light, Vec3(0, 0, lightHalf.z())},
      {l.side, Vec3(2 * lightHalf.x() + 0.001, 0, lightHalf.z())},
      {l.carrier, Vec3(0.01, 0, base + half.z())},
      {l.load, Vec3(0.01, 0, base + 3 * half.z())}};
  for (const auto& [id, position] : starts) {
    world.setPosition(id, position);
    world.setOrientation(id, Quat::Identity());
    world.setAngularVelocity(id, Vec3::Zero());
    const bool falling = id == l.carrier || id == l.load;
    world.setLinearVelocity(id, Vec3(0, 0, falling ? -2.2 : 0.0));
  }
}

inline LandingOnALightBox landingOnALightBox(World& world) {
  const Vec3 lightHalf(0.06, 0.06, 0.05), half(0.1, 0.1, 0.1);
  LandingOnALightBox l;
  auto box = [&](double mass, const Vec3& h) {
    const BodyId id = world.createBody(boxBody(Vec3::Zero(), mass, 2.0 * h));
    world.addShape(Shape::box(id, h));
    return id;
  };
  l.light = box(0.73, lightHalf);
  l.side = box(0.5, lightHalf);
  l.carrier = box(2.0, half);
  l.load = box(10.0, half);
  placeLanding(world, l);
  return l;
}

}  // namespace blockstep::test

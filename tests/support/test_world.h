// Small helpers the core tests share: bodies from shapes, stepping.
#pragma once

#include <gtest/gtest.h>

#include "core/body/mass.h"
#include "core/world/world.h"

namespace blockstep::test {

inline BodyDesc boxBody(const Vec3& position, double mass, const Vec3& sides) {
  BodyDesc d;
  d.position = position;
  const MassProperties m = boxMass(mass, sides);
  d.mass = m.mass;
  d.inertia = m.inertia;
  return d;
}

inline BodyDesc sphereBody(const Vec3& position, double mass, double radius) {
  BodyDesc d;
  d.position = position;
  const MassProperties m = sphereMass(mass, radius);
  d.mass = m.mass;
  d.inertia = m.inertia;
  return d;
}

// A box body of the given half extents with its box shape.
inline BodyId addBoxBody(World& world, const Vec3& position, double mass, const Vec3& half) {
  const BodyId id = world.createBody(boxBody(position, mass, 2.0 * half));
  world.addShape(Shape::box(id, half));
  return id;
}

// The compare runner's plank_load, natively, without its load: the ground
// plane, two static supports (0.2 x 0.4 x 0.5 m at x = -0.8 and 0.8) and
// a 1 kg plank (2 x 0.3 x 0.05 m) across them, all exactly touching.
// Returns the plank; a load on it rests at z = 0.55 + its half height.
inline BodyId plankOnTwoSupports(World& world) {
  world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  for (double x : {-0.8, 0.8}) {
    Shape support = Shape::box(kWorldBody, Vec3(0.1, 0.2, 0.25));
    support.localPosition = Vec3(x, 0.0, 0.25);
    world.addShape(support);
  }
  return addBoxBody(world, Vec3(0, 0, 0.525), 1.0, Vec3(1.0, 0.15, 0.025));
}

// A hinge between the world and body b, anchored at the origin.
inline JointId hingeToWorld(World& world, BodyId b, const Vec3& axis, const Limit& limit = {},
                            const Motor& motor = {}) {
  HingeJointDesc h;
  h.common.bodyB = b;
  h.anchor = Vec3::Zero();
  h.axis = axis;
  h.limit = limit;
  h.motor = motor;
  return world.createJoint(h);
}

inline void stepN(World& world, int n, double h) {
  for (int i = 0; i < n; ++i)
    world.step(h);
}

inline double kineticEnergy(const Body& b) {
  const Mat3 R = b.orientation.toRotationMatrix();
  const Vec3 wb = R.transpose() * b.angularVelocity;
  return 0.5 * b.mass * b.linearVelocity.squaredNorm() + 0.5 * wb.dot(b.inertiaBody * wb);
}

// Kinetic plus potential energy in the world's gravity of the bodies
// 0 .. n-1 (all dynamic), J.
inline double mechanicalEnergy(const World& world, int n) {
  double e = 0.0;
  for (BodyId b = 0; b < n; ++b) {
    const Body& body = world.body(b);
    e += test::kineticEnergy(body) - body.mass * world.gravity().dot(body.position);
  }
  return e;
}

inline Vec3 angularMomentum(const Body& b) {
  const Mat3 R = b.orientation.toRotationMatrix();
  return R * b.inertiaBody * R.transpose() * b.angularVelocity;
}

}  // namespace blockstep::test

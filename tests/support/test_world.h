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

inline Vec3 angularMomentum(const Body& b) {
  const Mat3 R = b.orientation.toRotationMatrix();
  return R * b.inertiaBody * R.transpose() * b.angularVelocity;
}

}  // namespace blockstep::test

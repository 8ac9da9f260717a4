// Two islands that take different sub-step counts under the sub-stepped
// preset (10 nominal, 0.1 rad a sub-step at most): a box circling a hinge
// 5 cm beside its centre at 150 rad/s, driven at that speed (sub-steps
// lose some of a circling body's energy), asks for 25 a step; a pendulum
// swinging slowly takes 10.
#pragma once

#include "core/world/world.h"
#include "support/test_world.h"

namespace blockstep::test {

inline BodyId circlingBox(World& world) {
  const BodyId box = world.createBody(boxBody(Vec3(0, 0, 0), 1.0, Vec3(0.4, 0.2, 0.1)));
  HingeJointDesc hinge;
  hinge.common.bodyB = box;
  hinge.anchor = Vec3(0.05, 0, 0);
  hinge.axis = Vec3::UnitZ();
  hinge.motor.targetVelocity = 150.0;
  hinge.motor.maxForce = 1e4;
  world.createJoint(hinge);
  world.setAngularVelocity(box, Vec3(0, 0, 150));
  world.setLinearVelocity(box, Vec3(0, 0, 150).cross(Vec3(-0.05, 0, 0)));
  return box;
}

inline BodyId slowPendulum(World& world) {
  const BodyId bob = world.createBody(sphereBody(Vec3(0.5, 3, -0.8), 1.0, 0.05));
  BallJointDesc joint;
  joint.common.bodyB = bob;
  joint.anchor = Vec3(0, 3, 0);
  world.createJoint(joint);
  return bob;
}

}  // namespace blockstep::test

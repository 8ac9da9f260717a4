// Collision shapes attached to bodies. This is the contact generation the
// solver's tests need (sphere, box, plane; box-box by SAT with face
// clipping); the collision module generalizes it (capsules, convex
// polyhedra through GJK/EPA, compounds, a broadphase for large scenes).
#pragma once

#include <cstdint>

#include "core/body/body.h"

namespace blockstep {

using ShapeId = std::int32_t;

struct Shape {
  enum class Kind : std::uint8_t { Sphere, Box, Plane };
  Kind kind = Kind::Sphere;
  BodyId body = kWorldBody;           // planes belong to the world
  Vec3 localPosition = Vec3::Zero();  // in the body's frame
  Quat localOrientation = Quat::Identity();
  double radius = 0.0;               // sphere
  Vec3 halfExtents = Vec3::Zero();   // box
  Vec3 planeNormal = Vec3::UnitZ();  // plane: points x with normal.x <= offset are inside
  double planeOffset = 0.0;
  double friction = 0.6;
  double restitution = 0.0;
  bool alive = true;

  static Shape sphere(BodyId body, double radius) {
    Shape s;
    s.kind = Kind::Sphere;
    s.body = body;
    s.radius = radius;
    return s;
  }
  static Shape box(BodyId body, const Vec3& halfExtents) {
    Shape s;
    s.kind = Kind::Box;
    s.body = body;
    s.halfExtents = halfExtents;
    return s;
  }
  static Shape plane(const Vec3& normal, double offset) {
    Shape s;
    s.kind = Kind::Plane;
    s.planeNormal = normal;
    s.planeOffset = offset;
    return s;
  }
};

// A shape placed in the world for one step.
struct ShapePose {
  Vec3 position;
  Mat3 rotation;  // columns: the shape's axes in the world
};

}  // namespace blockstep

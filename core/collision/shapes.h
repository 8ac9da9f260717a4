// Collision shapes attached to bodies (the paper's section 5): spheres,
// capsules, cylinders, boxes and convex hulls on bodies, planes on the
// world. A body may carry several shapes (a compound approximating a
// concave body). Capsules and cylinders lie along their local z axis, as
// in ODE.
#pragma once

#include <cstdint>
#include <memory>

#include "core/body/body.h"
#include "core/collision/convex_hull.h"

namespace blockstep {

using ShapeId = std::int32_t;

struct Shape {
  enum class Kind : std::uint8_t { Sphere, Capsule, Cylinder, Box, Convex, Plane };
  Kind kind = Kind::Sphere;
  BodyId body = kWorldBody;           // planes belong to the world
  Vec3 localPosition = Vec3::Zero();  // in the body's frame
  Quat localOrientation = Quat::Identity();
  double radius = 0.0;                     // sphere, capsule, cylinder
  double halfLength = 0.0;                 // capsule (its segment) and cylinder, along local z
  Vec3 halfExtents = Vec3::Zero();         // box
  std::shared_ptr<const ConvexHull> hull;  // convex: shared by the shapes made from it
  Vec3 planeNormal = Vec3::UnitZ();        // plane: points x with normal.x <= offset are inside
  double planeOffset = 0.0;
  double friction = 0.6;
  double restitution = 0.0;
  // Collision filter, ODE's rule: two shapes collide when the category of
  // either has a bit in the other's collide mask.
  std::uint64_t categoryBits = ~std::uint64_t{0};
  std::uint64_t collideBits = ~std::uint64_t{0};
  bool alive = true;

  static Shape sphere(BodyId body, double radius) {
    Shape s;
    s.kind = Kind::Sphere;
    s.body = body;
    s.radius = radius;
    return s;
  }
  // `length` is the cylinder part, without the caps (ODE's convention).
  static Shape capsule(BodyId body, double radius, double length) {
    return alongZ(Kind::Capsule, body, radius, length);
  }
  static Shape cylinder(BodyId body, double radius, double length) {
    return alongZ(Kind::Cylinder, body, radius, length);
  }
  static Shape convex(BodyId body, std::shared_ptr<const ConvexHull> hull) {
    Shape s;
    s.kind = Kind::Convex;
    s.body = body;
    s.hull = std::move(hull);
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

 private:
  static Shape alongZ(Kind kind, BodyId body, double radius, double length) {
    Shape s;
    s.kind = kind;
    s.body = body;
    s.radius = radius;
    s.halfLength = 0.5 * length;
    return s;
  }
};

// A shape placed in the world for one step.
struct ShapePose {
  Vec3 position;
  Mat3 rotation;  // columns: the shape's axes in the world
};

}  // namespace blockstep

// Mass properties of the primitive shapes (uniform density), about the
// centre of mass in the shape's own frame. Convex polyhedra come with the
// collision module.
#pragma once

#include "core/math/math.h"

namespace blockstep {

struct MassProperties {
  double mass = 0.0;
  Mat3 inertia = Mat3::Zero();
};

// Solid box with full side lengths `sides`.
MassProperties boxMass(double mass, const Vec3& sides);
// Solid sphere.
MassProperties sphereMass(double mass, double radius);
// Solid capsule along the z axis (ODE's convention): `length` is the
// cylinder part, without the caps.
MassProperties capsuleMass(double mass, double radius, double length);
// Solid cylinder along the z axis.
MassProperties cylinderMass(double mass, double radius, double length);

}  // namespace blockstep

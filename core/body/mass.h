// Mass properties of the primitive shapes (uniform density), about the
// centre of mass in the shape's own frame, and of compound bodies. Convex
// hulls have theirs beside the hull (collision/convex_hull.h).
#pragma once

#include <vector>

#include "core/math/math.h"

namespace blockstep {

struct MassProperties {
  double mass = 0.0;
  Mat3 inertia = Mat3::Zero();  // about the centre of mass, in the shape's axes
  Vec3 centre = Vec3::Zero();   // centre of mass in the shape's frame (primitives: 0)
};

// One part of a compound body: its mass properties and where its frame
// sits in the body's frame.
struct MassPart {
  MassProperties mass;
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
};

// The whole of several parts (the paper's compound bodies, section 5):
// masses add, the centre is the mass-weighted mean, and each part's
// inertia is turned into the body's axes (R I R^T) and moved to the common
// centre by the parallel-axis theorem, I + m (|d|^2 1 - d d^T). The body's
// origin should then be put at `centre` (shift the parts by -centre).
MassProperties combineMass(const std::vector<MassPart>& parts);

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

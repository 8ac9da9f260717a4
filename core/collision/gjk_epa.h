// Distance and penetration between two convex cores (section 5.1).
// GJK gives the distance of separated cores; where they overlap, EPA gives
// the penetration depth and direction, through libccd (the library ODE's
// own convex collider uses). The radii of spheres and capsules are added
// by the caller.
#pragma once

#include "core/collision/support.h"

namespace blockstep {

struct CoreDistance {
  bool overlapping = false;  // the cores touch or overlap: ask penetration()
  double distance = 0.0;
  Vec3 pointA = Vec3::Zero(), pointB = Vec3::Zero();  // closest points of the cores
  int iterations = 0;
};

// GJK (Gilbert, Johnson and Keerthi) on the Minkowski difference A - B,
// with the closest point of each simplex found by its Voronoi regions.
// Exact after finitely many steps for polytope cores (points, segments,
// boxes, hulls); to a relative 1e-12 for cylinders.
CoreDistance coreDistance(const PosedConvex& a, const PosedConvex& b);

struct CorePenetration {
  bool found = false;
  double depth = 0.0;            // how far B must move along normal to separate
  Vec3 normal = Vec3::UnitZ();   // unit, from A toward B
  Vec3 position = Vec3::Zero();  // midway between the cores' deepest points
};

// EPA (expanding polytope) through libccd's ccdGJKPenetration, its answer
// checked against the overlap along the line of centres and the cores'
// face normals (the least of them wins: libccd can end on a far face).
// Where libccd sees no overlap it can expand (cores merely touching, or
// overlapping flat, as crossing segments do), the search starts from the
// line of centres. `found` is false only for a non-finite answer.
CorePenetration corePenetration(const PosedConvex& a, const PosedConvex& b);

}  // namespace blockstep

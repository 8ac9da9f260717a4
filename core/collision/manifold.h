// Building contact manifolds (up to four points): the parts every
// narrow-phase path shares.
#pragma once

#include <cstdint>

#include "core/collision/support.h"
#include "core/constraints/contact.h"

namespace blockstep {

// Appends a point given on A's surface, placed midway between the two
// surfaces along the manifold's normal.
void addManifoldPoint(ContactManifold& m, const Vec3& surfacePointA, double separation,
                      std::uint32_t feature);

// Keeps at most four of n candidate points: the deepest, the one farthest
// from it, the one spanning the largest triangle with those two, and the
// one adding most area (largest quad). Writes their indices to `keep`.
int reduceToFour(const Vec3* pos, const double* sep, int n, int* keep);

// Adds the (at most four, by reduceToFour) points of n candidates given
// on A's surface, without feature ids. Returns how many were added.
int addReducedPoints(ContactManifold& m, const Vec3* pos, const double* sep, int n);

// The manifold of two convex shapes touching along the unit normal `n`
// (from A toward B): the features of A along n and of B along -n; the face
// more along n is the reference, the other feature is clipped to the
// reference's sides, and each clipped point's separation is measured along
// n to the reference's plane. Points farther than `margin` are dropped.
// Returns 0, leaving the single deepest point to the caller, when a
// feature is a point or both are far from the normal (edge against edge).
int clipFeatures(const PosedConvex& a, const PosedConvex& b, const Vec3& n, double margin,
                 ContactManifold& m);

}  // namespace blockstep

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

// A contact point's feature id from the features and lines it lies on,
// packed into `x`: mixed into 32 bits, never 0 (which means "no id"). Two
// points of one pair sharing an id by chance would only share their
// warm-start impulse.
std::uint32_t mixedFeatureId(std::uint64_t x);

// Keeps at most four of n candidate points: the deepest (the outermost of
// those as deep), the one farthest from it, the one spanning the largest
// triangle with those two, and the one adding most area to that triangle
// (none when all lie within it). Writes their indices to `keep`.
int reduceToFour(const Vec3* pos, const double* sep, int n, int* keep);

// Adds the (at most four, by reduceToFour) points of n candidates given
// on A's surface, with their feature ids. Returns how many were added.
int addReducedPoints(ContactManifold& m, const Vec3* pos, const double* sep,
                     const std::uint32_t* ids, int n);

// The manifold of two convex shapes touching along the unit normal `n`
// (from A toward B): the features of A along n and of B along -n; the face
// more along n is the reference, the other feature is clipped to the
// reference's sides, and each clipped point's separation is measured along
// n to the reference's plane. Points farther than `margin` are dropped.
// Each point's feature id names the two features and the incident edge or
// side plane it was cut from, so it is the same id while the same corner
// of the overlap touches.
// Returns 0, leaving the single deepest point to the caller, when a
// feature is a point or both are far from the normal (edge against edge).
int clipFeatures(const PosedConvex& a, const PosedConvex& b, const Vec3& n, double margin,
                 ContactManifold& m);

}  // namespace blockstep

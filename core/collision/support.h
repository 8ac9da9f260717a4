// Convex shapes as GJK and EPA see them (the paper's section 5.1): a
// support mapping, the point of the shape farthest along a direction. A
// sphere and a capsule are a core (a point, a segment) grown by a radius,
// so the distance algorithms work on the core, where they end exactly, and
// add the radius afterwards. The supporting feature (the face, edge or
// point that touches along a normal) is what the contact manifold clips.
#pragma once

#include <cstdint>

#include "core/collision/shapes.h"

namespace blockstep {

// Most vertices a supporting feature keeps; a hull face with more touches
// at its support point only.
inline constexpr int kMaxFeaturePoints = 64;

// A face touches along a normal only within about 25 degrees of it (the
// cosine): past that the contact is the face's edge (or vertex), and a
// point projected along the normal onto the face's plane may land beyond
// it. The manifold clips against a reference face only this close.
inline constexpr double kFaceContactCos = 0.9;

struct PosedConvex {
  const Shape* shape = nullptr;
  ShapePose pose;
  double radius = 0.0;  // sphere and capsule: their radius around the core

  PosedConvex(const Shape& s, const ShapePose& p);
  // The core's point farthest along `direction` (world; need not be unit).
  Vec3 coreSupport(const Vec3& direction) const;
  // Largest distance of the core from the pose's position.
  double coreRadius() const;
};

// The shape's feature farthest along the unit `direction` (world): a
// face's vertex loop (counter-clockwise seen along `direction`), an edge
// (two points) or one point, on the shape's surface (radius included).
// A face comes with its outward normal; an edge or a point with a zero
// normal. Whatever the feature, it holds the shape's support point
// along `direction`, so one point of it is exact. `id` names the feature
// on its shape (which face, edge or vertex, and the order of its points),
// so that contact points clipped from it can be told apart and followed
// from step to step (warm starting).
struct Feature {
  Vec3 points[kMaxFeaturePoints];
  int count = 0;
  Vec3 normal = Vec3::Zero();
  std::uint32_t id = 0;
};
void supportingFeature(const PosedConvex& c, const Vec3& direction, Feature& out);

// Where no face lies within kFaceContactCos of `direction`: the edge the
// shape touches by, when one lies nearly square to it (a box's or hull's
// edge, a capsule's or cylinder's side line), as an edge Feature.
// Returns false where the shape touches by a point only.
bool supportingEdge(const PosedConvex& c, const Vec3& direction, Feature& out);

}  // namespace blockstep

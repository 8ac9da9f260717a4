#include "core/collision/collide.h"

#include <algorithm>
#include <cmath>

#include "core/collision/manifold.h"
#include "core/collision/narrowphase.h"
#include "core/collision/support.h"

namespace blockstep {
namespace {

ShapePose poseOf(const Shape& s, const std::vector<Body>& bodies) {
  if (s.body == kWorldBody)
    return ShapePose{s.localPosition, s.localOrientation.toRotationMatrix()};
  const Body& b = bodies[s.body];
  return ShapePose{b.position + b.orientation * s.localPosition,
                   (b.orientation * s.localOrientation).toRotationMatrix()};
}

double leastReach(const CollisionSettings& settings) {
  return std::max(0.0, std::min(settings.margin, 0.5 * settings.restingMargin));
}

// How fast a point of the shape can move: its body's speed plus its turn
// rate times the shape's farthest point.
double surfaceSpeed(const Body& b, double farthest) {
  return b.linearVelocity.norm() + b.angularVelocity.norm() * farthest;
}

// How far the shape's surface reaches from its body's centre of mass
// (m), whatever the pose. Infinite for a plane.
double farthestPointOf(const Shape& s) {
  const PosedConvex convex(s, ShapePose{Vec3::Zero(), Mat3::Identity()});
  return s.localPosition.norm() + convex.coreRadius() + convex.radius;
}

}  // namespace

double turningGeometrySpeed(const Shape& s, const Quat& bodyOrientation, const Vec3& w) {
  const Vec3 wb = bodyOrientation.conjugate() * w;  // in the body's frame, as the shape is placed
  const Vec3& centre = s.localPosition;
  const Mat3 axes = s.localOrientation.toRotationMatrix();
  auto endsSpeed = [&](double halfLength) {
    const Vec3 along = axes.col(2) * halfLength;
    return std::max(wb.cross(centre + along).norm(), wb.cross(centre - along).norm());
  };
  switch (s.kind) {
    case Shape::Kind::Sphere:
      return wb.cross(centre).norm();
    case Shape::Kind::Capsule:
      return endsSpeed(s.halfLength);
    case Shape::Kind::Cylinder: {
      const Vec3 axis = axes.col(2);
      return endsSpeed(s.halfLength) + (wb - wb.dot(axis) * axis).norm() * s.radius;
    }
    case Shape::Kind::Box: {
      double fastest = 0.0;
      for (int c = 0; c < 8; ++c) {
        const Vec3 corner(c & 1 ? s.halfExtents.x() : -s.halfExtents.x(),
                          c & 2 ? s.halfExtents.y() : -s.halfExtents.y(),
                          c & 4 ? s.halfExtents.z() : -s.halfExtents.z());
        fastest = std::max(fastest, wb.cross(centre + axes * corner).norm());
      }
      return fastest;
    }
    case Shape::Kind::Convex:
      return wb.norm() * farthestPointOf(s);
    case Shape::Kind::Plane:
      return 0.0;
  }
  return 0.0;
}

double surfaceRoundness(Shape::Kind kind, double radius, const Vec3& axis, const Vec3& normal) {
  // A cylinder touches along its side when the normal is within this
  // cosine of square to its axis (lying on the ground, it rolls there).
  constexpr double kSideContact = 1e-3;
  switch (kind) {
    case Shape::Kind::Sphere:
    case Shape::Kind::Capsule:
      return radius;
    case Shape::Kind::Cylinder:
      return std::abs(axis.dot(normal)) < kSideContact ? radius : 0.0;
    default:
      return 0.0;
  }
}

// The exact fast paths (sphere and box against planes, spheres and boxes
// with each other, spheres, capsules and cylinders by their segments where
// their sides meet) come first; every other convex pair goes through
// GJK/EPA and feature clipping.
int collideShapes(const Shape& s1, const ShapePose& p1, const Shape& s2, const ShapePose& p2,
                  double margin, bool boxBoxBySat, ContactManifold& m, bool& swapped) {
  using K = Shape::Kind;
  swapped = false;
  const Shape* a = &s1;
  const Shape* b = &s2;
  const ShapePose* pa = &p1;
  const ShapePose* pb = &p2;
  // Order: plane < box < the rest as the first shape.
  auto rank = [](K k) { return k == K::Plane ? 0 : k == K::Box ? 1 : 2; };
  if (rank(b->kind) < rank(a->kind)) {
    std::swap(a, b);
    std::swap(pa, pb);
    swapped = true;
  }
  if (a->kind == K::Plane) {
    if (b->kind == K::Sphere) return collideSpherePlane(*a, *b, *pb, margin, m);
    if (b->kind == K::Box) return collideBoxPlane(*a, *b, *pb, margin, m);
    if (b->kind == K::Plane) return 0;  // both static
    return collideConvexPlane(*a, *b, *pb, margin, m);
  }
  if (a->kind == K::Box && b->kind == K::Box && boxBoxBySat)
    return collideBoxes(*a, *pa, *b, *pb, margin, m);
  if (a->kind == K::Box && b->kind == K::Sphere)
    return collideBoxSphere(*a, *pa, *b, *pb, margin, m);
  if (a->kind == K::Sphere && b->kind == K::Sphere)
    return collideSpheres(*a, *pa, *b, *pb, margin, m);
  auto round = [](K k) { return k == K::Sphere || k == K::Capsule; };
  if (round(a->kind) && round(b->kind)) return collideRoundSegments(*a, *pa, *b, *pb, margin, m);
  auto sides = [](K k) { return k == K::Capsule || k == K::Cylinder; };
  if (sides(a->kind) && sides(b->kind)) {
    const int n = collideRoundSegments(*a, *pa, *b, *pb, margin, m);
    if (n >= 0) return n;
  }
  return collideConvex(*a, *pa, *b, *pb, margin, m);
}

void Collider::collide(const std::vector<Shape>& shapes, const std::vector<Body>& bodies,
                       const CollisionSettings& settings, const std::vector<std::uint64_t>& jointed,
                       double h, std::vector<ContactManifold>& out) {
  poses_.resize(shapes.size());
  boxes_.resize(shapes.size());
  reach_.resize(shapes.size());
  farthest_.resize(shapes.size());
  const bool solvedSpeeds = solvedSpeed_.size() == shapes.size();
  const double most = settings.margin, least = leastReach(settings);
  // Each shape reaches as far as it may move before the next collision
  // (at the larger of its speed now and the one a retaken part's first
  // solve gave it), plus half the resting margin, within the margin.
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const Shape& s = shapes[i];
    if (s.alive) {
      poses_[i] = poseOf(s, bodies);
      farthest_[i] = farthestPointOf(s);
      reach_[i] = least;  // planes and static world shapes do not move
      if (s.body != kWorldBody) {
        double speed = surfaceSpeed(bodies[s.body], farthest_[i]);
        if (solvedSpeeds) speed = std::max(speed, solvedSpeed_[i]);
        const double motion = speed * h;
        reach_[i] = std::isfinite(motion) ? std::min(most, least + motion) : most;
      }
    }
    boxes_[i] = shapeAabb(s, poses_[i], reach_[i]);
  }
  solvedSpeed_.clear();
  broadPhase_.findPairs(boxes_, settings.broadPhase, pairs_);
  auto movable = [&](BodyId id) { return id != kWorldBody && bodies[id].type != BodyType::Static; };
  for (const auto& [i, j] : pairs_) {
    const Shape& s1 = shapes[i];
    const Shape& s2 = shapes[j];
    if (s1.body == s2.body) continue;
    if (!(s1.categoryBits & s2.collideBits) && !(s2.categoryBits & s1.collideBits)) continue;
    // Only dynamic bodies are pushed: two immovable shapes never collide.
    const bool dyn1 = s1.body != kWorldBody && bodies[s1.body].isDynamic();
    const bool dyn2 = s2.body != kWorldBody && bodies[s2.body].isDynamic();
    if (!dyn1 && !dyn2) continue;
    if (!movable(s1.body) && !movable(s2.body)) continue;
    if (!settings.collideConnected && s1.body != kWorldBody && s2.body != kWorldBody &&
        std::binary_search(jointed.begin(), jointed.end(), bodyPairKey(s1.body, s2.body))) {
      continue;
    }
    ContactManifold m;
    bool swapped = false;
    if (collideShapes(s1, poses_[i], s2, poses_[j],
                      std::min(settings.margin, reach_[i] + reach_[j]), settings.boxBoxBySat, m,
                      swapped) == 0) {
      continue;
    }
    const Shape& a = swapped ? s2 : s1;
    const Shape& b = swapped ? s1 : s2;
    m.bodyA = a.body;
    m.bodyB = b.body;
    const ShapePose& poseA = swapped ? poses_[j] : poses_[i];
    const ShapePose& poseB = swapped ? poses_[i] : poses_[j];
    // A point's feature id names the features of its two shapes; the
    // shape pair goes in too, since the world matches last step's points
    // by body pair: a plank on two static supports (two shape pairs of
    // one body pair, the same box features) handed both supports' warm
    // impulses to one support's points, 41 N s where 20 were due, and its
    // other end to none.
    const auto pair = static_cast<std::uint64_t>(std::min(i, j)) << 32 |
                      static_cast<std::uint64_t>(std::max(i, j));
    for (int k = 0; k < m.pointCount; ++k) {
      ContactPoint& p = m.points[k];
      if (p.feature != 0)
        p.feature = mixedFeatureId(mixedFeatureId(pair) ^ std::uint64_t{p.feature} << 32);
      const Vec3& n = p.normal.isZero() ? m.normal : p.normal;
      p.radiusA = surfaceRoundness(a.kind, a.radius, poseA.rotation.col(2), n);
      p.radiusB = surfaceRoundness(b.kind, b.radius, poseB.rotation.col(2), n);
    }
    m.surface = settings.surface;
    if (settings.surfaceFromShapes) {
      m.surface.mu = std::sqrt(a.friction * b.friction);
      m.surface.mu2 = -1.0;
      m.surface.restitution = std::max(a.restitution, b.restitution);
    }
    out.push_back(m);
  }
}

bool Collider::outranReach(const std::vector<Shape>& shapes, const std::vector<Body>& bodies,
                           const CollisionSettings& settings, double h) {
  if (reach_.size() != shapes.size()) return false;  // not collided yet
  solvedSpeed_.assign(shapes.size(), 0.0);
  bool outran = false;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const Shape& s = shapes[i];
    if (!s.alive || s.body == kWorldBody) continue;
    const Body& b = bodies[s.body];
    if (!b.isDynamic()) continue;
    solvedSpeed_[i] = surfaceSpeed(b, farthest_[i]);
    // A reach at the margin already reaches as far as any part does.
    outran |= reach_[i] < settings.margin && solvedSpeed_[i] * h > reach_[i];
  }
  return outran;
}

}  // namespace blockstep

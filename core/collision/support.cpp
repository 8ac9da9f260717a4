#include "core/collision/support.h"

#include <algorithm>
#include <cmath>

namespace blockstep {
namespace {

// Points of a cylinder's cap: its rim as a regular polygon with one corner
// at the rim's support point. Twelve corners: after reduction to four
// contact points, a cap resting flat keeps a support polygon within 3.4%
// of the disc's radius.
constexpr int kCapCorners = 12;

// A unit vector perpendicular to `axis`, toward `direction` when it has a
// part across the axis.
Vec3 across(const Vec3& axis, const Vec3& direction) {
  Vec3 u = direction - axis.dot(direction) * axis;
  const double len = u.norm();
  if (len > 1e-12) return u / len;
  u = axis.cross(std::abs(axis.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY());
  return u.normalized();
}

// A capsule's or cylinder's axis is closer than this (cosine) to a
// contact normal's perpendicular plane when its whole side touches.
constexpr double kSideTouchCos = 0.2;

// Feature ids: the kind in the top byte, an index below it.
enum FeatureKind : std::uint32_t { kFace = 1u << 24, kEdge = 2u << 24, kVertex = 3u << 24 };

}  // namespace

PosedConvex::PosedConvex(const Shape& s, const ShapePose& p) : shape(&s), pose(p) {
  if (s.kind == Shape::Kind::Sphere || s.kind == Shape::Kind::Capsule) radius = s.radius;
}

Vec3 PosedConvex::coreSupport(const Vec3& direction) const {
  const Vec3 d = pose.rotation.transpose() * direction;  // in the shape's frame
  Vec3 local = Vec3::Zero();
  switch (shape->kind) {
    case Shape::Kind::Sphere:
    case Shape::Kind::Plane:  // planes never reach the convex algorithms
      break;
    case Shape::Kind::Capsule:
      local = Vec3(0, 0, d.z() >= 0.0 ? shape->halfLength : -shape->halfLength);
      break;
    case Shape::Kind::Cylinder: {
      // Not std::hypot: its care for overflow cost 5% of a 1,000-shape
      // pile's step, and a direction's parts are nowhere near the limits.
      const double across = std::sqrt(d.x() * d.x() + d.y() * d.y());
      local = Vec3(0, 0, d.z() >= 0.0 ? shape->halfLength : -shape->halfLength);
      if (across > 0.0) {
        local.x() = shape->radius * d.x() / across;
        local.y() = shape->radius * d.y() / across;
      }
      break;
    }
    case Shape::Kind::Box: {
      const Vec3& e = shape->halfExtents;
      local = Vec3(d.x() >= 0.0 ? e.x() : -e.x(), d.y() >= 0.0 ? e.y() : -e.y(),
                   d.z() >= 0.0 ? e.z() : -e.z());
      break;
    }
    case Shape::Kind::Convex:
      local = shape->hull->vertices()[shape->hull->supportVertex(d)];
      break;
  }
  return pose.position + pose.rotation * local;
}

double PosedConvex::coreRadius() const {
  switch (shape->kind) {
    case Shape::Kind::Sphere:
      return 0.0;
    case Shape::Kind::Capsule:
      return shape->halfLength;
    case Shape::Kind::Cylinder:
      return std::hypot(shape->radius, shape->halfLength);
    case Shape::Kind::Box:
      return shape->halfExtents.norm();
    case Shape::Kind::Convex:
      return shape->hull->boundingRadius();
    case Shape::Kind::Plane:
      return kInf;
  }
  return kInf;
}

void supportingFeature(const PosedConvex& c, const Vec3& direction, Feature& out) {
  const Shape& s = *c.shape;
  const Mat3& R = c.pose.rotation;
  const Vec3& centre = c.pose.position;
  out.count = 0;
  out.normal = Vec3::Zero();
  switch (s.kind) {
    case Shape::Kind::Sphere:
      out.points[out.count++] = centre + s.radius * direction;
      out.id = kVertex;
      return;
    case Shape::Kind::Capsule: {
      // Along the side: the support end, and the other end's point on the
      // side line (on the surface, unlike the end grown by the radius).
      const Vec3 axis = R.col(2);
      const double along = axis.dot(direction);
      const Vec3 tip = centre + (along >= 0.0 ? 1.0 : -1.0) * s.halfLength * axis;
      out.points[out.count++] = tip + s.radius * direction;
      const std::uint32_t end = along >= 0.0 ? 0 : 1;
      out.id = kVertex | end;
      if (std::abs(along) < kSideTouchCos && s.halfLength > 0.0) {
        const Vec3 other = 2.0 * centre - tip;
        out.points[out.count++] = other + s.radius * across(axis, direction);
        out.id = kEdge | end;  // the side line, from that end
      }
      return;
    }
    case Shape::Kind::Cylinder: {
      const Vec3 axis = R.col(2);
      const double along = axis.dot(direction);
      const Vec3 u = across(axis, direction);
      if (std::abs(along) >= kSideTouchCos) {  // a cap
        const Vec3 capNormal = along >= 0.0 ? axis : Vec3(-axis);
        const Vec3 capCentre = centre + s.halfLength * capNormal;
        const Vec3 v = capNormal.cross(u);
        for (int k = 0; k < kCapCorners; ++k) {
          const double angle = 2.0 * kPi * k / kCapCorners;
          out.points[out.count++] =
              capCentre + s.radius * (std::cos(angle) * u + std::sin(angle) * v);
        }
        out.normal = capNormal;
        // The corners start from the rim's support point: corner k keeps
        // its place relative to the contact while the normal holds still.
        out.id = kFace | (along >= 0.0 ? 0 : 1);
      } else {  // the side line, support end first
        const double sign = along >= 0.0 ? 1.0 : -1.0;
        out.points[out.count++] = centre + sign * s.halfLength * axis + s.radius * u;
        out.points[out.count++] = centre - sign * s.halfLength * axis + s.radius * u;
        out.id = kEdge | (along >= 0.0 ? 0 : 1);
      }
      return;
    }
    case Shape::Kind::Box: {
      const Vec3 d = R.transpose() * direction;
      int axis = 0;
      for (int i = 1; i < 3; ++i)
        if (std::abs(d[i]) > std::abs(d[axis])) axis = i;
      const double sign = d[axis] >= 0.0 ? 1.0 : -1.0;
      const int i1 = (axis + 1) % 3, i2 = (axis + 2) % 3;
      const Vec3& e = s.halfExtents;
      const Vec3 faceCentre = centre + sign * e[axis] * R.col(axis);
      const Vec3 s1 = e[i1] * R.col(i1), s2 = e[i2] * R.col(i2);
      // Counter-clockwise about the outward normal sign * R.col(axis).
      const Vec3 corners[4] = {s1 + s2, -s1 + s2, -s1 - s2, s1 - s2};
      for (int k = 0; k < 4; ++k)
        out.points[out.count++] = faceCentre + (sign > 0 ? corners[k] : corners[3 - k]);
      out.normal = sign * R.col(axis);
      out.id = kFace | static_cast<std::uint32_t>(2 * axis + (sign > 0 ? 1 : 0));
      return;
    }
    case Shape::Kind::Convex: {
      const ConvexHull& hull = *s.hull;
      const Vec3 d = R.transpose() * direction;
      const int face = hull.supportFace(d);
      const int vertex = hull.supportVertex(d);
      const ConvexHull::Face& f = hull.faces()[face];
      const Vec3& tip = hull.vertices()[vertex];
      double faceMost = -kInf;
      for (int k = 0; k < f.count; ++k)
        faceMost = std::max(faceMost, hull.faceVertex(f, k).dot(d));
      // The most aligned face must hold the support point; a face too
      // large for the buffer touches at that point alone.
      if (f.count > kMaxFeaturePoints || faceMost < tip.dot(d) - 1e-9 * hull.boundingRadius()) {
        out.points[out.count++] = centre + R * tip;
        out.id = kVertex | static_cast<std::uint32_t>(vertex);
        return;
      }
      for (int k = 0; k < f.count; ++k)
        out.points[out.count++] = centre + R * hull.faceVertex(f, k);
      out.normal = R * f.normal;
      out.id = kFace | static_cast<std::uint32_t>(face);
      return;
    }
    case Shape::Kind::Plane:
      return;
  }
}

bool supportingEdge(const PosedConvex& c, const Vec3& direction, Feature& out) {
  const Shape& s = *c.shape;
  const Mat3& R = c.pose.rotation;
  const Vec3& centre = c.pose.position;
  out.count = 0;
  out.normal = Vec3::Zero();
  switch (s.kind) {
    case Shape::Kind::Capsule:
    case Shape::Kind::Cylinder:
      supportingFeature(c, direction, out);  // the side line where it lies square enough
      return out.count == 2;
    case Shape::Kind::Box: {
      // The edge along the axis most square to d, between the two faces
      // toward d.
      const Vec3 d = R.transpose() * direction;
      int along = 0;
      for (int i = 1; i < 3; ++i)
        if (std::abs(d[i]) < std::abs(d[along])) along = i;
      if (std::abs(d[along]) >= kSideTouchCos) return false;
      const Vec3& e = s.halfExtents;
      Vec3 middle = centre;
      std::uint32_t corner = 0;
      for (int i = 0; i < 3; ++i) {
        if (i == along) continue;
        middle += (d[i] >= 0.0 ? e[i] : -e[i]) * R.col(i);
        corner = corner << 1 | (d[i] >= 0.0 ? 1u : 0u);
      }
      out.points[out.count++] = middle - e[along] * R.col(along);
      out.points[out.count++] = middle + e[along] * R.col(along);
      out.id = kEdge | static_cast<std::uint32_t>(along) << 2 | corner;
      return true;
    }
    case Shape::Kind::Convex: {
      // An edge of the face most along d, from that face's vertex farthest
      // along d: on an edge, the two faces beside it are the most aligned,
      // and the edge lies nearly square to d.
      const ConvexHull& hull = *s.hull;
      const Vec3 d = R.transpose() * direction;
      const ConvexHull::Face& f = hull.faces()[hull.supportFace(d)];
      int top = 0;
      for (int k = 1; k < f.count; ++k)
        if (hull.faceVertex(f, k).dot(d) > hull.faceVertex(f, top).dot(d)) top = k;
      int best = -1;
      double squarest = kSideTouchCos;
      for (const int k : {(top + f.count - 1) % f.count, (top + 1) % f.count}) {
        const double slope =
            std::abs((hull.faceVertex(f, k) - hull.faceVertex(f, top)).normalized().dot(d));
        if (slope < squarest) squarest = slope, best = k;
      }
      if (best < 0) return false;
      // The lower vertex index first, so that either face names it alike.
      const int v0 = hull.faceVertices()[f.first + top];
      const int v1 = hull.faceVertices()[f.first + best];
      const auto lo = static_cast<std::uint32_t>(std::min(v0, v1));
      const auto hi = static_cast<std::uint32_t>(std::max(v0, v1));
      out.points[out.count++] = centre + R * hull.vertices()[lo];
      out.points[out.count++] = centre + R * hull.vertices()[hi];
      out.id = kEdge | (lo & 0xfffu) << 12 | (hi & 0xfffu);
      return true;
    }
    default:
      return false;
  }
}

}  // namespace blockstep

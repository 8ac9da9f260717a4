#include "core/collision/narrowphase.h"

#include <algorithm>
#include <cmath>

#include "core/collision/gjk_epa.h"
#include "core/collision/manifold.h"

namespace blockstep {
namespace {

// How much shallower than the separation GJK/EPA or the separating-axis
// test found a clipped manifold's deepest point may be (plus a tenth of
// the depth), m: clipping measures each point to the reference face's
// plane, so a face tilted off the normal or a round side's polygon reads
// a little shallower.
constexpr double kClippedDepthSlack = 1e-3;

// Clips the features of A and B touching along n into m and keeps them
// when their deepest point reaches `separation` (within the slack above);
// otherwise leaves m empty. Returns the points kept.
int clipToSeparation(const PosedConvex& A, const PosedConvex& B, const Vec3& n, double separation,
                     double margin, ContactManifold& m) {
  if (clipFeatures(A, B, n, margin, m) == 0) return 0;
  double least = kInf;
  for (int i = 0; i < m.pointCount; ++i)
    least = std::min(least, m.points[i].separation);
  if (least <= separation + kClippedDepthSlack + 0.1 * std::abs(separation)) return m.pointCount;
  m.pointCount = 0;
  return 0;
}

}  // namespace

int collideSpherePlane(const Shape& plane, const Shape& sphere, const ShapePose& ps, double margin,
                       ContactManifold& m) {
  m.normal = plane.planeNormal;
  m.pointCount = 0;
  const double separation = plane.planeNormal.dot(ps.position) - plane.planeOffset - sphere.radius;
  if (separation > margin) return 0;
  const Vec3 onPlane = ps.position - (separation + sphere.radius) * plane.planeNormal;
  addManifoldPoint(m, onPlane, separation, 1);
  return 1;
}

int collideBoxPlane(const Shape& plane, const Shape& box, const ShapePose& pb, double margin,
                    ContactManifold& m) {
  m.normal = plane.planeNormal;
  m.pointCount = 0;
  Vec3 pos[8];
  double sep[8];
  int ids[8];
  int n = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 local((corner & 1 ? 1 : -1) * box.halfExtents.x(),
                     (corner & 2 ? 1 : -1) * box.halfExtents.y(),
                     (corner & 4 ? 1 : -1) * box.halfExtents.z());
    const Vec3 p = pb.position + pb.rotation * local;
    const double s = plane.planeNormal.dot(p) - plane.planeOffset;
    if (s > margin) continue;
    pos[n] = p - s * plane.planeNormal;  // on the plane
    sep[n] = s;
    ids[n] = corner;
    ++n;
  }
  int keep[4];
  const int k = reduceToFour(pos, sep, n, keep);
  for (int i = 0; i < k; ++i) {
    addManifoldPoint(m, pos[keep[i]], sep[keep[i]], static_cast<std::uint32_t>(ids[keep[i]] + 1));
  }
  return k;
}

int collideSpheres(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                   double margin, ContactManifold& m) {
  m.pointCount = 0;
  const Vec3 d = pb.position - pa.position;
  const double dist = d.norm();
  const double separation = dist - a.radius - b.radius;
  if (separation > margin) return 0;
  m.normal = dist > 1e-12 ? Vec3(d / dist) : Vec3::UnitZ();
  addManifoldPoint(m, pa.position + a.radius * m.normal, separation, 1);
  return 1;
}

namespace {

// A sphere, capsule or cylinder as its core segment (a sphere's: one
// point) and radius; a cylinder's ends are flat (rims, not half spheres).
struct RoundSegment {
  Vec3 start, end;
  double radius;
  bool flatEnds;
};

RoundSegment roundSegmentOf(const Shape& s, const ShapePose& p) {
  const bool segment = s.kind == Shape::Kind::Capsule || s.kind == Shape::Kind::Cylinder;
  const Vec3 half = segment ? Vec3(s.halfLength * p.rotation.col(2)) : Vec3::Zero();
  return RoundSegment{p.position - half, p.position + half, s.radius,
                      s.kind == Shape::Kind::Cylinder};
}

// The point of segment [start, end] nearest to x, as its parameter in [0, 1].
double nearestOnSegment(const RoundSegment& s, const Vec3& x) {
  const Vec3 d = s.end - s.start;
  const double dd = d.squaredNorm();
  return dd > 0.0 ? std::clamp((x - s.start).dot(d) / dd, 0.0, 1.0) : 0.0;
}

Vec3 at(const RoundSegment& s, double t) {
  return s.start + t * (s.end - s.start);
}

// The parameters of the closest points of two segments: the unclamped
// closest points of the two lines, then each clamped to its segment and
// the other recomputed from it (parallel lines: from A's start).
void closestParameters(const RoundSegment& a, const RoundSegment& b, double& s, double& t) {
  const Vec3 u = a.end - a.start, v = b.end - b.start, w = a.start - b.start;
  const double uu = u.squaredNorm(), vv = v.squaredNorm(), uv = u.dot(v);
  const double uw = u.dot(w), vw = v.dot(w);
  if (uu <= 0.0 && vv <= 0.0) {
    s = t = 0.0;
    return;
  }
  if (uu <= 0.0) {
    s = 0.0;
    t = nearestOnSegment(b, a.start);
    return;
  }
  if (vv <= 0.0) {
    t = 0.0;
    s = nearestOnSegment(a, b.start);
    return;
  }
  const double den = uu * vv - uv * uv;  // >= 0; 0 when parallel
  s = den > 1e-12 * uu * vv ? std::clamp((uv * vw - vv * uw) / den, 0.0, 1.0) : 0.0;
  t = (uv * s + vw) / vv;
  if (t < 0.0 || t > 1.0) {
    t = std::clamp(t, 0.0, 1.0);
    s = std::clamp((uv * t - uw) / uu, 0.0, 1.0);
  }
}

}  // namespace

// Sphere or capsule against sphere or capsule, exactly, and a cylinder
// against a capsule or cylinder where their sides meet. Besides the
// closest points, each segment end within the margin of the other segment
// is a point of its own, with its own normal and separation: two capsules
// lying at a small angle touch where their segments cross, and that point
// runs along them fast as they turn (0.2 rad in one sub-step took it 57
// mm along a pair in the 1,000-shape pile), so a single point let them
// see-saw about it: they spun up from 5 to 65 rad/s in four sub-steps and
// met 8.8 mm deep at the next collision. The ends hold the pair wherever
// the crossing goes between collisions; lying side by side they are the
// two ends of the overlap. A cylinder's end is its rim: the point of the
// rim toward the other segment, against the other's side. (A 0.2 m rod
// lying along a cylinder at 15 degrees in the pile, levered by a ball
// landing on it, see-sawed on GJK/EPA's one point the same way, 5-20 mm
// deep.)
int collideRoundSegments(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                         double margin, ContactManifold& m) {
  m.pointCount = 0;
  const RoundSegment A = roundSegmentOf(a, pa), B = roundSegmentOf(b, pb);
  double s, t;
  closestParameters(A, B, s, t);
  // A cylinder's cap or rim nearest, or parallel sides (whose overlap the
  // face clipping gives): not side against side.
  auto inside = [](double x) { return x > 0.0 && x < 1.0; };
  if ((A.flatEnds && !inside(s)) || (B.flatEnds && !inside(t))) return -1;
  const Vec3 closestA = at(A, s), closestB = at(B, t);
  const double closest = (closestB - closestA).norm();
  if (closest - A.radius - B.radius > margin) return 0;
  // The normal where the cores meet (or cross): across both segments,
  // toward B's centre.
  const Vec3 centres = 0.5 * (B.start + B.end) - 0.5 * (A.start + A.end);
  const Vec3 u = A.end - A.start, v = B.end - B.start;
  Vec3 across = u.cross(v);
  if (across.squaredNorm() <= 1e-18 * u.squaredNorm() * v.squaredNorm()) {
    // Parallel, or one a point: across the segment, toward the other.
    const Vec3 axis = u.squaredNorm() >= v.squaredNorm() ? u : v;
    across = centres;
    if (axis.squaredNorm() > 0.0) {
      across -= centres.dot(axis) / axis.squaredNorm() * axis;
      if (across.squaredNorm() <= 1e-18 * axis.squaredNorm()) {
        Vec3 t1, t2;
        perpendicularBasis(axis.normalized(), t1, t2);
        across = t1;
      }
    } else if (across.squaredNorm() <= 0.0) {
      across = Vec3::UnitZ();
    }
  }
  const Vec3 meeting = (across.dot(centres) < 0.0 ? Vec3(-across) : across).normalized();

  // Candidates: the closest points first (the deepest), then the ends.
  // Each is a point of A and one of B, each that far inside its surface
  // (its radius on the core segment, 0 on a rim).
  struct Candidate {
    Vec3 onA, normal;
    double insideA, separation;
    std::uint32_t feature;
  };
  Candidate kept[5];
  int count = 0;
  // Ends nearer than this to a point already kept (on A's surface) add
  // nothing.
  const double distinct = 0.1 * (A.radius + B.radius);
  // An end's normal this far from the closest points' (cos 60 degrees)
  // comes from the far side of the other core, where nothing touches.
  constexpr double kSameSide = 0.5;
  auto consider = [&](const Vec3& onA, double insideA, const Vec3& onB, double insideB,
                      std::uint32_t feature) {
    const Vec3 d = onB - onA;
    const double dist = d.norm();
    const double separation = dist - insideA - insideB;
    if (separation > margin) return;
    const Vec3 n = dist > 1e-9 * (A.radius + B.radius) ? Vec3(d / dist) : meeting;
    const Vec3 surface = onA + insideA * n;
    for (int i = 0; i < count; ++i)
      if ((kept[i].onA + kept[i].insideA * kept[i].normal - surface).squaredNorm() <
          distinct * distinct)
        return;
    if (count > 0 && n.dot(kept[0].normal) < kSameSide) return;
    kept[count++] = Candidate{onA, n, insideA, separation, feature};
  };
  // An end of `own` against the other segment's side: a capsule's end
  // sphere, or a cylinder's rim point toward the other's core. Gives the
  // end's surface point (or core point) and the other's core point, or
  // false where the other's nearest is its cylinder's cap or rim.
  auto endAgainst = [&](const RoundSegment& own, const Vec3& end, const RoundSegment& other,
                        Vec3& onOwn, double& insideOwn, Vec3& onOther) {
    double q = nearestOnSegment(other, end);
    onOwn = end;
    insideOwn = own.radius;
    if (own.flatEnds) {
      const Vec3 axis = (own.end - own.start).normalized();
      Vec3 toward = at(other, q) - end;
      toward -= toward.dot(axis) * axis;
      if (toward.squaredNorm() <= 1e-24) return false;
      onOwn = end + own.radius * toward.normalized();
      insideOwn = 0.0;
      q = nearestOnSegment(other, onOwn);
    }
    if (other.flatEnds && !inside(q)) return false;
    onOther = at(other, q);
    return true;
  };
  consider(closestA, A.radius, closestB, B.radius, 1);
  Vec3 onA, onB;
  double insideEnd;
  if (endAgainst(A, A.start, B, onA, insideEnd, onB)) consider(onA, insideEnd, onB, B.radius, 2);
  if (endAgainst(A, A.end, B, onA, insideEnd, onB)) consider(onA, insideEnd, onB, B.radius, 3);
  if (endAgainst(B, B.start, A, onB, insideEnd, onA)) consider(onA, A.radius, onB, insideEnd, 4);
  if (endAgainst(B, B.end, A, onB, insideEnd, onA)) consider(onA, A.radius, onB, insideEnd, 5);
  // Past a manifold's room the shallowest ends go (two capsules crossing
  // at a small angle along most of their length).
  while (count > kMaxManifoldPoints) {
    int shallowest = 1;
    for (int i = 2; i < count; ++i)
      if (kept[i].separation > kept[shallowest].separation) shallowest = i;
    kept[shallowest] = kept[--count];
  }
  m.normal = kept[0].normal;
  for (int i = 0; i < count; ++i) {
    ContactPoint& p = m.points[m.pointCount++];
    p = ContactPoint{};
    p.separation = kept[i].separation;
    // Midway between the surfaces, along the point's own normal.
    p.position = kept[i].onA + (kept[i].insideA + 0.5 * p.separation) * kept[i].normal;
    p.normal = kept[i].normal;
    p.feature = kept[i].feature;
  }
  return m.pointCount;
}

int collideBoxSphere(const Shape& box, const ShapePose& pb, const Shape& sphere,
                     const ShapePose& ps, double margin, ContactManifold& m) {
  m.pointCount = 0;
  const Vec3 local = pb.rotation.transpose() * (ps.position - pb.position);
  const Vec3& e = box.halfExtents;
  const Vec3 clamped = local.cwiseMax(-e).cwiseMin(e);
  Vec3 normalLocal;
  double separation;
  Vec3 surfaceLocal;
  if (clamped != local) {  // centre outside the box
    const Vec3 d = local - clamped;
    const double dist = d.norm();
    normalLocal = d / dist;
    separation = dist - sphere.radius;
    surfaceLocal = clamped;
  } else {  // centre inside: leave through the nearest face
    int axis = 0;
    double depth = e.x() - std::abs(local.x());
    for (int i = 1; i < 3; ++i) {
      const double di = e[i] - std::abs(local[i]);
      if (di < depth) depth = di, axis = i;
    }
    normalLocal = Vec3::Zero();
    normalLocal[axis] = local[axis] >= 0.0 ? 1.0 : -1.0;
    separation = -depth - sphere.radius;
    surfaceLocal = local;
    surfaceLocal[axis] = normalLocal[axis] * e[axis];
  }
  if (separation > margin) return 0;
  m.normal = pb.rotation * normalLocal;
  addManifoldPoint(m, pb.position + pb.rotation * surfaceLocal, separation, 1);
  return 1;
}

int collideBoxes(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                 double margin, ContactManifold& m) {
  m.pointCount = 0;
  const Vec3 d = pb.position - pa.position;
  const Vec3& eA = a.halfExtents;
  const Vec3& eB = b.halfExtents;
  const Mat3& RA = pa.rotation;
  const Mat3& RB = pb.rotation;

  auto separationOn = [&](const Vec3& L) {
    double rA = 0.0, rB = 0.0;
    for (int i = 0; i < 3; ++i) {
      rA += eA[i] * std::abs(RA.col(i).dot(L));
      rB += eB[i] * std::abs(RB.col(i).dot(L));
    }
    return std::abs(d.dot(L)) - rA - rB;
  };

  // Face axes of A (0-2) and B (3-5).
  double faceSep = -kInf;
  int faceAxis = -1;
  for (int i = 0; i < 6; ++i) {
    const Vec3 L = i < 3 ? Vec3(RA.col(i)) : Vec3(RB.col(i - 3));
    const double s = separationOn(L);
    if (s > margin) return 0;
    // B's faces must be clearly better to win over A's: stable choice.
    if (s > faceSep + (i >= 3 ? 1e-4 : 0.0)) faceSep = s, faceAxis = i;
  }
  // Edge axes.
  double edgeSep = -kInf;
  int edgeA = -1, edgeB = -1;
  Vec3 edgeAxis = Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Vec3 L = RA.col(i).cross(RB.col(j));
      const double len = L.norm();
      if (len < 1e-6) continue;  // parallel edges: a face axis covers it
      L /= len;
      const double s = separationOn(L);
      if (s > margin) return 0;
      if (s > edgeSep) edgeSep = s, edgeA = i, edgeB = j, edgeAxis = L;
    }
  }

  // Edges only when clearly shallower than any face: face contacts give
  // the stable multi-point manifolds stacks need.
  if (edgeA >= 0 && edgeSep > faceSep + 0.02 * std::max(eA.minCoeff(), eB.minCoeff()) + 1e-4) {
    Vec3 n = edgeAxis;
    if (n.dot(d) < 0.0) n = -n;
    // The edge of A furthest along n and the edge of B furthest along -n.
    Vec3 pA = pa.position, pB = pb.position;
    for (int k = 0; k < 3; ++k) {
      if (k != edgeA) pA += eA[k] * (RA.col(k).dot(n) > 0.0 ? 1.0 : -1.0) * RA.col(k);
      if (k != edgeB) pB += eB[k] * (RB.col(k).dot(n) < 0.0 ? 1.0 : -1.0) * RB.col(k);
    }
    const Vec3 u = RA.col(edgeA), v = RB.col(edgeB);
    // Closest points of the lines pA + s u and pB + t v, clamped to the edges.
    const Vec3 w = pA - pB;
    const double uv = u.dot(v), uw = u.dot(w), vw = v.dot(w);
    const double den = 1.0 - uv * uv;
    double sParam = den > 1e-12 ? (uv * vw - uw) / den : 0.0;
    sParam = std::clamp(sParam, -eA[edgeA], eA[edgeA]);
    double tParam = std::clamp(vw + uv * sParam, -eB[edgeB], eB[edgeB]);
    const Vec3 qA = pA + sParam * u, qB = pB + tParam * v;
    m.normal = n;
    addManifoldPoint(m, qA, (qB - qA).dot(n), 100 + 3 * edgeA + edgeB);
    return 1;
  }

  // Face contact: the reference face is the one owning the axis, the
  // incident face the other box's most against it, and the manifold is
  // clipped as for every convex pair.
  const bool refIsA = faceAxis < 3;
  const Vec3 axis = refIsA ? RA.col(faceAxis) : RB.col(faceAxis - 3);
  const Vec3 n = axis.dot(d) >= 0.0 ? axis : Vec3(-axis);  // from A toward B
  // The face clipped must hold the overlap the test found. A small box's
  // face can win by the tie-break while the true contact is its corner in
  // a large box's face (a cloth cell pulled over the cube's edge): its
  // normal then picks another face of the large box to clip, no point
  // comes out, and the cell sank 9.9 mm through the cube's side unseen.
  // Such a pair goes by GJK/EPA and the clipping of its features instead.
  if (clipToSeparation(PosedConvex(a, pa), PosedConvex(b, pb), n, faceSep, margin, m) > 0)
    return m.pointCount;
  return collideConvex(a, pa, b, pb, margin, m);
}

int collideConvex(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                  double margin, ContactManifold& m) {
  m.pointCount = 0;
  const PosedConvex A(a, pa), B(b, pb);
  // The clipped features hold the shapes' closest (or deepest) point only
  // when it lies within the reference face's sides. When it lies beyond
  // them (a hull's vertex reaching past a box face's edge, turning in as
  // the hull spins), the points clipped from the face were up to 35 mm
  // shallower than GJK/EPA's separation: a box in the 1,000-shape pile
  // sank 38 mm into such a hull while its contact said 3 mm apart. Such a
  // manifold is dropped for the single point, at the true separation.
  auto clipped = [&](const Vec3& n, double separation) {
    return clipToSeparation(A, B, n, separation, margin, m) > 0;
  };
  const CoreDistance apart = coreDistance(A, B);
  if (!apart.overlapping) {
    const double separation = apart.distance - A.radius - B.radius;
    if (separation > margin) return 0;
    const Vec3 n = (apart.pointB - apart.pointA) / apart.distance;
    if (clipped(n, separation)) return m.pointCount;
    addManifoldPoint(m, apart.pointA + A.radius * n, separation, 0);
    return 1;
  }
  const CorePenetration deep = corePenetration(A, B);
  if (!deep.found) {
    // No finite answer (poses the world refuses to step): the radii are
    // the depth, along the line of centres.
    const Vec3 d = pb.position - pa.position;
    const Vec3 n = d.squaredNorm() > 0.0 ? Vec3(d.normalized()) : Vec3::UnitZ();
    if (clipFeatures(A, B, n, margin, m) > 0) return m.pointCount;
    addManifoldPoint(m, apart.pointA + A.radius * n, -A.radius - B.radius, 0);
    return 1;
  }
  const Vec3& n = deep.normal;
  const double separation = -deep.depth - A.radius - B.radius;
  if (clipped(n, separation)) return m.pointCount;
  // One point. libccd's position is a blend of the support points of
  // EPA's last face, off the contact on an edge crossing (0.11 m on the
  // crossed-edges test); the witness comes from GJK instead, with B moved
  // just clear along the normal.
  PosedConvex clear = B;
  const double gap = 1e-3 * (A.coreRadius() + B.coreRadius());
  clear.pose.position += (deep.depth + gap) * n;
  const CoreDistance witness = coreDistance(A, clear);
  const Vec3 surfaceA = witness.overlapping
                            ? Vec3(deep.position + (0.5 * deep.depth + A.radius) * n)
                            : Vec3(witness.pointA + A.radius * n);
  addManifoldPoint(m, surfaceA, separation, 0);
  return 1;
}

int collideConvexPlane(const Shape& plane, const Shape& shape, const ShapePose& ps, double margin,
                       ContactManifold& m) {
  m.normal = plane.planeNormal;
  m.pointCount = 0;
  const Vec3& n = plane.planeNormal;
  const PosedConvex c(shape, ps);
  const Vec3 deepest = c.coreSupport(-n) - c.radius * n;
  const double deepestSeparation = n.dot(deepest) - plane.planeOffset;
  if (deepestSeparation > margin) return 0;
  Vec3 pos[kMaxFeaturePoints];
  double sep[kMaxFeaturePoints];
  std::uint32_t ids[kMaxFeaturePoints];
  int count = 0;
  // A candidate on the plane; past the buffer's size the shallowest goes.
  auto candidate = [&](const Vec3& p, std::uint32_t id) {
    const double s = n.dot(p) - plane.planeOffset;
    if (s > margin) return;
    int slot = count;
    if (count == kMaxFeaturePoints) {
      slot = static_cast<int>(std::max_element(sep, sep + count) - sep);
      if (sep[slot] <= s) return;
    } else {
      ++count;
    }
    pos[slot] = p - s * n;
    sep[slot] = s;
    ids[slot] = id;
  };
  if (shape.kind == Shape::Kind::Convex) {
    // Every vertex within the margin, as a box's corners: a hull resting
    // on three vertices with no face flat on the plane has no supporting
    // face, and its support vertex alone let it rock from one vertex to
    // another each step, 14 mm deep (a pile of hulls never came to rest).
    const std::vector<Vec3>& vertices = shape.hull->vertices();
    for (std::size_t v = 0; v < vertices.size(); ++v)
      candidate(ps.position + ps.rotation * vertices[v],
                mixedFeatureId(std::uint64_t{1} << 40 | v));
  } else {
    Feature feature;
    supportingFeature(c, -n, feature);
    for (int i = 0; i < feature.count; ++i)
      candidate(feature.points[i], mixedFeatureId(std::uint64_t{feature.id} << 8 | i));
  }
  if (count == 0) {
    addManifoldPoint(m, deepest - deepestSeparation * n, deepestSeparation, 0);
    return 1;
  }
  return addReducedPoints(m, pos, sep, ids, count);
}

}  // namespace blockstep

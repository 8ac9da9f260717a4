#include "core/collision/narrowphase.h"

#include <algorithm>
#include <cmath>

#include "core/collision/gjk_epa.h"
#include "core/collision/manifold.h"

namespace blockstep {

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

  // Face contact: reference face on the box that owns the axis.
  const bool refIsA = faceAxis < 3;
  const int refAxis = refIsA ? faceAxis : faceAxis - 3;
  const Mat3& RR = refIsA ? RA : RB;
  const Mat3& RI = refIsA ? RB : RA;
  const Vec3& eR = refIsA ? eA : eB;
  const Vec3& eI = refIsA ? eB : eA;
  const Vec3 cR = refIsA ? pa.position : pb.position;
  const Vec3 cI = refIsA ? pb.position : pa.position;
  Vec3 nRef = RR.col(refAxis);
  if (nRef.dot(cI - cR) < 0.0) nRef = -nRef;  // toward the incident box

  // Incident face: the face of the other box most against nRef.
  int incAxis = 0;
  double most = -1.0;
  for (int k = 0; k < 3; ++k) {
    const double dot = std::abs(RI.col(k).dot(nRef));
    if (dot > most) most = dot, incAxis = k;
  }
  const Vec3 incNormal = RI.col(incAxis) * (RI.col(incAxis).dot(nRef) > 0.0 ? -1.0 : 1.0);
  const int i1 = (incAxis + 1) % 3, i2 = (incAxis + 2) % 3;
  const Vec3 incCentre = cI + eI[incAxis] * incNormal;
  const Vec3 s1 = eI[i1] * RI.col(i1), s2 = eI[i2] * RI.col(i2);

  Vec3 polygon[8] = {incCentre + s1 + s2, incCentre - s1 + s2, incCentre - s1 - s2,
                     incCentre + s1 - s2};
  int count = 4;
  // Clip against the reference face's four side planes
  // (Sutherland-Hodgman): keep |(p - cR).side| <= extent.
  const int r1 = (refAxis + 1) % 3, r2 = (refAxis + 2) % 3;
  for (int plane = 0; plane < 4 && count > 0; ++plane) {
    const int axis = plane < 2 ? r1 : r2;
    const Vec3 side = RR.col(axis) * (plane % 2 == 0 ? 1.0 : -1.0);
    const double limit = eR[axis] + side.dot(cR);
    Vec3 out[8];
    int outCount = 0;
    for (int k = 0; k < count; ++k) {
      const Vec3& p = polygon[k];
      const Vec3& q = polygon[(k + 1) % count];
      const double dp = side.dot(p) - limit, dq = side.dot(q) - limit;
      // One predicate for inside, so a convex polygon gains at most one
      // vertex per plane (4 + 4 = 8).
      const bool pIn = dp <= 0.0, qIn = dq <= 0.0;
      if (pIn && outCount < 8) out[outCount++] = p;
      if (pIn != qIn && outCount < 8) out[outCount++] = p + (q - p) * (dp / (dp - dq));
    }
    count = outCount;
    for (int k = 0; k < count; ++k)
      polygon[k] = out[k];
  }

  const Vec3 refFace = cR + eR[refAxis] * nRef;
  Vec3 pos[8];
  double sep[8];
  int n = 0;
  for (int k = 0; k < count; ++k) {
    const double s = (polygon[k] - refFace).dot(nRef);
    if (s > margin) continue;
    pos[n] = polygon[k] - s * nRef;  // on the reference face
    sep[n] = s;
    ++n;
  }
  int keep[4];
  const int kept = reduceToFour(pos, sep, n, keep);
  // The manifold's normal points from A to B; points sit on A's surface.
  m.normal = refIsA ? nRef : Vec3(-nRef);
  for (int k = 0; k < kept; ++k) {
    const Vec3 onA = refIsA ? pos[keep[k]] : Vec3(pos[keep[k]] + sep[keep[k]] * nRef);
    // Features are left 0: clipped points are matched across steps by
    // position.
    addManifoldPoint(m, onA, sep[keep[k]], 0);
  }
  return kept;
}

int collideConvex(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                  double margin, ContactManifold& m) {
  m.pointCount = 0;
  const PosedConvex A(a, pa), B(b, pb);
  const CoreDistance apart = coreDistance(A, B);
  if (!apart.overlapping) {
    const double separation = apart.distance - A.radius - B.radius;
    if (separation > margin) return 0;
    const Vec3 n = (apart.pointB - apart.pointA) / apart.distance;
    if (clipFeatures(A, B, n, margin, m) > 0) return m.pointCount;
    addManifoldPoint(m, apart.pointA + A.radius * n, separation, 0);
    return 1;
  }
  const CorePenetration deep = corePenetration(A, B);
  if (!deep.found) {
    // Cores just touching (libccd sees no overlap) or in a flat overlap
    // EPA cannot expand (crossing capsule segments): the radii are the
    // depth, along the line of centres.
    const Vec3 d = pb.position - pa.position;
    const Vec3 n = d.squaredNorm() > 0.0 ? Vec3(d.normalized()) : Vec3::UnitZ();
    if (clipFeatures(A, B, n, margin, m) > 0) return m.pointCount;
    addManifoldPoint(m, apart.pointA + A.radius * n, -A.radius - B.radius, 0);
    return 1;
  }
  const Vec3& n = deep.normal;
  const double separation = -deep.depth - A.radius - B.radius;
  if (clipFeatures(A, B, n, margin, m) > 0) return m.pointCount;
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
  Feature feature;
  supportingFeature(c, -n, feature);
  Vec3 pos[kMaxFeaturePoints];
  double sep[kMaxFeaturePoints];
  int count = 0;
  for (int i = 0; i < feature.count; ++i) {
    const double s = n.dot(feature.points[i]) - plane.planeOffset;
    if (s > margin) continue;
    pos[count] = feature.points[i] - s * n;  // on the plane
    sep[count++] = s;
  }
  if (count == 0) {
    addManifoldPoint(m, deepest - deepestSeparation * n, deepestSeparation, 0);
    return 1;
  }
  return addReducedPoints(m, pos, sep, count);
}

}  // namespace blockstep

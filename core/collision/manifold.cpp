#include "core/collision/manifold.h"

#include <algorithm>
#include <cmath>

namespace blockstep {

void addManifoldPoint(ContactManifold& m, const Vec3& surfacePointA, double separation,
                      std::uint32_t feature) {
  ContactPoint& p = m.points[m.pointCount++];
  p = ContactPoint{};
  // Midway between the two surfaces along the normal.
  p.position = surfacePointA + 0.5 * separation * m.normal;
  p.separation = separation;
  p.feature = feature;
}

int reduceToFour(const Vec3* pos, const double* sep, int n, int* keep) {
  if (n <= 4) {
    for (int i = 0; i < n; ++i)
      keep[i] = i;
    return n;
  }
  int a = 0;
  for (int i = 1; i < n; ++i)
    if (sep[i] < sep[a]) a = i;
  int b = -1;
  double best = -1.0;
  for (int i = 0; i < n; ++i) {
    const double d = (pos[i] - pos[a]).squaredNorm();
    if (i != a && d > best) best = d, b = i;
  }
  int c = -1;
  best = -1.0;
  for (int i = 0; i < n; ++i) {
    if (i == a || i == b) continue;
    const double area = (pos[b] - pos[a]).cross(pos[i] - pos[a]).squaredNorm();
    if (area > best) best = area, c = i;
  }
  int d = -1;
  best = -1.0;
  for (int i = 0; i < n; ++i) {
    if (i == a || i == b || i == c) continue;
    // Area added by i to the triangle: the largest of the three triangles
    // it forms with an edge of (a, b, c), taken on the far side.
    const double add = std::max({(pos[a] - pos[i]).cross(pos[b] - pos[i]).squaredNorm(),
                                 (pos[b] - pos[i]).cross(pos[c] - pos[i]).squaredNorm(),
                                 (pos[c] - pos[i]).cross(pos[a] - pos[i]).squaredNorm()});
    if (add > best) best = add, d = i;
  }
  keep[0] = a;
  keep[1] = b;
  keep[2] = c;
  keep[3] = d;
  return 4;
}

namespace {

// A reference face must lie within about 25 degrees of the normal to
// clip: past that the contact is edge against edge, and a point projected
// along the normal onto the reference's plane may land beyond its edge.
constexpr double kReferenceCos = 0.9;

// Most points clipping can make: an incident polygon gains at most one
// corner per side plane.
constexpr int kMaxClipped = 2 * kMaxFeaturePoints;

// Keeps the part of an incident polygon (or segment, count 2) on the inner
// side of each side plane (normal, offset: inside where normal.x >= offset).
int clipToSides(const Vec3* incident, int count, const Vec3* sideNormal, const double* sideOffset,
                int sides, Vec3* out) {
  if (count == 2) {  // a segment: clip its parameter range
    double t0 = 0.0, t1 = 1.0;
    const Vec3 d = incident[1] - incident[0];
    for (int k = 0; k < sides; ++k) {
      const double start = sideNormal[k].dot(incident[0]) - sideOffset[k];
      const double rate = sideNormal[k].dot(d);
      if (std::abs(rate) < 1e-15) {
        if (start < 0.0) return 0;
        continue;
      }
      const double t = -start / rate;
      if (rate > 0.0)
        t0 = std::max(t0, t);
      else
        t1 = std::min(t1, t);
    }
    if (t0 > t1) return 0;
    out[0] = incident[0] + t0 * d;
    out[1] = incident[0] + t1 * d;
    return t1 - t0 > 1e-12 ? 2 : 1;
  }
  Vec3 bufferA[kMaxClipped], bufferB[kMaxClipped];
  Vec3* polygon = bufferA;
  Vec3* next = bufferB;
  for (int i = 0; i < count; ++i)
    polygon[i] = incident[i];
  for (int k = 0; k < sides && count > 0; ++k) {
    int n = 0;
    for (int i = 0; i < count; ++i) {
      const Vec3& p = polygon[i];
      const Vec3& q = polygon[(i + 1) % count];
      const double dp = sideNormal[k].dot(p) - sideOffset[k];
      const double dq = sideNormal[k].dot(q) - sideOffset[k];
      const bool pIn = dp >= 0.0, qIn = dq >= 0.0;
      if (pIn && n < kMaxClipped) next[n++] = p;
      if (pIn != qIn && n < kMaxClipped) next[n++] = p + (q - p) * (dp / (dp - dq));
    }
    std::swap(polygon, next);
    count = n;
  }
  for (int i = 0; i < count; ++i)
    out[i] = polygon[i];
  return count;
}

}  // namespace

int addReducedPoints(ContactManifold& m, const Vec3* pos, const double* sep, int n) {
  int keep[4];
  const int k = reduceToFour(pos, sep, n, keep);
  for (int i = 0; i < k; ++i)
    addManifoldPoint(m, pos[keep[i]], sep[keep[i]], 0);
  return k;
}

int clipFeatures(const PosedConvex& a, const PosedConvex& b, const Vec3& n, double margin,
                 ContactManifold& m) {
  m.normal = n;
  m.pointCount = 0;
  auto onePoint = [] { return 0; };  // the caller's single point
  Feature featureA, featureB;
  supportingFeature(a, n, featureA);
  supportingFeature(b, -n, featureB);
  if (featureA.count == 1 || featureB.count == 1) return onePoint();

  // The reference: the face most along the normal (A's on a tie), or A's
  // edge when neither feature is a face.
  const double alignA = featureA.normal.dot(n), alignB = -featureB.normal.dot(n);
  const bool refIsA = alignA >= alignB - 1e-9;
  const Feature& ref = refIsA ? featureA : featureB;
  const Feature& inc = refIsA ? featureB : featureA;
  const Vec3 outward = refIsA ? n : Vec3(-n);  // from the reference toward the other shape
  Vec3 planeNormal = ref.normal;
  Vec3 sideNormal[kMaxFeaturePoints];
  double sideOffset[kMaxFeaturePoints];
  int sides = 0;
  if (ref.count == 2) {
    const Vec3 u = ref.points[1] - ref.points[0];
    planeNormal = outward - outward.dot(u) / u.squaredNorm() * u;
    if (planeNormal.squaredNorm() < 1e-12) return onePoint();
    planeNormal.normalize();
    sideNormal[0] = u, sideOffset[0] = u.dot(ref.points[0]);
    sideNormal[1] = -u, sideOffset[1] = -u.dot(ref.points[1]);
    sides = 2;
  } else {
    if (planeNormal.dot(outward) < kReferenceCos) return onePoint();
    for (int k = 0; k < ref.count; ++k) {
      const Vec3& p = ref.points[k];
      const Vec3 inward = planeNormal.cross(ref.points[(k + 1) % ref.count] - p);
      sideNormal[sides] = inward;
      sideOffset[sides++] = inward.dot(p);
    }
  }
  if (ref.count == 2 && inc.count > 2) return onePoint();  // an edge on a face: the face clips

  Vec3 clipped[kMaxClipped];
  const int count = clipToSides(inc.points, inc.count, sideNormal, sideOffset, sides, clipped);
  const double rate = outward.dot(planeNormal);
  Vec3 pos[kMaxClipped];
  double sep[kMaxClipped];
  int kept = 0;
  for (int i = 0; i < count; ++i) {
    // Along the normal from the incident point to the reference's plane.
    const double s = (clipped[i] - ref.points[0]).dot(planeNormal) / rate;
    if (s > margin) continue;
    pos[kept] = refIsA ? Vec3(clipped[i] - s * n) : clipped[i];  // on A's surface
    sep[kept++] = s;
  }
  if (kept == 0) return onePoint();
  return addReducedPoints(m, pos, sep, kept);
}

}  // namespace blockstep

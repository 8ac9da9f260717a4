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

std::uint32_t mixedFeatureId(std::uint64_t x) {
  // splitmix64's finaliser: every input bit moves every output bit.
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  x ^= x >> 31;
  const auto id = static_cast<std::uint32_t>(x ^ (x >> 32));
  return id != 0 ? id : 1;
}

// The most candidates a manifold reduces: clipped points (two per
// feature point) or a hull's vertices within the margin.
constexpr int kMaxReduced = 2 * kMaxFeaturePoints;

// A point this close to touching (m) touches, for reduceToFour: a face
// resting on a face clips to points micrometres either side of zero. At
// zero itself, a hull's face on another's kept the four points just in,
// all on one side of the patch, and left out its far corner, 0.005 mm
// apart: the hull, spinning, rocked onto that corner and went 7.8 mm
// into the other (the 1,000-shape pile).
constexpr double kTouching = 1e-4;

int reduceToFour(const Vec3* pos, const double* sep, int n, int* keep) {
  // Points that touch come before points still apart within the margin:
  // with four or more touching, the four are chosen among them. A hull
  // tilted onto two vertices about 7 mm deep, with two more touching and
  // one 0.3 mm above, lost the second deep one to the one above, whose
  // spread was larger; left out it sank, came back at the next collision
  // in place of the first, and the hull rocked between the two every few
  // steps at up to 27 mm/s.
  if (n > 4) {
    int touching = 0;
    for (int i = 0; i < n; ++i)
      touching += sep[i] <= kTouching ? 1 : 0;
    if (touching >= 4 && touching < n) {
      Vec3 p[kMaxReduced];
      double s[kMaxReduced];
      int index[kMaxReduced];
      int k = 0;
      for (int i = 0; i < n && k < kMaxReduced; ++i) {
        if (sep[i] > kTouching) continue;
        p[k] = pos[i];
        s[k] = sep[i];
        index[k++] = i;
      }
      const int kept = reduceToFour(p, s, k, keep);
      for (int i = 0; i < kept; ++i)
        keep[i] = index[keep[i]];
      return kept;
    }
  }
  if (n <= 4) {
    // All of them, the deepest first: a contact block's LDL^T leaves a
    // redundant row (four points on a plane) to the rows before it, so
    // the first is the one whose push-out is never left out.
    int deepest = 0;
    for (int i = 1; i < n; ++i)
      if (sep[i] < sep[deepest]) deepest = i;
    for (int i = 0; i < n; ++i)
      keep[i] = i;
    std::swap(keep[0], keep[deepest]);
    return n;
  }
  // The first: the deepest, and among points as deep (to a thousandth of
  // the patch's size) the one farthest out, so that a patch lying flat
  // starts from a corner rather than from a point along an edge that
  // rounding made a hair deeper.
  Vec3 centre = Vec3::Zero();
  double deepest = sep[0];
  for (int i = 0; i < n; ++i) {
    centre += pos[i];
    deepest = std::min(deepest, sep[i]);
  }
  centre /= n;
  double size2 = 0.0;
  for (int i = 0; i < n; ++i)
    size2 = std::max(size2, (pos[i] - centre).squaredNorm());
  const double asDeep = deepest + 1e-3 * std::sqrt(size2);
  int a = -1;
  double farthest = -1.0;
  for (int i = 0; i < n; ++i) {
    const double d2 = (pos[i] - centre).squaredNorm();
    if (sep[i] <= asDeep && d2 > farthest) farthest = d2, a = i;
  }
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
  // The fourth: the point adding most area to the triangle, which is the
  // triangle it makes with the edge it lies beyond (signed against the
  // triangle's normal). A point beside an edge but inside the triangle's
  // strip adds nothing, however large its triangle with another edge: a
  // box on a box of its size, turned a hair, clips to its corners and to
  // points anywhere along nearly parallel edges, and the largest unsigned
  // triangle chose one of those over the fourth corner.
  const Vec3 normal = (pos[b] - pos[a]).cross(pos[c] - pos[a]);
  const int corner[3] = {a, b, c};
  int d = -1;
  best = 0.0;
  for (int i = 0; i < n; ++i) {
    if (i == a || i == b || i == c) continue;
    for (int e = 0; e < 3; ++e) {
      const Vec3& p = pos[corner[e]];
      const Vec3& q = pos[corner[(e + 1) % 3]];
      const double beyond = -(q - p).cross(pos[i] - p).dot(normal);
      if (beyond > best) best = beyond, d = i;
    }
  }
  keep[0] = a;
  keep[1] = b;
  keep[2] = c;
  if (d < 0) return 3;  // every other point lies within the triangle
  keep[3] = d;
  return 4;
}

namespace {

// Two side lines further apart than this (sine of their angle) cross
// rather than lie side by side. At 0.05 (3 degrees) a 0.2 m side line's
// end is 5 mm off the other's, which a 30 mm radius curves 0.4 mm away.
constexpr double kParallelSides = 0.05;

// Lines at a larger angle still touch along a line where one only pitches
// against the other (its far end rises along the normal, as a box's edge
// over a rod it see-saws on): their clipped points lie over the reference
// line, no more than this (m) to its side, and are kept; a point farther
// to the side lies where nothing touches.
constexpr double kBesideLine = 0.001;

// Most points clipping can make: an incident polygon gains at most one
// corner per side plane.
constexpr int kMaxClipped = 2 * kMaxFeaturePoints;

// A clipped point and the two lines it lies on, which name it: an
// incident vertex lies on the incident edges before and after it, a point
// made by clipping on an incident edge (or, where two side planes cut one
// after the other, a side line) and the side plane that cut it.
struct ClipPoint {
  Vec3 position;
  std::uint8_t line[2];
};

// Line labels: incident edge k (from vertex k to k + 1) is k; side plane
// s is kSideLine + s; a segment's two ends are kSegmentEnd and + 1.
constexpr std::uint8_t kSideLine = kMaxFeaturePoints;
constexpr std::uint8_t kSegmentEnd = 2 * kMaxFeaturePoints;
static_assert(2 * kMaxFeaturePoints + 2 <= 256, "line labels fit a byte");

// Keeps the part of an incident polygon (or segment, count 2) on the inner
// side of each side plane (normal, offset: inside where normal.x >= offset).
int clipToSides(const Vec3* incident, int count, const Vec3* sideNormal, const double* sideOffset,
                int sides, ClipPoint* out) {
  if (count == 2) {  // a segment: clip its parameter range
    double t0 = 0.0, t1 = 1.0;
    std::uint8_t cut0 = kSegmentEnd, cut1 = kSegmentEnd + 1;
    const Vec3 d = incident[1] - incident[0];
    for (int k = 0; k < sides; ++k) {
      const double start = sideNormal[k].dot(incident[0]) - sideOffset[k];
      const double rate = sideNormal[k].dot(d);
      if (std::abs(rate) < 1e-15) {
        if (start < 0.0) return 0;
        continue;
      }
      const double t = -start / rate;
      const auto side = static_cast<std::uint8_t>(kSideLine + k);
      if (rate > 0.0 && t > t0) t0 = t, cut0 = side;
      if (rate < 0.0 && t < t1) t1 = t, cut1 = side;
    }
    if (t0 > t1) return 0;
    out[0] = {incident[0] + t0 * d, {0, cut0}};
    out[1] = {incident[0] + t1 * d, {0, cut1}};
    return t1 - t0 > 1e-12 ? 2 : 1;
  }
  ClipPoint bufferA[kMaxClipped], bufferB[kMaxClipped];
  ClipPoint* polygon = bufferA;
  ClipPoint* next = bufferB;
  for (int i = 0; i < count; ++i) {
    polygon[i] = {
        incident[i],
        {static_cast<std::uint8_t>((i + count - 1) % count), static_cast<std::uint8_t>(i)}};
  }
  for (int k = 0; k < sides && count > 0; ++k) {
    const auto side = static_cast<std::uint8_t>(kSideLine + k);
    int n = 0;
    for (int i = 0; i < count; ++i) {
      const ClipPoint& p = polygon[i];
      const ClipPoint& q = polygon[(i + 1) % count];
      // The line from p to q: the one the two points share.
      const std::uint8_t edge =
          p.line[0] == q.line[0] || p.line[0] == q.line[1] ? p.line[0] : p.line[1];
      const double dp = sideNormal[k].dot(p.position) - sideOffset[k];
      const double dq = sideNormal[k].dot(q.position) - sideOffset[k];
      const bool pIn = dp >= 0.0, qIn = dq >= 0.0;
      if (pIn && n < kMaxClipped) next[n++] = p;
      if (pIn != qIn && n < kMaxClipped) {
        next[n++] = {p.position + (q.position - p.position) * (dp / (dp - dq)), {edge, side}};
      }
    }
    std::swap(polygon, next);
    count = n;
  }
  for (int i = 0; i < count; ++i)
    out[i] = polygon[i];
  return count;
}

// A clipped point's id: the reference and incident features and the two
// lines it lies on.
std::uint32_t clippedPointId(bool refIsA, std::uint32_t ref, std::uint32_t inc,
                             const std::uint8_t line[2]) {
  const std::uint32_t lo = std::min(line[0], line[1]), hi = std::max(line[0], line[1]);
  const std::uint64_t features = mixedFeatureId(std::uint64_t{ref} << 32 | inc);
  return mixedFeatureId(features << 32 | (refIsA ? 1u << 16 : 0u) | lo << 8 | hi);
}

}  // namespace

int addReducedPoints(ContactManifold& m, const Vec3* pos, const double* sep,
                     const std::uint32_t* ids, int n) {
  int keep[4];
  const int k = reduceToFour(pos, sep, n, keep);
  for (int i = 0; i < k; ++i)
    addManifoldPoint(m, pos[keep[i]], sep[keep[i]], ids[keep[i]]);
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
  bool refIsA = alignA >= alignB - 1e-9;
  // Where no face lies within kFaceContactCos of the normal the two touch
  // edge to edge, if at all along a line: a box on its edge along a rod
  // touched by one point, see-sawed about it and put its edge's other end
  // 15.7 mm into the rod (ConvexCollision.ABoxOnItsEdgeAlongARod...).
  if (std::max(alignA, alignB) > 0.0 && std::max(alignA, alignB) < kFaceContactCos) {
    if (!supportingEdge(a, n, featureA) || !supportingEdge(b, -n, featureB)) return onePoint();
    refIsA = true;
  }
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
    if (planeNormal.dot(outward) < kFaceContactCos) return onePoint();
    for (int k = 0; k < ref.count; ++k) {
      const Vec3& p = ref.points[k];
      const Vec3 inward = planeNormal.cross(ref.points[(k + 1) % ref.count] - p);
      sideNormal[sides] = inward;
      sideOffset[sides++] = inward.dot(p);
    }
  }
  if (ref.count == 2 && inc.count > 2) return onePoint();  // an edge on a face: the face clips
  // Two side lines (capsules, cylinders) or edges touch along a line only
  // when they lie side by side. Crossing, they touch where they cross,
  // which is the caller's single point: clipped to the reference's ends,
  // the incident line kept points far to the side of the reference, where
  // nothing touches, at the depth of the crossing (a thin cylinder lying
  // across a fat one in a pile stayed 12.7 mm deep while the solver turned
  // it about its own axis). So past kParallelSides only points within
  // kBesideLine of the reference line count, both ends or none.
  Vec3 sideways = Vec3::Zero();
  if (ref.count == 2 && inc.count == 2) {
    const Vec3 u = (ref.points[1] - ref.points[0]).normalized();
    const Vec3 v = (inc.points[1] - inc.points[0]).normalized();
    if (u.cross(v).norm() > kParallelSides) sideways = u.cross(planeNormal);
  }

  ClipPoint clipped[kMaxClipped];
  const int count = clipToSides(inc.points, inc.count, sideNormal, sideOffset, sides, clipped);
  const double rate = outward.dot(planeNormal);
  Vec3 pos[kMaxClipped];
  double sep[kMaxClipped];
  std::uint32_t ids[kMaxClipped];
  int kept = 0;
  for (int i = 0; i < count; ++i) {
    const Vec3& p = clipped[i].position;
    if (std::abs((p - ref.points[0]).dot(sideways)) > kBesideLine) return onePoint();
    // Along the normal from the incident point to the reference's plane.
    const double s = (p - ref.points[0]).dot(planeNormal) / rate;
    if (s > margin) continue;
    pos[kept] = refIsA ? Vec3(p - s * n) : p;  // on A's surface
    sep[kept] = s;
    ids[kept++] = clippedPointId(refIsA, ref.id, inc.id, clipped[i].line);
  }
  if (kept == 0 || (kept == 1 && !sideways.isZero())) return onePoint();
  return addReducedPoints(m, pos, sep, ids, kept);
}

}  // namespace blockstep

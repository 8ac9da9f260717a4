#include "core/collision/gjk_epa.h"

#include <ccd/ccd.h>

#include <cmath>

namespace blockstep {
namespace {

// A vertex of the Minkowski difference, with the two support points it
// came from (the closest points are their barycentric mix).
struct SimplexVertex {
  Vec3 w, a, b;  // w = a - b
};

struct Simplex {
  SimplexVertex v[4];
  double weight[4];
  int count = 0;

  Vec3 closest() const {
    Vec3 p = Vec3::Zero();
    for (int i = 0; i < count; ++i)
      p += weight[i] * v[i].w;
    return p;
  }
  void keep(std::initializer_list<std::pair<int, double>> vertices) {
    SimplexVertex kept[4];
    double weights[4];
    int n = 0;
    for (const auto& [i, lambda] : vertices) {
      kept[n] = v[i];
      weights[n++] = lambda;
    }
    for (int i = 0; i < n; ++i)
      v[i] = kept[i], weight[i] = weights[i];
    count = n;
  }
};

void closestOnSegment(Simplex& s) {
  const Vec3 &A = s.v[0].w, &B = s.v[1].w;
  const Vec3 AB = B - A;
  const double len2 = AB.squaredNorm();
  const double t = len2 > 0.0 ? -A.dot(AB) / len2 : 0.0;
  if (t <= 0.0) return s.keep({{0, 1.0}});
  if (t >= 1.0) return s.keep({{1, 1.0}});
  s.keep({{0, 1.0 - t}, {1, t}});
}

// Ericson, "Real-Time Collision Detection" 5.1.5: the origin's closest
// point on triangle ABC by its Voronoi regions.
void closestOnTriangle(Simplex& s, int ia, int ib, int ic) {
  const Vec3 &a = s.v[ia].w, &b = s.v[ib].w, &c = s.v[ic].w;
  const Vec3 ab = b - a, ac = c - a, ap = -a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return s.keep({{ia, 1.0}});
  const Vec3 bp = -b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return s.keep({{ib, 1.0}});
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return s.keep({{ia, 1.0 - t}, {ib, t}});
  }
  const Vec3 cp = -c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return s.keep({{ic, 1.0}});
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return s.keep({{ia, 1.0 - t}, {ic, t}});
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return s.keep({{ib, 1.0 - t}, {ic, t}});
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  s.keep({{ia, 1.0 - v - w}, {ib, v}, {ic, w}});
}

// Whether the origin and D lie on opposite sides of plane ABC (a flat
// tetrahedron counts every face as facing the origin).
bool originOutside(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 n = (b - a).cross(c - a);
  const double signOrigin = -a.dot(n), signD = (d - a).dot(n);
  if (signD * signD <= 1e-24 * n.squaredNorm() * (d - a).squaredNorm()) return true;
  return signOrigin * signD < 0.0;
}

// The closest point of tetrahedron ABCD: the best of the faces the origin
// is outside of; false when the origin is inside.
bool closestOnTetrahedron(Simplex& s) {
  static constexpr int kFaces[4][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 3, 2, 0}};
  Simplex best;
  double bestDistance = kInf;
  bool outside = false;
  for (const auto& f : kFaces) {
    if (!originOutside(s.v[f[0]].w, s.v[f[1]].w, s.v[f[2]].w, s.v[f[3]].w)) continue;
    outside = true;
    Simplex trial = s;
    closestOnTriangle(trial, f[0], f[1], f[2]);
    const double d = trial.closest().squaredNorm();
    if (d < bestDistance) bestDistance = d, best = trial;
  }
  if (outside) s = best;
  return outside;
}

// libccd's view of a core: its support mapping and centre, and the
// support points asked for so far. libccd's EPA has no bound of its own:
// it expands its polytope until a support point gains less than the
// tolerance, and on a pile's cylinder it went on for minutes (each step
// searching the whole polytope for its nearest face). Past
// kMostSupportPoints the support is the core's centre, inside the
// shapes: EPA's next point gains nothing and it ends on its nearest face.
struct CcdCore {
  const PosedConvex* convex;
  int* supportPoints;
};
constexpr int kMostSupportPoints = 1000;  // GJK's 200 steps take 400
// Rounds of moving B out along the best normal and taking the closest
// points' direction (corePenetration): each overlaps less or the rounds end.
constexpr int kApartRounds = 4;

void ccdSupport(const void* object, const ccd_vec3_t* direction, ccd_vec3_t* out) {
  const auto* core = static_cast<const CcdCore*>(object);
  const PosedConvex& c = *core->convex;
  const Vec3 p = ++*core->supportPoints > kMostSupportPoints
                     ? c.pose.position
                     : c.coreSupport(Vec3(direction->v[0], direction->v[1], direction->v[2]));
  ccdVec3Set(out, p.x(), p.y(), p.z());
}

void ccdCentre(const void* object, ccd_vec3_t* out) {
  const PosedConvex& c = *static_cast<const CcdCore*>(object)->convex;
  ccdVec3Set(out, c.pose.position.x(), c.pose.position.y(), c.pose.position.z());
}

// Calls f(normal, height) for each face of c's core: its outward normal
// (world, unit) and how far the face's plane lies along it (the core's
// support along the normal, without a support search): a box's six faces,
// a hull's, a cylinder's two caps. Points and segments (the cores of
// spheres and capsules) have none.
template <class F>
void forEachFace(const PosedConvex& c, F f) {
  const Mat3& r = c.pose.rotation;
  const Vec3& p = c.pose.position;
  auto both = [&](const Vec3& axis, double half) {
    const double centre = axis.dot(p);
    f(axis, centre + half);
    f(Vec3(-axis), half - centre);
  };
  switch (c.shape->kind) {
    case Shape::Kind::Box:
      for (int k = 0; k < 3; ++k)
        both(r.col(k), c.shape->halfExtents[k]);
      return;
    case Shape::Kind::Cylinder:
      both(r.col(2), c.shape->halfLength);
      return;
    case Shape::Kind::Convex:
      for (const ConvexHull::Face& face : c.shape->hull->faces()) {
        const Vec3 n = r * face.normal;
        f(n, face.offset + n.dot(p));
      }
      return;
    case Shape::Kind::Sphere:
    case Shape::Kind::Capsule:
    case Shape::Kind::Plane:
      return;
  }
}

// Calls f(direction) with the direction of each of the core's straight
// edges: a box's three axes, a hull's edges (each once), a cylinder's and
// a capsule's axis (the lines of its side, its segment). A sphere's core
// has none; a cylinder's rims are round and left out.
template <class F>
void forEachEdgeDirection(const PosedConvex& c, F f) {
  const Mat3& r = c.pose.rotation;
  switch (c.shape->kind) {
    case Shape::Kind::Box:
      for (int k = 0; k < 3; ++k)
        f(Vec3(r.col(k)));
      return;
    case Shape::Kind::Cylinder:
    case Shape::Kind::Capsule:
      f(Vec3(r.col(2)));
      return;
    case Shape::Kind::Convex: {
      const ConvexHull& hull = *c.shape->hull;
      const std::vector<int>& loop = hull.faceVertices();
      for (const ConvexHull::Face& face : hull.faces()) {
        for (int k = 0; k < face.count; ++k) {
          const int from = loop[face.first + k];
          const int to = loop[face.first + (k + 1) % face.count];
          // Each edge borders two faces, once in each direction.
          if (from < to) f(Vec3(r * (hull.vertices()[to] - hull.vertices()[from])));
        }
      }
      return;
    }
    case Shape::Kind::Sphere:
    case Shape::Kind::Plane:
      return;
  }
}

}  // namespace

CoreDistance coreDistance(const PosedConvex& a, const PosedConvex& b) {
  CoreDistance out;
  const double scale = a.coreRadius() + b.coreRadius() + a.radius + b.radius +
                       (b.pose.position - a.pose.position).norm();
  const double touching = 1e-10 * scale;
  auto vertex = [&](const Vec3& direction) {
    SimplexVertex v;
    v.a = a.coreSupport(direction);
    v.b = b.coreSupport(-direction);
    v.w = v.a - v.b;
    return v;
  };
  Simplex s;
  Vec3 start = b.pose.position - a.pose.position;
  if (start.squaredNorm() == 0.0) start = Vec3::UnitX();
  s.v[0] = vertex(start);
  s.weight[0] = 1.0;
  s.count = 1;
  Vec3 v = s.v[0].w;
  double vv = v.squaredNorm();
  // Overlapping: the cores' points the simplex holds, averaged (a point
  // inside both, for callers that need one).
  auto overlap = [&] {
    out.overlapping = true;
    out.pointA = out.pointB = Vec3::Zero();
    for (int i = 0; i < s.count; ++i) {
      out.pointA += s.v[i].a / s.count;
      out.pointB += s.v[i].b / s.count;
    }
    return out;
  };
  constexpr int kMaxIterations = 64;
  // Whether some support point w along -v had v.w > 0: v then separates
  // the cores (no point of the difference lies beyond it), so no later
  // simplex can hold the origin. On a round core the support points bunch
  // up as GJK converges; three of them 1e-7 m apart made a flat
  // tetrahedron whose faces all looked away from the origin, and a
  // capsule 50 mm clear of a cylinder's core was taken for overlapping,
  // its whole radius deep (the 1,000-shape pile flung such pairs apart).
  bool separated = false;
  for (out.iterations = 0; out.iterations < kMaxIterations; ++out.iterations) {
    if (vv <= touching * touching) return overlap();
    const SimplexVertex w = vertex(-v);
    separated = separated || v.dot(w.w) > 0.0;
    // Converged: the support along -v gains nothing on |v| (the distance
    // lies between v.w / |v| and |v|).
    if (vv - v.dot(w.w) <= 1e-12 * vv) break;
    bool repeated = false;
    for (int i = 0; i < s.count; ++i)
      repeated |= s.v[i].w == w.w;
    if (repeated) break;
    // Where a step makes no progress the answer is the simplex before it:
    // its points and |v| agree (the points of the new simplex with the old
    // |v| made a hull-cylinder normal 4.9 long, its points 53 mm deep).
    const Simplex before = s;
    s.v[s.count] = w;
    s.weight[s.count++] = 0.0;
    if (s.count == 2) closestOnSegment(s);
    if (s.count == 3) closestOnTriangle(s, 0, 1, 2);
    if (s.count == 4 && !closestOnTetrahedron(s)) {
      if (!separated) return overlap();
      s = before;
      break;
    }
    const Vec3 next = s.closest();
    const double nn = next.squaredNorm();
    if (nn >= vv) {  // rounding: no more progress
      s = before;
      break;
    }
    v = next;
    vv = nn;
  }
  out.distance = std::sqrt(vv);
  out.pointA = out.pointB = Vec3::Zero();
  for (int i = 0; i < s.count; ++i) {
    out.pointA += s.weight[i] * s.v[i].a;
    out.pointB += s.weight[i] * s.v[i].b;
  }
  if (out.distance <= touching) return overlap();
  return out;
}

CorePenetration corePenetration(const PosedConvex& a, const PosedConvex& b) {
  ccd_t ccd;
  CCD_INIT(&ccd);
  ccd.support1 = ccdSupport;
  ccd.support2 = ccdSupport;
  ccd.center1 = ccdCentre;
  ccd.center2 = ccdCentre;
  ccd.max_iterations = 200;
  // Absolute, in metres: polytope cores end exactly anyway; a cylinder's
  // round side converges to this.
  ccd.epa_tolerance = 1e-10 * (a.coreRadius() + b.coreRadius());
  ccd_real_t depth = 0.0;
  ccd_vec3_t dir, pos;
  CorePenetration out;
  int supportPoints = 0;
  const CcdCore coreA{&a, &supportPoints}, coreB{&b, &supportPoints};
  const bool ccdAnswered = ccdGJKPenetration(&coreA, &coreB, &ccd, &depth, &dir, &pos) == 0;
  const Vec3 n(dir.v[0], dir.v[1], dir.v[2]);
  const Vec3 p(pos.v[0], pos.v[1], pos.v[2]);
  const bool epaAnswered = ccdAnswered && std::isfinite(depth) && n.allFinite() && p.allFinite() &&
                           n.squaredNorm() >= 0.5;
  // Where libccd sees the cores merely touching (an overlap it cannot
  // expand) the line of centres starts the search instead, and the
  // candidates below find the least overlap: along the line of centres
  // alone, a cylinder standing still against a box's edge in the
  // 1,000-shape pile came out 17.5 mm deep between answers 0.14 mm apart.
  const Vec3 centres = b.pose.position - a.pose.position;
  out.found = true;
  out.depth = epaAnswered ? depth : 0.0;
  out.normal = epaAnswered                     ? Vec3(n.normalized())
               : centres.squaredNorm() > 1e-24 ? Vec3(centres.normalized())
                                               : Vec3(Vec3::UnitZ());
  out.position = epaAnswered ? p : 0.5 * (a.coreSupport(out.normal) + b.coreSupport(-out.normal));
  // Cores that barely overlap put the origin on the boundary of EPA's
  // polytope, and the face it ends on may be the far one: its normal then
  // points from B back into A. Clipped along it, a cylinder resting
  // against a box's side, 4 nm into it, gave points 275 mm deep, and the
  // push-out flung it away at 5 m/s (the 1,000-shape pile). The true
  // normal is the direction the cores overlap least along; its reverse
  // overlaps by both widths less that.
  auto overlapAlong = [&](const Vec3& d) {
    return a.coreSupport(d).dot(d) - b.coreSupport(-d).dot(d);
  };
  if (overlapAlong(-out.normal) < overlapAlong(out.normal)) out.normal = -out.normal;
  // The depth is the overlap along the normal: it bounds the depth from
  // above, as the candidates below do. EPA's own distance can understate
  // it: cut short, its nearest face lies inside the shapes' difference;
  // and for cores just touching it can end at distance 0 on a face whose
  // normal they overlap 91 mm along (a box against a hull in the 1,000-
  // shape pile: the clipped points came out 91 mm deep and threw a 15 kg
  // box up, 37 J in a frame). Then no answer of EPA's is trusted, and the
  // candidates include every pair of edges, so that for two polytopes the
  // least overlap is the separating-axis test's exact one. (Understated by
  // more than 1e-4 of the cores' size: by 1e-6, a third of the pile's EPA
  // answers on round cores were, and the edges' pairs cost the 100 hulls
  // 10% more collision time.)
  const double along = overlapAlong(out.normal);
  const bool understated = !epaAnswered || supportPoints > kMostSupportPoints ||
                           along > out.depth + 1e-4 * (a.coreRadius() + b.coreRadius());
  out.depth = along;
  // EPA on round cores can also end on a face far from the least overlap
  // (two cylinders 0.9 mm into one another came out 84 mm deep): the
  // overlap along any direction bounds the depth from above, so the line
  // of centres is tried too, and the lesser overlap wins. (MPR's
  // direction as a third candidate caught nothing more over the pile's
  // first 100 frames.)
  auto keepIfLess = [&](const Vec3& d, double overlap) {
    if (overlap < out.depth) {
      out.depth = overlap;
      out.normal = d;
    }
  };
  auto consider = [&](Vec3 d) {
    if (!d.allFinite() || d.squaredNorm() < 1e-24) return;
    d.normalize();
    keepIfLess(d, overlapAlong(d));
  };
  consider(b.pose.position - a.pose.position);
  // libccd's EPA can also stop on a far face when the cores barely
  // overlap: a hull resting 10 um against a box's face in the 1,000-shape
  // pile came out 160 mm deep (the line of centres: 149 mm), and the
  // push-out threw the 0.55 kg hull out at 23 m/s. Where the cores touch
  // face to something, one of their faces' normals is the least overlap
  // itself, so every face normal is tried as well (box, hull and
  // cylinder cap; a sphere's or capsule's core has none). Each is an upper
  // bound like the others, so the answer never gets deeper.
  forEachFace(a, [&](const Vec3& face, double height) {
    keepIfLess(face, height - b.coreSupport(-face).dot(face));
  });
  forEachFace(b, [&](const Vec3& face, double height) {
    keepIfLess(Vec3(-face), height - a.coreSupport(-face).dot(face));
  });
  if (understated) {
    forEachEdgeDirection(a, [&](const Vec3& edgeA) {
      forEachEdgeDirection(b, [&](const Vec3& edgeB) {
        const Vec3 d = edgeA.cross(edgeB);
        consider(d);
        consider(-d);
      });
    });
    // Where a round side meets an edge no candidate above need be the
    // least overlap either (a cylinder standing against a box's edge in
    // the 1,000-shape pile: 0.031 mm by the best of them, 0.012 mm after
    // these rounds). B moved out along the best normal so far by its
    // overlap, and a little more, lies apart from A; the direction
    // between their closest points then is nearer the least overlap, and
    // an upper bound like the others.
    const double gap = 1e-3 * (a.coreRadius() + b.coreRadius());
    for (int round = 0; round < kApartRounds; ++round) {
      PosedConvex apart = b;
      apart.pose.position += (out.depth + gap) * out.normal;
      const CoreDistance w = coreDistance(a, apart);
      const double before = out.depth;
      if (!w.overlapping) consider(w.pointB - w.pointA);
      if (!(out.depth < before - 1e-12)) break;
    }
  }
  out.found = std::isfinite(out.depth) && out.normal.allFinite();
  return out;
}

}  // namespace blockstep

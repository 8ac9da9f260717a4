#include "core/collision/convex_hull.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "core/world/error.h"

namespace blockstep {
namespace {

// A triangle of the hull under construction, counter-clockwise seen from
// outside; adjacent[k] is the triangle across the edge v[k] -> v[k+1].
struct Triangle {
  int v[3];
  int adjacent[3] = {-1, -1, -1};
  Vec3 normal;
  double offset;
  bool alive = true;
};

// The incremental hull (each point in turn: the triangles it sees are
// removed and the hole's rim, the horizon, is joined to the point). Quadratic
// in the worst case, which is fine for the few hundred points of a
// collision hull, and simpler to keep robust than Quickhull's conflict lists.
class HullBuilder {
 public:
  HullBuilder(const std::vector<Vec3>& points, double tolerance)
      : p_(points), tol_(tolerance), startOf_(points.size(), -1), endOf_(points.size(), -1) {}

  // The four starting points, or an Error saying why there are none.
  void startTetrahedron() {
    const int n = static_cast<int>(p_.size());
    int i0 = 0;
    for (int i = 1; i < n; ++i)
      if (p_[i].x() < p_[i0].x()) i0 = i;
    int i1 = farthest([&](int i) { return (p_[i] - p_[i0]).norm(); });
    if ((p_[i1] - p_[i0]).norm() <= tol_)
      throw Error("convex hull: all " + std::to_string(n) + " points coincide");
    const Vec3 axis = (p_[i1] - p_[i0]).normalized();
    int i2 = farthest([&](int i) { return axis.cross(p_[i] - p_[i0]).norm(); });
    if (axis.cross(p_[i2] - p_[i0]).norm() <= tol_)
      throw Error("convex hull: the points are collinear (no volume)");
    const Vec3 normal = (p_[i1] - p_[i0]).cross(p_[i2] - p_[i0]).normalized();
    int i3 = farthest([&](int i) { return std::abs(normal.dot(p_[i] - p_[i0])); });
    const double height = normal.dot(p_[i3] - p_[i0]);
    if (std::abs(height) <= tol_)
      throw Error("convex hull: the points are coplanar (a flat hull has no volume)");
    if (height > 0.0) std::swap(i1, i2);  // the apex behind the base
    addTriangle(i0, i1, i2);
    addTriangle(i1, i0, i3);
    addTriangle(i2, i1, i3);
    addTriangle(i0, i2, i3);
    for (int f = 0; f < 4; ++f)
      for (int k = 0; k < 3; ++k)
        tris_[f].adjacent[k] = findTriangleWithEdge(tris_[f].v[(k + 1) % 3], tris_[f].v[k]);
  }

  void addPoint(int pi) {
    const Vec3& point = p_[pi];
    int best = -1;
    double bestDistance = tol_;
    for (int f = 0; f < static_cast<int>(tris_.size()); ++f) {
      if (!tris_[f].alive) continue;
      const double d = distance(f, point);
      if (d > bestDistance) bestDistance = d, best = f;
    }
    if (best < 0) return;  // inside, on the hull, or a duplicate

    // The visible triangles, grown from the one seen most: a connected
    // region whatever rounding says of triangles seen edge-on.
    ++visit_;
    visited_.resize(tris_.size(), 0);
    visible_.clear();
    horizon_.clear();
    visited_[best] = visit_;
    visible_.push_back(best);
    for (std::size_t i = 0; i < visible_.size(); ++i) {
      const int f = visible_[i];
      for (int k = 0; k < 3; ++k) {
        const int g = tris_[f].adjacent[k];
        if (visited_[g] == visit_) continue;
        if (distance(g, point) > tol_) {
          visited_[g] = visit_;
          visible_.push_back(g);
        } else {
          horizon_.push_back({f, k});
        }
      }
    }
    // The rim must be one simple loop; rounding on a nearly flat patch can
    // pinch it, and then the point (within rounding of the hull) is left out.
    for (const auto& [f, k] : horizon_) {
      const int a = tris_[f].v[k];
      if (startOf_[a] >= 0) {
        for (const auto& [f2, k2] : horizon_)
          startOf_[tris_[f2].v[k2]] = -1;
        return;
      }
      startOf_[a] = 0;
    }

    for (int f : visible_)
      tris_[f].alive = false;
    for (const auto& [f, k] : horizon_) {
      const int a = tris_[f].v[k], b = tris_[f].v[(k + 1) % 3];
      const int g = tris_[f].adjacent[k];
      const int t = addTriangle(a, b, pi);
      tris_[t].adjacent[0] = g;
      for (int& across : tris_[g].adjacent)
        if (across == f) across = t;
      startOf_[a] = t;
      endOf_[b] = t;
    }
    for (const auto& [f, k] : horizon_) {
      const int a = tris_[f].v[k];
      Triangle& t = tris_[startOf_[a]];
      t.adjacent[1] = startOf_[t.v[1]];  // across b -> p: the triangle starting at b
      t.adjacent[2] = endOf_[a];         // across p -> a: the triangle ending at a
    }
    for (const auto& [f, k] : horizon_) {
      startOf_[tris_[f].v[k]] = -1;
      endOf_[tris_[f].v[(k + 1) % 3]] = -1;
    }
  }

  // Merges coplanar neighbours into polygons and fills the hull.
  void finish(std::vector<Vec3>& vertices, std::vector<ConvexHull::Face>& faces,
              std::vector<int>& loops) const {
    std::vector<int> group(tris_.size(), -1);
    std::vector<std::vector<int>> polygons;
    for (int seed = 0; seed < static_cast<int>(tris_.size()); ++seed) {
      if (!tris_[seed].alive || group[seed] >= 0) continue;
      const int id = static_cast<int>(polygons.size());
      std::vector<int> members = {seed};
      group[seed] = id;
      const Triangle& s = tris_[seed];
      for (std::size_t i = 0; i < members.size(); ++i) {
        for (int g : tris_[members[i]].adjacent) {
          if (group[g] >= 0) continue;
          const Triangle& t = tris_[g];
          bool coplanar = t.normal.dot(s.normal) > 1.0 - 1e-9;
          for (int v : t.v)
            coplanar = coplanar && std::abs(s.normal.dot(p_[v]) - s.offset) <= tol_;
          if (!coplanar) continue;
          group[g] = id;
          members.push_back(g);
        }
      }
      polygons.push_back(boundaryLoop(members, group, id));
    }

    // Keep the vertices the polygons use, renumbered.
    std::vector<int> index(p_.size(), -1);
    vertices.clear();
    faces.clear();
    loops.clear();
    for (const std::vector<int>& polygon : polygons) {
      ConvexHull::Face face;
      face.first = static_cast<int>(loops.size());
      face.count = static_cast<int>(polygon.size());
      Vec3 newell = Vec3::Zero();
      for (std::size_t k = 0; k < polygon.size(); ++k) {
        const Vec3& a = p_[polygon[k]];
        const Vec3& b = p_[polygon[(k + 1) % polygon.size()]];
        newell += a.cross(b);
        if (index[polygon[k]] < 0) {
          index[polygon[k]] = static_cast<int>(vertices.size());
          vertices.push_back(a);
        }
        loops.push_back(index[polygon[k]]);
      }
      face.normal = newell.normalized();
      double sum = 0.0;
      for (int v : polygon)
        sum += face.normal.dot(p_[v]);
      face.offset = sum / static_cast<double>(polygon.size());
      faces.push_back(face);
    }
  }

 private:
  template <class Measure>
  int farthest(Measure measure) const {
    int best = 0;
    double most = -1.0;
    for (int i = 0; i < static_cast<int>(p_.size()); ++i) {
      const double m = measure(i);
      if (m > most) most = m, best = i;
    }
    return best;
  }

  int addTriangle(int a, int b, int c) {
    Triangle t;
    t.v[0] = a, t.v[1] = b, t.v[2] = c;
    t.normal = (p_[b] - p_[a]).cross(p_[c] - p_[a]).normalized();
    t.offset = t.normal.dot(p_[a]);
    tris_.push_back(t);
    return static_cast<int>(tris_.size() - 1);
  }

  int findTriangleWithEdge(int a, int b) const {
    for (int f = 0; f < static_cast<int>(tris_.size()); ++f)
      for (int k = 0; k < 3; ++k)
        if (tris_[f].v[k] == a && tris_[f].v[(k + 1) % 3] == b) return f;
    return -1;
  }

  double distance(int f, const Vec3& point) const {
    return tris_[f].normal.dot(point) - tris_[f].offset;
  }

  // The rim of a group of coplanar triangles, counter-clockwise seen from
  // outside, without the vertices that lie on a straight stretch of it.
  std::vector<int> boundaryLoop(const std::vector<int>& members, const std::vector<int>& group,
                                int id) const {
    std::vector<std::pair<int, int>> edges;
    for (int f : members)
      for (int k = 0; k < 3; ++k)
        if (group[tris_[f].adjacent[k]] != id)
          edges.emplace_back(tris_[f].v[k], tris_[f].v[(k + 1) % 3]);
    std::vector<int> loop = {edges[0].first};
    int current = edges[0].second;
    while (current != loop[0] && loop.size() <= edges.size()) {
      loop.push_back(current);
      const auto next = std::find_if(edges.begin(), edges.end(),
                                     [current](const auto& e) { return e.first == current; });
      if (next == edges.end()) break;
      current = next->second;
    }
    for (bool removed = true; removed && loop.size() > 3;) {
      removed = false;
      for (std::size_t k = 0; k < loop.size() && loop.size() > 3; ++k) {
        const Vec3& u = p_[loop[(k + loop.size() - 1) % loop.size()]];
        const Vec3& v = p_[loop[k]];
        const Vec3& w = p_[loop[(k + 1) % loop.size()]];
        const double span = (w - u).norm();
        if (span > 0.0 && (v - u).cross(w - u).norm() / span <= tol_) {
          loop.erase(loop.begin() + static_cast<std::ptrdiff_t>(k));
          removed = true;
        }
      }
    }
    return loop;
  }

  const std::vector<Vec3>& p_;
  double tol_;
  std::vector<Triangle> tris_;
  std::vector<int> startOf_,
      endOf_;  // per point: the new triangle whose rim edge starts/ends there
  std::vector<int> visited_;
  int visit_ = 0;
  std::vector<int> visible_;
  std::vector<std::pair<int, int>> horizon_;  // (triangle, edge)
};

}  // namespace

ConvexHull ConvexHull::fromPoints(const std::vector<Vec3>& points, double tolerance) {
  if (points.size() < 4) {
    throw Error("convex hull: needs at least 4 points, got " + std::to_string(points.size()));
  }
  if (!(tolerance >= 0.0) || !std::isfinite(tolerance))
    throw Error("convex hull: tolerance must be >= 0 and finite");
  double scale = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw Error("convex hull: point " + std::to_string(i) + " is not finite");
    }
    scale = std::max(scale, points[i].cwiseAbs().maxCoeff());
  }
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points)
    lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  scale = std::max(scale, (hi - lo).maxCoeff());
  const double tol = std::max(tolerance * scale, 1e-14 * scale);

  HullBuilder builder(points, tol);
  builder.startTetrahedron();
  for (int i = 0; i < static_cast<int>(points.size()); ++i)
    builder.addPoint(i);

  ConvexHull hull;
  builder.finish(hull.vertices_, hull.faces_, hull.faceVertices_);
  // Every point inside every face's plane, and a closed surface
  // (V - E + F = 2): a failed build is an error, never a wrong shape.
  int edgeEnds = 0;
  for (const Face& f : hull.faces_) {
    edgeEnds += f.count;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (f.normal.dot(points[i]) - f.offset > 16.0 * tol) {
        throw Error("convex hull: build failed (point " + std::to_string(i) +
                    " outside a face); the points may be nearly coplanar");
      }
    }
  }
  const int euler =
      static_cast<int>(hull.vertices_.size()) - edgeEnds / 2 + static_cast<int>(hull.faces_.size());
  if (euler != 2) throw Error("convex hull: build failed (not a closed surface)");
  hull.localMin_ = hull.localMax_ = hull.vertices_[0];
  for (const Vec3& v : hull.vertices_) {
    hull.boundingRadius_ = std::max(hull.boundingRadius_, v.norm());
    hull.localMin_ = hull.localMin_.cwiseMin(v);
    hull.localMax_ = hull.localMax_.cwiseMax(v);
  }
  return hull;
}

int ConvexHull::supportVertex(const Vec3& direction) const {
  int best = 0;
  double most = -kInf;
  for (int i = 0; i < static_cast<int>(vertices_.size()); ++i) {
    const double d = vertices_[i].dot(direction);
    if (d > most) most = d, best = i;
  }
  return best;
}

int ConvexHull::supportFace(const Vec3& direction) const {
  int best = 0;
  double most = -kInf;
  for (int i = 0; i < static_cast<int>(faces_.size()); ++i) {
    const double d = faces_[i].normal.dot(direction);
    if (d > most) most = d, best = i;
  }
  return best;
}

namespace {

// Sums over the hull's tetrahedra (reference point r, then a fan triangle):
// volume, first moment and covariance, all relative to r.
struct TetrahedraSums {
  double volume = 0.0;
  Vec3 moment = Vec3::Zero();
  Mat3 covariance = Mat3::Zero();
  Vec3 reference;
};

TetrahedraSums sumTetrahedra(const ConvexHull& hull) {
  TetrahedraSums s;
  s.reference = Vec3::Zero();
  for (const Vec3& v : hull.vertices())
    s.reference += v;
  s.reference /= static_cast<double>(hull.vertices().size());
  // The covariance of the unit tetrahedron (0, e1, e2, e3) with density 1.
  Mat3 canonical;
  canonical << 2, 1, 1, 1, 2, 1, 1, 1, 2;
  canonical /= 120.0;
  for (const ConvexHull::Face& f : hull.faces()) {
    const Vec3 a = hull.faceVertex(f, 0) - s.reference;
    for (int k = 1; k + 1 < f.count; ++k) {
      Mat3 A;
      A.col(0) = a;
      A.col(1) = hull.faceVertex(f, k) - s.reference;
      A.col(2) = hull.faceVertex(f, k + 1) - s.reference;
      const double det = A.determinant();  // 6 x the signed volume
      s.volume += det / 6.0;
      s.moment += det / 6.0 * (A.col(0) + A.col(1) + A.col(2)) / 4.0;
      s.covariance += det * A * canonical * A.transpose();
    }
  }
  return s;
}

}  // namespace

double hullVolume(const ConvexHull& hull) {
  return sumTetrahedra(hull).volume;
}

MassProperties hullMass(const ConvexHull& hull, double density) {
  if (!(density > 0.0) || !std::isfinite(density)) {
    throw Error("hull mass: density must be positive and finite, got " + std::to_string(density));
  }
  const TetrahedraSums s = sumTetrahedra(hull);
  MassProperties m;
  m.mass = density * s.volume;
  const Vec3 c = s.moment / s.volume;  // centre relative to the reference point
  // Covariance about the centre, then the inertia tensor from it.
  const Mat3 C = density * s.covariance - m.mass * c * c.transpose();
  m.inertia = C.trace() * Mat3::Identity() - C;
  m.centre = s.reference + c;
  return m;
}

}  // namespace blockstep

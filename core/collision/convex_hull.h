// A convex polyhedron built from a cloud of points (the paper's section 5:
// convex shapes, and compounds of them for concave bodies). Its faces are
// planar polygons, the coplanar triangles of the build merged, because the
// contact manifold clips whole faces: a box given by its 8 corners has 6
// square faces and rests on 4 points, not on a triangle's 3.
#pragma once

#include <vector>

#include "core/body/mass.h"
#include "core/math/math.h"

namespace blockstep {

class ConvexHull {
 public:
  struct Face {
    Vec3 normal;    // unit, outward
    double offset;  // the face's plane: normal.x == offset
    int first;      // its vertex loop in faceVertices(), counter-clockwise seen from outside
    int count;
  };

  // The hull of `points` (in the shape's frame). Points within `tolerance`
  // of the hull (relative to the cloud's extent) are left out: duplicates,
  // points inside, points on a face. Throws Error, naming the reason, for
  // fewer than 4 points, non-finite points, or a cloud without volume
  // (coincident, collinear or coplanar points).
  static ConvexHull fromPoints(const std::vector<Vec3>& points, double tolerance = 1e-9);

  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<Face>& faces() const { return faces_; }
  const std::vector<int>& faceVertices() const { return faceVertices_; }
  const Vec3& faceVertex(const Face& f, int k) const {
    return vertices_[faceVertices_[f.first + k]];
  }

  // The vertex farthest along `direction`, and the face whose normal is
  // most along it (the face a contact along that normal touches).
  int supportVertex(const Vec3& direction) const;
  int supportFace(const Vec3& direction) const;
  // Largest distance of a vertex from the origin of the hull's frame.
  double boundingRadius() const { return boundingRadius_; }
  // The vertices' box in the hull's frame (the broad phase turns it each step).
  const Vec3& localMin() const { return localMin_; }
  const Vec3& localMax() const { return localMax_; }

 private:
  std::vector<Vec3> vertices_;
  std::vector<Face> faces_;
  std::vector<int> faceVertices_;
  double boundingRadius_ = 0.0;
  Vec3 localMin_ = Vec3::Zero(), localMax_ = Vec3::Zero();
};

// The mass properties of the solid hull at `density` (kg/m^3): volume,
// centre and inertia, exact for the polyhedron. Each face is cut into a fan
// of triangles, each triangle with a reference point inside makes a
// tetrahedron, and the tetrahedra's covariance matrices add (the
// divergence-theorem method of Mirtich's "Fast and accurate computation of
// polyhedral mass properties", in the covariance form of Blow and
// Binstock); the inertia is trace(C) 1 - C about the centre.
MassProperties hullMass(const ConvexHull& hull, double density);
double hullVolume(const ConvexHull& hull);

}  // namespace blockstep

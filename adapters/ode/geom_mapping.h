// ODE's geoms in the core's terms, for blockstep's own collision
// (dWorldSetBlockCollision) and for its colliders registered in ODE
// (dBlockSetColliders): a sphere, box, capsule, cylinder, convex or plane
// geom becomes the core Shape of the same size, placed on the core body
// of the geom's body (offset included) or, for a geom without a body, on
// the world at the geom's pose. Rays, trimeshes, heightfields and
// transforms have no core shape.
//
// ODE keeps a convex geom's points where the program has them and has no
// getter for them: the plugin records them as dCreateConvex and
// dGeomSetConvex pass them (ConvexGeoms), and the hull is built from them
// once, on first use.
#pragma once

#include <ode/ode.h>

#include <memory>
#include <mutex>
#include <string>

#include "adapters/ode/pointer_map.h"
#include "core/collision/shapes.h"

namespace blockstep::ode {

// The convex geoms' points, process-wide (geoms are not tied to a world).
class ConvexGeoms {
 public:
  static ConvexGeoms& instance();
  // `points`: `count` points of 3 dReals each, kept by the program.
  void remember(dGeomID geom, const dReal* points, unsigned count);
  void forget(dGeomID geom);
  // The geom's hull, built at the first call after its points were given;
  // nullptr with `why` set when the points were never seen (the geom was
  // made before the plugin was loaded) or enclose no volume.
  std::shared_ptr<const ConvexHull> hull(dGeomID geom, std::string& why);

 private:
  struct Entry {
    const dReal* points = nullptr;
    unsigned count = 0;
    std::shared_ptr<const ConvexHull> hull;
    std::string error;
  };
  std::mutex mutex_;
  PointerMap<dGeomID, Entry> geoms_;
};

// The sphere, capsule and cylinder geoms alive, process-wide: a contact
// names its two geoms (dContactGeom g1, g2), but a program filling a
// dContact by hand may leave them unset, so only geoms seen made and not
// yet destroyed are read.
class RoundGeoms {
 public:
  static RoundGeoms& instance();
  void remember(dGeomID geom);
  void forget(dGeomID geom);
  // How round `geom`'s surface is where it touches along `normal`
  // (ContactPoint::radiusA); 0 for a geom not remembered.
  double roundness(dGeomID geom, const dReal* normal);

 private:
  std::mutex mutex_;
  PointerMap<dGeomID, bool> geoms_;
};

// Fills `out` with the shape of `geom` on core body `body` (kWorldBody:
// a geom without a body), its filter from the geom's category and collide
// bits; out's friction and restitution are kept. Returns false with
// `why` for a geom with no core shape.
bool shapeOfGeom(dGeomID geom, BodyId body, Shape& out, std::string& why);

// The geom's pose in the world (for a geom on a body, the body's pose
// times the offset), as the core places shapes.
ShapePose geomPose(dGeomID geom);

}  // namespace blockstep::ode

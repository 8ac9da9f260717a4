// blockstep's convex collision as ODE's collider (dBlockSetColliders,
// BLOCKSTEP_COLLIDERS=1): every pair with a convex geom or a cylinder
// goes through the core's GJK/EPA and face clipping through
// dSetColliderOverride, so an ODE program gets manifolds of up to four
// points where ODE's own convex and cylinder paths (libccd) give one
// point a pair: a hull resting on a face stands on its face instead of
// rocking on one point.
#include <atomic>
#include <cstring>

#include "adapters/ode/geom_mapping.h"
#include "core/collision/collide.h"
#include "plugin/plugin_state.h"

namespace blockstep::plugin {
namespace {

std::atomic<bool> wanted{false};
std::atomic<bool> odeInitialized{false};

ShapePose poseOf(dGeomID g, const Shape& s) {
  // A plane is not placeable: its shape holds its place.
  return s.kind == Shape::Kind::Plane ? ShapePose{Vec3::Zero(), Mat3::Identity()}
                                      : ode::geomPose(g);
}

// ODE's collider signature. ODE calls it with o1 of the class it was
// registered for first, or with the pair turned round and then flips the
// normals itself. Contacts: o1 is moved out along +normal by depth.
int collide(dGeomID o1, dGeomID o2, int flags, dContactGeom* contacts, int skip) {
  const int room = flags & 0xffff;
  if (room < 1) return 0;
  Shape s1, s2;
  std::string why;
  // Shapes placed by their poses alone: bodies and offsets are in them.
  if (!ode::shapeOfGeom(o1, kWorldBody, s1, why) || !ode::shapeOfGeom(o2, kWorldBody, s2, why)) {
    return 0;  // a convex geom whose points were never seen
  }
  s1.localPosition = s2.localPosition = Vec3::Zero();
  s1.localOrientation = s2.localOrientation = Quat::Identity();
  ContactManifold m;
  bool swapped = false;
  // Margin 0: ODE programs take every contact as touching.
  const int n = collideShapes(s1, poseOf(o1, s1), s2, poseOf(o2, s2), 0.0, true, m, swapped);
  // The core's normal points from its first shape to its second: from o1
  // to o2 unless swapped. ODE's pushes o1 out, so it points from o2 to o1.
  const double sign = swapped ? 1.0 : -1.0;
  int written = 0;
  for (int i = 0; i < n && written < room; ++i) {
    const ContactPoint& p = m.points[i];
    if (p.separation > 0.0) continue;
    auto* c = reinterpret_cast<dContactGeom*>(reinterpret_cast<char*>(contacts) + written * skip);
    const Vec3 normal = sign * (p.normal.isZero() ? m.normal : p.normal);
    for (int k = 0; k < 3; ++k) {
      c->pos[k] = p.position[k];
      c->normal[k] = normal[k];
    }
    c->pos[3] = c->normal[3] = 0;
    c->depth = -p.separation;
    c->g1 = o1;
    c->g2 = o2;
    c->side1 = c->side2 = -1;
    ++written;
  }
  return written;
}

void registerColliders() {
  const int classes[] = {dSphereClass,   dBoxClass,    dCapsuleClass,
                         dCylinderClass, dConvexClass, dPlaneClass};
  for (int a : classes) {
    for (int b : classes) {
      const bool ours =
          a == dConvexClass || b == dConvexClass || a == dCylinderClass || b == dCylinderClass;
      if (ours && a <= b) dSetColliderOverride(a, b, &collide);
    }
  }
}

}  // namespace

void collidersAfterInit() {
  odeInitialized = true;
  if (wanted) registerColliders();
}

void collidersBeforeClose() {
  odeInitialized = false;
}

void setCollidersFromEnvironment(bool on) {
  wanted = on;
}

}  // namespace blockstep::plugin

extern "C" int dBlockSetColliders(int on) {
  using namespace blockstep::plugin;
  if (!on) {
    const bool inPlace = wanted && odeInitialized;
    wanted = false;
    if (inPlace) {
      say("dBlockSetColliders(0): ODE keeps no copy of the colliders blockstep replaced; they stay "
          "until dCloseODE (the next dInitODE keeps ODE's own)");
    }
    return inPlace ? 0 : 1;
  }
  wanted = true;
  if (!odeInitialized) {
    // dInitODE clears ODE's collider table: registered when it runs.
    return 1;
  }
  registerColliders();
  return 1;
}

#include "adapters/ode/geom_mapping.h"

#include <vector>

#include "adapters/ode/body_state.h"
#include "core/collision/collide.h"
#include "core/world/error.h"

namespace blockstep::ode {

ConvexGeoms& ConvexGeoms::instance() {
  static ConvexGeoms geoms;
  return geoms;
}

void ConvexGeoms::remember(dGeomID geom, const dReal* points, unsigned count) {
  std::lock_guard<std::mutex> lock(mutex_);
  geoms_[geom] = Entry{points, count, nullptr, {}};
}

void ConvexGeoms::forget(dGeomID geom) {
  std::lock_guard<std::mutex> lock(mutex_);
  geoms_.erase(geom);
}

std::shared_ptr<const ConvexHull> ConvexGeoms::hull(dGeomID geom, std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  Entry* e = geoms_.find(geom);
  if (!e || !e->points) {
    why = "its points were not seen (made before blockstep was loaded)";
    return nullptr;
  }
  if (!e->hull && e->error.empty()) {
    std::vector<Vec3> points(e->count);
    for (unsigned i = 0; i < e->count; ++i)
      points[i] = Vec3(e->points[3 * i], e->points[3 * i + 1], e->points[3 * i + 2]);
    try {
      e->hull = std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points));
    } catch (const Error& error) {
      e->error = error.what();
    }
  }
  if (!e->hull) why = e->error;
  return e->hull;
}

RoundGeoms& RoundGeoms::instance() {
  static RoundGeoms geoms;
  return geoms;
}

void RoundGeoms::remember(dGeomID geom) {
  std::lock_guard<std::mutex> lock(mutex_);
  geoms_[geom] = true;
}

void RoundGeoms::forget(dGeomID geom) {
  std::lock_guard<std::mutex> lock(mutex_);
  geoms_.erase(geom);
}

double RoundGeoms::roundness(dGeomID geom, const dReal* normal) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!geom || !geoms_.find(geom)) return 0.0;
  }
  dReal radius = 0, length = 0;
  Shape::Kind kind = Shape::Kind::Sphere;
  switch (dGeomGetClass(geom)) {
    case dSphereClass:
      radius = dGeomSphereGetRadius(geom);
      break;
    case dCapsuleClass:
      kind = Shape::Kind::Capsule;
      dGeomCapsuleGetParams(geom, &radius, &length);
      break;
    case dCylinderClass:
      kind = Shape::Kind::Cylinder;
      dGeomCylinderGetParams(geom, &radius, &length);
      break;
    default:
      return 0.0;
  }
  const dReal* R = dGeomGetRotation(geom);  // 3 x 4, rows: its z axis is column 2
  return surfaceRoundness(kind, radius, Vec3(R[2], R[6], R[10]),
                          Vec3(normal[0], normal[1], normal[2]));
}

namespace {

Quat odeQuat(const dQuaternion q) {
  return Quat(q[0], q[1], q[2], q[3]);  // ODE: w, x, y, z
}

}  // namespace

bool shapeOfGeom(dGeomID geom, BodyId body, Shape& out, std::string& why) {
  Shape s = out;
  switch (dGeomGetClass(geom)) {
    case dSphereClass:
      s.kind = Shape::Kind::Sphere;
      s.radius = dGeomSphereGetRadius(geom);
      break;
    case dBoxClass: {
      dVector3 sides;
      dGeomBoxGetLengths(geom, sides);
      s.kind = Shape::Kind::Box;
      s.halfExtents = 0.5 * vec(sides);
      break;
    }
    case dCapsuleClass:
    case dCylinderClass: {
      dReal radius = 0, length = 0;
      const bool capsule = dGeomGetClass(geom) == dCapsuleClass;
      if (capsule) {
        dGeomCapsuleGetParams(geom, &radius, &length);
      } else {
        dGeomCylinderGetParams(geom, &radius, &length);
      }
      s.kind = capsule ? Shape::Kind::Capsule : Shape::Kind::Cylinder;
      s.radius = radius;
      s.halfLength = 0.5 * length;  // both along local z, length without caps
      break;
    }
    case dConvexClass: {
      s.kind = Shape::Kind::Convex;
      s.hull = ConvexGeoms::instance().hull(geom, why);
      if (!s.hull) {
        why = "convex geom: " + why;
        return false;
      }
      break;
    }
    case dPlaneClass: {
      dVector4 p;
      dGeomPlaneGetParams(geom, p);
      s.kind = Shape::Kind::Plane;
      s.planeNormal = Vec3(p[0], p[1], p[2]);
      s.planeOffset = p[3];  // ODE: n.x = d on the plane, n.x < d inside
      break;
    }
    case dRayClass:
      why = "rays";
      return false;
    case dTriMeshClass:
      why = "triangle meshes";
      return false;
    case dHeightfieldClass:
      why = "heightfields";
      return false;
    default:
      why = "geom class " + std::to_string(dGeomGetClass(geom));
      return false;
  }
  if (s.kind == Shape::Kind::Plane || !dGeomGetBody(geom)) {
    s.body = kWorldBody;
    if (s.kind != Shape::Kind::Plane) {
      dQuaternion q;
      dGeomGetQuaternion(geom, q);
      s.localPosition = vec(dGeomGetPosition(geom));
      s.localOrientation = odeQuat(q);
    }
  } else {
    s.body = body;
    dQuaternion q;
    dGeomGetOffsetQuaternion(geom, q);
    s.localPosition = vec(dGeomGetOffsetPosition(geom));
    s.localOrientation = odeQuat(q);
  }
  s.categoryBits = dGeomGetCategoryBits(geom);
  s.collideBits = dGeomGetCollideBits(geom);
  out = s;
  return true;
}

ShapePose geomPose(dGeomID geom) {
  const dReal* p = dGeomGetPosition(geom);
  const dReal* R = dGeomGetRotation(geom);  // 3x4, row major
  ShapePose pose;
  pose.position = vec(p);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      pose.rotation(r, c) = R[4 * r + c];
  return pose;
}

}  // namespace blockstep::ode

// A comparison scene's world, collision and joint measurements.
#include "compare/ode/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "adapters/ode/body_state.h"
#include "core/collision/convex_hull.h"
#include "core/collision/gjk_epa.h"

namespace blockstep::compare {

namespace {

constexpr int kMaxContactsPerPair = 8;

double length(const dReal* v) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

// A point fixed in a body (or in the world) in world coordinates.
void worldPoint(dBodyID b, const dReal* local, dVector3 out) {
  if (!b) {
    out[0] = local[0], out[1] = local[1], out[2] = local[2];
    return;
  }
  dBodyGetRelPointPos(b, local[0], local[1], local[2], out);
}

void worldVector(dBodyID b, const dReal* local, dVector3 out) {
  if (!b) {
    out[0] = local[0], out[1] = local[1], out[2] = local[2];
    return;
  }
  dBodyVectorToWorld(b, local[0], local[1], local[2], out);
}

void orientation(dBodyID b, dQuaternion q) {
  if (!b) {
    dQSetIdentity(q);
    return;
  }
  const dReal* p = dBodyGetQuaternion(b);
  for (int k = 0; k < 4; ++k)
    q[k] = p[k];
}

}  // namespace

Scene::Scene() {
  world_ = dWorldCreate();
  dWorldSetGravity(world_, 0, 0, -9.81);
  space_ = dHashSpaceCreate(nullptr);
  contacts_ = dJointGroupCreate(0);
  surface_.mode = dContactApprox1;
  surface_.mu = 0.6;
}

Scene::~Scene() {
  dJointGroupDestroy(contacts_);
  dSpaceDestroy(space_);  // destroys its geoms
  dWorldDestroy(world_);
}

dBodyID Scene::addBody(const dMass& mass, double x, double y, double z) {
  dBodyID b = dBodyCreate(world_);
  // A zero mass: the caller sets it once a shape gives it (convexBody).
  if (mass.mass > 0.0) dBodySetMass(b, &mass);
  dBodySetPosition(b, x, y, z);
  bodies_.push_back(b);
  return b;
}

void Scene::addGeom(dGeomID geom, dBodyID body) {
  if (body) dGeomSetBody(geom, body);
}

dGeomID Scene::addConvex(const std::vector<double>& points, dBodyID body, double density,
                         dMass* mass) {
  std::vector<Vec3> cloud;
  for (std::size_t i = 0; i + 2 < points.size(); i += 3)
    cloud.emplace_back(points[i], points[i + 1], points[i + 2]);
  const ConvexHull hull = ConvexHull::fromPoints(cloud);  // throws for a flat cloud
  auto data = std::make_unique<ConvexData>();
  for (const Vec3& v : hull.vertices())
    data->points.insert(data->points.end(), {v.x(), v.y(), v.z()});
  for (const ConvexHull::Face& f : hull.faces()) {
    data->planes.insert(data->planes.end(), {f.normal.x(), f.normal.y(), f.normal.z(), f.offset});
    data->polygons.push_back(static_cast<unsigned>(f.count));
    for (int k = 0; k < f.count; ++k)
      data->polygons.push_back(static_cast<unsigned>(hull.faceVertices()[f.first + k]));
  }
  if (mass) {
    const MassProperties m = hullMass(hull, density);
    const Mat3& I = m.inertia;
    dMassSetParameters(mass, m.mass, 0, 0, 0, I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2));
  }
  dGeomID g = dCreateConvex(space_, data->planes.data(), static_cast<unsigned>(hull.faces().size()),
                            data->points.data(), static_cast<unsigned>(hull.vertices().size()),
                            data->polygons.data());
  data->geom = g;
  data->hull = std::make_shared<const ConvexHull>(hull);
  convexData_.push_back(std::move(data));
  addGeom(g, body);
  return g;
}

const std::vector<dReal>* Scene::convexPoints(dGeomID geom) const {
  for (const auto& data : convexData_)
    if (data->geom == geom) return &data->points;
  return nullptr;
}

JointRecord& Scene::record(dJointID j, JointKind kind, dBodyID b1, dBodyID b2,
                           const dReal* anchor) {
  JointRecord r;
  r.joint = j;
  r.kind = kind;
  r.body1 = b1;
  r.body2 = b2;
  dBodyGetPosRelPoint(b1, anchor[0], anchor[1], anchor[2], r.anchor1);
  if (b2) {
    dBodyGetPosRelPoint(b2, anchor[0], anchor[1], anchor[2], r.anchor2);
  } else {
    r.anchor2[0] = anchor[0], r.anchor2[1] = anchor[1], r.anchor2[2] = anchor[2];
  }
  dQuaternion q1, q2;
  orientation(b1, q1);
  orientation(b2, q2);
  dQMultiply1(r.relative0, q1, q2);  // q1^-1 q2
  joints_.push_back(r);
  return joints_.back();
}

dJointID Scene::ball(dBodyID b1, dBodyID b2, double x, double y, double z) {
  dJointID j = dJointCreateBall(world_, nullptr);
  dJointAttach(j, b1, b2);
  dJointSetBallAnchor(j, x, y, z);
  const dVector3 anchor = {x, y, z};
  record(j, JointKind::Ball, b1, b2, anchor);
  return j;
}

dJointID Scene::hinge(dBodyID b1, dBodyID b2, const dVector3 anchor, const dVector3 axis) {
  dJointID j = dJointCreateHinge(world_, nullptr);
  dJointAttach(j, b1, b2);
  dJointSetHingeAnchor(j, anchor[0], anchor[1], anchor[2]);
  dJointSetHingeAxis(j, axis[0], axis[1], axis[2]);
  JointRecord& r = record(j, JointKind::Hinge, b1, b2, anchor);
  dBodyVectorFromWorld(b1, axis[0], axis[1], axis[2], r.axis1);
  if (b2) {
    dBodyVectorFromWorld(b2, axis[0], axis[1], axis[2], r.axis2);
  } else {
    r.axis2[0] = axis[0], r.axis2[1] = axis[1], r.axis2[2] = axis[2];
  }
  return j;
}

dJointID Scene::fixed(dBodyID b1, dBodyID b2) {
  dJointID j = dJointCreateFixed(world_, nullptr);
  dJointAttach(j, b1, b2);
  dJointSetFixed(j);
  // Anchored midway between the two centres: its separation is how far
  // the bodies moved apart or sideways from where they were fixed.
  const dReal* p1 = dBodyGetPosition(b1);
  const dReal* p2 = b2 ? dBodyGetPosition(b2) : p1;
  const dVector3 mid = {0.5 * (p1[0] + p2[0]), 0.5 * (p1[1] + p2[1]), 0.5 * (p1[2] + p2[2])};
  record(j, JointKind::Fixed, b1, b2, mid);
  return j;
}

dJointID Scene::hinge2(dBodyID b1, dBodyID b2, const dVector3 anchor, const dVector3 steering,
                       const dVector3 axle) {
  dJointID j = dJointCreateHinge2(world_, nullptr);
  dJointAttach(j, b1, b2);
  dJointSetHinge2Anchor(j, anchor[0], anchor[1], anchor[2]);
  dJointSetHinge2Axes(j, steering, axle);
  JointRecord& r = record(j, JointKind::Hinge2, b1, b2, anchor);
  dBodyVectorFromWorld(b1, steering[0], steering[1], steering[2], r.axis1);
  dBodyVectorFromWorld(b2, axle[0], axle[1], axle[2], r.axis2);
  return j;
}

void Scene::setProbe(dBodyID b) {
  probe_ = b;
  const dReal* p = dBodyGetPosition(b);
  probeStart_[0] = p[0], probeStart_[1] = p[1], probeStart_[2] = p[2];
}

void Scene::nearCallback(void* data, dGeomID a, dGeomID b) {
  auto* self = static_cast<Scene*>(data);
  dBodyID b1 = dGeomGetBody(a);
  dBodyID b2 = dGeomGetBody(b);
  if (b1 && b2 && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;
  dContact contact[kMaxContactsPerPair];
  const int n = dCollide(a, b, kMaxContactsPerPair, &contact[0].geom, sizeof(dContact));
  double depth = 0.0;
  for (int i = 0; i < n; ++i) {
    contact[i].surface = self->surface_;
    dJointID j = dJointCreateContact(self->world_, self->contacts_, &contact[i]);
    dJointAttach(j, b1, b2);
    depth = std::max(depth, static_cast<double>(contact[i].geom.depth));
  }
  self->contactCount_ += n;
  if (n == 0) return;
  self->deepestOde_ = std::max(self->deepestOde_, depth);
  auto round = [](dGeomID g) {
    const int c = dGeomGetClass(g);
    return c == dCylinderClass || c == dConvexClass;
  };
  const bool plane = dGeomGetClass(a) == dPlaneClass || dGeomGetClass(b) == dPlaneClass;
  if (pairKey(b) < pairKey(a)) std::swap(a, b);
  self->touching_.push_back({a, b, depth, !plane && (round(a) || round(b))});
}

double Scene::collide() {
  // The pairs the last collide() found become those of the one before
  // (ordered here should deepestContact() not have been asked: the
  // convergence study collides without measuring).
  keepTouching();
  std::swap(touchingBefore_, touchingLast_);
  touchingKept_ = false;
  contactCount_ = 0;
  deepestOde_ = 0.0;
  touching_.clear();
  dSpaceCollide(space_, this, &nearCallback);
  return deepestOde_;
}

double Scene::deepestContact() {
  // MPR's depth is never less than the least one (it is the shapes'
  // overlap along its direction), so only pairs ODE finds deeper than the
  // deepest so far can raise it: the deepest first.
  std::sort(touching_.begin(), touching_.end(),
            [](const TouchingPair& x, const TouchingPair& y) { return x.odeDepth > y.odeDepth; });
  double deepest = 0.0, held = 0.0;
  for (const TouchingPair& pair : touching_) {
    const bool wasTouching = touchingBefore(pair);
    if (pair.odeDepth <= deepest && (!wasTouching || pair.odeDepth <= held)) continue;
    const double depth = measuredDepth(pair);
    deepest = std::max(deepest, depth);
    if (wasTouching) held = std::max(held, depth);
  }
  deepestHeld_ = held;
  keepTouching();
  return deepest;
}

std::vector<Scene::DeepPair> Scene::pairsDeeperThan(double depth) const {
  std::vector<DeepPair> deep;
  for (const TouchingPair& pair : touching_) {
    if (pair.odeDepth <= depth) continue;  // the least depth is never more
    const double d = measuredDepth(pair);
    if (d > depth) deep.push_back({d, touchingBefore(pair), pair.a, pair.b});
  }
  std::sort(deep.begin(), deep.end(),
            [](const DeepPair& x, const DeepPair& y) { return x.depth > y.depth; });
  return deep;
}

double Scene::measuredDepth(const TouchingPair& pair) const {
  return pair.round ? leastDepth(pair) : pair.odeDepth;
}

bool Scene::touchingBefore(const TouchingPair& pair) const {
  return std::binary_search(touchingBefore_.begin(), touchingBefore_.end(), pairKey(pair));
}

std::string Scene::describeGeom(dGeomID g) {
  const char* name = "geom";
  switch (dGeomGetClass(g)) {
    case dSphereClass:
      name = "sphere";
      break;
    case dBoxClass:
      name = "box";
      break;
    case dCapsuleClass:
      name = "capsule";
      break;
    case dCylinderClass:
      name = "cylinder";
      break;
    case dPlaneClass:
      name = "plane";
      break;
    case dConvexClass:
      name = "convex";
      break;
    case dTriMeshClass:
      name = "trimesh";
      break;
    case dHeightfieldClass:
      name = "heightfield";
      break;
    default:
      break;
  }
  char line[256];
  dBodyID b = dGeomGetBody(g);
  if (!b) {
    std::snprintf(line, sizeof line, "%s (static)", name);
    return line;
  }
  dMass m;
  dBodyGetMass(b, &m);
  const dReal* x = dBodyGetPosition(b);
  const dReal* v = dBodyGetLinearVel(b);
  const dReal* w = dBodyGetAngularVel(b);
  std::snprintf(line, sizeof line,
                "%s %.3f kg at (%.3f, %.3f, %.3f) m, v (%.2f, %.2f, %.2f) m/s, "
                "w (%.1f, %.1f, %.1f) rad/s",
                name, m.mass, x[0], x[1], x[2], v[0], v[1], v[2], w[0], w[1], w[2]);
  return line;
}

void Scene::keepTouching() {
  if (touchingKept_) return;
  touchingKept_ = true;
  touchingLast_.clear();
  for (const TouchingPair& pair : touching_)
    touchingLast_.push_back(pairKey(pair));
  std::sort(touchingLast_.begin(), touchingLast_.end());
}

bool Scene::coreShape(dGeomID g, Shape& out) const {
  switch (dGeomGetClass(g)) {
    case dSphereClass:
      out = Shape::sphere(0, dGeomSphereGetRadius(g));
      return true;
    case dBoxClass: {
      dVector3 side;
      dGeomBoxGetLengths(g, side);
      out = Shape::box(0, Vec3(0.5 * side[0], 0.5 * side[1], 0.5 * side[2]));
      return true;
    }
    case dCapsuleClass: {
      dReal r, length;
      dGeomCapsuleGetParams(g, &r, &length);
      out = Shape::capsule(0, r, length);
      return true;
    }
    case dCylinderClass: {
      dReal r, length;
      dGeomCylinderGetParams(g, &r, &length);
      out = Shape::cylinder(0, r, length);
      return true;
    }
    case dConvexClass:
      for (const auto& data : convexData_) {
        if (data->geom == g) {
          out = Shape::convex(0, data->hull);
          return true;
        }
      }
      return false;
    default:
      return false;
  }
}

double Scene::leastDepth(const TouchingPair& pair) const {
  Shape sa, sb;
  if (!coreShape(pair.a, sa) || !coreShape(pair.b, sb)) return pair.odeDepth;
  auto pose = [](dGeomID g) {
    const dReal* p = dGeomGetPosition(g);
    const dReal* R = dGeomGetRotation(g);  // 3 x 4, row by row
    Mat3 m;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        m(i, j) = R[4 * i + j];
    return ShapePose{Vec3(p[0], p[1], p[2]), m};
  };
  const PosedConvex A(sa, pose(pair.a)), B(sb, pose(pair.b));
  const double radii = A.radius + B.radius;  // spheres' and capsules' cores are points, lines
  const CoreDistance apart = coreDistance(A, B);
  if (!apart.overlapping) return std::max(0.0, radii - apart.distance);
  const CorePenetration deep = corePenetration(A, B);
  return deep.found ? deep.depth + radii : pair.odeDepth;
}

JointError Scene::jointError() const {
  JointError e;
  for (const JointRecord& r : joints_) {
    dVector3 p1, p2, d;
    worldPoint(r.body1, r.anchor1, p1);
    worldPoint(r.body2, r.anchor2, p2);
    for (int k = 0; k < 3; ++k)
      d[k] = p1[k] - p2[k];
    double angle = 0.0;
    if (r.kind == JointKind::Hinge2) {
      // The suspension gives along the steering axis by design: only the
      // separation across it is error; the axle stays square with it.
      dVector3 a1, a2;
      worldVector(r.body1, r.axis1, a1);
      worldVector(r.body2, r.axis2, a2);
      const double along = dCalcVectorDot3(d, a1);
      for (int k = 0; k < 3; ++k)
        d[k] -= along * a1[k];
      const double c = std::clamp(static_cast<double>(dCalcVectorDot3(a1, a2)), -1.0, 1.0);
      angle = std::abs(std::acos(c) - M_PI / 2);
    }
    const double sep = length(d);
    if (r.kind == JointKind::Hinge) {
      dVector3 a1, a2;
      worldVector(r.body1, r.axis1, a1);
      worldVector(r.body2, r.axis2, a2);
      const double c = std::clamp(static_cast<double>(dCalcVectorDot3(a1, a2)), -1.0, 1.0);
      angle = std::acos(c);
    } else if (r.kind == JointKind::Fixed) {
      dQuaternion q1, q2, rel, change;
      orientation(r.body1, q1);
      orientation(r.body2, q2);
      dQMultiply1(rel, q1, q2);
      dQMultiply2(change, rel, r.relative0);  // rel * relative0^-1
      angle = 2.0 * std::acos(std::min(1.0, std::abs(static_cast<double>(change[0]))));
    }
    if (!std::isfinite(sep) || !std::isfinite(angle)) {
      e.separation = e.angle = INFINITY;
      continue;
    }
    e.separation = std::max(e.separation, sep);
    e.angle = std::max(e.angle, angle);
    e.separationSumSq += sep * sep;
    ++e.joints;
  }
  return e;
}

double Scene::kineticEnergy() const {
  double energy = 0.0;
  for (dBodyID b : bodies_)
    energy += ode::kineticEnergy(b);
  return energy;
}

double Scene::potentialEnergy() const {
  dVector3 g;
  dWorldGetGravity(world_, g);
  double energy = 0.0;
  for (dBodyID b : bodies_) {
    if (!dBodyGetGravityMode(b)) continue;
    dMass m;
    dBodyGetMass(b, &m);
    const dReal* x = dBodyGetPosition(b);
    energy -= m.mass * (g[0] * x[0] + g[1] * x[1] + g[2] * x[2]);
  }
  return energy;
}

}  // namespace blockstep::compare

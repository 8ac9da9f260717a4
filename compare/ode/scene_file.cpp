// Writing a scene to JSON and building one from JSON (scene_file.h gives
// the format).
#include "compare/ode/scene_file.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <utility>
#include <vector>

namespace blockstep::compare {

namespace {

using nlohmann::json;

json vec3(const dReal* v) {
  return json::array({v[0], v[1], v[2]});
}

json quat(const dReal* q) {
  return json::array({q[0], q[1], q[2], q[3]});
}

int indexOf(const Scene& s, dBodyID b) {
  if (!b) return -1;
  const auto& bodies = s.bodies();
  return static_cast<int>(std::find(bodies.begin(), bodies.end(), b) - bodies.begin());
}

// The hinge2 parameters a scene file carries, by name.
const std::vector<std::pair<std::string, int>>& hinge2Params() {
  static const std::vector<std::pair<std::string, int>> params = {
      {"lo", dParamLoStop},
      {"hi", dParamHiStop},
      {"suspension_erp", dParamSuspensionERP},
      {"suspension_cfm", dParamSuspensionCFM},
      {"velocity2", dParamVel2},
      {"fmax2", dParamFMax2}};
  return params;
}

json geomToJson(const Scene& s, dGeomID g) {
  json j;
  switch (dGeomGetClass(g)) {
    case dConvexClass: {
      const std::vector<dReal>* points = s.convexPoints(g);
      if (!points)
        throw std::invalid_argument("scene file: a convex geom not made by Scene::addConvex");
      j = {{"type", "convex"}, {"points", *points}};
      break;
    }
    case dBoxClass: {
      dVector3 size;
      dGeomBoxGetLengths(g, size);
      j = {{"type", "box"}, {"size", vec3(size)}};
      break;
    }
    case dSphereClass:
      j = {{"type", "sphere"}, {"radius", dGeomSphereGetRadius(g)}};
      break;
    case dCapsuleClass:
    case dCylinderClass: {
      dReal r, l;
      const bool capsule = dGeomGetClass(g) == dCapsuleClass;
      if (capsule) {
        dGeomCapsuleGetParams(g, &r, &l);
      } else {
        dGeomCylinderGetParams(g, &r, &l);
      }
      j = {{"type", capsule ? "capsule" : "cylinder"}, {"radius", r}, {"length", l}};
      break;
    }
    case dPlaneClass: {
      dVector4 p;
      dGeomPlaneGetParams(g, p);
      return {{"type", "plane"}, {"normal", vec3(p)}, {"offset", p[3]}};
    }
    default:
      throw std::invalid_argument("scene file: geom class " + std::to_string(dGeomGetClass(g)) +
                                  " cannot be written (box, sphere, capsule, cylinder, convex, "
                                  "plane)");
  }
  if (!dGeomGetBody(g)) {
    j["position"] = vec3(dGeomGetPosition(g));
    dQuaternion q;
    dGeomGetQuaternion(g, q);
    j["quaternion"] = quat(q);
  } else if (dGeomGetOffsetPosition(g) && dGeomIsOffset(g)) {
    throw std::invalid_argument("scene file: geoms offset from their body cannot be written");
  }
  j["category_bits"] = static_cast<std::uint64_t>(dGeomGetCategoryBits(g));
  j["collide_bits"] = static_cast<std::uint64_t>(dGeomGetCollideBits(g));
  return j;
}

// Reading, with the path of the field being read for every error.
struct Reader {
  std::string path;

  [[noreturn]] void fail(const std::string& why) const {
    throw std::invalid_argument("scene file: " + path + ": " + why);
  }
  Reader at(const std::string& key) const { return {path.empty() ? key : path + "." + key}; }
  Reader at(std::size_t i) const { return {path + "[" + std::to_string(i) + "]"}; }

  const json& field(const json& j, const char* key) const {
    if (!j.is_object()) fail("must be an object");
    const auto it = j.find(key);
    if (it == j.end()) at(key).fail("missing");
    return *it;
  }
  double number(const json& j) const {
    if (!j.is_number()) fail("must be a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail("must be finite");
    return v;
  }
  void vector(const json& j, int n, dReal* out) const {
    if (!j.is_array() || static_cast<int>(j.size()) != n)
      fail("must be an array of " + std::to_string(n) + " numbers");
    for (int k = 0; k < n; ++k)
      out[k] = at(static_cast<std::size_t>(k)).number(j[static_cast<std::size_t>(k)]);
  }
  double positive(const json& j) const {
    const double v = number(j);
    if (!(v > 0.0)) fail("must be > 0");
    return v;
  }
  // j[key] when it must be an array (nullptr when it may be and is absent).
  const json* array(const json& j, const char* key, bool required) const {
    if (!j.contains(key)) {
      if (required) at(key).fail("missing");
      return nullptr;
    }
    const json& a = j.at(key);
    if (!a.is_array()) at(key).fail("must be an array");
    return &a;
  }
  std::string text(const json& j) const {
    if (!j.is_string()) fail("must be a string");
    return j.get<std::string>();
  }
};

void readOptionalVector(const Reader& r, const json& j, const char* key, int n, dReal* out) {
  if (j.contains(key)) r.at(key).vector(j.at(key), n, out);
}

void normalizedQuaternion(const Reader& r, const json& j, dQuaternion q) {
  dQSetIdentity(q);
  if (!j.contains("quaternion")) return;
  r.at("quaternion").vector(j.at("quaternion"), 4, q);
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (n < 1e-9) r.at("quaternion").fail("must not be zero");
  if (std::abs(n - 1.0) > 1e-12) {  // a written one reads back bit for bit
    for (int k = 0; k < 4; ++k)
      q[k] /= n;
  }
}

dGeomID makeGeom(const Reader& r, const json& j, Scene& s) {
  dSpaceID space = s.space();
  const std::string type = r.at("type").text(r.field(j, "type"));
  dGeomID g = nullptr;
  if (type == "box") {
    dVector3 size;
    r.at("size").vector(r.field(j, "size"), 3, size);
    for (int k = 0; k < 3; ++k)
      if (!(size[k] > 0)) r.at("size").fail("sides must be > 0");
    g = dCreateBox(space, size[0], size[1], size[2]);
  } else if (type == "sphere") {
    g = dCreateSphere(space, r.at("radius").positive(r.field(j, "radius")));
  } else if (type == "capsule" || type == "cylinder") {
    const double radius = r.at("radius").positive(r.field(j, "radius"));
    const double length = r.at("length").positive(r.field(j, "length"));
    g = type == "capsule" ? dCreateCapsule(space, radius, length)
                          : dCreateCylinder(space, radius, length);
  } else if (type == "plane") {
    dVector3 n;
    r.at("normal").vector(r.field(j, "normal"), 3, n);
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len < 1e-9) r.at("normal").fail("must not be zero");
    const double d = r.at("offset").number(r.field(j, "offset"));
    g = dCreatePlane(space, n[0] / len, n[1] / len, n[2] / len, d / len);
  } else if (type == "convex") {
    const json& points = r.field(j, "points");
    if (!points.is_array() || points.size() < 12 || points.size() % 3 != 0)
      r.at("points").fail("must be x, y, z of 4 or more points");
    std::vector<double> xyz;
    for (std::size_t k = 0; k < points.size(); ++k)
      xyz.push_back(r.at("points").at(k).number(points[k]));
    try {
      g = s.addConvex(xyz, nullptr, 0.0, nullptr);
    } catch (const std::exception& e) {
      r.at("points").fail(e.what());
    }
  } else {
    r.at("type").fail("'" + type + "' is not box, sphere, capsule, cylinder, convex or plane");
  }
  if (j.contains("category_bits")) {
    if (!j.at("category_bits").is_number_unsigned()) r.at("category_bits").fail("must be >= 0");
    dGeomSetCategoryBits(g, j.at("category_bits").get<std::uint64_t>());
  }
  if (j.contains("collide_bits")) {
    if (!j.at("collide_bits").is_number_unsigned()) r.at("collide_bits").fail("must be >= 0");
    dGeomSetCollideBits(g, j.at("collide_bits").get<std::uint64_t>());
  }
  return g;
}

void readMass(const Reader& r, const json& j, dMass& m) {
  const double total = r.at("total").positive(r.field(j, "total"));
  dVector3 c = {0, 0, 0};
  readOptionalVector(r, j, "center", 3, c);
  dReal I[6];
  r.at("inertia").vector(r.field(j, "inertia"), 6, I);
  // Positive definite: the leading minors of [I11 I12 I13; I12 I22 I23; I13 I23 I33].
  const double m1 = I[0], m2 = I[0] * I[1] - I[3] * I[3];
  const double m3 = I[0] * (I[1] * I[2] - I[5] * I[5]) - I[3] * (I[3] * I[2] - I[5] * I[4]) +
                    I[4] * (I[3] * I[5] - I[1] * I[4]);
  if (!(m1 > 0 && m2 > 0 && m3 > 0)) r.at("inertia").fail("must be positive definite");
  dMassSetParameters(&m, total, c[0], c[1], c[2], I[0], I[1], I[2], I[3], I[4], I[5]);
}

}  // namespace

nlohmann::json sceneToJson(const Scene& s) {
  json j;
  j["name"] = s.name();
  dVector3 g;
  dWorldGetGravity(s.world(), g);
  j["gravity"] = vec3(g);
  j["erp"] = dWorldGetERP(s.world());
  j["cfm"] = dWorldGetCFM(s.world());
  json bodies = json::array();
  for (dBodyID b : s.bodies()) {
    json body;
    body["position"] = vec3(dBodyGetPosition(b));
    body["quaternion"] = quat(dBodyGetQuaternion(b));
    body["linear_velocity"] = vec3(dBodyGetLinearVel(b));
    body["angular_velocity"] = vec3(dBodyGetAngularVel(b));
    dMass m;
    dBodyGetMass(b, &m);
    body["mass"] = {{"total", m.mass},
                    {"center", vec3(m.c)},
                    {"inertia", {m.I[0], m.I[5], m.I[10], m.I[1], m.I[2], m.I[6]}}};
    json geoms = json::array();
    for (dGeomID geom = dBodyGetFirstGeom(b); geom; geom = dBodyGetNextGeom(geom))
      geoms.push_back(geomToJson(s, geom));
    if (!geoms.empty()) body["geoms"] = geoms;
    bodies.push_back(body);
  }
  j["bodies"] = bodies;
  json statics = json::array();
  for (int i = 0; i < dSpaceGetNumGeoms(s.space()); ++i) {
    dGeomID geom = dSpaceGetGeom(s.space(), i);
    if (!dGeomGetBody(geom)) statics.push_back(geomToJson(s, geom));
  }
  // The space keeps geoms in the order they last moved: static geoms never
  // move, so they come out in reverse of their making; put them back.
  std::reverse(statics.begin(), statics.end());
  j["static"] = statics;
  json joints = json::array();
  for (const JointRecord& r : s.joints()) {
    json joint;
    joint["bodies"] = {indexOf(s, r.body1), indexOf(s, r.body2)};
    dVector3 anchor, axis;
    switch (r.kind) {
      case JointKind::Ball:
        joint["type"] = "ball";
        dJointGetBallAnchor(r.joint, anchor);
        joint["anchor"] = vec3(anchor);
        break;
      case JointKind::Hinge: {
        joint["type"] = "hinge";
        dJointGetHingeAnchor(r.joint, anchor);
        dJointGetHingeAxis(r.joint, axis);
        joint["anchor"] = vec3(anchor);
        joint["axis"] = vec3(axis);
        const double lo = dJointGetHingeParam(r.joint, dParamLoStop);
        const double hi = dJointGetHingeParam(r.joint, dParamHiStop);
        if (std::isfinite(lo)) joint["lo"] = lo;
        if (std::isfinite(hi)) joint["hi"] = hi;
        if (dJointGetHingeParam(r.joint, dParamFMax) > 0.0) {
          joint["velocity"] = dJointGetHingeParam(r.joint, dParamVel);
          joint["fmax"] = dJointGetHingeParam(r.joint, dParamFMax);
        }
        break;
      }
      case JointKind::Fixed:
        joint["type"] = "fixed";
        break;
      case JointKind::Hinge2: {
        joint["type"] = "hinge2";
        dJointGetHinge2Anchor(r.joint, anchor);
        dVector3 axle;
        dJointGetHinge2Axis1(r.joint, axis);
        dJointGetHinge2Axis2(r.joint, axle);
        joint["anchor"] = vec3(anchor);
        joint["steering"] = vec3(axis);
        joint["axle"] = vec3(axle);
        for (const auto& [key, param] : hinge2Params()) {
          const double v = dJointGetHinge2Param(r.joint, param);
          if (std::isfinite(v)) joint[key] = v;
        }
        break;
      }
    }
    joints.push_back(joint);
  }
  j["joints"] = joints;
  if (s.probe()) j["probe"] = indexOf(s, s.probe());
  const dSurfaceParameters& surface = s.contactSurface();
  j["contact"] = {{"mu", std::isfinite(surface.mu) ? surface.mu : -1.0},
                  {"approx1", (surface.mode & dContactApprox1) != 0}};
  if (surface.mode & dContactBounce) j["contact"]["bounce"] = {surface.bounce, surface.bounce_vel};
  const DrawHints& draw = s.drawHints();
  if (draw.surfaceColumns > 0)
    j["draw"]["surface"] = {{"columns", draw.surfaceColumns}, {"bodies", draw.surface}};
  if (!draw.strands.empty()) j["draw"]["strands"] = draw.strands;
  return j;
}

// A unit vector from a non-zero one.
void unitVector(const Reader& r, const json& j, dVector3 out) {
  r.vector(j, 3, out);
  const double len = std::sqrt(dCalcVectorDot3(out, out));
  if (len < 1e-9) r.fail("must not be zero");
  for (int k = 0; k < 3; ++k)
    out[k] /= len;
}

// The contact surface: {"mu": m (-1: infinite), "approx1": true,
// "bounce": [restitution, least speed]}.
void readContact(const Reader& r, const json& j, Scene& s) {
  if (!j.is_object()) r.fail("must be an object");
  dSurfaceParameters surface{};
  const double mu = r.at("mu").number(r.field(j, "mu"));
  if (mu < 0 && mu != -1.0) r.at("mu").fail("must be >= 0, or -1 for no limit");
  surface.mu = mu < 0 ? dInfinity : mu;
  if (j.contains("approx1")) {
    if (!j.at("approx1").is_boolean()) r.at("approx1").fail("must be true or false");
    if (j.at("approx1").get<bool>()) surface.mode |= dContactApprox1;
  }
  if (j.contains("bounce")) {
    dReal bounce[2];
    r.at("bounce").vector(j.at("bounce"), 2, bounce);
    if (bounce[0] < 0 || bounce[0] > 1) r.at("bounce").fail("restitution must be in [0, 1]");
    surface.mode |= dContactBounce;
    surface.bounce = bounce[0];
    surface.bounce_vel = bounce[1];
  }
  s.setContactSurface(surface);
}

// A list of body indices, each in 0..count-1.
std::vector<int> bodyIndices(const Reader& r, const json& j, int count) {
  if (!j.is_array()) r.fail("must be an array of body indices");
  std::vector<int> out;
  for (std::size_t k = 0; k < j.size(); ++k) {
    if (!j[k].is_number_integer() || j[k].get<int>() < 0 || j[k].get<int>() >= count)
      r.at(k).fail("must be a body index 0.." + std::to_string(count - 1));
    out.push_back(j[k].get<int>());
  }
  return out;
}

void readDrawHints(const Reader& r, const json& j, int count, DrawHints& draw) {
  if (!j.is_object()) r.fail("must be an object");
  if (j.contains("surface")) {
    const Reader rs = r.at("surface");
    const json& surface = j.at("surface");
    const json& columns = rs.field(surface, "columns");
    if (!columns.is_number_integer() || columns.get<int>() < 2)
      rs.at("columns").fail("must be a whole number >= 2");
    draw.surfaceColumns = columns.get<int>();
    draw.surface = bodyIndices(rs.at("bodies"), rs.field(surface, "bodies"), count);
    if (draw.surface.size() < 2 * static_cast<std::size_t>(draw.surfaceColumns) ||
        draw.surface.size() % draw.surfaceColumns != 0)
      rs.at("bodies").fail("must be at least two whole rows of 'columns' bodies");
  }
  if (const json* strands = r.array(j, "strands", false)) {
    for (std::size_t k = 0; k < strands->size(); ++k)
      draw.strands.push_back(bodyIndices(r.at("strands").at(k), (*strands)[k], count));
  }
}

std::unique_ptr<Scene> sceneFromJson(const nlohmann::json& j) {
  const Reader root{""};
  if (!j.is_object()) root.fail("the scene must be a JSON object");
  auto s = std::make_unique<Scene>();
  s->setName(j.contains("name") ? root.at("name").text(j.at("name")) : "scene_file");
  if (j.contains("gravity")) {
    dVector3 g;
    root.at("gravity").vector(j.at("gravity"), 3, g);
    dWorldSetGravity(s->world(), g[0], g[1], g[2]);
  }
  if (j.contains("erp")) {
    const double erp = root.at("erp").number(j.at("erp"));
    if (erp < 0 || erp > 1) root.at("erp").fail("must be in [0, 1]");
    dWorldSetERP(s->world(), erp);
  }
  if (j.contains("cfm")) {
    const double cfm = root.at("cfm").number(j.at("cfm"));
    if (cfm < 0) root.at("cfm").fail("must be >= 0");
    dWorldSetCFM(s->world(), cfm);
  }
  const json& bodies = *root.array(j, "bodies", true);
  const Reader rb = root.at("bodies");
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const Reader r = rb.at(i);
    const json& body = bodies[i];
    dMass m;
    readMass(r.at("mass"), r.field(body, "mass"), m);
    dVector3 p;
    r.at("position").vector(r.field(body, "position"), 3, p);
    dBodyID b = s->addBody(m, p[0], p[1], p[2]);
    dQuaternion q;
    normalizedQuaternion(r, body, q);
    dBodySetQuaternion(b, q);
    dVector3 v = {0, 0, 0}, w = {0, 0, 0};
    readOptionalVector(r, body, "linear_velocity", 3, v);
    readOptionalVector(r, body, "angular_velocity", 3, w);
    dBodySetLinearVel(b, v[0], v[1], v[2]);
    dBodySetAngularVel(b, w[0], w[1], w[2]);
    if (const json* geomList = r.array(body, "geoms", false)) {
      const json& geoms = *geomList;
      for (std::size_t k = 0; k < geoms.size(); ++k) {
        const Reader rg = r.at("geoms").at(k);
        dGeomID g = makeGeom(rg, geoms[k], *s);
        if (dGeomGetClass(g) == dPlaneClass) rg.at("type").fail("a plane cannot belong to a body");
        s->addGeom(g, b);
      }
    }
  }
  if (const json* staticList = root.array(j, "static", false)) {
    const json& statics = *staticList;
    const Reader rs = root.at("static");
    for (std::size_t i = 0; i < statics.size(); ++i) {
      const Reader r = rs.at(i);
      dGeomID g = makeGeom(r, statics[i], *s);
      if (dGeomGetClass(g) == dPlaneClass) continue;
      dVector3 p;
      r.at("position").vector(r.field(statics[i], "position"), 3, p);
      dGeomSetPosition(g, p[0], p[1], p[2]);
      dQuaternion q;
      normalizedQuaternion(r, statics[i], q);
      dGeomSetQuaternion(g, q);
    }
  }
  const int count = static_cast<int>(s->bodies().size());
  auto body = [&](const Reader& r, const json& index, bool worldAllowed) -> dBodyID {
    if (!index.is_number_integer()) r.fail("must be a body index");
    const int k = index.get<int>();
    if (k == -1 && worldAllowed) return nullptr;
    if (k < 0 || k >= count)
      r.fail(std::to_string(k) + " is not a body (0.." + std::to_string(count - 1) +
             (worldAllowed ? ", or -1 for the world)" : ")"));
    return s->bodies()[static_cast<std::size_t>(k)];
  };
  if (const json* jointList = root.array(j, "joints", false)) {
    const json& joints = *jointList;
    const Reader rj = root.at("joints");
    for (std::size_t i = 0; i < joints.size(); ++i) {
      const Reader r = rj.at(i);
      const json& joint = joints[i];
      const std::string type = r.at("type").text(r.field(joint, "type"));
      const json& pair = r.field(joint, "bodies");
      if (!pair.is_array() || pair.size() != 2) r.at("bodies").fail("must be [i, j]");
      dBodyID b1 = body(r.at("bodies").at(std::size_t{0}), pair[0], false);
      dBodyID b2 = body(r.at("bodies").at(std::size_t{1}), pair[1], true);
      if (b1 == b2) r.at("bodies").fail("a joint needs two different bodies");
      if (type == "ball" || type == "hinge") {
        dVector3 anchor;
        r.at("anchor").vector(r.field(joint, "anchor"), 3, anchor);
        if (type == "ball") {
          s->ball(b1, b2, anchor[0], anchor[1], anchor[2]);
          continue;
        }
        dVector3 axis;
        r.at("axis").vector(r.field(joint, "axis"), 3, axis);
        const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        if (len < 1e-9) r.at("axis").fail("must not be zero");
        for (int k = 0; k < 3; ++k)
          axis[k] /= len;
        dJointID h = s->hinge(b1, b2, anchor, axis);
        const double lo = joint.contains("lo") ? r.at("lo").number(joint.at("lo")) : -dInfinity;
        const double hi = joint.contains("hi") ? r.at("hi").number(joint.at("hi")) : dInfinity;
        if (lo > hi) r.at("lo").fail("must not be above hi");
        dJointSetHingeParam(h, dParamLoStop, lo);
        dJointSetHingeParam(h, dParamHiStop, hi);
        if (joint.contains("velocity"))
          dJointSetHingeParam(h, dParamVel, r.at("velocity").number(joint.at("velocity")));
        if (joint.contains("fmax")) {
          const double fmax = r.at("fmax").number(joint.at("fmax"));
          if (fmax < 0.0) r.at("fmax").fail("must be >= 0");
          dJointSetHingeParam(h, dParamFMax, fmax);
        }
      } else if (type == "fixed") {
        s->fixed(b1, b2);
      } else if (type == "hinge2") {
        if (!b2) r.at("bodies").fail("a hinge2 joins two bodies");
        dVector3 anchor, steering, axle;
        r.at("anchor").vector(r.field(joint, "anchor"), 3, anchor);
        unitVector(r.at("steering"), r.field(joint, "steering"), steering);
        unitVector(r.at("axle"), r.field(joint, "axle"), axle);
        if (std::abs(dCalcVectorDot3(steering, axle)) > 0.999)
          r.at("axle").fail("must not be parallel to the steering axis");
        dJointID h = s->hinge2(b1, b2, anchor, steering, axle);
        for (const auto& [key, param] : hinge2Params()) {
          if (joint.contains(key)) dJointSetHinge2Param(h, param, r.at(key).number(joint.at(key)));
        }
      } else {
        r.at("type").fail("'" + type + "' is not ball, hinge, fixed or hinge2");
      }
    }
  }
  if (j.contains("probe")) s->setProbe(body(root.at("probe"), j.at("probe"), false));
  if (j.contains("contact")) readContact(root.at("contact"), j.at("contact"), *s);
  if (j.contains("draw")) readDrawHints(root.at("draw"), j.at("draw"), count, s->drawHints());
  return s;
}

void saveSceneFile(const Scene& scene, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << sceneToJson(scene).dump(1) << '\n';
}

std::unique_ptr<Scene> loadSceneFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("scene file " + path + ": cannot be read");
  json j;
  try {
    in >> j;
  } catch (const json::parse_error& e) {
    throw std::invalid_argument("scene file " + path + ": not JSON: " + e.what());
  }
  return sceneFromJson(j);
}

}  // namespace blockstep::compare

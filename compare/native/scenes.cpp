#include "compare/native/scenes.h"

#include <algorithm>
#include <cmath>

#include "core/body/mass.h"

namespace blockstep::scenes {
namespace {

BodyId addBody(World& w, const Vec3& position, const MassProperties& m,
               const Quat& q = Quat::Identity()) {
  BodyDesc d;
  d.position = position;
  d.orientation = q;
  d.mass = m.mass;
  d.inertia = m.inertia;
  return w.createBody(d);
}

}  // namespace

const std::vector<std::string>& sceneNames() {
  static const std::vector<std::string> names = {"ragdoll",       "chain",   "chain_swing",
                                                 "cloth16",       "cloth32", "softcube",
                                                 "softcube_ball", "stack",   "pyramid"};
  return names;
}

void makeScene(const std::string& name, Scene& s) {
  if (name == "ragdoll") return ragdoll(s);
  if (name == "chain") return chain(s, false);
  if (name == "chain_swing") return chain(s, true);
  if (name == "cloth16") return cloth(s, 16);
  if (name == "cloth32") return cloth(s, 32);
  if (name == "softcube") return softcube(s, false);
  if (name == "softcube_ball") return softcube(s, true);
  if (name == "stack") return stack(s);
  if (name == "pyramid") return pyramid(s, 20);
  throw Error("unknown scene '" + name + "'");
}

void ragdoll(Scene& s) {
  s.name = "ragdoll";
  World& w = s.world;
  const BodyId pelvis = addBody(w, Vec3(0, 0, 1.2), boxMass(10.0, Vec3(0.30, 0.20, 0.20)));
  const BodyId torso = addBody(w, Vec3(0, 0, 1.5), boxMass(15.0, Vec3(0.34, 0.20, 0.40)));
  const BodyId head = addBody(w, Vec3(0, 0, 1.85), capsuleMass(5.0, 0.08, 0.14));
  const BodyId thighL = addBody(w, Vec3(-0.1, 0, 0.85), capsuleMass(7.0, 0.06, 0.38));
  const BodyId thighR = addBody(w, Vec3(0.1, 0, 0.85), capsuleMass(7.0, 0.06, 0.38));
  for (BodyId b : {pelvis, torso, head, thighL, thighR})
    w.setLinearVelocity(b, Vec3(0.5, 0.2, 0));
  w.setAngularVelocity(torso, Vec3(1, 2, 0));

  HingeJointDesc spine;
  spine.common.bodyA = pelvis;
  spine.common.bodyB = torso;
  spine.anchor = Vec3(0, 0, 1.3);
  spine.axis = Vec3::UnitX();
  spine.limit = Limit{true, -0.3, 0.8, Softness::erpCfm(0.2, 0.0)};
  s.joints.push_back(w.createJoint(spine));

  BallJointDesc neck;
  neck.common.bodyA = torso;
  neck.common.bodyB = head;
  neck.anchor = Vec3(0, 0, 1.7);
  s.joints.push_back(w.createJoint(neck));

  for (BodyId thigh : {thighL, thighR}) {
    HingeJointDesc hip;
    hip.common.bodyA = pelvis;
    hip.common.bodyB = thigh;
    hip.anchor = Vec3(w.body(thigh).position.x(), 0, 1.1);
    hip.axis = Vec3::UnitX();
    hip.limit = Limit{true, -1.2, 0.5, Softness::erpCfm(0.2, 0.0)};
    s.joints.push_back(w.createJoint(hip));
  }
}

void chain(Scene& s, bool swing) {
  s.name = swing ? "chain_swing" : "chain";
  World& w = s.world;
  const int links = 50;
  const double length = 0.1, radius = 0.01;
  const Vec3 pin(0, 0, 6);
  // Hanging: links go down -z; swinging: released horizontally along +x.
  const Vec3 dir = swing ? Vec3(Vec3::UnitX()) : Vec3(-Vec3::UnitZ());
  // Capsules lie along their own z axis: turn z onto the chain direction.
  const Quat q = Quat::FromTwoVectors(Vec3::UnitZ(), dir);
  BodyId previous = kWorldBody;
  for (int i = 0; i < links; ++i) {
    const double mass = i == links - 1 ? 10.0 : 0.1;
    const BodyId link = addBody(w, pin + dir * (length * (i + 0.5)),
                                capsuleMass(mass, radius, length - 2 * radius), q);
    BallJointDesc j;
    j.common.bodyA = previous;
    j.common.bodyB = link;
    j.anchor = pin + dir * (length * i);
    s.joints.push_back(w.createJoint(j));
    previous = link;
  }
}

void cloth(Scene& s, int n) {
  s.name = "cloth" + std::to_string(n);
  World& w = s.world;
  const double cell = 0.05, spacing = 0.05, z = 1.5;
  std::vector<BodyId> ids(static_cast<std::size_t>(n) * n);
  const MassProperties m = boxMass(0.01, Vec3(cell, cell, cell));
  const double offset = 0.5 * spacing * (n - 1);  // centred over the origin
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      ids[i * n + j] = addBody(w, Vec3(i * spacing - offset, j * spacing - offset, z), m);
    }
  }
  auto link = [&](BodyId a, BodyId b) {
    BallJointDesc d;
    d.common.bodyA = a;
    d.common.bodyB = b;
    d.anchor = 0.5 * (w.body(a).position + w.body(b).position);  // the shared edge's midpoint
    s.joints.push_back(w.createJoint(d));
  };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i + 1 < n) link(ids[i * n + j], ids[(i + 1) * n + j]);
      if (j + 1 < n) link(ids[i * n + j], ids[i * n + j + 1]);
    }
  }
  for (BodyId corner : {ids[0], ids[(n - 1) * n]}) {  // cells (0, 0) and (n - 1, 0)
    BallJointDesc pin;
    pin.common.bodyB = corner;
    pin.anchor = w.body(corner).position;
    s.joints.push_back(w.createJoint(pin));
  }
}

void softcube(Scene& s, bool ballJoints) {
  s.name = ballJoints ? "softcube_ball" : "softcube";
  World& w = s.world;
  const int n = 5;
  const double cell = 0.1;
  const Quat q(Eigen::AngleAxisd(0.4, Vec3(1, 1, 0).normalized()));
  const Vec3 centre(0, 0, 1.0);
  const MassProperties m = boxMass(0.1, Vec3(cell, cell, cell));
  std::vector<BodyId> ids(n * n * n);
  auto index = [&](int i, int j, int k) { return (i * n + j) * n + k; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Vec3 local = cell * Vec3(i - 2, j - 2, k - 2);
        ids[index(i, j, k)] = addBody(w, centre + q * local, m, q);
      }
  auto link = [&](BodyId a, BodyId b) {
    if (ballJoints) {
      BallJointDesc d;
      d.common.bodyA = a;
      d.common.bodyB = b;
      d.anchor = 0.5 * (w.body(a).position + w.body(b).position);
      s.joints.push_back(w.createJoint(d));
    } else {
      FixedJointDesc d;
      d.common.bodyA = a;
      d.common.bodyB = b;
      s.joints.push_back(w.createJoint(d));
    }
  };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        if (i + 1 < n) link(ids[index(i, j, k)], ids[index(i + 1, j, k)]);
        if (j + 1 < n) link(ids[index(i, j, k)], ids[index(i, j + 1, k)]);
        if (k + 1 < n) link(ids[index(i, j, k)], ids[index(i, j, k + 1)]);
      }
  // Without the ground yet, hang it by one top corner so the joints carry
  // the whole lattice's weight and swing.
  const BodyId corner = ids[index(0, 0, n - 1)];
  BallJointDesc pin;
  pin.common.bodyB = corner;
  pin.anchor = w.body(corner).position;
  s.joints.push_back(w.createJoint(pin));
}

namespace {

BodyId addGroundBox(World& w, const Vec3& position) {
  const MassProperties m = boxMass(1.0, Vec3(0.5, 0.5, 0.5));
  const BodyId id = addBody(w, position, m);
  w.addShape(Shape::box(id, Vec3(0.25, 0.25, 0.25)));
  return id;
}

}  // namespace

void stack(Scene& s) {
  s.name = "stack";
  s.world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  for (int i = 0; i < 10; ++i)
    s.tracked = addGroundBox(s.world, Vec3(0, 0, 0.25 + 0.5 * i));
  s.trackedStart = s.world.body(s.tracked).position;
}

void pyramid(Scene& s, int base) {
  s.name = "pyramid";
  s.world.addShape(Shape::plane(Vec3::UnitZ(), 0.0));
  for (int row = 0; row < base; ++row) {
    const int count = base - row;
    for (int k = 0; k < count; ++k) {
      // Each row sits half a spacing in from the one below.
      const double x = (k - 0.5 * (count - 1)) * 0.525;
      s.tracked = addGroundBox(s.world, Vec3(x, 0, 0.25 + 0.5 * row));
    }
  }
  s.trackedStart = s.world.body(s.tracked).position;
}

Quality measure(const Scene& s) {
  Quality q;
  if (s.tracked != kWorldBody) {
    q.drift = (s.world.body(s.tracked).position - s.trackedStart).norm();
  }
  for (const ContactManifold& m : s.world.contacts()) {
    for (int i = 0; i < m.pointCount; ++i) {
      q.penetration = std::max(q.penetration, -m.points[i].separation);
    }
  }
  for (JointId j : s.joints) {
    const JointError e = s.world.jointError(j);
    q.maxSeparation = std::max(q.maxSeparation, e.linear);
    q.maxAngle = std::max(q.maxAngle, e.angular);
  }
  return q;
}

}  // namespace blockstep::scenes

// World: shapes, caller-given contacts, the collide stage and the
// matching of contact points across steps for warm starting.
#include <algorithm>
#include <cmath>
#include <string>

#include "core/world/world.h"

namespace blockstep {
namespace {

std::string bodyName(BodyId id) {
  return id == kWorldBody ? std::string("the world") : "body " + std::to_string(id);
}

}  // namespace

ShapeId World::addShape(const Shape& shape) {
  Shape s = shape;
  const std::string who = "shape on " + bodyName(s.body);
  if (s.body != kWorldBody) body(s.body);
  if (!s.localPosition.allFinite()) throw Error(who + ": position is not finite");
  if (!isFinite(s.localOrientation) || s.localOrientation.norm() < 1e-9) {
    throw Error(who + ": orientation must be a finite, non-zero quaternion");
  }
  s.localOrientation.normalize();
  switch (s.kind) {
    case Shape::Kind::Sphere:
      if (!(s.radius > 0.0) || !std::isfinite(s.radius)) {
        throw Error(who + ": sphere radius must be positive and finite");
      }
      break;
    case Shape::Kind::Box:
      if (!(s.halfExtents.minCoeff() > 0.0) || !s.halfExtents.allFinite()) {
        throw Error(who + ": box half extents must be positive and finite");
      }
      break;
    case Shape::Kind::Plane: {
      if (s.body != kWorldBody) throw Error(who + ": planes belong to the world (kWorldBody)");
      const double n = s.planeNormal.norm();
      if (!s.planeNormal.allFinite() || n < 1e-9 || !std::isfinite(s.planeOffset)) {
        throw Error(who + ": plane needs a finite non-zero normal and a finite offset");
      }
      s.planeNormal /= n;
      s.planeOffset /= n;
      break;
    }
  }
  if (!(s.friction >= 0.0) || !(s.restitution >= 0.0 && s.restitution <= 1.0)) {
    throw Error(who + ": friction must be >= 0 and restitution in [0, 1]");
  }
  shapes_.push_back(s);
  return static_cast<ShapeId>(shapes_.size() - 1);
}

void World::removeShape(ShapeId id) {
  if (id < 0 || id >= static_cast<ShapeId>(shapes_.size()) || !shapes_[id].alive) {
    throw Error("no shape " + std::to_string(id) + " in this world");
  }
  shapes_[id].alive = false;
}

void World::addContact(const ContactManifold& manifold) {
  ContactManifold m = manifold;
  // Named only when there is an error: contacts are added every step.
  auto who = [&m] { return "contact between " + bodyName(m.bodyA) + " and " + bodyName(m.bodyB); };
  if (m.bodyA == m.bodyB) throw Error(who() + ": a contact needs two different bodies");
  if (m.bodyA != kWorldBody) body(m.bodyA);
  if (m.bodyB != kWorldBody) body(m.bodyB);
  const double n = m.normal.norm();
  if (!m.normal.allFinite() || n < 1e-9)
    throw Error(who() + ": normal must be finite and non-zero");
  m.normal /= n;
  if (m.pointCount < 1 || m.pointCount > kMaxManifoldPoints) {
    throw Error(who() + ": 1 to 4 points, got " + std::to_string(m.pointCount));
  }
  for (int i = 0; i < m.pointCount; ++i) {
    if (!m.points[i].position.allFinite() || !std::isfinite(m.points[i].separation)) {
      throw Error(who() + ": point " + std::to_string(i) + " is not finite");
    }
  }
  const ContactSurface& c = m.surface;
  if (!(c.mu >= 0.0) || std::isnan(c.mu2) || !(c.rolling >= 0.0) || !(c.spinning >= 0.0) ||
      !(c.slip1 >= 0.0) || !(c.slip2 >= 0.0) || !std::isfinite(c.slip1) ||
      !std::isfinite(c.slip2)) {
    throw Error(who() + ": friction, rolling, spinning and slip must be >= 0");
  }
  if (!(c.restitution >= 0.0 && c.restitution <= 1.0) || !(c.restitutionThreshold >= 0.0)) {
    throw Error(who() + ": restitution must be in [0, 1] with a threshold >= 0");
  }
  if (!c.softness.valid() || !(c.slop >= 0.0) || !(c.maxCorrectingVelocity > 0.0)) {
    throw Error(who() + ": invalid softness, slop (>= 0) or max correcting velocity (> 0)");
  }
  if (!c.frictionDir1.allFinite() || !std::isfinite(c.motion1) || !std::isfinite(c.motion2) ||
      !std::isfinite(c.motionN)) {
    throw Error(who() + ": friction direction and surface velocities must be finite");
  }
  // Impulses come from our own matching with the last step, not the caller.
  for (ContactPoint& p : m.points) {
    p.normalImpulse = p.tangentImpulse[0] = p.tangentImpulse[1] = 0.0;
  }
  m.rollingImpulse[0] = m.rollingImpulse[1] = m.rollingImpulse[2] = 0.0;
  m.warmStepSize = 0.0;
  contacts_.push_back(m);
}

void World::setContactMatchDistance(double d) {
  if (!(d >= 0.0) || !std::isfinite(d)) throw Error("contact match distance must be >= 0");
  matchDistance_ = d;
}

void World::collide() {
  bool anyShape = false;
  for (const Shape& s : shapes_)
    anyShape |= s.alive;
  if (!anyShape) return;
  jointedPairs_.clear();
  for (const Joint& j : joints_) {
    if (!j.alive) continue;
    const JointCommon& c = common(j.desc);
    if (c.bodyA != kWorldBody && c.bodyB != kWorldBody) {
      jointedPairs_.push_back(bodyPairKey(c.bodyA, c.bodyB));
    }
  }
  std::sort(jointedPairs_.begin(), jointedPairs_.end());
  collideShapes(shapes_, bodies_, collision_, jointedPairs_, contacts_);
}

// Tangents, body-fixed anchors, and the impulses of the matching points of
// the last step (ODE makes its contacts anew every step: this matching is
// what lets them warm start).
void World::prepareContacts() {
  auto pairLess = [](const ContactManifold& m, std::uint64_t key) {
    return bodyPairKey(m.bodyA, m.bodyB) < key;
  };
  for (ContactManifold& m : contacts_) {
    const Body& a = endpoint(m.bodyA);
    const Body& b = endpoint(m.bodyB);
    const Vec3 dir = m.surface.frictionDir1 - m.surface.frictionDir1.dot(m.normal) * m.normal;
    if (dir.norm() > 1e-6) {
      m.tangent1 = dir.normalized();
      m.tangent2 = m.normal.cross(m.tangent1);
    } else {
      perpendicularBasis(m.normal, m.tangent1, m.tangent2);
    }
    for (int i = 0; i < m.pointCount; ++i) {
      m.points[i].localA = a.localPoint(m.points[i].position);
      m.points[i].localB = b.localPoint(m.points[i].position);
    }
    const std::uint64_t key = bodyPairKey(m.bodyA, m.bodyB);
    auto it = std::lower_bound(previousContacts_.begin(), previousContacts_.end(), key, pairLess);
    for (; it != previousContacts_.end() && bodyPairKey(it->bodyA, it->bodyB) == key; ++it) {
      const ContactManifold& old = *it;
      // The pair may be named the other way round; the normals must agree.
      const double sign = old.bodyA == m.bodyA ? 1.0 : -1.0;
      if (sign * old.normal.dot(m.normal) < 0.95) continue;
      bool matched = false;
      for (int i = 0; i < m.pointCount; ++i) {
        ContactPoint& p = m.points[i];
        const ContactPoint* match = nullptr;
        double best = matchDistance_ * matchDistance_;
        for (int k = 0; k < old.pointCount; ++k) {
          const ContactPoint& q = old.points[k];
          if (p.feature != 0) {
            if (q.feature == p.feature) match = &q;
            if (match) break;
            continue;
          }
          const double d2 = (q.position - p.position).squaredNorm();
          if (d2 <= best) best = d2, match = &q;
        }
        if (!match) continue;
        matched = true;
        // Carry the old tangent impulse over onto the new tangents.
        const Vec3 oldT = sign * (match->tangentImpulse[0] * old.tangent1 +
                                  match->tangentImpulse[1] * old.tangent2);
        p.normalImpulse = match->normalImpulse;
        p.tangentImpulse[0] = oldT.dot(m.tangent1);
        p.tangentImpulse[1] = oldT.dot(m.tangent2);
      }
      if (matched) {
        m.warmStepSize = old.warmStepSize;
        for (int k = 0; k < 3; ++k)
          m.rollingImpulse[k] = sign * old.rollingImpulse[k];
      }
    }
  }
}

}  // namespace blockstep

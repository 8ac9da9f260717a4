// World: shapes, caller-given contacts, the collide stage and the
// matching of contact points across steps for warm starting.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/world/world.h"

namespace blockstep {
namespace {

std::string ownerName(BodyId id) {
  return id == kWorldBody ? std::string("the world") : "body " + std::to_string(id);
}

}  // namespace

ShapeId World::addShape(const Shape& shape) {
  shapes_.push_back(checkedShape(shape));
  return static_cast<ShapeId>(shapes_.size() - 1);
}

void World::replaceShape(ShapeId id, const Shape& shape) {
  if (id < 0 || id >= static_cast<ShapeId>(shapes_.size()) || !shapes_[id].alive) {
    throw Error("no shape " + std::to_string(id) + " in this world");
  }
  shapes_[id] = checkedShape(shape);
}

Shape World::checkedShape(const Shape& shape) const {
  Shape s = shape;
  // Named only when there is an error: a mirror of ODE geoms replaces
  // its shapes every step.
  auto who = [&s] { return "shape on " + ownerName(s.body); };
  if (s.body != kWorldBody) body(s.body);
  if (!s.localPosition.allFinite()) throw Error(who() + ": position is not finite");
  if (!isFinite(s.localOrientation) || s.localOrientation.norm() < 1e-9) {
    throw Error(who() + ": orientation must be a finite, non-zero quaternion");
  }
  s.localOrientation.normalize();
  switch (s.kind) {
    case Shape::Kind::Sphere:
      if (!(s.radius > 0.0) || !std::isfinite(s.radius)) {
        throw Error(who() + ": sphere radius must be positive and finite");
      }
      break;
    case Shape::Kind::Capsule:
    case Shape::Kind::Cylinder: {
      const bool capsule = s.kind == Shape::Kind::Capsule;
      const char* name = capsule ? "capsule" : "cylinder";
      if (!(s.radius > 0.0) || !std::isfinite(s.radius)) {
        throw Error(who() + ": " + name + " radius must be positive and finite");
      }
      if (!(capsule ? s.halfLength >= 0.0 : s.halfLength > 0.0) || !std::isfinite(s.halfLength)) {
        throw Error(who() + ": " + name + " length must be " + (capsule ? ">= 0" : "positive") +
                    " and finite");
      }
      break;
    }
    case Shape::Kind::Box:
      if (!(s.halfExtents.minCoeff() > 0.0) || !s.halfExtents.allFinite()) {
        throw Error(who() + ": box half extents must be positive and finite");
      }
      break;
    case Shape::Kind::Convex:
      if (!s.hull || s.hull->faces().empty()) {
        throw Error(who() + ": a convex shape needs a hull (ConvexHull::fromPoints)");
      }
      break;
    case Shape::Kind::Plane: {
      if (s.body != kWorldBody) throw Error(who() + ": planes belong to the world (kWorldBody)");
      const double n = s.planeNormal.norm();
      if (!s.planeNormal.allFinite() || n < 1e-9 || !std::isfinite(s.planeOffset)) {
        throw Error(who() + ": plane needs a finite non-zero normal and a finite offset");
      }
      s.planeNormal /= n;
      s.planeOffset /= n;
      break;
    }
  }
  if (!(s.friction >= 0.0) || !(s.restitution >= 0.0 && s.restitution <= 1.0)) {
    throw Error(who() + ": friction must be >= 0 and restitution in [0, 1]");
  }
  s.alive = true;
  return s;
}

void World::removeShape(ShapeId id) {
  if (id < 0 || id >= static_cast<ShapeId>(shapes_.size()) || !shapes_[id].alive) {
    throw Error("no shape " + std::to_string(id) + " in this world");
  }
  shapes_[id].alive = false;
}

void World::addContact(const ContactManifold& manifold) {
  // Checked and normalized where it is kept (copied once: contacts come
  // every step), and taken back out if it is refused.
  ContactManifold& m = contacts_.emplace_back(manifold);
  struct Refused {
    std::vector<ContactManifold>& contacts;
    bool kept = false;
    ~Refused() {
      if (!kept) contacts.pop_back();
    }
  } refused{contacts_};
  // Named only when there is an error: contacts are added every step.
  auto who = [&m] {
    return "contact between " + ownerName(m.bodyA) + " and " + ownerName(m.bodyB);
  };
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
    ContactPoint& p = m.points[i];
    if (!p.position.allFinite() || !std::isfinite(p.separation) || !p.normal.allFinite()) {
      throw Error(who() + ": point " + std::to_string(i) + " is not finite");
    }
    if (!(p.radiusA >= 0.0) || !(p.radiusB >= 0.0) || !std::isfinite(p.radiusA) ||
        !std::isfinite(p.radiusB)) {
      throw Error(who() + ": point " + std::to_string(i) +
                  ": its surfaces' radii must be finite and >= 0");
    }
    const double pn = p.normal.norm();
    if (pn > 0.0 && pn < 1e-9)
      throw Error(who() + ": point " + std::to_string(i) + " has a degenerate normal");
    p.normal = pn > 0.0 ? Vec3(p.normal / pn) : m.normal;
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
  refused.kept = true;
}

void World::setContactMatchDistance(double d) {
  if (!(d >= 0.0) || !std::isfinite(d)) throw Error("contact match distance must be >= 0");
  matchDistance_ = d;
}

void World::setContactPersistence(double d) {
  if (!(d >= 0.0) || !std::isfinite(d)) throw Error("contact persistence distance must be >= 0");
  persistDistance_ = d;
}

double World::timedCollide(double h) {
  const auto start = std::chrono::steady_clock::now();
  collide(h);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void World::collide(double h) {
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
  const std::size_t before = contacts_.size();
  collider_.collide(shapes_, bodies_, collision_, jointedPairs_, h, contacts_);
  for (std::size_t k = before; k < contacts_.size(); ++k) {
    for (int i = 0; i < contacts_[k].pointCount; ++i)
      stats_.deepestFound = std::max(stats_.deepestFound, -contacts_[k].points[i].separation);
  }
}

// Tangents, body-fixed anchors, and the impulses of the matching points of
// the last step (ODE makes its contacts anew every step: this matching is
// what lets them warm start). Each old point hands its impulse to the new
// point of the same pair with its feature id or, when none has it (no
// ids, or the touching features changed), to the nearest; a new point
// sums what it was handed: a pair's total impulse carries over whether
// the collider gives a point once or several times. When each new point
// took its nearest old point's impulse instead, copies multiplied it:
// ODE's trimesh pairs give points several times, and a resting body's
// friction impulses grew to 0.86 N s against 0.003 N s of weight per step
// until a change of the set threw it (demo_moving_trimesh).
namespace {

// Friction directions across a normal: the surface's first direction
// (ODE's fdir1) where given, any perpendicular pair otherwise.
void frictionBasis(const Vec3& normal, const Vec3& dir1, Vec3& t1, Vec3& t2) {
  const Vec3 dir = dir1 - dir1.dot(normal) * normal;
  if (dir.norm() > 1e-6) {
    t1 = dir.normalized();
    t2 = normal.cross(t1);
  } else {
    perpendicularBasis(normal, t1, t2);
  }
}

}  // namespace

void World::prepareContacts() {
  for (ContactManifold& m : contacts_) {
    const Body& a = endpoint(m.bodyA);
    const Body& b = endpoint(m.bodyB);
    frictionBasis(m.normal, m.surface.frictionDir1, m.tangent1, m.tangent2);
    for (int i = 0; i < m.pointCount; ++i) {
      ContactPoint& p = m.points[i];
      if (p.normal.isZero()) p.normal = m.normal;  // from the core's own collision
      frictionBasis(p.normal, m.surface.frictionDir1, p.tangent1, p.tangent2);
      p.localA = a.localPoint(p.position - p.radiusA * p.normal);
      p.localB = b.localPoint(p.position + p.radiusB * p.normal);
      p.anchorSeparation = p.separation;
      p.carried = false;
      p.normalImpulse = 0.0;
      p.tangentImpulse[0] = p.tangentImpulse[1] = 0.0;
    }
    m.warmStepSize = 0.0;
    m.rollingImpulse[0] = m.rollingImpulse[1] = m.rollingImpulse[2] = 0.0;
  }
  carryContactPoints();
  if (previousContacts_.empty() || contacts_.empty()) return;

  // This step's manifolds grouped by body pair, as the last step's are.
  contactOrder_.resize(contacts_.size());
  for (std::size_t k = 0; k < contacts_.size(); ++k)
    contactOrder_[k] = static_cast<std::int32_t>(k);
  auto keyOf = [&](std::int32_t k) { return bodyPairKey(contacts_[k].bodyA, contacts_[k].bodyB); };
  std::sort(contactOrder_.begin(), contactOrder_.end(),
            [&](std::int32_t x, std::int32_t y) { return keyOf(x) < keyOf(y); });

  std::size_t next = 0;  // into contactOrder_
  for (std::size_t o = 0; o < previousContacts_.size(); ++o) {
    const ContactManifold& old = previousContacts_[o];
    const std::uint64_t key = bodyPairKey(old.bodyA, old.bodyB);
    while (next < contactOrder_.size() && keyOf(contactOrder_[next]) < key)
      ++next;
    std::size_t end = next;
    while (end < contactOrder_.size() && keyOf(contactOrder_[end]) == key)
      ++end;
    if (end == next) continue;
    for (int k = 0; k < old.pointCount; ++k) {
      // A carried point took its impulse with it.
      if (!carriedOld_.empty() && carriedOld_[o * kMaxManifoldPoints + k]) continue;
      const ContactPoint& q = old.points[k];
      ContactManifold* target = nullptr;
      ContactPoint* match = nullptr;
      // The point of the same feature id; failing that (no ids, or the
      // features changed), the nearest point.
      bool sameFeature = false;
      double best = matchDistance_ * matchDistance_;
      for (std::size_t n = next; n < end && !sameFeature; ++n) {
        ContactManifold& m = contacts_[contactOrder_[n]];
        // The pair may be named the other way round; the normals must agree.
        const double sign = old.bodyA == m.bodyA ? 1.0 : -1.0;
        for (int i = 0; i < m.pointCount; ++i) {
          ContactPoint& p = m.points[i];
          if (sign * q.normal.dot(p.normal) < 0.95) continue;
          if (q.feature != 0 && p.feature == q.feature) {
            target = &m, match = &p, sameFeature = true;
            break;
          }
          const double d2 = (q.position - p.position).squaredNorm();
          if (d2 <= best) best = d2, target = &m, match = &p;
        }
      }
      if (!match) continue;
      const double sign = old.bodyA == target->bodyA ? 1.0 : -1.0;
      // Carry the old tangent impulse over onto the new tangents.
      const Vec3 oldT =
          sign * (q.tangentImpulse[0] * q.tangent1 + q.tangentImpulse[1] * q.tangent2);
      match->normalImpulse += q.normalImpulse;
      match->tangentImpulse[0] += oldT.dot(match->tangent1);
      match->tangentImpulse[1] += oldT.dot(match->tangent2);
      if (target->warmStepSize == 0.0) {
        target->warmStepSize = old.warmStepSize;
        for (int r = 0; r < 3; ++r)
          target->rollingImpulse[r] = sign * old.rollingImpulse[r];
      }
    }
  }
}

namespace {

// Whether the points' normals pass beside the body's centre, so that they
// turn it: a sphere's single point does not, and holds
// it up alone; a coin's rim point does, and tips it over.
bool turnsAbout(const ContactManifold& m, const Body& body) {
  for (int i = 0; i < m.pointCount; ++i) {
    const Vec3 r = m.points[i].position - body.position;
    if (r.cross(m.points[i].normal).norm() > 0.05 * r.norm()) return true;
  }
  return false;
}

}  // namespace

// Contact persistence (setContactPersistence). An old point is carried
// when its normal agrees with the manifold's, no point given this step
// stands for it (within the match distance), and, measured from the body-
// fixed anchors it was made with, it has neither opened by more than the
// persistence distance nor slid that far across the normal (the surfaces
// it touched may end there). It carries its impulse for warm starting.
// Measured on a coin (ODE's cylinder-plane gives the deepest rim point):
// with one point a step it rocked with its rim 10 mm deep, and under
// sub-steps the rocking grew into a 15 degree wobble; with the points
// carried it lies flat on four.
void World::carryContactPoints() {
  carriedOld_.clear();
  if (persistDistance_ <= 0.0 || previousContacts_.empty()) return;
  // Grown as contacts_ grows (geometrically), so a warmed-up scene whose
  // contact count wanders does not allocate each step.
  const std::size_t slots = previousContacts_.size() * kMaxManifoldPoints;
  if (slots > carriedOld_.capacity())
    carriedOld_.reserve(std::max(slots, 2 * carriedOld_.capacity()));
  carriedOld_.resize(slots, 0);
  auto pairBefore = [](const ContactManifold& m, std::uint64_t key) {
    return bodyPairKey(m.bodyA, m.bodyB) < key;
  };
  const double given2 = matchDistance_ * matchDistance_;
  for (ContactManifold& m : contacts_) {
    if (m.pointCount >= 3) continue;
    const std::uint64_t key = bodyPairKey(m.bodyA, m.bodyB);
    auto old =
        std::lower_bound(previousContacts_.begin(), previousContacts_.end(), key, pairBefore);
    if (old == previousContacts_.end() || bodyPairKey(old->bodyA, old->bodyB) != key) continue;
    const Body& a = endpoint(m.bodyA);
    const Body& b = endpoint(m.bodyB);
    const bool needed =
        (m.bodyA == kWorldBody || a.type != BodyType::Dynamic || turnsAbout(m, a)) &&
        (m.bodyB == kWorldBody || b.type != BodyType::Dynamic || turnsAbout(m, b));
    if (!needed) continue;
    for (; old != previousContacts_.end() && bodyPairKey(old->bodyA, old->bodyB) == key; ++old) {
      const bool flipped = old->bodyA != m.bodyA;
      const double sign = flipped ? -1.0 : 1.0;
      const std::size_t o = static_cast<std::size_t>(old - previousContacts_.begin());
      for (int k = 0; k < old->pointCount && m.pointCount < kMaxManifoldPoints; ++k) {
        const ContactPoint& q = old->points[k];
        const Vec3 n = sign * q.normal;
        if (n.dot(m.normal) < 0.99) continue;
        const Vec3& onA = flipped ? q.localB : q.localA;
        const Vec3& onB = flipped ? q.localA : q.localB;
        const double radiusA = flipped ? q.radiusB : q.radiusA;
        const double radiusB = flipped ? q.radiusA : q.radiusB;
        // The surfaces' points: each centre of curvature out by its radius.
        const Vec3 pA = a.worldPoint(onA) + radiusA * n;
        const Vec3 pB = b.worldPoint(onB) - radiusB * n;
        const Vec3 gap = pB - pA;  // zero when the point was made
        const double separation = q.anchorSeparation + n.dot(gap);
        const double slid = (gap - n.dot(gap) * n).norm();
        if (separation > persistDistance_ || slid > persistDistance_) continue;
        const Vec3 where = 0.5 * (pA + pB);
        bool standsFor = false;
        for (int i = 0; i < m.pointCount; ++i)
          standsFor |= (m.points[i].position - where).squaredNorm() <= given2;
        if (standsFor) continue;

        ContactPoint& c = m.points[m.pointCount++];
        c = q;
        c.position = where;
        c.separation = separation;
        c.normal = n;
        c.localA = onA;
        c.localB = onB;
        c.radiusA = radiusA;
        c.radiusB = radiusB;
        c.carried = true;
        frictionBasis(n, m.surface.frictionDir1, c.tangent1, c.tangent2);
        const Vec3 oldT =
            sign * (q.tangentImpulse[0] * q.tangent1 + q.tangentImpulse[1] * q.tangent2);
        c.tangentImpulse[0] = oldT.dot(c.tangent1);
        c.tangentImpulse[1] = oldT.dot(c.tangent2);
        if (m.warmStepSize == 0.0) m.warmStepSize = old->warmStepSize;
        carriedOld_[o * kMaxManifoldPoints + k] = 1;
      }
    }
  }
}

}  // namespace blockstep

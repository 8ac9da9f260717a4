// Position based dynamics on point masses (particles.h says what and why).
#include "compare/pbd/particles.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace blockstep::pbd {

int ParticleSystem::addParticle(const Vec3& position, const Vec3& velocity, double mass,
                                double radius) {
  x_.push_back(position);
  v_.push_back(velocity);
  p_.push_back(position);
  invMass_.push_back(mass > 0.0 && std::isfinite(mass) ? 1.0 / mass : 0.0);
  radius_.push_back(radius);
  mask_.push_back(0);
  return particleCount() - 1;
}

void ParticleSystem::addDistance(int a, int b) {
  Constraint c;
  c.a = a;
  c.b = b;
  c.rest = (x_[a] - x_[b]).norm();
  constraints_.push_back(c);
}

void ParticleSystem::addPin(int a, const Vec3& point) {
  Constraint c;
  c.a = a;
  c.point = point;
  c.rest = (x_[a] - point).norm();
  constraints_.push_back(c);
}

void ParticleSystem::addShape(const StaticShape& shape) {
  if (shapes_.size() >= 64) throw std::invalid_argument("PBD: at most 64 static shapes");
  shapes_.push_back(shape);
}

double ParticleSystem::depth(const StaticShape& s, const Vec3& p, double r, Vec3& normal) const {
  switch (s.kind) {
    case StaticShape::Kind::Plane:
      normal = s.normal;
      return r - (s.normal.dot(p) - s.offset);
    case StaticShape::Kind::Sphere: {
      const Vec3 d = p - s.centre;
      const double len = d.norm();
      normal = len > 1e-12 ? Vec3(d / len) : Vec3(Vec3::UnitZ());
      return r + s.radius - len;
    }
    case StaticShape::Kind::Box: {
      const Vec3 local = s.rotation.transpose() * (p - s.centre);
      const Vec3 clamped = local.cwiseMax(-s.halfExtents).cwiseMin(s.halfExtents);
      const Vec3 outside = local - clamped;
      const double dist = outside.norm();
      if (dist > 1e-12) {  // the centre is outside: nearest point on the surface
        normal = s.rotation * (outside / dist);
        return r - dist;
      }
      // The centre is inside: out through the nearest face.
      const Vec3 room = s.halfExtents - local.cwiseAbs();
      int axis = 0;
      room.minCoeff(&axis);
      Vec3 n = Vec3::Zero();
      n[axis] = local[axis] >= 0.0 ? 1.0 : -1.0;
      normal = s.rotation * n;
      return r + room[axis];
    }
  }
  return 0.0;
}

// Gauss-Seidel over the constraints, in the order they were added.
// PBD: C = |pa - pb| - rest moved to zero, split by inverse mass.
// XPBD: dlambda = (-C - alpha~ lambda) / (wa + wb + alpha~), alpha~ = alpha / h^2.
void ParticleSystem::projectDistances(double h, const Settings& settings) {
  const bool xpbd = settings.mode == Settings::Mode::Xpbd;
  const double alphaTilde = xpbd ? settings.compliance / (h * h) : 0.0;
  for (Constraint& c : constraints_) {
    const double wa = invMass_[c.a];
    const double wb = c.b >= 0 ? invMass_[c.b] : 0.0;
    const Vec3 other = c.b >= 0 ? p_[c.b] : c.point;
    const Vec3 d = p_[c.a] - other;
    const double len = d.norm();
    const double w = wa + wb;
    if (w <= 0.0) continue;
    if (len < 1e-12) continue;  // on the point already: no direction to move along
    const Vec3 n = d / len;
    const double C = len - c.rest;
    double dlambda;
    if (xpbd) {
      dlambda = (-C - alphaTilde * c.lambda) / (w + alphaTilde);
      c.lambda += dlambda;
    } else {
      dlambda = -C / w;
    }
    p_[c.a] += wa * dlambda * n;
    if (c.b >= 0) p_[c.b] -= wb * dlambda * n;
  }
}

// Each particle out of the shapes it is in, then friction over the
// sub-step's sideways motion: held while it is within mu times the push
// (static), cut by mu times the push beyond (kinetic).
void ParticleSystem::projectContacts(double mu) {
  for (int i = 0; i < particleCount(); ++i) {
    if (invMass_[i] == 0.0 || mask_[i] == 0) continue;
    for (int k = 0; k < shapeCount(); ++k) {
      if (!((mask_[i] >> k) & 1u)) continue;
      Vec3 n;
      const double d = depth(shapes_[k], p_[i], radius_[i], n);
      if (d <= 0.0) continue;
      p_[i] += d * n;
      const Vec3 moved = p_[i] - x_[i];
      const Vec3 sideways = moved - n.dot(moved) * n;
      const double slide = sideways.norm();
      if (slide <= mu * d) {
        p_[i] -= sideways;
      } else {
        p_[i] -= sideways * (mu * d / slide);
      }
    }
  }
}

void ParticleSystem::step(double dt, const Settings& settings) {
  const int substeps = std::max(1, settings.substeps);
  const double h = dt / substeps;
  // ODE takes its damping fraction off once per step; spread over the sub-steps.
  const double keep = std::pow(1.0 - std::clamp(settings.linearDamping, 0.0, 1.0), 1.0 / substeps);
  for (int sub = 0; sub < substeps; ++sub) {
    for (int i = 0; i < particleCount(); ++i) {
      // Damping slows the motion, not gravity's pull (a damped hanger
      // still hangs by its whole weight).
      if (invMass_[i] > 0.0) v_[i] = keep * v_[i] + h * settings.gravity;
      p_[i] = x_[i] + h * v_[i];
    }
    for (Constraint& c : constraints_)
      c.lambda = 0.0;
    for (int it = 0; it < std::max(1, settings.iterations); ++it) {
      projectDistances(h, settings);
      projectContacts(settings.friction);
    }
    for (int i = 0; i < particleCount(); ++i) {
      if (invMass_[i] == 0.0) continue;
      v_[i] = (p_[i] - x_[i]) / h;
      x_[i] = p_[i];
    }
  }
}

double ParticleSystem::maxDistanceError(double* sumSquares) const {
  double worst = 0.0, sum = 0.0;
  for (const Constraint& c : constraints_) {
    const Vec3 other = c.b >= 0 ? x_[c.b] : c.point;
    const double e = std::abs((x_[c.a] - other).norm() - c.rest);
    worst = std::max(worst, std::isfinite(e) ? e : INFINITY);
    sum += e * e;
  }
  if (sumSquares) *sumSquares = sum;
  return worst;
}

double ParticleSystem::deepestContact(int* contacts) const {
  double deepest = 0.0;
  int count = 0;
  for (int i = 0; i < particleCount(); ++i) {
    for (int k = 0; k < shapeCount(); ++k) {
      if (!((mask_[i] >> k) & 1u)) continue;
      Vec3 n;
      const double d = depth(shapes_[k], x_[i], radius_[i], n);
      if (d > 0.0) {
        deepest = std::max(deepest, d);
        ++count;
      }
    }
  }
  if (contacts) *contacts = count;
  return deepest;
}

double ParticleSystem::kineticEnergy() const {
  double e = 0.0;
  for (int i = 0; i < particleCount(); ++i)
    if (invMass_[i] > 0.0) e += 0.5 / invMass_[i] * v_[i].squaredNorm();
  return e;
}

bool ParticleSystem::finite() const {
  for (int i = 0; i < particleCount(); ++i)
    if (!x_[i].allFinite() || !v_[i].allFinite()) return false;
  return true;
}

}  // namespace blockstep::pbd

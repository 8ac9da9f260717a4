#include "core/body/mass.h"

#include "core/world/error.h"

namespace blockstep {
namespace {

void requirePositive(double value, const char* what) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw Error(std::string(what) + " must be positive and finite, got " + std::to_string(value));
  }
}

}  // namespace

MassProperties boxMass(double mass, const Vec3& sides) {
  requirePositive(mass, "box mass");
  requirePositive(sides.x(), "box side x");
  requirePositive(sides.y(), "box side y");
  requirePositive(sides.z(), "box side z");
  const Vec3 s2 = sides.cwiseProduct(sides);
  MassProperties m;
  m.mass = mass;
  m.inertia.diagonal() = mass / 12.0 * Vec3(s2.y() + s2.z(), s2.x() + s2.z(), s2.x() + s2.y());
  return m;
}

MassProperties sphereMass(double mass, double radius) {
  requirePositive(mass, "sphere mass");
  requirePositive(radius, "sphere radius");
  MassProperties m;
  m.mass = mass;
  m.inertia.diagonal().setConstant(0.4 * mass * radius * radius);
  return m;
}

MassProperties cylinderMass(double mass, double radius, double length) {
  requirePositive(mass, "cylinder mass");
  requirePositive(radius, "cylinder radius");
  requirePositive(length, "cylinder length");
  MassProperties m;
  m.mass = mass;
  const double side = mass * (3.0 * radius * radius + length * length) / 12.0;
  m.inertia.diagonal() = Vec3(side, side, 0.5 * mass * radius * radius);
  return m;
}

MassProperties capsuleMass(double mass, double radius, double length) {
  requirePositive(mass, "capsule mass");
  requirePositive(radius, "capsule radius");
  if (!(length >= 0.0) || !std::isfinite(length)) {
    throw Error("capsule length must be >= 0 and finite, got " + std::to_string(length));
  }
  // Split the mass by volume between the cylinder and the two hemispheres,
  // then move each hemisphere's inertia to the capsule's centre with the
  // parallel-axis theorem (hemisphere centroid at 3r/8 from its flat face).
  const double r = radius, l = length;
  const double vCyl = kPi * r * r * l;
  const double vSph = 4.0 / 3.0 * kPi * r * r * r;
  const double mCyl = mass * vCyl / (vCyl + vSph);
  const double mSph = mass - mCyl;  // both caps together
  const double izz = 0.5 * mCyl * r * r + 0.4 * mSph * r * r;
  const double d = 0.5 * l + 3.0 * r / 8.0;  // cap centroid from the centre
  const double capAboutOwnCentroid = 0.4 * mSph * r * r - mSph * (3.0 * r / 8.0) * (3.0 * r / 8.0);
  const double ixx = mCyl * (3.0 * r * r + l * l) / 12.0 + capAboutOwnCentroid + mSph * d * d;
  MassProperties m;
  m.mass = mass;
  m.inertia.diagonal() = Vec3(ixx, ixx, izz);
  return m;
}

MassProperties combineMass(const std::vector<MassPart>& parts) {
  if (parts.empty()) throw Error("compound mass: no parts");
  MassProperties total;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const MassPart& p = parts[i];
    const std::string who = "compound mass: part " + std::to_string(i);
    if (!(p.mass.mass > 0.0) || !std::isfinite(p.mass.mass))
      throw Error(who + " needs a positive, finite mass");
    if (!p.mass.inertia.allFinite() || !p.mass.centre.allFinite() || !p.position.allFinite() ||
        !isFinite(p.orientation) || p.orientation.norm() < 1e-9) {
      throw Error(who + " is not finite");
    }
    total.mass += p.mass.mass;
    total.centre += p.mass.mass * (p.position + p.orientation.normalized() * p.mass.centre);
  }
  total.centre /= total.mass;
  for (const MassPart& p : parts) {
    const Mat3 R = p.orientation.normalized().toRotationMatrix();
    const Vec3 d = p.position + R * p.mass.centre - total.centre;
    total.inertia += R * p.mass.inertia * R.transpose() +
                     p.mass.mass * (d.squaredNorm() * Mat3::Identity() - d * d.transpose());
  }
  return total;
}

}  // namespace blockstep

// Validation and frame set-up shared by all joint kinds.
#include <cmath>
#include <string>

#include "core/constraints/joint_kinds.h"
#include "core/world/error.h"

namespace blockstep {
namespace {

std::string str(const Vec3& v) {
  return "(" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " + std::to_string(v.z()) +
         ")";
}

// `what` is `prefix` + `suffix`, joined only when there is an error to
// report: validation runs on every joint update, and must not allocate.
void validateSoftness(const Softness& s, const char* prefix, const char* suffix) {
  if (!s.valid()) {
    const std::string what = std::string(prefix) + suffix;
    if (s.mode == Softness::Mode::ErpCfm) {
      throw Error(what + ": ERP must be in [0, 1] and CFM >= 0 and finite (got ERP " +
                  std::to_string(s.erp) + ", CFM " + std::to_string(s.cfm) + ")");
    }
    if (s.mode == Softness::Mode::Stiffness) {
      throw Error(what + ": stiffness and damping must be >= 0, finite and not both 0 (got " +
                  std::to_string(s.stiffness) + ", " + std::to_string(s.damping) + ")");
    }
    if (s.mode == Softness::Mode::StepSpring) {
      throw Error(what + ": step fraction must be > 0 and damping ratio >= 0 (got " +
                  std::to_string(s.stepFraction) + ", " + std::to_string(s.dampingRatio) + ")");
    }
    throw Error(what + ": spring frequency must be > 0 and damping ratio >= 0 (got " +
                std::to_string(s.hertz) + " Hz, " + std::to_string(s.dampingRatio) + ")");
  }
}

}  // namespace

void requireFinite(const Vec3& v, const char* what) {
  if (!v.allFinite()) throw Error(std::string(what) + " is not finite: " + str(v));
}

Vec3 requireAxis(const Vec3& axis, const char* what) {
  requireFinite(axis, what);
  const double n = axis.norm();
  if (n < 1e-9) throw Error(std::string(what) + " has zero length: " + str(axis));
  return axis / n;
}

void validateCommon(const JointCommon& c, const char* kind) {
  validateSoftness(c.softness, kind, " joint softness");
  if (!(c.bodyA == kWorldBody && c.bodyB == kWorldBody) && c.bodyA != c.bodyB &&
      c.breakForce > 0.0 && c.breakTorque > 0.0) {
    return;  // the common case, without building any message
  }
  const std::string k = std::string(kind) + " joint";
  if (c.bodyA == kWorldBody && c.bodyB == kWorldBody) {
    throw Error(k + " attaches the world to itself: give at least one body");
  }
  if (c.bodyA == c.bodyB) {
    throw Error(k + " attaches body " + std::to_string(c.bodyA) + " to itself");
  }
  if (!(c.breakForce > 0.0) || !(c.breakTorque > 0.0) || std::isnan(c.breakForce) ||
      std::isnan(c.breakTorque)) {
    throw Error(k + ": break force and torque must be > 0 (use infinity for unbreakable)");
  }
}

void validateLimit(const Limit& l, const char* what) {
  if (!l.enabled) return;
  if (!std::isfinite(l.lo) || !std::isfinite(l.hi) || l.lo > l.hi) {
    throw Error(std::string(what) + " limit needs finite lo <= hi (got " + std::to_string(l.lo) +
                ", " + std::to_string(l.hi) + ")");
  }
  validateSoftness(l.softness, what, " limit softness");
  if (!(l.bounce >= 0.0 && l.bounce <= 1.0)) {
    throw Error(std::string(what) + " limit bounce must be in [0, 1] (got " +
                std::to_string(l.bounce) + ")");
  }
}

void validateMotor(const Motor& m, const char* what) {
  if (!std::isfinite(m.targetVelocity) || !(m.maxForce >= 0.0)) {
    throw Error(std::string(what) +
                " motor needs a finite target velocity and a max force >= 0 (infinity allowed)");
  }
  if (!std::isfinite(m.cfm) || m.cfm < 0.0) {
    throw Error(std::string(what) + " motor cfm must be finite and >= 0");
  }
}

JointFrames framesAt(const Body& a, const Body& b, const Vec3& anchor, const Quat& worldFrame) {
  JointFrames f;
  f.localAnchorA = a.localPoint(anchor);
  f.localAnchorB = b.localPoint(anchor);
  f.localFrameA = a.orientation.conjugate() * worldFrame;
  f.localFrameB = b.orientation.conjugate() * worldFrame;
  return f;
}

FreeTurn turnAboutAnchor(const Vec3& anchor) {
  const double length = anchor.norm();
  if (length == 0.0) return {FreeTurn::Kind::None, Vec3::Zero()};
  return {FreeTurn::Kind::About, anchor / length};
}

FreeTurn turnAboutAxle(const Vec3& axis, const Vec3& anchor) {
  if (anchor.cross(axis).norm() > kOnLine * anchor.norm()) return {};
  return {FreeTurn::Kind::About, axis};
}

const char* jointKindName(const JointDesc& d) {
  struct Names {
    const char* operator()(const BallJointDesc&) const { return "ball"; }
    const char* operator()(const HingeJointDesc&) const { return "hinge"; }
    const char* operator()(const SliderJointDesc&) const { return "slider"; }
    const char* operator()(const FixedJointDesc&) const { return "fixed"; }
    const char* operator()(const UniversalJointDesc&) const { return "universal"; }
    const char* operator()(const ConeTwistJointDesc&) const { return "cone-twist"; }
    const char* operator()(const SixDofJointDesc&) const { return "6-DOF"; }
    const char* operator()(const DistanceJointDesc&) const { return "distance"; }
    const char* operator()(const PrismaticRotoideJointDesc&) const { return "prismatic-rotoide"; }
    const char* operator()(const DoubleHingeJointDesc&) const { return "double hinge"; }
    const char* operator()(const GearJointDesc&) const { return "gear"; }
    const char* operator()(const PrismaticUniversalJointDesc&) const {
      return "prismatic-universal";
    }
    const char* operator()(const MotorJointDesc& m) const {
      return m.angular ? "angular motor" : "linear motor";
    }
  };
  return std::visit(Names{}, d);
}

}  // namespace blockstep

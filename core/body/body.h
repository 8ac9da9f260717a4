// Rigid body state and settings (the "cold" data the user sees).
// The solver copies what it needs into SolverBody (solver_body.h) each step.
#pragma once

#include <cstdint>
#include <limits>

#include "core/math/math.h"

namespace blockstep {

// Index of a body in its World. kWorldBody stands for the fixed world frame
// in joints attached to a single body.
using BodyId = std::int32_t;
inline constexpr BodyId kWorldBody = -1;

enum class BodyType : std::uint8_t {
  Dynamic,    // moved by forces and constraints
  Kinematic,  // moved by its own velocity, infinite mass for the solver
  Static,     // never moves
};

// How a body's orientation follows its angular velocity. By default the
// first-order quaternion step of section 3, q += h/2 w q, normalized.
// Finite: the exact rotation by w h (ODE's finite rotation mode), for
// bodies that turn far in one step (fast wheels), or only about `axis`
// when it is set (world, unit; the rest of w takes the first-order step),
// as for a wheel on its axle. gyroscopic: the body feels the w x (I w)
// term when SolverSettings::gyroscopic is on (ODE's per-body gyroscopic
// mode).
struct RotationUpdate {
  bool finite = false;
  Vec3 axis = Vec3::Zero();  // zero: finite about w itself
  bool gyroscopic = true;
};

struct BodyDesc {
  BodyType type = BodyType::Dynamic;
  Vec3 position = Vec3::Zero();         // centre of mass, world, m
  Quat orientation = Quat::Identity();  // body to world
  Vec3 linearVelocity = Vec3::Zero();   // m/s
  Vec3 angularVelocity = Vec3::Zero();  // world frame, rad/s
  double mass = 1.0;                    // kg, > 0 for dynamic bodies
  Mat3 inertia = Mat3::Identity();      // body frame, about the centre of mass, kg m^2
  bool gravity = true;                  // world gravity applies
  double linearDamping = 0.0;           // 1/s: v *= 1 / (1 + h c)
  double angularDamping = 0.0;          // 1/s
  double maxAngularSpeed = std::numeric_limits<double>::infinity();  // rad/s
  RotationUpdate rotation;
};

struct Body {
  BodyType type = BodyType::Dynamic;
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
  Vec3 linearVelocity = Vec3::Zero();
  Vec3 angularVelocity = Vec3::Zero();
  Vec3 force = Vec3::Zero();   // accumulated for the next step, cleared by it, N
  Vec3 torque = Vec3::Zero();  // world frame, N m
  double mass = 1.0;
  double invMass = 1.0;
  Mat3 inertiaBody = Mat3::Identity();
  Mat3 invInertiaBody = Mat3::Identity();
  bool gravity = true;
  double linearDamping = 0.0;
  double angularDamping = 0.0;
  double maxAngularSpeed = std::numeric_limits<double>::infinity();
  RotationUpdate rotation;
  bool alive = true;  // false once destroyed; the slot is reused
  // Which body holds the slot (World numbers them as it makes them): what
  // the solver kept of a slot's last body is not the next one's.
  std::uint64_t serial = 0;

  bool isDynamic() const { return type == BodyType::Dynamic; }

  // World inverse inertia R I0^-1 R^T (section 4.1: I = R I0 R^T).
  Mat3 invInertiaWorld() const {
    if (!isDynamic()) return Mat3::Zero();
    const Mat3 R = orientation.toRotationMatrix();
    return R * invInertiaBody * R.transpose();
  }

  Vec3 worldPoint(const Vec3& local) const { return position + orientation * local; }
  Vec3 localPoint(const Vec3& world) const { return orientation.conjugate() * (world - position); }
  Vec3 pointVelocity(const Vec3& world) const {
    return linearVelocity + angularVelocity.cross(world - position);
  }
};

}  // namespace blockstep

// Contact manifolds: up to four points between two bodies, usually sharing
// one normal, with the surface properties ODE's dSurfaceParameters carry.
// They come each step from the core's collision (collision/) or from a
// caller (the ODE adapter turns ODE's contact joints into them), and are
// solved as blocks beside the joints (section 4.2 contact rows).
#pragma once

#include <cstdint>
#include <limits>

#include "core/body/body.h"
#include "core/constraints/softness.h"

namespace blockstep {

inline constexpr int kMaxManifoldPoints = 4;

struct ContactSurface {
  enum class Friction : std::uint8_t {
    Box,   // each tangent row within +-mu P_n (ODE with dContactApprox1)
    Cone,  // the tangent impulse within the disk of radius mu P_n
    Force  // each tangent row within +-mu N s of force, whatever the load
           // (ODE without dContactApprox1: mu is a force limit)
  };
  Friction friction = Friction::Box;
  double mu = 0.6;                   // along the first tangent (and the second unless mu2 >= 0)
  double mu2 = -1.0;                 // along the second tangent; < 0: same as mu
  Vec3 frictionDir1 = Vec3::Zero();  // first tangent (ODE fdir1); zero: any
  double rolling = 0.0;              // rolling resistance: torque <= rolling * normal force (m)
  double spinning = 0.0;             // about the normal
  double restitution = 0.0;
  double restitutionThreshold = 0.0;  // m/s: slower impacts do not bounce
  // Softness of the normal rows past the slop (ODE soft_erp, soft_cfm).
  Softness softness = Softness::erpCfm(0.2, 1e-5);
  double slop = 0.0;  // allowed penetration, m (ODE's contact surface layer)
  double maxCorrectingVelocity = std::numeric_limits<double>::infinity();  // m/s
  // Surface velocities (ODE motion1, motion2, motionN): the contact drives
  // the relative velocity of B over A toward these.
  double motion1 = 0.0, motion2 = 0.0, motionN = 0.0;
  double slip1 = 0.0, slip2 = 0.0;  // force-dependent slip: CFM of the tangent rows
};

struct ContactPoint {
  Vec3 position = Vec3::Zero();  // world, when the manifold was made
  double separation = 0.0;       // m, < 0 when penetrating, along the point's normal
  // The point's own normal (unit, from A toward B); zero: the manifold's.
  // Points of one body pair touching along different normals (a ball in a
  // groove on both walls) are still one block: their normal impulses are
  // solved together (section 4.3), so a symmetric impact stays symmetric.
  // The world fills it in when zero.
  Vec3 normal = Vec3::Zero();
  std::uint32_t feature = 0;  // the caller's id for matching across steps; 0: none
  // How round each surface is at the point: the radius of a sphere, of a
  // capsule, of a cylinder touching along its side (0: a vertex, an edge
  // or a flat face). The centres of that curvature, A's at position -
  // radiusA normal and B's at position + radiusB normal, move with the
  // bodies as the surfaces do: a ball rolling keeps its centre's height
  // while the material point under it rises.
  double radiusA = 0.0, radiusB = 0.0;
  // Filled by the world: those centres as anchors fixed in each body, so
  // sub-steps update the separation from the bodies' motion without
  // colliding again, and the friction directions across the point's
  // normal.
  Vec3 localA = Vec3::Zero(), localB = Vec3::Zero();
  // The separation when those anchors were made: a point kept from an
  // earlier step (carried) measures its separation from there.
  double anchorSeparation = 0.0;
  // Kept by contact persistence, not given this step: it holds against the
  // normal and takes friction only from its own load (no friction force).
  bool carried = false;
  Vec3 tangent1 = Vec3::UnitX(), tangent2 = Vec3::UnitY();
  // Accumulated impulses (warm starting), and summed over the last step.
  double normalImpulse = 0.0;
  double tangentImpulse[2] = {0.0, 0.0};
  double stepNormalImpulse = 0.0;
  double stepTangentImpulse[2] = {0.0, 0.0};
};

struct ContactManifold {
  BodyId bodyA = kWorldBody;
  BodyId bodyB = kWorldBody;
  Vec3 normal = Vec3::UnitZ();  // unit, from A toward B (rolling and spinning act about it)
  int pointCount = 0;
  ContactPoint points[kMaxManifoldPoints];
  ContactSurface surface;
  // Filled by the world: the friction directions across the manifold's
  // normal (the axes of the rolling rows).
  Vec3 tangent1 = Vec3::UnitX(), tangent2 = Vec3::UnitY();
  double rollingImpulse[3] = {0.0, 0.0, 0.0};  // about tangent1, tangent2, normal
  double warmStepSize = 0.0;
};

}  // namespace blockstep

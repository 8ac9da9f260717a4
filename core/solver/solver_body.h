// The solver's per-body data: only what the iteration touches, contiguous.
#pragma once

#include "core/math/math.h"

namespace blockstep {

struct SolverBody {
  Vec3 v = Vec3::Zero();     // linear velocity, m/s
  Vec3 w = Vec3::Zero();     // angular velocity, world, rad/s
  Mat3 invI = Mat3::Zero();  // world inverse inertia R I0^-1 R^T
  double invMass = 0.0;
};
// The hot loop streams these; keep them to a few cache lines.
static_assert(sizeof(SolverBody) <= 128, "SolverBody grew: keep the solver's body data compact");

}  // namespace blockstep

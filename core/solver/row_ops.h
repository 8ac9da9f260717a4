// What every solver stage does with one row: its velocity, its residual,
// its coupling with another row, and applying an impulse along it. Shared
// by the per-joint blocks (solver.cpp), the island blocks
// (island_block.cpp) and the contact islands (contact_island.cpp).
#pragma once

#include <vector>

#include "core/constraints/row.h"
#include "core/solver/solver_body.h"

namespace blockstep {

inline double rowVelocity(const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
  return row.linA.dot(a.v) + row.angA.dot(a.w) + row.linB.dot(b.v) + row.angB.dot(b.w);
}

// K_rr = J_r M^-1 J_r^T: the row's inverse effective mass (invIang* set).
inline double rowDiagonal(const ConstraintRow& row, const SolverBody& a, const SolverBody& b) {
  return a.invMass * row.linA.squaredNorm() + row.angA.dot(row.invIangA) +
         b.invMass * row.linB.squaredNorm() + row.angB.dot(row.invIangB);
}

// Adds a velocity change to a body. An immovable body (the static frame,
// a kinematic body: no inverse mass) is never written: islands share it,
// and islands swept on different threads must not write the same memory
// (they would only add zero, but racing).
inline void addVelocity(SolverBody& body, const Vec3& dv, const Vec3& dw) {
  if (body.invMass == 0.0) return;
  body.v += dv;
  body.w += dw;
}

// K_ij = J_i M^-1 J_j^T of rows i and j of blocks pi and pj: the sum over
// the movable bodies both rows act on (the static frame and kinematic
// bodies couple nothing).
[[gnu::always_inline]] inline double rowCoupling(const ConstraintRow& ri, const ConstraintBlock& pi,
                                                 const ConstraintRow& rj, const ConstraintBlock& pj,
                                                 const std::vector<SolverBody>& bodies) {
  double k = 0.0;
  for (int sideI = 0; sideI < 2; ++sideI) {
    const std::int32_t body = sideI == 0 ? pi.bodyA : pi.bodyB;
    if (bodies[body].invMass == 0.0) continue;
    const Vec3& linI = sideI == 0 ? ri.linA : ri.linB;
    const Vec3& angI = sideI == 0 ? ri.angA : ri.angB;
    for (int sideJ = 0; sideJ < 2; ++sideJ) {
      if ((sideJ == 0 ? pj.bodyA : pj.bodyB) != body) continue;
      const Vec3& linJ = sideJ == 0 ? rj.linA : rj.linB;
      const Vec3& invIangJ = sideJ == 0 ? rj.invIangA : rj.invIangB;
      k += bodies[body].invMass * linI.dot(linJ) + angI.dot(invIangJ);
    }
  }
  return k;
}

inline void applyImpulse(const ConstraintRow& row, double dP, SolverBody& a, SolverBody& b) {
  addVelocity(a, (a.invMass * dP) * row.linA, dP * row.invIangA);
  addVelocity(b, (b.invMass * dP) * row.linB, dP * row.invIangB);
}

// Relax sweeps remove the velocity that position correction added. A row
// that is a physical spring (stiffness and damping in absolute units, as
// ODE's (ERP, CFM) read at the program's step) corrects nothing: its force
// is real, so relax leaves its velocity alone (residual 0). Relaxing it
// let it give way by gamma P every sub-step with no spring force pushing
// back: an ODE hinge2 suspension sagged 166 mm where ODE's spring sags 2.
inline bool relaxSkips(const ConstraintRow& row, bool useBias) {
  return !useBias && row.spring;
}

// The row's J v + b + gamma P in the solve pass (useBias) or the relax
// pass. Relax treats contact normals as rigid (Box2D v3 does the same):
// it leaves out their softness's gamma P, which in the solve pass lets a
// loaded row give way. Kept, it made relax drive every loaded contact to
// a creep velocity gamma P: a resting box's contacts crept and friction
// answered them, and a sliding box's normals ended below its weight, so
// friction (bounded by the solve pass's normals) reached 1.06 mu N.
inline double rowResidual(const ConstraintRow& row, bool useBias, const SolverBody& a,
                          const SolverBody& b) {
  return useBias ? rowVelocity(row, a, b) + row.bias + row.gamma * row.impulse
                 : rowVelocity(row, a, b) + row.biasRelax + row.gammaRelax * row.impulse;
}

}  // namespace blockstep

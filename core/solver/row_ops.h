// What every solver stage does with one row: its velocity, its residual,
// and applying an impulse along it. Shared by the per-joint blocks
// (solver.cpp) and the island blocks (island_block.cpp).
#pragma once

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

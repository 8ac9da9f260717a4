// The solver's safety net: after a step, finds the islands whose state
// went non-finite or whose kinetic energy grew far beyond what the step
// can explain, so the World can put them back as they were and name them.
//
// What a step can explain, per island (J): the kinetic energy before it,
// plus the work of gravity and the applied forces and torques along the
// path the bodies took (E_free below: what they alone would give), plus
// what the constraint rows may add:
// - Rows that drive a speed d (motors, moving contact surfaces, rows a
//   kinematic body drags). Over one (sub-)step the solver turns the free
//   velocities into v = v_free + M^-1 J^T P, and when the rows hold
//   (J v + gamma P = d) the kinetic energy is
//     E_free + P^T d - 1/2 P^T K P - gamma |P|^2  <=  E_free + P^T d,
//   so these add at most their impulse times their speed, however the
//   rows are coupled (a motor turning a gear train delivers P d to every
//   wheel). Summed as |P_r| |d_r| after each (sub-)step.
// - Position corrections: closing the error C the step started with at
//   d = C / h adds at most 1/2 d^T K^-1 d (the free velocity projected
//   onto the constraints, plus M^-1 J^T K^-1 d, M-orthogonal to it):
//   exactly so with the island's factor where an island block covers its
//   joints' equality rows, as each row's 1/2 d_r^2 / K_rr elsewhere, from
//   the first sub-step. Not the work of the sub-steps' corrections: sweeps
//   that diverge create the errors they then correct, and counting that
//   would explain them away.
// Ideal joints and contacts add nothing, so diverging sweeps (per-joint
// Gauss-Seidel on a light body carrying heavy ones: 2-5x per step while
// the forces explain almost nothing) show within a few steps. Any honest
// count of the corrections explains a divergence away once it has torn
// the joints (closing errors of meters is a lot of energy), so the guard
// looks for growth beyond this count that goes on from step to step
// (kCarry in the .cpp): coupled corrections exceed the sum of their
// diagonals (a light link holding a heavy one, a taut chain), but only
// for a step or a few, as the structure springs back.
// That fast test misses a slow divergence, a few percent a step (the star
// of ODE's demo_I on the paper's solver: 0.46 J to 5410 J in 250 frames,
// its joints torn 5 m apart, no message): each step's errors explain its
// growth. A slow test therefore treats the errors' 1/2 d^T K^-1 d as a
// potential energy: the kinetic energy plus it, after the step (the last
// sub-step's rows, their errors moved on to first order), against the work
// done plus it before the step, with a longer memory (kSlowCarry). Turning
// error into motion keeps that sum; a divergence that tears the joints
// while it speeds the bodies up grows both.
// A structure ringing after an impact trades its kinetic energy with
// energy the count does not see: at each turning point its kinetic
// energy nearly vanishes and then comes back. So the island's recent peak,
// forgotten over kPeakMemory (in the .cpp), also explains: energy
// returning to where it was is not growth, while sweeps that diverge
// exceed every earlier step's energy and still show.
// SolverSettings::runawayEnergyGain is the carried growth allowed (both
// tests).
#pragma once

#include <cstdint>
#include <vector>

#include "core/body/body.h"
#include "core/constraints/row.h"
#include "core/solver/island_block.h"
#include "core/solver/settings.h"
#include "core/solver/solver_body.h"

namespace blockstep {

class RunawayGuard {
 public:
  // Before the step: groupOfBody[i] is body i's island (or lone dynamic
  // body) in [0, groups), -1 for bodies that do not move.
  void begin(const std::vector<Body>& bodies, const std::vector<std::int32_t>& groupOfBody,
             int groups, const Vec3& gravity, double h);
  // The first sub-step's rows, once prepared: the errors they start with.
  // Blocks [groupStart[g], groupStart[g + 1]) belong to island g; these
  // and the calls below count islands [firstIsland, endIsland).
  // Islands whose joint equality rows `islands` (if given) covers have
  // them measured exactly, 1/2 d^T K^-1 d with the island's factor.
  void addCorrections(const std::vector<ConstraintBlock>& blocks,
                      const std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies,
                      const std::vector<std::int32_t>& groupStart, int firstIsland, int endIsland,
                      double h, IslandBlocks* islands);
  // After the last sub-step: the errors its rows leave, closed to first
  // order by the bodies' velocities over hLast (that sub-step's size).
  void addRemainingErrors(const std::vector<ConstraintBlock>& blocks,
                          const std::vector<ConstraintRow>& rows,
                          const std::vector<SolverBody>& bodies,
                          const std::vector<std::int32_t>& groupStart, int firstIsland,
                          int endIsland, double hLast, double h, IslandBlocks* islands);
  // After each (sub-)step's sweeps: the work its driving rows may have done.
  // Blocks [groupStart[g], groupStart[g + 1]) belong to island g.
  void addWork(const std::vector<ConstraintBlock>& blocks, const std::vector<ConstraintRow>& rows,
               const std::vector<SolverBody>& bodies, const std::vector<std::int32_t>& groupStart,
               int firstIsland, int endIsland);
  // After the step: the groups that ran away, into stats.runaways (and
  // their bodies and joints into stats.runawayBodies / runawayJoints).
  void check(const std::vector<Body>& bodies, const std::vector<ConstraintBlock>& blocks,
             const std::vector<std::int32_t>& groupStart, int islandCount, const SolverSettings& s,
             StepStats& stats);

 private:
  struct Group;
  template <class F>
  void addOverRows(const std::vector<ConstraintBlock>& blocks,
                   const std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies,
                   const std::vector<std::int32_t>& groupStart, int firstIsland, int endIsland,
                   double Group::*sum, F f);
  // The error energy of each island at the errors errorOf(row, a, b).
  template <class ErrorOf>
  void addErrorEnergy(const std::vector<ConstraintBlock>& blocks,
                      const std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies,
                      const std::vector<std::int32_t>& groupStart, int firstIsland, int endIsland,
                      double h, IslandBlocks* islands, double Group::*sum, ErrorOf errorOf);
  struct Group {
    double before = 0.0;        // kinetic energy before the step
    double explained = 0.0;     // E_free plus the rows' targets
    double errorsBefore = 0.0;  // 1/2 d^2 / K summed over the rows, at the step's start
    double errorsAfter = 0.0;   // ... and at its end
    double mass = 0.0;
    double peak = 0.0;  // its recent peak kinetic energy, decayed to now
    // After the step:
    double after = 0.0;
    double fastest = 0.0;  // largest linear speed, m/s
    bool nonFinite = false;
    BodyId culprit = -1;  // the non-finite body, or the one that gained most
    double culpritGain = 0.0;
    double excess = 0.0;        // log(after / explained), floored
    double slowExcess = 0.0;    // the same against what the step released (slow test)
    double growth = 0.0;        // the largest carried growth of its bodies (a log)
    double slowGrowth = 0.0;    // ... and the slow test's
    double ledgerBefore = 0.0;  // the slow test's explained: work plus the errors' energy
    double ledgerAfter = 0.0;   // kinetic energy plus the errors' energy after the step
  };
  std::vector<Group> groups_;
  const std::vector<std::int32_t>* groupOfBody_ = nullptr;
  struct BodyStart {      // each body before the step
    double energy = 0.0;  // kinetic
    Vec3 position, angularVelocity;
    Vec3 force, torque;     // applied, with gravity
    double freeGain = 0.0;  // kinetic energy the forces alone give in the step
  };
  std::vector<BodyStart> start_;
  double h_ = 0.0;
  // Per body: unexplained growth carried across steps (a log of an energy
  // ratio, >= 0).
  std::vector<double> growth_;
  // ... and the slow test's, counted only over steps whose errors grew.
  std::vector<double> slowGrowth_;
  // Per body: the recent peak kinetic energy of its island (J).
  std::vector<double> peak_;
};

double kineticEnergy(const Body& b);
// ... moving at (v, w) in its current orientation.
double kineticEnergy(const Body& b, const Vec3& v, const Vec3& w);

}  // namespace blockstep

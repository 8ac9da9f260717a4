// An island's joint equality rows solved as one block.
//
// The paper's solver (section 4.3) makes each joint one block and lets
// Gauss-Seidel couple the blocks. That coupling converges slowly where a
// light body carries heavy ones: ODE's demo_I (a 0.1 kg anchor holding
// ten heavier particles on ball joints) was still 0.2 rad/s off after 200
// sweeps, and a 40-link chain of 0.1 kg links ending in a 10 kg body flew
// apart at 3e8 m/s under the sub-stepped default. Solving every equality
// row of the island together, with K = J M^-1 J^T + gamma of the whole
// island factored by LDL^T once per (sub-)step, makes those rows exact in
// one sweep whatever the mass ratios; limits, motors and contacts stay
// bounded rows around it, as in the per-joint blocks.
//
// An island with more rows than that (a cloth, a lattice) is cut into
// chains instead: paths of joints, body to body, each as straight as the
// bodies lie and of at most maxRows rows, and each chain is one block
// inside the Gauss-Seidel sweep. A chain's K is block tridiagonal, so its
// factor costs a few times a joint's; in return a pull travels the whole
// chain in one sweep where per-joint blocks pass it one joint a sweep
// (Baraff 1996 solves a tree's rows exactly the same way). A grid's
// joints fall into its rows and columns: alternating line relaxation.
//
// K is sparse: two rows couple only when their joints share a body. The
// joints are ordered breadth-first over the bodies they share (the
// Cuthill-McKee ordering), which keeps each row's non-zeros close to the
// diagonal, and the factor is computed and stored within that profile
// (the envelope of K, where LDL^T creates no fill): a chain or a ragdoll
// costs time and memory linear in its length, a star of n joints on one
// body n^2 (it is dense).
//
// The joints' bounded rows (limits, motors) stay rows clamped one at a
// time, but each in the null space of the whole island's equality rows:
// its impulse lambda carries equality impulses w lambda, w = -K^-1 J_e
// M^-1 J_b^T, that leave every equality row's J v + gamma P as it was, and
// its effective mass is the island's Schur complement. In the null space
// of its own joint only (as the per-joint blocks do), a motor holding a
// hinge in the middle of a chain saw the two links beside it and not the
// chain they hang in: its impulses overshot, the island solve took them
// back, and ODE's demo_feedback bridge (15 hinge motors between two
// sliders) shook, calmed, then gained energy again until the runaway
// guard caught it. An island that touches something keeps the per-joint
// coupling: its contacts are Gauss-Seidel partners outside the island's
// null space, and island-wide limit impulses moved the bodies they hold
// (a ragdoll lying on the ground settled 4-7x deeper, 4-8 mm against
// 1-2 mm, at 9-11 sub-steps). So do the joints of an island cut into
// chains.
// The price is paid once per sub-step, where each bounded row's w takes
// one solve with the island's factor: the bridge of 17 motors on 85
// equality rows steps 3x slower (perf: those solves 33%, forming w and
// the velocity changes 32%); a sweep moves the island's bodies by each
// row's precomputed velocity changes.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/constraints/row.h"
#include "core/solver/solver_body.h"

namespace blockstep {

class IslandBlocks {
 public:
  // Chooses this (sub-)step's blocks once the joint blocks' rows are
  // written: every island whose joints have 2..maxRows equality rows in
  // all gets one, its rows ordered; with cutIntoChains, a larger island is
  // cut into chains of at most maxRows rows (positions: each solver body's
  // position, to keep the chains straight; a body beyond its end has
  // none). Island i owns blocks [islandStart[i], islandStart[i+1]).
  // With withContacts (or, for island i, a non-zero (*contactsOf)[i]),
  // an island that touches something solves the
  // normal rows of its jointed bodies' contacts in the null space of its
  // equality rows too
  // (SolverSettings::islandBlockContacts), where that costs no more than
  // kCoupledContactWork a sweep.
  void select(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody,
              const std::vector<std::int32_t>& islandStart, int islandCount, int maxRows,
              bool cutIntoChains = false, const std::vector<Vec3>* positions = nullptr,
              bool withContacts = false) {
    selectIslands(blocks, staticBody, islandStart, 0, islandCount, maxRows, cutIntoChains,
                  positions, withContacts);
  }
  // The same for islands [firstIsland, endIsland) only (the solver steps
  // classes of islands apart); the others get none.
  void selectIslands(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody,
                     const std::vector<std::int32_t>& islandStart, int firstIsland, int endIsland,
                     int maxRows, bool cutIntoChains, const std::vector<Vec3>* positions,
                     bool withContacts = false,
                     const std::vector<std::uint8_t>* contactsOf = nullptr);
  // The most a sweep's coupled contacts may cost, in multiply-adds (each
  // row's velocity changes over the island's bodies and its equality
  // impulses): a ragdoll on the ground takes about 700, a hair strand on
  // the head 500; a pile of eight ragdolls in one island, about 50,000,
  // keeps its contacts as Gauss-Seidel partners.
  static constexpr std::size_t kCoupledContactWork = 30000;
  // K of each chosen group and its LDL^T, once the rows are prepared
  // (Jacobians times M^-1, gamma).
  // Bounded rows with a mass-relative spring get their gamma here.
  void factorAll(const std::vector<ConstraintBlock>& blocks, std::vector<ConstraintRow>& rows,
                 const std::vector<SolverBody>& bodies);
  // The same in parts, so groups can be factored at once: the storage
  // first, then factorOne for each of the count() groups (any order, any
  // thread: each writes only its own).
  void prepareFactors();
  int count() const { return static_cast<int>(groups_.size()); }
  void factorOne(int k, const std::vector<ConstraintBlock>& blocks,
                 std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies);

  // Whether all of island i's joint equality rows are one block here.
  bool covers(int island) const {
    return island < static_cast<int>(wholeIsland_.size()) && wholeIsland_[island] >= 0;
  }
  // Whether a joint block's equality rows are solved here, in its island's
  // block or in one of its chains (the sweep then skips the joint's own).
  bool solvesEquality(std::int32_t block) const {
    return block < static_cast<std::int32_t>(groupOfBlock_.size()) && groupOfBlock_[block] >= 0;
  }
  // Island i's groups are [groupsBegin(i), groupsEnd(i)).
  int groupsBegin(int island) const { return islandGroups_[island]; }
  int groupsEnd(int island) const { return islandGroups_[island + 1]; }

  // Whether island i's joint bounded rows are solved here (solveBounded).
  bool solvesBounded(int island) const {
    return covers(island) && groups_[wholeIsland_[island]].bounded;
  }
  // Whether some of island i's contact normals are solved here too
  // (solveBounded), and whether contact block b's are: the solver's sweep
  // then solves only its friction.
  bool solvesContacts(int island) const {
    return covers(island) && groups_[wholeIsland_[island]].contacts;
  }
  bool solvesContactNormals(std::int32_t block) const {
    return block < static_cast<std::int32_t>(coupledContact_.size()) && coupledContact_[block];
  }

  // The island's joint bounded rows, each clamped and solved in the null
  // space of the island's equality rows (its impulse moves them by w):
  // one Gauss-Seidel pass over them all, then motorPasses - 1 more over
  // its joints' motors (Solver::kMotorPassesPerStep).
  void solveBounded(int island, bool useBias, int motorPasses,
                    const std::vector<ConstraintBlock>& blocks, std::vector<ConstraintRow>& rows,
                    std::vector<SolverBody>& bodies);

  // One exact solve of a group's equality rows: dP = -K^-1 (J v + b +
  // gamma P), applied to the bodies and accumulated in the rows.
  void solve(int group, bool useBias, const std::vector<ConstraintBlock>& blocks,
             std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies);

  // Post-stabilization (SolverSettings::positionProjections): K of a
  // group's rows as written at the bodies' new pose (poseRows, indexed
  // like the solver's rows: Jacobians and M^-1 J^T) factored beside the
  // sub-step's own factor, which the relax sweeps and carried sub-steps
  // still use; then the position impulses lambda = -K^-1 e that take the
  // rows' errors e out to first order (e and lambda indexed like the
  // solver's rows). The factor is of (1 + c) K where the rows share a
  // mass-relative spring: lambda is of K itself.
  // Room for factorAtPose's factors (before groups are factored at once).
  void preparePoseFactors() {
    if (poseFactor_.size() < factor_.size()) poseFactor_.resize(factor_.size());
  }
  void factorAtPose(int group, const std::vector<ConstraintBlock>& blocks,
                    std::vector<ConstraintRow>& poseRows, const std::vector<SolverBody>& bodies);
  // atPose: with factorAtPose's factor, else with the (sub-)step's own.
  void solvePositionErrors(int group, const std::vector<double>& error, std::vector<double>& lambda,
                           bool atPose) const;
  // f(solver row, its block) for each of a group's rows.
  template <class F>
  void forEachRow(int group, F f) const {
    const Group& g = groups_[group];
    for (std::int32_t k = 0; k < g.size; ++k)
      f(entryRow_[g.firstEntry + k], entryBlock_[g.firstEntry + k]);
  }

  // 1/2 d^T K^-1 d over island i's equality rows (the island must be
  // covered), d_r = speed(row r, its block's index) (the runaway guard's
  // measure of the energy the rows' errors hold: the sum of the diagonals
  // 1/2 d_r^2 / K_rr undercounts a taut chain's fivefold).
  template <class F>
  double inverseQuadratic(int island, const std::vector<ConstraintRow>& rows, F speed) {
    const Group& g = groups_[wholeIsland_[island]];
    rhs_.resize(std::max<std::size_t>(rhs_.size(), static_cast<std::size_t>(g.size)));
    double* x = rhs_.data();
    for (std::int32_t k = 0; k < g.size; ++k)
      x[k] = speed(rows[entryRow_[g.firstEntry + k]], entryBlock_[g.firstEntry + k]);
    return 0.5 * inverseQuadraticInPlace(g, x);
  }

  // Equality rows covered in all (statistics).
  int coveredRows() const { return static_cast<int>(entryRow_.size()); }
  // Entries of the factors in all (statistics, tests: the profile's size).
  std::size_t factorEntries() const { return factorSize_; }

 private:
  // Rows solved as one block: a whole island's, or one chain's.
  struct Group {
    std::int32_t firstEntry = 0;    // into entryRow_, entryBlock_, first_, rowBase_
    std::int32_t size = 0;          // rows
    std::size_t factor = 0;         // offset of its profile's entries in factor_
    std::int32_t firstBounded = 0;  // into bounded_
    std::int32_t boundedCount = 0;
    bool bounded = false;        // its joints' bounded rows are solved here
    bool contacts = false;       // and those of its contacts on jointed bodies (solvesContacts)
    std::int32_t firstBody = 0;  // into islandBodies_: the bodies its joints move
    std::int32_t bodyCount = 0;
    // c of its joints' common mass-relative spring (Solver::blockSpringShare):
    // the factor is of (1 + c) K; 0: each row's own gamma.
    double springShare = 0.0;
    bool mixedSprings = false;  // its joints' springs differ: each row keeps its own gamma
  };
  // A joint's bounded row in a covered island.
  struct BoundedRow {
    std::int32_t row = 0;     // index into the solver's rows
    std::int32_t block = 0;   // its joint's block
    std::size_t weights = 0;  // offset of its w (one per equality row) in weights_
    // Offset of its velocity change per unit impulse in deltas_ (linear,
    // angular) for each of the island's bodies.
    std::size_t deltas = 0;
    double effMass = 0.0;  // 1 / (Schur complement + gamma)
  };

  // Whether select() was last called with the same structure (bodies,
  // rows and islands of every block): its choice then stands. Keeps this
  // call's structure for the next.
  bool sameAsLastSelection(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody,
                           const std::vector<std::int32_t>& islandStart, int firstIsland,
                           int endIsland, int maxRows, bool cutIntoChains, bool withContacts,
                           const std::vector<std::uint8_t>* contactsOf);
  // The joint blocks of an island that have equality rows, into joints_.
  void collectJoints(int island, const std::vector<ConstraintBlock>& blocks,
                     const std::vector<std::int32_t>& islandStart);
  // A whole island as one group (Cuthill-McKee order).
  void addIsland(int island, int rows, const std::vector<ConstraintBlock>& blocks,
                 const std::vector<std::int32_t>& islandStart, std::int32_t staticBody,
                 bool withContacts);
  // A large island cut into chains, each a group.
  void addChains(int maxRows, const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody,
                 const std::vector<Vec3>* positions);
  // Each movable body's joints (indices into joints_), as compressed
  // lists: incidence_[incidenceStart_[b] ..][incidenceCount_[b]]; the
  // bodies set are in touched_, and clearIncidence() unsets them.
  void collectIncidence(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody);
  void clearIncidence();
  // Reverse Cuthill-McKee over joints_, into order_.
  void orderByProfile(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody);
  // A new group of the joints in order_ (indices into joints_), laid out
  // in that order with each row's profile start.
  Group& addGroup(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody);
  void factor(Group& g, const std::vector<ConstraintBlock>& blocks,
              std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies);
  // The LDL^T of the group's K from `rows`, into F (the group's profile).
  void factorInto(const Group& g, const std::vector<ConstraintBlock>& blocks,
                  std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies,
                  double* F);
  // x = L^-1 x with the group's factor (K = L D L^T; F: another factor
  // in its profile, such as poseFactor_'s).
  void forwardSubstitute(const Group& g, double* x, const double* F = nullptr) const;
  // x = K^-1 x with the group's factor (or F).
  void solveInPlace(const Group& g, double* x, const double* F = nullptr) const;
  // x^T K^-1 x, as y^T D^-1 y with y = L^-1 x (K = L D L^T): half a solve.
  // Overwrites x with y.
  double inverseQuadraticInPlace(const Group& g, double* x) const;
  // Each bounded row's w and effective mass, once the factor is made.
  void coupleBounded(const Group& g, const std::vector<ConstraintBlock>& blocks,
                     std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies);

  std::vector<std::int32_t> wholeIsland_;     // island -> its whole-island group, or -1
  std::vector<std::int32_t> islandGroups_;    // island i's groups from islandGroups_[i]
  std::vector<std::int32_t> groupOfBlock_;    // block -> the group solving its equality rows, or -1
  std::vector<std::uint8_t> coupledContact_;  // contact block -> its normals solved here
  std::vector<std::int32_t> heldMark_;        // addIsland's: the island whose joints hold a body
  std::vector<Group> groups_;
  // Per covered row, in the group's elimination order:
  std::vector<std::int32_t> entryRow_;    // index into the solver's rows
  std::vector<std::int32_t> entryBlock_;  // its block
  std::vector<std::int32_t> first_;       // first column of its profile (group-local)
  // Its profile's entries (columns first_ .. itself) are at rowBase_ +
  // column in the group's part of factor_.
  std::vector<std::size_t> rowBase_;
  std::vector<double> factor_;                // L left of the diagonal, 1/D on it (row profiles)
  std::vector<double> poseFactor_;            // the same at the new pose (factorAtPose)
  std::vector<double> rhs_;                   // the guard's scratch (one island at a time)
  mutable std::vector<double> solveScratch_;  // per covered row: a solve's right side, by group
  std::vector<double> factorScratch_;         // per covered row: factor()'s 1/D, coupleBounded's u
  std::size_t factorSize_ = 0;
  std::vector<BoundedRow> bounded_;
  std::vector<double> weights_;
  std::size_t weightsSize_ = 0;
  std::vector<std::int32_t> islandBodies_;
  std::vector<std::int32_t> bodyLocal_;  // a body's index in its island's list (scratch)
  std::vector<Vec3> deltas_;
  std::size_t deltasSize_ = 0;
  std::vector<double> boundedStep_;  // each bounded row's impulse change in a sweep
  // Ordering scratch, reused.
  std::vector<std::int32_t> joints_, order_, queue_, bodyFirst_, blockStart_;
  // Chain scratch: each body's joints, the chain a body is in, the
  // chain's part grown from its seed's first body.
  std::vector<std::int32_t> incidenceStart_, incidenceCount_, incidence_, bodyMark_, chainFront_;
  std::vector<std::int32_t> touched_, neighbourMark_, byDegree_;
  std::vector<std::int32_t> signature_, lastSignature_;  // sameAsLastSelection's
  std::vector<std::uint8_t> visited_;
};

}  // namespace blockstep

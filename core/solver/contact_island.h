// An island's contact normal rows solved together, exactly.
//
// Gauss-Seidel passes a load from contact to contact one sweep at a time,
// and where a light body carries a heavy one it passes only the light
// body's share: a 1000 kg block on a 1 kg plank across two supports needs
// about a thousand sweeps before the supports carry the block, so under
// every sub-stepped setting the plank was pushed through them (240 mm
// deep, the block 0.55 m down) and at 10 sub-steps the runaway guard
// fired; a resting stack of ten boxes sank 0.8 mm a contact and its top
// drifted 4.3 mm in 300 frames. ODE's dWorldStep holds both: it solves
// each island's rows at once (Dantzig's LCP).
//
// Here an island of contacts only (no joints: those keep their own
// blocks, island_block.h) with at most maxRows normal rows solves them as
// one block: K = J M^-1 J^T of all its normal rows, and an active set (the
// points that push) solved exactly with K's LDL^T on it, each point that
// would pull dropped and each inactive point that would sink added,
// until neither is left (a few rounds; the factor is remade only when
// the set changes, so a resting pile keeps one factor per prepare).
//
// K is singular wherever the island is statically indeterminate: a face's
// four corners on a plane (rank 3), a plank on two supports. Impulses
// along those directions move no body, so the solve leaves them out (the
// zero pivots of the factor give a basis of them) and the impulses kept
// are the least-norm ones: a face's load spread over its corners, as the
// per-manifold passes do. Targets that no impulse meets together (one
// corner apart from its face's plane, the others touching) are met in the
// least-squares sense, and the manifolds then finish one by one.
//
// Solved exactly, the rows need no softness to converge: they are rigid
// (CFM 0) and correct position error at their softness's rate. They keep
// each contact kRestDepth deep rather than exactly touching: at zero
// depth ODE's box collider found some points of a resting plank and not
// others from frame to frame, and the island's points came and went.
// Friction stays bounded rows around the block (Gauss-Seidel).
//
// A larger island (a pile of a thousand shapes) is too large to solve at
// once, but its worst case for Gauss-Seidel is local: a light body pressed
// between a heavy one and the ground (a 44 g cylinder under a 2 kg ball)
// passes on only its share of the load a sweep: the ball pushed it 10 mm
// into the ground in six sub-steps, and it came out 26 mm deep, spinning.
// So each body at least
// kLightBodyRatio times lighter than a body it touches gets its manifolds
// solved as one group the same way (SolverSettings::lightBodyGroups),
// Gauss-Seidel with the island's other manifolds and groups.
#pragma once

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/constraints/row.h"
#include "core/solver/solver_body.h"

namespace blockstep {

// The chosen islands' groups of contact manifolds: one group for a whole
// small island, one per light body in a larger one.
class ContactIslands {
 public:
  // The depth (m) the island's contacts rest at.
  static constexpr double kRestDepth = 1e-5;

  // Chooses this prepare's groups from the built (not yet finished)
  // blocks of islands [islandBegin, islandEnd): the whole island when it
  // has no joint, every manifold is eligible(block) and it has at most
  // maxRows normal rows in all; otherwise, when lightBodies is set, its
  // light bodies' eligible manifolds (addLightBodies; joints keep their
  // blocks). Eligible:
  // not restitutive (solved at once, Newton's cradle would pass its
  // impulse down the row as one shove) and not a physical spring (its
  // softness is real, rows here are rigid). A lone manifold counts too:
  // its points' active set is exact where the manifold's own block falls
  // back to projected passes (a hull on two vertices and an edge crept at
  // 12 mm/s for good).
  template <class Eligible, class Impact>
  void select(const std::vector<ConstraintBlock>& blocks,
              const std::vector<std::int32_t>& islandStart, int islandBegin, int islandEnd,
              std::int32_t staticBody, const std::vector<SolverBody>& bodies, int maxRows,
              bool lightBodies, bool impactGroups, Eligible eligible, Impact impact);
  // Whether island i has groups; whether block b is in one.
  bool covers(int island) const {
    return island < static_cast<int>(groupsOfIsland_.size()) &&
           groupsOfIsland_[island].first < groupsOfIsland_[island].second;
  }
  bool groups(std::int32_t block) const {
    return block < static_cast<std::int32_t>(groupOfBlock_.size()) && groupOfBlock_[block] >= 0;
  }
  // The groups of island i: [groupsBegin, groupsEnd).
  int groupsBegin(int island) const { return groupsOfIsland_[island].first; }
  int groupsEnd(int island) const { return groupsOfIsland_[island].second; }
  // Whether group g is its whole island (else a light body's manifolds
  // or an impact's).
  bool wholeIsland(int g) const { return groups_[g].wholeIsland; }
  // f(block index) for each manifold of group g, in the island's order
  // (a light body's; a whole island's group is breadth-first).
  template <class F>
  void forEachBlock(int g, F f) const {
    const Group& group = groups_[g];
    for (std::int32_t e = group.firstEntry; e < group.firstEntry + group.size; ++e) {
      if (e == group.firstEntry || entryBlock_[e] != entryBlock_[e - 1]) f(entryBlock_[e]);
    }
  }
  // K of each group, once its rows are finished (Jacobians times M^-1);
  // the active set starts as the points touching.
  void prepare(const std::vector<ConstraintBlock>& blocks, const std::vector<ConstraintRow>& rows,
               const std::vector<SolverBody>& bodies);

  // Each row of an impact's group (addImpacts) back to at most the
  // impulse it was warm started with at prepare.
  void capImpactImpulses(std::vector<ConstraintRow>& rows) const;

  // After the sweeps of islands [islandBegin, islandEnd): around each
  // usable manifold that sinking(block) says still closes too fast, in an
  // island not solved whole, a group as for an impact (addImpacts: the
  // manifolds breadth-first over the bodies they share, each body's on
  // the static body first, at most maxRows rows), manifolds of this
  // prepare's groups included, solved kSinkingPasses times in turn, rigid
  // and without bias: they stop the sinking and leave the push-out to the
  // rows' own bias. Gauss-Seidel with soft rows passes a landing load on
  // a sweep at a time and sinks under it: in the 1,000-shape pile a 2 kg
  // body with 10 kg on it landed at 2.2 m/s on a 0.73 kg hull, which sank
  // 0.3-1.5 m/s into the ground after every sub-step's sweeps and went
  // 7.7 mm deep. With the groups' push-out too, or their impulses kept
  // from warm starting the next sub-step as an impact's are, the pile
  // gained up to 3.9 J in a frame and settled deeper (last second 2.1
  // against 1.0-1.3 mm on two frame steps). Returns the groups made.
  template <class Eligible, class Sinking>
  int solveSinking(const std::vector<ConstraintBlock>& blocks,
                   const std::vector<std::int32_t>& islandStart, int islandBegin, int islandEnd,
                   std::int32_t staticBody, std::vector<SolverBody>& bodies, int maxRows,
                   Eligible eligible, Sinking sinking, std::vector<ConstraintRow>& rows);

  enum class Outcome {
    Exact,     // solved and applied
    Unmet,     // applied; some targets could not all be met: finish per manifold
    Unsolved,  // nothing applied (the active set did not settle): solve per manifold
  };
  // One solve of group g's normal rows (its own scratch: islands may be
  // solved at once on different threads).
  Outcome solve(int g, bool useBias, const std::vector<ConstraintBlock>& blocks,
                std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies);

 private:
  struct Group {
    std::int32_t firstEntry = 0;  // into entryRow_, entryBlock_, active_
    std::int32_t size = 0;        // normal rows
    std::size_t matrix = 0;       // K (size^2), then the active set's factor and null basis
    std::int32_t activeCount = 0;
    std::int32_t nullCount = 0;  // null basis vectors of the active set's K
    bool factorStale = true;
    bool wholeIsland = false;
    bool impact = false;  // an impact's: its impulses capped
  };
  // The most rounds of the active set a solve may take.
  static constexpr int kMaxRounds = 8;
  // Passes over the sinking groups (solveSinking). Solved once each, one
  // after the other, two groups sharing a landing's bodies left a 12 kg
  // load on a 0.73 kg box 2.2 mm deep and moving up at 0.45 m/s (each
  // passed its share of the impulse to the other's bodies unseen); in
  // four passes 0.46 mm, in eight 0.38 mm.
  static constexpr int kSinkingPasses = 4;

  // A body is light beside a body it touches at least this many times
  // heavier: the pile's 44 g cylinder under a 2 kg ball. Chosen over 2,
  // 2.5 and 4 (README, "Light bodies in larger islands").
  static constexpr double kLightBodyRatio = 3.0;

  // Island i's manifolds as one group, in breadth-first order over the
  // bodies they share from one on the static body (Cuthill-McKee): a
  // stack's K is then banded, and its factor and solves follow the band.
  void addIsland(int island, const std::vector<ConstraintBlock>& blocks,
                 const std::vector<std::int32_t>& islandStart, std::int32_t staticBody);
  // A group of each light body's usable_ manifolds (at most maxRows rows,
  // two manifolds or more, none in an earlier group), lightest body
  // first; bodies with a joint are not taken for light.
  void addLightBodies(int island, const std::vector<ConstraintBlock>& blocks,
                      const std::vector<std::int32_t>& islandStart, std::int32_t staticBody,
                      const std::vector<SolverBody>& bodies, int maxRows);
  // A group around each impact (a usable manifold impact(blk) says closes
  // fast): the usable manifolds breadth-first from it over the bodies
  // they share, at most maxRows rows, none in an earlier group.
  // A sinking group (`late`) leaves groupOfBlock_ as it is: its manifolds
  // keep their place in the sweeps.
  void addImpacts(int island, const std::vector<ConstraintBlock>& blocks,
                  const std::vector<std::int32_t>& islandStart, std::int32_t staticBody,
                  int maxRows, bool late = false);
  // Marks the bodies a joint of island i holds with a new stamp_ (the
  // static body never).
  void markJointBodies(int island, const std::vector<ConstraintBlock>& blocks,
                       const std::vector<std::int32_t>& islandStart, std::int32_t staticBody,
                       std::size_t bodyCount);
  bool heldByJoint(const ConstraintBlock& blk) const {
    return jointStamp_[blk.bodyA] == stamp_ || jointStamp_[blk.bodyB] == stamp_;
  }
  // incidence_: (body, block) of island i, by body (the static body left
  // out); once an island (indexed_).
  void indexBodies(int island, const std::vector<ConstraintBlock>& blocks,
                   const std::vector<std::int32_t>& islandStart, std::int32_t staticBody);
  // A group of the island's manifolds first + k for k in `members`
  // (`late`: not marked in groupOfBlock_).
  void appendGroup(const std::vector<ConstraintBlock>& blocks, std::int32_t first,
                   const std::vector<std::int32_t>& members, bool late = false);
  // Storage for groups_ (grown only while warming up), and group g's K and
  // starting active set.
  void reserveStorage();
  void prepareGroup(Group& g, const std::vector<ConstraintBlock>& blocks,
                    const std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies);
  // The active set's K, its LDL^T and null basis, into the group's storage.
  void factorActive(Group& g);
  double* kOf(const Group& g) { return &storage_[g.matrix]; }
  double* factorOf(const Group& g) {
    return &storage_[g.matrix + static_cast<std::size_t>(g.size) * g.size];
  }
  double* nullsOf(const Group& g) {
    return &storage_[g.matrix + 2 * static_cast<std::size_t>(g.size) * g.size];
  }

  std::vector<std::pair<std::int32_t, std::int32_t>> groupsOfIsland_;  // [begin, end) of groups_
  // How many of groups_ select made (sinking groups follow them), and the
  // entries they hold.
  std::size_t selectedGroups_ = 0, selectedEntries_ = 0;
  std::vector<std::int32_t> groupOfBlock_;  // -1: none
  std::vector<Group> groups_;
  // Per normal row of a group, in the group's order:
  std::vector<std::int32_t> entryRow_, entryBlock_;
  std::vector<double> warmImpulse_;       // an impact group's rows': as warm started
  std::vector<std::int32_t> activeList_;  // the active rows (group-local), first activeCount
  std::vector<std::uint8_t> active_;
  std::vector<double> storage_;  // per group: K, factor, null basis (size^2 each)
  std::vector<double> scratch_;  // per group: 4 size
  // Per active row (in active order): the first column of its row of K
  // (the factor's profile); per null basis vector: the rows it spans.
  std::vector<std::int32_t> profileFirst_, nullBegin_, nullEnd_;
  // Grouping scratch: (body, manifold) pairs by body, the breadth-first
  // queue, manifolds taken, a group's members, (-1/m, body) of the light
  // bodies.
  std::vector<std::pair<std::int32_t, std::int32_t>> incidence_;
  std::vector<std::int32_t> order_, members_;
  std::vector<std::uint8_t> taken_;
  std::vector<std::pair<double, std::int32_t>> lightBodies_;
  // select's: whether each manifold of the island at hand may be grouped
  // (a contact, eligible); joints never are.
  std::vector<std::uint8_t> usable_;
  // select's: whether each manifold of the island at hand is an impact;
  // whether incidence_ holds the island at hand.
  std::vector<std::uint8_t> impact_;
  bool indexed_ = false;
  // The bodies a joint of the island at hand holds carry stamp_
  // (markJointBodies).
  std::vector<std::uint32_t> jointStamp_;
  std::uint32_t stamp_ = 0;
};

template <class Eligible, class Impact>
void ContactIslands::select(const std::vector<ConstraintBlock>& blocks,
                            const std::vector<std::int32_t>& islandStart, int islandBegin,
                            int islandEnd, std::int32_t staticBody,
                            const std::vector<SolverBody>& bodies, int maxRows, bool lightBodies,
                            bool impactGroups, Eligible eligible, Impact impact) {
  if (static_cast<int>(groupsOfIsland_.size()) < islandEnd) groupsOfIsland_.resize(islandEnd);
  std::fill(groupsOfIsland_.begin() + islandBegin, groupsOfIsland_.begin() + islandEnd,
            std::pair<std::int32_t, std::int32_t>{0, 0});
  if (groupOfBlock_.size() < blocks.size()) groupOfBlock_.resize(blocks.size(), -1);
  std::fill(groupOfBlock_.begin() + islandStart[islandBegin],
            groupOfBlock_.begin() + islandStart[islandEnd], -1);
  groups_.clear();
  entryRow_.clear();
  entryBlock_.clear();
  for (int island = islandBegin; island < islandEnd; ++island) {
    int rows = 0;
    bool all = true;
    usable_.clear();
    indexed_ = false;
    for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      usable_.push_back(blk.unilateral && eligible(blk));
      all = all && usable_.back();
      rows += blk.equality;
    }
    if (all && rows <= maxRows) {
      addIsland(island, blocks, islandStart, staticBody);
      continue;
    }
    const auto groupsBefore = static_cast<std::int32_t>(groups_.size());
    groupsOfIsland_[island] = {groupsBefore, groupsBefore};
    taken_.assign(usable_.size(), 0);
    if (impactGroups || lightBodies)
      markJointBodies(island, blocks, islandStart, staticBody, bodies.size());
    if (impactGroups) {
      impact_.clear();
      for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi)
        impact_.push_back(usable_[bi - islandStart[island]] && impact(blocks[bi]));
      addImpacts(island, blocks, islandStart, staticBody, maxRows);
    }
    if (lightBodies) addLightBodies(island, blocks, islandStart, staticBody, bodies, maxRows);
    groupsOfIsland_[island].second = static_cast<std::int32_t>(groups_.size());
  }
  selectedGroups_ = groups_.size();
  selectedEntries_ = entryRow_.size();
}

template <class Eligible, class Sinking>
int ContactIslands::solveSinking(const std::vector<ConstraintBlock>& blocks,
                                 const std::vector<std::int32_t>& islandStart, int islandBegin,
                                 int islandEnd, std::int32_t staticBody,
                                 std::vector<SolverBody>& bodies, int maxRows, Eligible eligible,
                                 Sinking sinking, std::vector<ConstraintRow>& rows) {
  // The last sub-step's sinking groups go (rows carried from an earlier
  // prepare keep select's groups).
  groups_.resize(selectedGroups_);
  entryRow_.resize(selectedEntries_);
  entryBlock_.resize(selectedEntries_);
  for (int island = islandBegin; island < islandEnd; ++island) {
    if (covers(island) && wholeIsland(groupsBegin(island))) continue;
    const std::int32_t first = islandStart[island];
    const std::int32_t count = islandStart[island + 1] - first;
    bool any = false;
    for (std::int32_t k = 0; k < count && !any; ++k) {
      const ConstraintBlock& blk = blocks[first + k];
      any = blk.unilateral && sinking(blk) && eligible(blk);
    }
    if (!any) continue;
    usable_.clear();
    impact_.clear();
    for (std::int32_t k = 0; k < count; ++k) {
      const ConstraintBlock& blk = blocks[first + k];
      usable_.push_back(blk.unilateral && eligible(blk));
      impact_.push_back(usable_.back() && sinking(blk));
    }
    taken_.assign(static_cast<std::size_t>(count), 0);
    indexed_ = false;
    markJointBodies(island, blocks, islandStart, staticBody, bodies.size());
    addImpacts(island, blocks, islandStart, staticBody, maxRows, true);
  }
  if (groups_.size() == selectedGroups_) return 0;
  reserveStorage();
  // Rigid, as every group's rows are: a soft row sinks by gamma P under
  // its impulse P, 0.7 m/s for that hull.
  for (std::size_t k = selectedGroups_; k < groups_.size(); ++k) {
    Group& g = groups_[k];
    for (std::int32_t e = g.firstEntry; e < g.firstEntry + g.size; ++e)
      rows[entryRow_[e]].gamma = 0.0;
    prepareGroup(g, blocks, rows, bodies);
  }
  for (int pass = 0; pass < kSinkingPasses; ++pass)
    for (std::size_t k = selectedGroups_; k < groups_.size(); ++k)
      solve(static_cast<int>(k), false, blocks, rows, bodies);
  return static_cast<int>(groups_.size() - selectedGroups_);
}

}  // namespace blockstep

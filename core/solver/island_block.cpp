#include "core/solver/island_block.h"

#include <algorithm>
#include <cmath>

#include "core/solver/row_ops.h"

namespace blockstep {
namespace {

// A body that the rows cannot move (the static frame, kinematic bodies)
// couples nothing: joints meeting only there are independent.
bool immovable(const SolverBody& b) {
  return b.invMass == 0.0;
}

}  // namespace

void IslandBlocks::selectIslands(const std::vector<ConstraintBlock>& blocks,
                                 std::int32_t staticBody,
                                 const std::vector<std::int32_t>& islandStart, int firstIsland,
                                 int endIsland, int maxRows, bool cutIntoChains,
                                 const std::vector<Vec3>* positions, bool withContacts,
                                 const std::vector<std::uint8_t>* contactsOf) {
  if (sameAsLastSelection(blocks, staticBody, islandStart, firstIsland, endIsland, maxRows,
                          cutIntoChains, withContacts, contactsOf))
    return;
  wholeIsland_.assign(endIsland, -1);
  islandGroups_.assign(endIsland + 1, 0);
  groupOfBlock_.assign(blocks.size(), -1);
  coupledContact_.assign(blocks.size(), 0);
  groups_.clear();
  entryRow_.clear();
  entryBlock_.clear();
  first_.clear();
  rowBase_.clear();
  bounded_.clear();
  islandBodies_.clear();
  factorSize_ = weightsSize_ = deltasSize_ = 0;
  if (maxRows < 2) return;
  const auto bodySlots = static_cast<std::size_t>(staticBody) + 1;
  if (bodyLocal_.size() < bodySlots) bodyLocal_.resize(bodySlots);
  if (heldMark_.size() < bodySlots) heldMark_.resize(bodySlots, -1);
  if (bodyFirst_.size() < bodySlots) bodyFirst_.resize(bodySlots);
  for (int island = firstIsland; island < endIsland; ++island) {
    islandGroups_[island] = static_cast<std::int32_t>(groups_.size());
    collectJoints(island, blocks, islandStart);
    int n = 0;
    for (std::int32_t bi : joints_)
      n += blocks[bi].equality;
    // One joint is already one block.
    if (joints_.size() < 2) continue;
    if (n <= maxRows) {
      addIsland(island, n, blocks, islandStart, staticBody,
                withContacts || (contactsOf && (*contactsOf)[island]));
    } else if (cutIntoChains) {
      addChains(maxRows, blocks, staticBody, positions);
    }
    // Otherwise the per-joint blocks and Gauss-Seidel take over.
  }
  islandGroups_[endIsland] = static_cast<std::int32_t>(groups_.size());
}

// What select() reads of the blocks, islands and settings, laid out one
// after another; chains also follow where the bodies are, so a selection
// with chains is always made afresh.
bool IslandBlocks::sameAsLastSelection(const std::vector<ConstraintBlock>& blocks,
                                       std::int32_t staticBody,
                                       const std::vector<std::int32_t>& islandStart,
                                       int firstIsland, int endIsland, int maxRows,
                                       bool cutIntoChains, bool withContacts,
                                       const std::vector<std::uint8_t>* contactsOf) {
  signature_.clear();
  signature_.insert(signature_.end(),
                    {staticBody, firstIsland, endIsland, maxRows, cutIntoChains ? 1 : 0,
                     withContacts ? 1 : 0, static_cast<std::int32_t>(blocks.size())});
  signature_.insert(signature_.end(), islandStart.begin() + firstIsland,
                    islandStart.begin() + endIsland + 1);
  if (contactsOf) {
    for (int island = firstIsland; island < endIsland; ++island)
      signature_.push_back((*contactsOf)[island]);
  }
  for (std::int32_t bi = islandStart[firstIsland]; bi < islandStart[endIsland]; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    signature_.insert(signature_.end(), {blk.bodyA, blk.bodyB, blk.firstRow, blk.equality,
                                         blk.bounded, blk.unilateral ? 1 : 0});
  }
  const bool same = !cutIntoChains && signature_ == lastSignature_;
  std::swap(signature_, lastSignature_);
  return same;
}

void IslandBlocks::collectJoints(int island, const std::vector<ConstraintBlock>& blocks,
                                 const std::vector<std::int32_t>& islandStart) {
  joints_.clear();
  for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (!blk.unilateral && blk.equality > 0) joints_.push_back(bi);
  }
}

// The island's joints' bounded rows, each in the null space of its
// equality rows, when nothing touches it; with withContacts, also when
// something does: then the normal rows of its contacts on jointed bodies
// join them, so every row that holds the joints' bodies up is solved in
// the null space of the joints. Contacts left outside as Gauss-Seidel
// partners see only their own bodies' mass: a thrown ragdoll's thigh
// landing at 3.4 m/s stopped its own 7 kg while the joints pulled the
// other 37 kg down after it, and one sweep left it still sinking at
// 1.6 m/s, 66 mm deep (quickstep's 20 iterations: 30 mm). Where limits
// were in the null space and contacts were not, a ragdoll lying on the
// ground settled 4-7 times deeper. Friction stays each manifold's,
// Gauss-Seidel before the island's solve: in the null space too it
// tripled the rows' cost (hair at 10 sub-steps 13.6 against 9.8 ms a
// frame, 9.2 without the setting) and the thrown ragdoll tumbled onto its
// head harder (deepest contact over four perturbed starts, median 73 mm
// against 38). Only contacts on a jointed body are coupled, and they stay
// in their manifold blocks' light-body groups too (Gauss-Seidel over
// blocks that overlap): a free body's contacts otherwise lose what keeps
// it from being pressed into others. A loose 2 kg box pushed by the
// 150 kg car went 43 mm into the next box with its manifolds row by row
// in the car's null space, and 86 mm into the ground with its group
// short of its contact with the car. An island where the coupled rows
// would cost more than kCoupledContactWork a sweep keeps all its
// contacts' manifold blocks.
void IslandBlocks::addIsland(int island, int rows, const std::vector<ConstraintBlock>& blocks,
                             const std::vector<std::int32_t>& islandStart, std::int32_t staticBody,
                             bool withContacts) {
  orderByProfile(blocks, staticBody);
  wholeIsland_[island] = static_cast<std::int32_t>(groups_.size());
  Group& g = addGroup(blocks, staticBody);
  g.firstBounded = static_cast<std::int32_t>(bounded_.size());
  const std::int32_t begin = islandStart[island], end = islandStart[island + 1];
  // The bodies a joint holds.
  for (std::int32_t bi = begin; bi < end; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (blk.unilateral) continue;
    for (std::int32_t body : {blk.bodyA, blk.bodyB})
      if (body != staticBody) heldMark_[body] = island;
  }
  auto held = [&](std::int32_t body) { return body != staticBody && heldMark_[body] == island; };
  auto coupled = [&](const ConstraintBlock& blk) {
    return blk.unilateral && withContacts && (held(blk.bodyA) || held(blk.bodyB));
  };
  bool touches = false;
  std::size_t boundedRows = 0;
  g.firstBody = static_cast<std::int32_t>(islandBodies_.size());
  for (std::int32_t bi = begin; bi < end; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    touches = touches || blk.unilateral;
    if (blk.unilateral && !coupled(blk)) continue;
    if (blk.unilateral) coupledContact_[bi] = 1;
    boundedRows += blk.unilateral ? blk.equality : blk.bounded;
    for (std::int32_t body : {blk.bodyA, blk.bodyB}) {
      if (body == staticBody || bodyMark_[body] == island) continue;
      bodyMark_[body] = island;
      islandBodies_.push_back(body);
    }
  }
  g.bodyCount = static_cast<std::int32_t>(islandBodies_.size()) - g.firstBody;
  for (std::int32_t k = g.firstBody; k < g.firstBody + g.bodyCount; ++k)
    bodyMark_[islandBodies_[k]] = heldMark_[islandBodies_[k]] = -1;
  const std::size_t work = boundedRows * (6 * static_cast<std::size_t>(g.bodyCount) + rows);
  g.bounded = !touches || (withContacts && work <= kCoupledContactWork);
  if (!g.bounded) {
    std::fill(coupledContact_.begin() + begin, coupledContact_.begin() + end, 0);
    islandBodies_.resize(g.firstBody);
    g.bodyCount = 0;
    g.boundedCount = 0;
    return;
  }
  auto addBounded = [&](int r, std::int32_t bi) {
    bounded_.push_back({r, bi, weightsSize_, deltasSize_, 0.0});
    weightsSize_ += static_cast<std::size_t>(rows);
    deltasSize_ += 2 * static_cast<std::size_t>(g.bodyCount);
  };
  for (std::int32_t bi = begin; bi < end; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (blk.unilateral) continue;
    for (int r = blk.boundedBegin(); r < blk.boundedEnd(); ++r)
      addBounded(r, bi);
  }
  for (std::int32_t bi = begin; bi < end; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (!coupledContact_[bi]) continue;
    g.contacts = true;
    for (int r = blk.firstRow; r < blk.firstRow + blk.equality; ++r)
      addBounded(r, bi);
  }
  g.boundedCount = static_cast<std::int32_t>(bounded_.size()) - g.firstBounded;
}

// Chains grow from each joint not yet taken, at both ends, body by body:
// at each end the joint that continues the chain straightest (by where
// the bodies are) and is within 60 degrees of straight on, until the end
// is static, no such joint is left, a body would repeat (a loop), or the
// chain would pass maxRows. A chain of one joint stays that joint's block.
void IslandBlocks::addChains(int maxRows, const std::vector<ConstraintBlock>& blocks,
                             std::int32_t staticBody, const std::vector<Vec3>* positions) {
  constexpr double kStraightEnough = 0.5;  // cos 60 degrees
  const auto m = static_cast<std::int32_t>(joints_.size());
  auto otherBody = [&](std::int32_t l, std::int32_t body) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    return blk.bodyA == body ? blk.bodyB : blk.bodyA;
  };
  collectIncidence(blocks, staticBody);
  // The unit direction from one body to another, or zero where a
  // position is unknown (the static frame).
  auto direction = [&](std::int32_t from, std::int32_t to) -> Vec3 {
    const auto known = positions ? static_cast<std::int32_t>(positions->size()) : 0;
    if (from == staticBody || to == staticBody || from >= known || to >= known) return Vec3::Zero();
    const Vec3 d = (*positions)[to] - (*positions)[from];
    const double length = d.norm();
    return length > 0.0 ? Vec3(d / length) : Vec3::Zero();
  };

  visited_.assign(m, 0);
  if (blockStart_.size() < static_cast<std::size_t>(m)) blockStart_.resize(m);
  for (std::int32_t seed = 0; seed < m; ++seed) {
    if (visited_[seed]) continue;
    visited_[seed] = 1;
    int rows = blocks[joints_[seed]].equality;
    const ConstraintBlock& seedBlock = blocks[joints_[seed]];
    for (std::int32_t b : {seedBlock.bodyA, seedBlock.bodyB})
      if (b != staticBody) bodyMark_[b] = seed;
    // order_ holds the chain grown from A's end reversed, then the seed,
    // then the chain grown from B's end (chainFront_ the first part).
    chainFront_.clear();
    order_.assign(1, seed);
    for (int side = 0; side < 2; ++side) {
      std::int32_t previous = seed;
      std::int32_t end = side == 0 ? seedBlock.bodyA : seedBlock.bodyB;
      while (end != staticBody) {
        const Vec3 in = direction(otherBody(previous, end), end);
        std::int32_t best = -1;
        double bestScore = -kInf;
        for (std::int32_t k = incidenceStart_[end]; k < incidenceStart_[end] + incidenceCount_[end];
             ++k) {
          const std::int32_t l = incidence_[k];
          if (visited_[l] || rows + blocks[joints_[l]].equality > maxRows) continue;
          const std::int32_t next = otherBody(l, end);
          if (next != staticBody && bodyMark_[next] == seed) continue;  // a loop
          const Vec3 out = direction(end, next);
          const bool known = in != Vec3::Zero() && out != Vec3::Zero();
          const double score = known ? in.dot(out) : 0.0;
          if (known && score < kStraightEnough) continue;
          if (score > bestScore) {
            best = l;
            bestScore = score;
          }
        }
        if (best < 0) break;
        visited_[best] = 1;
        rows += blocks[joints_[best]].equality;
        (side == 0 ? chainFront_ : order_).push_back(best);
        end = otherBody(best, end);
        if (end != staticBody) bodyMark_[end] = seed;
        previous = best;
      }
    }
    if (!chainFront_.empty() || order_.size() > 1) {
      order_.insert(order_.begin(), chainFront_.rbegin(), chainFront_.rend());
      addGroup(blocks, staticBody);
    }
  }
  clearIncidence();
}

void IslandBlocks::collectIncidence(const std::vector<ConstraintBlock>& blocks,
                                    std::int32_t staticBody) {
  const auto m = static_cast<std::int32_t>(joints_.size());
  const auto bodySlots = static_cast<std::size_t>(staticBody) + 1;
  if (incidenceStart_.size() < bodySlots) {
    incidenceStart_.resize(bodySlots, -1);
    incidenceCount_.resize(bodySlots, 0);
    bodyMark_.resize(bodySlots, -1);
  }
  touched_.clear();
  for (std::int32_t l = 0; l < m; ++l) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    for (std::int32_t b : {blk.bodyA, blk.bodyB}) {
      if (b == staticBody || (b == blk.bodyB && blk.bodyA == blk.bodyB)) continue;
      if (incidenceStart_[b] < 0) {
        incidenceStart_[b] = 0;
        incidenceCount_[b] = 0;
        touched_.push_back(b);
      }
      ++incidenceCount_[b];
    }
  }
  std::int32_t offset = 0;
  for (std::int32_t b : touched_) {
    incidenceStart_[b] = offset;
    offset += incidenceCount_[b];
    incidenceCount_[b] = 0;
  }
  incidence_.resize(offset);
  for (std::int32_t l = 0; l < m; ++l) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    for (std::int32_t b : {blk.bodyA, blk.bodyB}) {
      if (b == staticBody || (b == blk.bodyB && blk.bodyA == blk.bodyB)) continue;
      incidence_[incidenceStart_[b] + incidenceCount_[b]++] = l;
    }
  }
}

void IslandBlocks::clearIncidence() {
  for (std::int32_t b : touched_) {
    incidenceStart_[b] = -1;
    bodyMark_[b] = -1;
  }
  touched_.clear();
}

void IslandBlocks::prepareFactors() {
  // All grow only while warming up.
  if (factor_.size() < factorSize_) factor_.resize(factorSize_);
  if (weights_.size() < weightsSize_) weights_.resize(weightsSize_);
  if (deltas_.size() < deltasSize_) deltas_.resize(deltasSize_);
  if (boundedStep_.size() < bounded_.size()) boundedStep_.resize(bounded_.size());
  if (solveScratch_.size() < entryRow_.size()) solveScratch_.resize(entryRow_.size());
  if (factorScratch_.size() < entryRow_.size()) factorScratch_.resize(entryRow_.size());
}

void IslandBlocks::factorOne(int k, const std::vector<ConstraintBlock>& blocks,
                             std::vector<ConstraintRow>& rows,
                             const std::vector<SolverBody>& bodies) {
  factor(groups_[k], blocks, rows, bodies);
  coupleBounded(groups_[k], blocks, rows, bodies);
}

void IslandBlocks::factorAll(const std::vector<ConstraintBlock>& blocks,
                             std::vector<ConstraintRow>& rows,
                             const std::vector<SolverBody>& bodies) {
  prepareFactors();
  for (int k = 0; k < count(); ++k)
    factorOne(k, blocks, rows, bodies);
}

// Reverse Cuthill-McKee over joints_ (neighbours: joints that share a
// movable body), into order_. Each joint's neighbours come from its
// bodies' joint lists, so a chain or a ragdoll orders in linear time
// (comparing every pair of joints was a tenth of a 50-link chain's step).
void IslandBlocks::orderByProfile(const std::vector<ConstraintBlock>& blocks,
                                  std::int32_t staticBody) {
  const auto m = static_cast<std::int32_t>(joints_.size());
  collectIncidence(blocks, staticBody);
  // Calls f(k) once for each joint k sharing a movable body with joint l.
  // neighbourMark_ (one stamp per l) keeps a joint that shares both of
  // l's bodies from counting twice.
  neighbourMark_.assign(m, -1);
  auto forNeighbours = [&](std::int32_t l, auto&& f) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    for (std::int32_t b : {blk.bodyA, blk.bodyB}) {
      if (b == staticBody || (b == blk.bodyB && blk.bodyA == blk.bodyB)) continue;
      for (std::int32_t i = incidenceStart_[b]; i < incidenceStart_[b] + incidenceCount_[b]; ++i) {
        const std::int32_t k = incidence_[i];
        if (k == l || neighbourMark_[k] == l) continue;
        neighbourMark_[k] = l;
        f(k);
      }
    }
  };
  // Degree of a joint: the joints it shares a body with.
  queue_.assign(m, 0);
  visited_.assign(m, 0);
  blockStart_.assign(m, 0);
  std::vector<std::int32_t>& degree = blockStart_;  // reused before the starts are set
  for (std::int32_t l = 0; l < m; ++l)
    forNeighbours(l, [&](std::int32_t) { ++degree[l]; });
  // Each part starts from its joint of least degree (the first such).
  byDegree_.resize(m);
  for (std::int32_t l = 0; l < m; ++l)
    byDegree_[l] = l;
  // Ties in index order, as a stable sort leaves them (std::stable_sort
  // takes a buffer from the heap).
  std::sort(byDegree_.begin(), byDegree_.end(), [&](std::int32_t p, std::int32_t q) {
    return degree[p] != degree[q] ? degree[p] < degree[q] : p < q;
  });
  neighbourMark_.assign(m, -1);
  std::int32_t head = 0, tail = 0, nextStart = 0;
  while (tail < m) {
    while (visited_[byDegree_[nextStart]])
      ++nextStart;
    const std::int32_t startAt = byDegree_[nextStart];
    visited_[startAt] = 1;
    queue_[tail++] = startAt;
    while (head < tail) {
      const std::int32_t l = queue_[head++];
      // Breadth first, each joint's new neighbours in index order.
      const std::int32_t added = tail;
      forNeighbours(l, [&](std::int32_t k) {
        if (visited_[k]) return;
        visited_[k] = 1;
        queue_[tail++] = k;
      });
      std::sort(queue_.begin() + added, queue_.begin() + tail);
    }
  }
  clearIncidence();
  order_.assign(queue_.rbegin(), queue_.rend());
}

IslandBlocks::Group& IslandBlocks::addGroup(const std::vector<ConstraintBlock>& blocks,
                                            std::int32_t staticBody) {
  auto bodiesOf = [&](std::int32_t l, auto&& f) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    if (blk.bodyA != staticBody) f(blk.bodyA);
    if (blk.bodyB != staticBody && blk.bodyB != blk.bodyA) f(blk.bodyB);
  };
  Group g;
  g.firstEntry = static_cast<std::int32_t>(entryRow_.size());
  const auto group = static_cast<std::int32_t>(groups_.size());
  if (blockStart_.size() < joints_.size()) blockStart_.resize(joints_.size());
  // Rows in order; each joint's rows start at blockStart_.
  std::int32_t position = 0;
  for (std::int32_t l : order_) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    blockStart_[l] = position;
    for (int r = 0; r < blk.equality; ++r) {
      entryRow_.push_back(blk.firstRow + r);
      entryBlock_.push_back(joints_[l]);
      first_.push_back(0);
      rowBase_.push_back(0);
    }
    groupOfBlock_[joints_[l]] = group;
    position += blk.equality;
  }
  g.size = position;
  // A row's profile starts at the first row of the earliest joint it
  // shares a body with (its own joint included).
  for (std::int32_t l : order_)
    bodiesOf(l, [&](std::int32_t b) { bodyFirst_[b] = position; });
  for (std::int32_t l : order_)
    bodiesOf(l, [&](std::int32_t b) { bodyFirst_[b] = std::min(bodyFirst_[b], blockStart_[l]); });
  for (std::int32_t l : order_) {
    const ConstraintBlock& blk = blocks[joints_[l]];
    std::int32_t start = blockStart_[l];
    bodiesOf(l, [&](std::int32_t b) { start = std::min(start, bodyFirst_[b]); });
    for (int r = 0; r < blk.equality; ++r)
      first_[g.firstEntry + blockStart_[l] + r] = start;
  }
  // Row i keeps columns first_[i] .. i, one after another: its column j
  // is at rowBase_[i] + j (rowBase_ >= 0, as every earlier row keeps at
  // least its diagonal).
  std::size_t stored = 0;
  for (std::int32_t i = 0; i < g.size; ++i) {
    const std::int32_t firstColumn = first_[g.firstEntry + i];
    rowBase_[g.firstEntry + i] = stored - firstColumn;
    stored += static_cast<std::size_t>(i - firstColumn + 1);
  }
  g.factor = factorSize_;
  factorSize_ += stored;
  groups_.push_back(g);
  return groups_.back();
}

// K within the profile, then L D L^T in place (Crout, row by row): entries
// left of a row's profile start are zero in K and stay zero in L.
void IslandBlocks::factor(Group& g, const std::vector<ConstraintBlock>& blocks,
                          std::vector<ConstraintRow>& rows, const std::vector<SolverBody>& bodies) {
  const std::int32_t n = g.size;
  const std::int32_t* blockOf = &entryBlock_[g.firstEntry];
  // Joints whose rows share one spring relative to their block's mass
  // (Solver::blockSpringShare: every rigid row under the sub-stepped
  // preset) keep it relative to the chain's, Gamma = c K: with each row's
  // gamma from its own diagonal instead, a chain solved exactly gave way
  // under the load it carries: cloth16 at 10 sub-steps 7.7 mm where this
  // gives 3.4 (per-joint blocks 5.5), chain_swing cut into chains of 10
  // joints 3.5 m where this gives 56 mm.
  // Joints with different springs each keep theirs on their diagonal.
  g.springShare = n > 0 ? blocks[blockOf[0]].springShare : 0.0;
  for (std::int32_t i = 1; i < n; ++i)
    if (blocks[blockOf[i]].springShare != g.springShare) g.springShare = -1.0;
  g.mixedSprings = g.springShare < 0.0;
  if (g.mixedSprings) g.springShare = 0.0;
  factorInto(g, blocks, rows, bodies, &factor_[g.factor]);
}

void IslandBlocks::factorInto(const Group& g, const std::vector<ConstraintBlock>& blocks,
                              std::vector<ConstraintRow>& rows,
                              const std::vector<SolverBody>& bodies, double* F) {
  const std::int32_t n = g.size;
  const std::int32_t* first = &first_[g.firstEntry];
  const std::size_t* base = &rowBase_[g.firstEntry];
  const std::int32_t* rowOf = &entryRow_[g.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[g.firstEntry];
  const bool mixed = g.mixedSprings;
  const double scaleK = 1.0 + g.springShare;
  double scale = 0.0;
  for (std::int32_t i = 0; i < n; ++i) {
    ConstraintRow& ri = rows[rowOf[i]];
    const ConstraintBlock& pi = blocks[blockOf[i]];
    double* Ki = F + base[i];
    for (std::int32_t j = first[i]; j <= i; ++j)
      Ki[j] = scaleK * rowCoupling(ri, pi, rows[rowOf[j]], blocks[blockOf[j]], bodies);
    if (mixed && pi.springShare > 0.0) ri.gamma = ri.gammaRelax = pi.springShare * Ki[i];
    Ki[i] += ri.gamma;
    scale = std::max(scale, std::abs(Ki[i]));
  }
  // A pivot that is not clearly positive (a row that repeats others, as
  // in a closed loop with CFM 0) leaves that direction to the other rows,
  // as the per-joint LDL^T does (ldlt.h).
  const double tiny = 1e-12 * (scale > 0.0 ? scale : 1.0);
  double* invD = &factorScratch_[static_cast<std::size_t>(g.firstEntry)];
  for (std::int32_t i = 0; i < n; ++i) {
    double* Li = F + base[i];
    // Row i first holds t_ij = L_ij D_j, which the next columns need
    // (t_ij = K_ij - sum_k t_ik L_jk), then L_ij = t_ij / D_j.
    for (std::int32_t j = first[i]; j < i; ++j) {
      const double* Lj = F + base[j];
      double t = Li[j];
      for (std::int32_t k = std::max(first[i], first[j]); k < j; ++k)
        t -= Li[k] * Lj[k];
      Li[j] = t;
    }
    double d = Li[i];
    for (std::int32_t j = first[i]; j < i; ++j) {
      const double l = Li[j] * invD[j];
      d -= Li[j] * l;
      Li[j] = l;
    }
    const bool pivotOk = d > tiny;
    invD[i] = pivotOk ? 1.0 / d : 0.0;
  }
  for (std::int32_t i = 0; i < n; ++i)
    F[base[i] + i] = invD[i];
}

void IslandBlocks::forwardSubstitute(const Group& g, double* x, const double* F) const {
  if (!F) F = &factor_[g.factor];
  const std::int32_t* first = &first_[g.firstEntry];
  const std::size_t* base = &rowBase_[g.firstEntry];
  for (std::int32_t i = 0; i < g.size; ++i) {
    const double* Li = F + base[i];
    double xi = x[i];
    for (std::int32_t k = first[i]; k < i; ++k)
      xi -= Li[k] * x[k];
    x[i] = xi;
  }
}

double IslandBlocks::inverseQuadraticInPlace(const Group& g, double* x) const {
  forwardSubstitute(g, x);
  const double* F = &factor_[g.factor];
  const std::size_t* base = &rowBase_[g.firstEntry];
  double sum = 0.0;
  for (std::int32_t i = 0; i < g.size; ++i)
    sum += x[i] * x[i] * F[base[i] + i];  // 1/D on the diagonal (0 for a dropped pivot)
  return sum;
}

void IslandBlocks::solveInPlace(const Group& g, double* x, const double* F) const {
  const std::int32_t n = g.size;
  if (!F) F = &factor_[g.factor];
  const std::int32_t* first = &first_[g.firstEntry];
  const std::size_t* base = &rowBase_[g.firstEntry];
  // L y = r, y *= 1/D, L^T x = y; each within the profile.
  forwardSubstitute(g, x, F);
  for (std::int32_t i = 0; i < n; ++i)
    x[i] *= F[base[i] + i];
  for (std::int32_t k = n - 1; k > 0; --k) {
    const double* Lk = F + base[k];
    const double xk = x[k];
    for (std::int32_t i = first[k]; i < k; ++i)
      x[i] -= Lk[i] * xk;
  }
}

// u = J_e M^-1 J_b^T (non-zero for the rows sharing a body with the
// bounded row's joint), w = -K^-1 u, and the Schur complement
// J_b M^-1 J_b^T - u^T K^-1 u = K_bb + u . w.
void IslandBlocks::coupleBounded(const Group& isl, const std::vector<ConstraintBlock>& blocks,
                                 std::vector<ConstraintRow>& rows,
                                 const std::vector<SolverBody>& bodies) {
  const std::int32_t n = isl.size;
  const std::int32_t* rowOf = &entryRow_[isl.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[isl.firstEntry];
  const std::int32_t* islandBody = &islandBodies_[isl.firstBody];
  // Immovable bodies are skipped (addRow): islands share them.
  for (std::int32_t k = 0; k < isl.bodyCount; ++k) {
    if (!immovable(bodies[islandBody[k]])) bodyLocal_[islandBody[k]] = k;
  }
  // Adds a row's M^-1 J^T times p to a bounded row's velocity changes.
  auto addRow = [&](Vec3* delta, const ConstraintRow& row, const ConstraintBlock& blk, double p) {
    for (int side = 0; side < 2; ++side) {
      const std::int32_t body = side == 0 ? blk.bodyA : blk.bodyB;
      const SolverBody& sb = bodies[body];
      if (immovable(sb)) continue;
      Vec3* d = delta + 2 * bodyLocal_[body];
      d[0] += (p * sb.invMass) * (side == 0 ? row.linA : row.linB);
      d[1] += p * (side == 0 ? row.invIangA : row.invIangB);
    }
  };
  for (std::int32_t k = isl.firstBounded; k < isl.firstBounded + isl.boundedCount; ++k) {
    BoundedRow& br = bounded_[k];
    ConstraintRow& row = rows[br.row];
    const ConstraintBlock& blk = blocks[br.block];
    double* w = &weights_[br.weights];
    for (std::int32_t i = 0; i < n; ++i)
      w[i] = rowCoupling(rows[rowOf[i]], blocks[blockOf[i]], row, blk, bodies);
    double kbb = rowDiagonal(row, bodies[blk.bodyA], bodies[blk.bodyB]);
    double uKu = 0.0;
    // u is kept beside w only long enough to form u . K^-1 u.
    double* u = &factorScratch_[static_cast<std::size_t>(isl.firstEntry)];
    std::copy(w, w + n, u);
    solveInPlace(isl, w);
    for (std::int32_t i = 0; i < n; ++i) {
      uKu += u[i] * w[i];
      w[i] = -w[i];
    }
    Vec3* delta = &deltas_[br.deltas];
    std::fill(delta, delta + 2 * isl.bodyCount, Vec3::Zero());
    addRow(delta, row, blk, 1.0);
    for (std::int32_t i = 0; i < n; ++i) {
      if (w[i] != 0.0) addRow(delta, rows[rowOf[i]], blocks[blockOf[i]], w[i]);
    }
    // A mass-relative spring sees the Schur complement as its mass
    // (Solver::coupleBoundedRows says why).
    // A contact normal stays rigid in relax (rowResidual says why).
    if (row.gammaShare > 0.0) {
      row.gamma = row.gammaShare * (kbb - uKu);
      if (!blk.unilateral || br.row >= blk.firstRow + blk.equality) row.gammaRelax = row.gamma;
    }
    const double schur = kbb - uKu + row.gamma;
    // A bounded row that the equality rows already fix has no freedom left.
    br.effMass = schur > 1e-12 * std::max(kbb, 1e-300) ? 1.0 / schur : 0.0;
  }
}

// Each row moves the island's bodies by its precomputed velocity changes;
// the equality rows' share, w times the row's impulse, is added once at
// the end (only the island solve reads their impulses).
void IslandBlocks::solveBounded(int island, bool useBias, int motorPasses,
                                const std::vector<ConstraintBlock>& blocks,
                                std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies) {
  const Group& isl = groups_[wholeIsland_[island]];
  const std::int32_t n = isl.size;
  const std::int32_t* rowOf = &entryRow_[isl.firstEntry];
  const std::int32_t* islandBody = &islandBodies_[isl.firstBody];
  const std::int32_t firstBounded = isl.firstBounded, endBounded = firstBounded + isl.boundedCount;
  for (std::int32_t k = firstBounded; k < endBounded; ++k)
    boundedStep_[k] = 0.0;
  for (int pass = 0; pass < motorPasses; ++pass) {
    for (std::int32_t k = firstBounded; k < endBounded; ++k) {
      const BoundedRow& br = bounded_[k];
      ConstraintRow& row = rows[br.row];
      if (relaxSkips(row, useBias)) continue;
      const ConstraintBlock& blk = blocks[br.block];
      if (pass > 0 && (row.biasKind != RowBias::Velocity || blk.joint < 0)) continue;
      const double residual = rowResidual(row, useBias, bodies[blk.bodyA], bodies[blk.bodyB]);
      const double next = std::clamp(row.impulse - residual * br.effMass, row.lo, row.hi);
      const double dP = next - row.impulse;
      if (dP == 0.0) continue;
      row.impulse = next;
      boundedStep_[k] += dP;
      const Vec3* delta = &deltas_[br.deltas];
      for (std::int32_t b = 0; b < isl.bodyCount; ++b)
        addVelocity(bodies[islandBody[b]], dP * delta[2 * b], dP * delta[2 * b + 1]);
    }
  }
  for (std::int32_t k = firstBounded; k < endBounded; ++k) {
    const double dP = boundedStep_[k];
    if (dP == 0.0) continue;
    const double* w = &weights_[bounded_[k].weights];
    for (std::int32_t i = 0; i < n; ++i)
      rows[rowOf[i]].impulse += w[i] * dP;
  }
}

void IslandBlocks::solve(int group, bool useBias, const std::vector<ConstraintBlock>& blocks,
                         std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies) {
  const Group& g = groups_[group];
  const std::int32_t n = g.size;
  const std::int32_t* rowOf = &entryRow_[g.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[g.firstEntry];
  // Each group its own part of the scratch: islands may be solved at once.
  double* x = &solveScratch_[g.firstEntry];
  for (std::int32_t i = 0; i < n; ++i) {
    const ConstraintRow& row = rows[rowOf[i]];
    const ConstraintBlock& blk = blocks[blockOf[i]];
    x[i] = relaxSkips(row, useBias)
               ? 0.0
               : -rowResidual(row, useBias, bodies[blk.bodyA], bodies[blk.bodyB]);
  }
  solveInPlace(g, x);
  const double impulseShare = g.springShare / (1.0 + g.springShare);
  for (std::int32_t i = 0; i < n; ++i) {
    ConstraintRow& row = rows[rowOf[i]];
    if (impulseShare > 0.0) x[i] -= impulseShare * row.impulse;
    const ConstraintBlock& blk = blocks[blockOf[i]];
    row.impulse += x[i];
    applyImpulse(row, x[i], bodies[blk.bodyA], bodies[blk.bodyB]);
  }
}

void IslandBlocks::factorAtPose(int group, const std::vector<ConstraintBlock>& blocks,
                                std::vector<ConstraintRow>& poseRows,
                                const std::vector<SolverBody>& bodies) {
  const Group& g = groups_[group];
  factorInto(g, blocks, poseRows, bodies, &poseFactor_[g.factor]);
}

void IslandBlocks::solvePositionErrors(int group, const std::vector<double>& error,
                                       std::vector<double>& lambda, bool atPose) const {
  const Group& g = groups_[group];
  const std::int32_t* rowOf = &entryRow_[g.firstEntry];
  double* x = &solveScratch_[g.firstEntry];
  for (std::int32_t i = 0; i < g.size; ++i)
    x[i] = -error[rowOf[i]];
  solveInPlace(g, x, atPose ? &poseFactor_[g.factor] : nullptr);
  const double scale = 1.0 + g.springShare;
  for (std::int32_t i = 0; i < g.size; ++i)
    lambda[rowOf[i]] = scale * x[i];
}

}  // namespace blockstep

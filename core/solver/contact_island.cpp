#include "core/solver/contact_island.h"

#include <algorithm>
#include <cmath>

#include "core/solver/row_ops.h"

namespace blockstep {
namespace {

// A pivot below this share of its row's diagonal is taken for zero: the
// row depends on earlier ones. Exact dependencies leave 1e-16; nearly
// repeated points of two manifolds on one pair of boxes left 1e-9 to
// 1e-7, and kept, their tiny pivots turned rounding into impulses of 1e9.
// A light body under a heavy one leaves its mass ratio (1e-3 for the
// 1000:1 plank), which this keeps up to a million to one.
constexpr double kDependentPivot = 1e-6;

// LDL^T of an m x m symmetric matrix (lower triangle, column-major) in
// place: unit L below the diagonal, 1/D on it, 0 where the pivot was
// dropped (kDependentPivot). Row i of the matrix is zero left of
// first[i] (its profile), and so is L's: the loops skip it.
void factorProfile(double* F, int m, const std::int32_t* first) {
  for (int j = 0; j < m; ++j) {
    const double diag = F[j + m * j];
    double d = diag;
    for (int k = first[j]; k < j; ++k)
      d -= F[j + m * k] * F[j + m * k] * F[k + m * k];
    const bool kept = diag > 0.0 && d > kDependentPivot * diag;
    const double invD = kept ? 1.0 / d : 0.0;
    for (int i = j + 1; i < m; ++i) {
      if (first[i] > j) continue;
      double s = F[i + m * j];
      for (int k = std::max(first[i], first[j]); k < j; ++k)
        s -= F[i + m * k] * F[j + m * k] * F[k + m * k];
      F[i + m * j] = s * invD;
    }
    F[j + m * j] = kept ? d : 0.0;  // D for the columns still to come
  }
  for (int j = 0; j < m; ++j)
    F[j + m * j] = F[j + m * j] > 0.0 ? 1.0 / F[j + m * j] : 0.0;
}

// x = K^-1 x with the factor (a dropped row's equation left out).
void solveProfile(const double* F, int m, const std::int32_t* first, double* x) {
  for (int i = 1; i < m; ++i)
    for (int k = first[i]; k < i; ++k)
      x[i] -= F[i + m * k] * x[k];
  for (int i = 0; i < m; ++i)
    x[i] *= F[i + m * i];
  for (int i = m - 1; i > 0; --i)
    for (int k = first[i]; k < i; ++k)
      x[k] -= F[i + m * k] * x[i];
}

// Removes x's part along each of the orthonormal vectors (vector k spans
// rows [begin[k], end[k]) of m); returns the largest entry removed.
double projectOut(const double* basis, int count, int m, const std::int32_t* begin,
                  const std::int32_t* end, double* x) {
  double removed = 0.0;
  for (int k = 0; k < count; ++k) {
    const double* u = basis + static_cast<std::size_t>(k) * m;
    double dot = 0.0;
    for (int i = begin[k]; i < end[k]; ++i)
      dot += x[i] * u[i];
    for (int i = begin[k]; i < end[k]; ++i) {
      x[i] -= dot * u[i];
      removed = std::max(removed, std::abs(dot * u[i]));
    }
  }
  return removed;
}

// An inactive point joins the set once it would sink faster than this
// (m/s), and targets missed by more than kUnmetTarget send the manifolds
// to finish them (Solver::kUnmetResidual's measure).
constexpr double kSinkTolerance = 1e-9;
constexpr double kUnmetTarget = 1e-3;

}  // namespace

void ContactIslands::indexBodies(int island, const std::vector<ConstraintBlock>& blocks,
                                 const std::vector<std::int32_t>& islandStart,
                                 std::int32_t staticBody) {
  const std::int32_t first = islandStart[island];
  incidence_.clear();
  for (std::int32_t k = 0; k < islandStart[island + 1] - first; ++k) {
    const ConstraintBlock& blk = blocks[first + k];
    for (const std::int32_t body : {blk.bodyA, blk.bodyB}) {
      if (body != staticBody) incidence_.emplace_back(body, k);
    }
  }
  std::sort(incidence_.begin(), incidence_.end());
  indexed_ = true;
}

void ContactIslands::addIsland(int island, const std::vector<ConstraintBlock>& blocks,
                               const std::vector<std::int32_t>& islandStart,
                               std::int32_t staticBody) {
  const std::int32_t first = islandStart[island];
  const std::int32_t count = islandStart[island + 1] - first;
  indexBodies(island, blocks, islandStart, staticBody);
  std::int32_t start = 0;
  for (std::int32_t k = 0; k < count; ++k) {
    const ConstraintBlock& blk = blocks[first + k];
    if (blk.bodyA == staticBody || blk.bodyB == staticBody) start = k;
  }
  order_.assign(1, start);
  taken_.assign(static_cast<std::size_t>(count), 0);
  taken_[start] = 1;
  for (std::size_t q = 0; q < order_.size(); ++q) {
    const ConstraintBlock& blk = blocks[first + order_[q]];
    for (const std::int32_t body : {blk.bodyA, blk.bodyB}) {
      auto it = std::lower_bound(incidence_.begin(), incidence_.end(), std::make_pair(body, 0));
      for (; it != incidence_.end() && it->first == body; ++it) {
        if (taken_[it->second]) continue;
        taken_[it->second] = 1;
        order_.push_back(it->second);
      }
    }
  }
  for (std::int32_t k = 0; k < count; ++k) {  // an island is connected; kept safe
    if (!taken_[k]) order_.push_back(k);
  }
  groupsOfIsland_[island].first = static_cast<std::int32_t>(groups_.size());
  appendGroup(blocks, first, order_);
  groups_.back().wholeIsland = true;
  groupsOfIsland_[island].second = static_cast<std::int32_t>(groups_.size());
}

void ContactIslands::addLightBodies(int island, const std::vector<ConstraintBlock>& blocks,
                                    const std::vector<std::int32_t>& islandStart,
                                    std::int32_t staticBody, const std::vector<SolverBody>& bodies,
                                    int maxRows) {
  const std::int32_t first = islandStart[island];
  const std::int32_t count = islandStart[island + 1] - first;
  // Most islands have no light body (a cloth over a static cube, a
  // stack): a pass over the manifolds says so before the bodies are
  // indexed (indexing cloth32's island every sub-step cost it 20%). The
  // bodies a joint holds are never light (a cloth's cells under a heavy
  // roller: cloth_roll spent 9% more indexing them).
  auto lightBeside = [&](std::int32_t body, std::int32_t other) {
    return jointStamp_[body] != stamp_ &&
           bodies[body].invMass >= kLightBodyRatio * bodies[other].invMass;
  };
  bool any = false;
  for (std::int32_t k = 0; k < count && !any; ++k) {
    const ConstraintBlock& blk = blocks[first + k];
    if (!usable_[k] || blk.bodyA == staticBody || blk.bodyB == staticBody) continue;
    any = lightBeside(blk.bodyA, blk.bodyB) || lightBeside(blk.bodyB, blk.bodyA);
  }
  if (!any) return;
  if (!indexed_) indexBodies(island, blocks, islandStart, staticBody);
  // The bodies at least kLightBodyRatio times lighter than a body they
  // touch, lightest first. A body a joint holds is left out: the joint
  // adds its neighbours' mass, which the group would not see (a 1 kg
  // bridge plank on its support under a 100 kg crate, solved as light,
  // was pushed about until the runaway guard caught the bridge).
  lightBodies_.clear();
  for (std::size_t p = 0; p < incidence_.size();) {
    const std::int32_t body = incidence_[p].first;
    double heaviestNeighbour = bodies[body].invMass;  // as an inverse mass
    for (; p < incidence_.size() && incidence_[p].first == body; ++p) {
      const ConstraintBlock& blk = blocks[first + incidence_[p].second];
      const std::int32_t other = blk.bodyA == body ? blk.bodyB : blk.bodyA;
      if (usable_[incidence_[p].second] && other != staticBody)
        heaviestNeighbour = std::min(heaviestNeighbour, bodies[other].invMass);
    }
    if (jointStamp_[body] != stamp_ && heaviestNeighbour > 0.0 &&
        bodies[body].invMass >= kLightBodyRatio * heaviestNeighbour)
      lightBodies_.emplace_back(-bodies[body].invMass, body);
  }
  std::sort(lightBodies_.begin(), lightBodies_.end());
  for (const auto& [negativeInvMass, body] : lightBodies_) {
    members_.clear();
    int rows = 0;
    auto it = std::lower_bound(incidence_.begin(), incidence_.end(), std::make_pair(body, 0));
    for (; it != incidence_.end() && it->first == body; ++it) {
      const int more = blocks[first + it->second].equality;
      if (!usable_[it->second] || taken_[it->second] || rows + more > maxRows) continue;
      members_.push_back(it->second);
      rows += more;
    }
    if (members_.size() < 2) continue;  // one manifold alone is already one block
    for (const std::int32_t k : members_)
      taken_[k] = 1;
    appendGroup(blocks, first, members_);
  }
}

void ContactIslands::markJointBodies(int island, const std::vector<ConstraintBlock>& blocks,
                                     const std::vector<std::int32_t>& islandStart,
                                     std::int32_t staticBody, std::size_t bodyCount) {
  if (jointStamp_.size() < bodyCount) jointStamp_.resize(bodyCount, 0);
  ++stamp_;
  for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (blk.unilateral) continue;
    jointStamp_[blk.bodyA] = jointStamp_[blk.bodyB] = stamp_;
  }
  if (static_cast<std::size_t>(staticBody) < jointStamp_.size()) jointStamp_[staticBody] = 0;
}

void ContactIslands::addImpacts(int island, const std::vector<ConstraintBlock>& blocks,
                                const std::vector<std::int32_t>& islandStart,
                                std::int32_t staticBody, int maxRows, bool late) {
  const std::int32_t first = islandStart[island];
  const std::int32_t count = islandStart[island + 1] - first;
  for (std::int32_t start = 0; start < count; ++start) {
    if (!impact_[start] || taken_[start] || heldByJoint(blocks[first + start])) continue;
    if (!indexed_) indexBodies(island, blocks, islandStart, staticBody);
    members_.assign(1, start);
    taken_[start] = 1;
    int rows = blocks[first + start].equality;
    bool full = false;
    // A body's manifolds on the static body first: the impulse's path ends
    // there, and a group cut off before it would hand the whole impulse
    // to the last body inside it.
    for (std::size_t q = 0; q < members_.size() && !full; ++q) {
      const ConstraintBlock& blk = blocks[first + members_[q]];
      for (const std::int32_t body : {blk.bodyA, blk.bodyB}) {
        if (body == staticBody) continue;
        const auto begin =
            std::lower_bound(incidence_.begin(), incidence_.end(), std::make_pair(body, 0));
        for (const bool toStatic : {true, false}) {
          for (auto it = begin; it != incidence_.end() && it->first == body && !full; ++it) {
            const std::int32_t k = it->second;
            const ConstraintBlock& other = blocks[first + k];
            if ((other.bodyA == staticBody || other.bodyB == staticBody) != toStatic) continue;
            if (!usable_[k] || taken_[k] || heldByJoint(other)) continue;
            if (rows + other.equality > maxRows) {
              full = true;
              break;
            }
            taken_[k] = 1;
            members_.push_back(k);
            rows += other.equality;
          }
        }
        if (full) break;
      }
    }
    if (members_.size() < 2) {  // one manifold alone is already one block
      taken_[start] = 0;
      continue;
    }
    appendGroup(blocks, first, members_, late);
    groups_.back().impact = !late;
  }
}

void ContactIslands::appendGroup(const std::vector<ConstraintBlock>& blocks, std::int32_t first,
                                 const std::vector<std::int32_t>& members, bool late) {
  Group g;
  g.firstEntry = static_cast<std::int32_t>(entryRow_.size());
  if (!groups_.empty()) {
    const Group& last = groups_.back();
    g.matrix = last.matrix + 3 * static_cast<std::size_t>(last.size) * last.size;
  }
  for (const std::int32_t k : members) {
    const ConstraintBlock& blk = blocks[first + k];
    if (!late) groupOfBlock_[first + k] = static_cast<std::int32_t>(groups_.size());
    for (int i = 0; i < blk.equality; ++i) {
      entryRow_.push_back(blk.firstRow + i);
      entryBlock_.push_back(first + k);
    }
  }
  g.size = static_cast<std::int32_t>(entryRow_.size()) - g.firstEntry;
  groups_.push_back(g);
}

void ContactIslands::reserveStorage() {
  if (groups_.empty()) return;
  const Group& last = groups_.back();
  const std::size_t storage = last.matrix + 3 * static_cast<std::size_t>(last.size) * last.size;
  // Grow only while warming up.
  if (storage_.size() < storage) storage_.resize(storage);
  if (scratch_.size() < 4 * entryRow_.size()) scratch_.resize(4 * entryRow_.size());
  if (warmImpulse_.size() < entryRow_.size()) warmImpulse_.resize(entryRow_.size());
  if (active_.size() < entryRow_.size()) {
    active_.resize(entryRow_.size());
    activeList_.resize(entryRow_.size());
    profileFirst_.resize(entryRow_.size());
    nullBegin_.resize(entryRow_.size());
    nullEnd_.resize(entryRow_.size());
  }
}

void ContactIslands::prepareGroup(Group& g, const std::vector<ConstraintBlock>& blocks,
                                  const std::vector<ConstraintRow>& rows,
                                  const std::vector<SolverBody>& bodies) {
  const int n = g.size;
  const std::int32_t* rowOf = &entryRow_[g.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[g.firstEntry];
  double* K = kOf(g);  // full, K[i n + j]
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j) {
      K[i * n + j] = K[j * n + i] = rowCoupling(rows[rowOf[i]], blocks[blockOf[i]], rows[rowOf[j]],
                                                blocks[blockOf[j]], bodies);
    }
  }
  // The points touching (C holds the rest depth) push; those apart join
  // when they would close.
  std::uint8_t* active = &active_[g.firstEntry];
  std::int32_t* list = &activeList_[g.firstEntry];
  g.activeCount = 0;
  for (int i = 0; i < n; ++i) {
    active[i] = rows[rowOf[i]].C <= kRestDepth;
    if (active[i]) list[g.activeCount++] = i;
  }
  g.factorStale = true;
}

void ContactIslands::prepare(const std::vector<ConstraintBlock>& blocks,
                             const std::vector<ConstraintRow>& rows,
                             const std::vector<SolverBody>& bodies) {
  reserveStorage();
  for (Group& g : groups_) {
    prepareGroup(g, blocks, rows, bodies);
    if (g.impact) {
      for (std::int32_t e = g.firstEntry; e < g.firstEntry + g.size; ++e)
        warmImpulse_[e] = rows[entryRow_[e]].impulse;
    }
  }
}

void ContactIslands::capImpactImpulses(std::vector<ConstraintRow>& rows) const {
  for (const Group& g : groups_) {
    if (!g.impact) continue;
    for (std::int32_t e = g.firstEntry; e < g.firstEntry + g.size; ++e) {
      double& impulse = rows[entryRow_[e]].impulse;
      impulse = std::min(impulse, warmImpulse_[e]);
    }
  }
}

void ContactIslands::factorActive(Group& g) {
  const int n = g.size, m = g.activeCount;
  const double* K = kOf(g);
  const std::int32_t* list = &activeList_[g.firstEntry];
  std::int32_t* first = &profileFirst_[g.firstEntry];
  double* F = factorOf(g);
  for (int a = 0; a < m; ++a) {
    const double* Ka = K + static_cast<std::size_t>(list[a]) * n;
    first[a] = a;
    for (int b = 0; b <= a; ++b) {
      F[a + m * b] = Ka[list[b]];
      if (first[a] == a && Ka[list[b]] != 0.0) first[a] = b;
    }
  }
  factorProfile(F, m, first);
  // Each dropped pivot j gives a null vector: L^T u = e_j, so K u =
  // L D e_j = 0. A face's warp spans that face's points alone. Made
  // orthonormal, leaving them out is a projection.
  double* basis = nullsOf(g);
  std::int32_t* begin = &nullBegin_[g.firstEntry];
  std::int32_t* end = &nullEnd_[g.firstEntry];
  g.nullCount = 0;
  for (int j = 0; j < m; ++j) {
    if (F[j + m * j] != 0.0) continue;
    const int k = g.nullCount;
    double* u = basis + static_cast<std::size_t>(k) * m;
    std::fill(u, u + m, 0.0);
    u[j] = 1.0;
    begin[k] = j;
    end[k] = j + 1;
    for (int i = j; i > 0; --i) {
      if (u[i] == 0.0) continue;
      for (int c = first[i]; c < i; ++c)
        u[c] -= F[i + m * c] * u[i];
      begin[k] = std::min(begin[k], first[i]);
    }
    // Its rows: a face's warp spans that face's points, though the
    // profile it was found through reaches further (rounding is left
    // there: dropped, the projections keep to the face).
    double largest = 0.0;
    for (int i = begin[k]; i <= j; ++i)
      largest = std::max(largest, std::abs(u[i]));
    for (int i = begin[k]; i <= j; ++i) {
      if (std::abs(u[i]) < 1e-12 * largest) u[i] = 0.0;
    }
    while (begin[k] < j && u[begin[k]] == 0.0)
      ++begin[k];
    for (int b = 0; b < k; ++b) {
      const double* ub = basis + static_cast<std::size_t>(b) * m;
      const int lo = std::max(begin[k], begin[b]), hi = std::min(end[k], end[b]);
      double dot = 0.0;
      for (int i = lo; i < hi; ++i)
        dot += u[i] * ub[i];
      if (dot == 0.0) continue;
      for (int i = begin[b]; i < end[b]; ++i)
        u[i] -= dot * ub[i];
      begin[k] = std::min(begin[k], begin[b]);
      end[k] = std::max(end[k], end[b]);
    }
    double norm = 0.0;
    for (int i = begin[k]; i < end[k]; ++i)
      norm += u[i] * u[i];
    if (!(norm > 1e-24)) continue;
    const double scale = 1.0 / std::sqrt(norm);
    for (int i = begin[k]; i < end[k]; ++i)
      u[i] *= scale;
    ++g.nullCount;
  }
  g.factorStale = false;
}

ContactIslands::Outcome ContactIslands::solve(int group, bool useBias,
                                              const std::vector<ConstraintBlock>& blocks,
                                              std::vector<ConstraintRow>& rows,
                                              std::vector<SolverBody>& bodies) {
  Group& g = groups_[group];
  const int n = g.size;
  const std::int32_t* rowOf = &entryRow_[g.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[g.firstEntry];
  std::uint8_t* active = &active_[g.firstEntry];
  std::int32_t* list = &activeList_[g.firstEntry];
  const double* K = kOf(g);
  double* residual = &scratch_[4 * static_cast<std::size_t>(g.firstEntry)];
  double* change = residual + n;  // each row's impulse change
  double* x = change + n;         // the active rows' (active-set order)
  double* next = x + n;
  for (int i = 0; i < n; ++i) {
    const ConstraintRow& row = rows[rowOf[i]];
    const ConstraintBlock& blk = blocks[blockOf[i]];
    residual[i] = rowResidual(row, useBias, bodies[blk.bodyA], bodies[blk.bodyB]);
  }
  for (int round = 0; round < kMaxRounds; ++round) {
    if (g.factorStale) factorActive(g);
    const int m = g.activeCount;
    // Inactive points let go of what they hold (most hold nothing).
    int letGo = 0;
    for (int i = 0; i < n; ++i) {
      change[i] = active[i] ? 0.0 : -rows[rowOf[i]].impulse;
      letGo += change[i] != 0.0;
    }
    for (int a = 0; a < m; ++a) {
      double r = residual[list[a]];
      if (letGo > 0) {
        const double* Ki = K + static_cast<std::size_t>(list[a]) * n;
        for (int j = 0; j < n; ++j)
          r += Ki[j] * change[j];
      }
      x[a] = -r;
    }
    const std::int32_t* begin = &nullBegin_[g.firstEntry];
    const std::int32_t* end = &nullEnd_[g.firstEntry];
    const double unmet = projectOut(nullsOf(g), g.nullCount, m, begin, end, x);
    solveProfile(factorOf(g), m, &profileFirst_[g.firstEntry], x);
    for (int a = 0; a < m; ++a)
      next[a] = rows[rowOf[list[a]]].impulse + x[a];
    projectOut(nullsOf(g), g.nullCount, m, begin, end, next);  // the least-norm impulses
    double largest = 0.0;
    for (int a = 0; a < m; ++a)
      largest = std::max(largest, std::abs(next[a]));
    const double pullTolerance = 1e-9 * largest + 1e-12;
    // Points that would pull leave the set.
    int kept = 0;
    for (int a = 0; a < m; ++a) {
      if (next[a] < -pullTolerance) {
        active[list[a]] = 0;
      } else {
        next[kept] = next[a];
        list[kept++] = list[a];
      }
    }
    if (kept < m) {
      g.activeCount = kept;
      g.factorStale = true;
      continue;
    }
    for (int a = 0; a < m; ++a)
      change[list[a]] = std::max(next[a], 0.0) - rows[rowOf[list[a]]].impulse;
    // The inactive points that would sink join the set, all at once: one
    // a round, an impact's group of 128 points (SolverSettings::
    // impactDepth) ran out of rounds three times as often in the pile's
    // landing, and each time its manifolds fell back to Gauss-Seidel.
    int joined = 0;
    for (int i = 0; i < n; ++i) {
      if (active[i]) continue;
      const double* Ki = K + static_cast<std::size_t>(i) * n;
      double w = residual[i];
      for (int j = 0; j < n; ++j)
        w += Ki[j] * change[j];
      if (w < -kSinkTolerance) {
        active[i] = 1;
        ++joined;
      }
    }
    if (joined > 0) {
      // In island order, to keep the factor's profile.
      g.activeCount = 0;
      for (int i = 0; i < n; ++i) {
        if (active[i]) list[g.activeCount++] = i;
      }
      g.factorStale = true;
      continue;
    }
    for (int i = 0; i < n; ++i) {
      if (change[i] == 0.0) continue;
      ConstraintRow& row = rows[rowOf[i]];
      const ConstraintBlock& blk = blocks[blockOf[i]];
      row.impulse += change[i];
      applyImpulse(row, change[i], bodies[blk.bodyA], bodies[blk.bodyB]);
    }
    return unmet > kUnmetTarget ? Outcome::Unmet : Outcome::Exact;
  }
  return Outcome::Unsolved;
}

}  // namespace blockstep

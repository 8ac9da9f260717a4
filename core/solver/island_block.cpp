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

// K_ij = J_i M^-1 J_j^T: the sum over the bodies both rows act on.
double coupling(const ConstraintRow& ri, const ConstraintBlock& pi, const ConstraintRow& rj,
                const ConstraintBlock& pj, const std::vector<SolverBody>& bodies) {
  double k = 0.0;
  for (int sideI = 0; sideI < 2; ++sideI) {
    const std::int32_t body = sideI == 0 ? pi.bodyA : pi.bodyB;
    if (immovable(bodies[body])) continue;
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

}  // namespace

void IslandBlocks::select(const std::vector<ConstraintBlock>& blocks, std::int32_t staticBody,
                          const std::vector<std::int32_t>& islandStart, int islandCount,
                          int maxRows) {
  islandOf_.assign(islandCount, -1);
  islands_.clear();
  entryRow_.clear();
  entryBlock_.clear();
  first_.clear();
  bounded_.clear();
  islandBodies_.clear();
  if (maxRows < 2) return;
  if (bodyLocal_.size() < static_cast<std::size_t>(staticBody) + 1)
    bodyLocal_.resize(staticBody + 1);
  if (bodyFirst_.size() < static_cast<std::size_t>(staticBody) + 1)
    bodyFirst_.resize(staticBody + 1);
  std::size_t factorSize = 0;
  std::size_t weightsSize = 0, deltasSize = 0;
  for (int island = 0; island < islandCount; ++island) {
    int n = 0, joints = 0;
    for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      if (blk.unilateral || blk.equality == 0) continue;
      n += blk.equality;
      ++joints;
    }
    // One joint is already one block; beyond maxRows the per-joint blocks
    // and Gauss-Seidel take over (the factor's memory grows as n^2).
    if (joints < 2 || n > maxRows) continue;
    Island isl;
    isl.firstEntry = static_cast<std::int32_t>(entryRow_.size());
    isl.size = n;
    isl.factor = factorSize;
    factorSize += static_cast<std::size_t>(n) * n;
    order(island, blocks, islandStart, staticBody);
    isl.firstBounded = static_cast<std::int32_t>(bounded_.size());
    bool touches = false;
    for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi)
      touches = touches || blocks[bi].unilateral;
    isl.firstBody = static_cast<std::int32_t>(islandBodies_.size());
    if (!touches) {
      for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
        const ConstraintBlock& blk = blocks[bi];
        for (std::int32_t body : {blk.bodyA, blk.bodyB}) {
          if (body == staticBody) continue;
          if (std::find(islandBodies_.begin() + isl.firstBody, islandBodies_.end(), body) ==
              islandBodies_.end())
            islandBodies_.push_back(body);
        }
      }
    }
    isl.bodyCount = static_cast<std::int32_t>(islandBodies_.size()) - isl.firstBody;
    for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
      const ConstraintBlock& blk = blocks[bi];
      if (blk.unilateral || touches) continue;
      for (int r = blk.boundedBegin(); r < blk.boundedEnd(); ++r) {
        bounded_.push_back({r, bi, weightsSize, deltasSize, 0.0});
        weightsSize += static_cast<std::size_t>(n);
        deltasSize += 2 * static_cast<std::size_t>(isl.bodyCount);
      }
    }
    isl.boundedCount = static_cast<std::int32_t>(bounded_.size()) - isl.firstBounded;
    isl.bounded = !touches;
    islandOf_[island] = static_cast<std::int32_t>(islands_.size());
    islands_.push_back(isl);
  }
  factorSize_ = factorSize;
  weightsSize_ = weightsSize;
  deltasSize_ = deltasSize;
}

void IslandBlocks::prepareFactors() {
  // All grow only while warming up.
  if (factor_.size() < factorSize_) factor_.resize(factorSize_);
  if (weights_.size() < weightsSize_) weights_.resize(weightsSize_);
  if (deltas_.size() < deltasSize_) deltas_.resize(deltasSize_);
  if (boundedStep_.size() < bounded_.size()) boundedStep_.resize(bounded_.size());
  if (solveScratch_.size() < entryRow_.size()) solveScratch_.resize(entryRow_.size());
  if (factorScratch_.size() < 2 * entryRow_.size()) factorScratch_.resize(2 * entryRow_.size());
}

void IslandBlocks::factorOne(int k, const std::vector<ConstraintBlock>& blocks,
                             std::vector<ConstraintRow>& rows,
                             const std::vector<SolverBody>& bodies) {
  factor(islands_[k], blocks, rows, bodies);
  coupleBounded(islands_[k], blocks, rows, bodies);
}

void IslandBlocks::factorAll(const std::vector<ConstraintBlock>& blocks,
                             std::vector<ConstraintRow>& rows,
                             const std::vector<SolverBody>& bodies) {
  prepareFactors();
  for (int k = 0; k < count(); ++k)
    factorOne(k, blocks, rows, bodies);
}

// Reverse Cuthill-McKee over the island's joints (neighbours: joints that
// share a movable body), then each row's profile start.
void IslandBlocks::order(int island, const std::vector<ConstraintBlock>& blocks,
                         const std::vector<std::int32_t>& islandStart, std::int32_t staticBody) {
  orderedBlocks_.clear();
  for (std::int32_t bi = islandStart[island]; bi < islandStart[island + 1]; ++bi) {
    const ConstraintBlock& blk = blocks[bi];
    if (!blk.unilateral && blk.equality > 0) orderedBlocks_.push_back(bi);
  }
  const auto m = static_cast<std::int32_t>(orderedBlocks_.size());
  auto bodiesOf = [&](std::int32_t local, auto&& f) {
    const ConstraintBlock& blk = blocks[orderedBlocks_[local]];
    if (blk.bodyA != staticBody) f(blk.bodyA);
    if (blk.bodyB != staticBody && blk.bodyB != blk.bodyA) f(blk.bodyB);
  };
  auto share = [&](std::int32_t l, std::int32_t k) {
    const ConstraintBlock& p = blocks[orderedBlocks_[l]];
    const ConstraintBlock& q = blocks[orderedBlocks_[k]];
    return (p.bodyA != staticBody && (q.bodyA == p.bodyA || q.bodyB == p.bodyA)) ||
           (p.bodyB != staticBody && (q.bodyA == p.bodyB || q.bodyB == p.bodyB));
  };
  // Degree of a joint: the joints it shares a body with (m is small: the
  // island has at most maxRows rows).
  queue_.assign(m, 0);
  visited_.assign(m, 0);
  blockStart_.assign(m, 0);
  std::vector<std::int32_t>& degree = blockStart_;  // reused before the starts are set
  for (std::int32_t l = 0; l < m; ++l)
    for (std::int32_t k = 0; k < m; ++k)
      if (k != l && share(l, k)) ++degree[l];
  std::int32_t head = 0, tail = 0;
  while (tail < m) {
    std::int32_t startAt = -1;
    for (std::int32_t l = 0; l < m; ++l)
      if (!visited_[l] && (startAt < 0 || degree[l] < degree[startAt])) startAt = l;
    visited_[startAt] = 1;
    queue_[tail++] = startAt;
    while (head < tail) {
      const std::int32_t l = queue_[head++];
      for (std::int32_t k = 0; k < m; ++k) {
        if (visited_[k] || !share(l, k)) continue;
        visited_[k] = 1;
        queue_[tail++] = k;
      }
    }
  }
  std::reverse(queue_.begin(), queue_.begin() + m);

  // Rows in that order; each joint's rows start at blockStart_.
  const auto islandFirst = static_cast<std::int32_t>(entryRow_.size());
  std::int32_t position = 0;
  for (std::int32_t q = 0; q < m; ++q) {
    const std::int32_t l = queue_[q];
    const ConstraintBlock& blk = blocks[orderedBlocks_[l]];
    blockStart_[l] = position;
    for (int r = 0; r < blk.equality; ++r) {
      entryRow_.push_back(blk.firstRow + r);
      entryBlock_.push_back(orderedBlocks_[l]);
      first_.push_back(0);
    }
    position += blk.equality;
  }
  // A row's profile starts at the first row of the earliest joint it
  // shares a body with (its own joint included).
  for (std::int32_t l = 0; l < m; ++l)
    bodiesOf(l, [&](std::int32_t b) { bodyFirst_[b] = position; });
  for (std::int32_t l = 0; l < m; ++l)
    bodiesOf(l, [&](std::int32_t b) { bodyFirst_[b] = std::min(bodyFirst_[b], blockStart_[l]); });
  for (std::int32_t l = 0; l < m; ++l) {
    const ConstraintBlock& blk = blocks[orderedBlocks_[l]];
    std::int32_t start = blockStart_[l];
    bodiesOf(l, [&](std::int32_t b) { start = std::min(start, bodyFirst_[b]); });
    for (int r = 0; r < blk.equality; ++r)
      first_[islandFirst + blockStart_[l] + r] = start;
  }
}

// K within the profile, then L D L^T in place (Crout, row by row): entries
// left of a row's profile start are zero in K and stay zero in L.
void IslandBlocks::factor(const Island& isl, const std::vector<ConstraintBlock>& blocks,
                          const std::vector<ConstraintRow>& rows,
                          const std::vector<SolverBody>& bodies) {
  const std::int32_t n = isl.size;
  double* F = &factor_[isl.factor];
  const std::int32_t* first = &first_[isl.firstEntry];
  const std::int32_t* rowOf = &entryRow_[isl.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[isl.firstEntry];
  double scale = 0.0;
  for (std::int32_t i = 0; i < n; ++i) {
    const ConstraintRow& ri = rows[rowOf[i]];
    const ConstraintBlock& pi = blocks[blockOf[i]];
    for (std::int32_t j = first[i]; j <= i; ++j)
      F[i * n + j] = coupling(ri, pi, rows[rowOf[j]], blocks[blockOf[j]], bodies);
    F[i * n + i] += ri.gamma;
    scale = std::max(scale, std::abs(F[i * n + i]));
  }
  // A pivot that is not clearly positive (a row that repeats others, as
  // in a closed loop with CFM 0) leaves that direction to the other rows,
  // as the per-joint LDL^T does (ldlt.h).
  const double tiny = 1e-12 * (scale > 0.0 ? scale : 1.0);
  double* D = &factorScratch_[2 * static_cast<std::size_t>(isl.firstEntry)];
  double* invD = D + n;
  for (std::int32_t i = 0; i < n; ++i) {
    double* Li = F + static_cast<std::ptrdiff_t>(i) * n;
    for (std::int32_t j = first[i]; j < i; ++j) {
      const double* Lj = F + static_cast<std::ptrdiff_t>(j) * n;
      double s = Li[j];
      for (std::int32_t k = std::max(first[i], first[j]); k < j; ++k)
        s -= Li[k] * Lj[k] * D[k];
      Li[j] = s * invD[j];
    }
    double d = Li[i];
    for (std::int32_t k = first[i]; k < i; ++k)
      d -= Li[k] * Li[k] * D[k];
    const bool pivotOk = d > tiny;
    D[i] = pivotOk ? d : 0.0;
    invD[i] = pivotOk ? 1.0 / d : 0.0;
  }
  for (std::int32_t i = 0; i < n; ++i)
    F[i * n + i] = invD[i];
}

void IslandBlocks::solveInPlace(const Island& isl, double* x) const {
  const std::int32_t n = isl.size;
  const double* F = &factor_[isl.factor];
  const std::int32_t* first = &first_[isl.firstEntry];
  // L y = r, y *= 1/D, L^T x = y; each within the profile.
  for (std::int32_t i = 0; i < n; ++i) {
    const double* Li = F + static_cast<std::ptrdiff_t>(i) * n;
    for (std::int32_t k = first[i]; k < i; ++k)
      x[i] -= Li[k] * x[k];
  }
  for (std::int32_t i = 0; i < n; ++i)
    x[i] *= F[i * n + i];
  for (std::int32_t k = n - 1; k > 0; --k) {
    const double* Lk = F + static_cast<std::ptrdiff_t>(k) * n;
    for (std::int32_t i = first[k]; i < k; ++i)
      x[i] -= Lk[i] * x[k];
  }
}

// u = J_e M^-1 J_b^T (non-zero for the rows sharing a body with the
// bounded row's joint), w = -K^-1 u, and the Schur complement
// J_b M^-1 J_b^T - u^T K^-1 u = K_bb + u . w.
void IslandBlocks::coupleBounded(const Island& isl, const std::vector<ConstraintBlock>& blocks,
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
      w[i] = coupling(rows[rowOf[i]], blocks[blockOf[i]], row, blk, bodies);
    double kbb = rowDiagonal(row, bodies[blk.bodyA], bodies[blk.bodyB]);
    double uKu = 0.0;
    // u is kept beside w only long enough to form u . K^-1 u.
    double* u = &factorScratch_[2 * static_cast<std::size_t>(isl.firstEntry)];
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
    if (row.gammaShare > 0.0) row.gamma = row.gammaRelax = row.gammaShare * (kbb - uKu);
    const double schur = kbb - uKu + row.gamma;
    // A bounded row that the equality rows already fix has no freedom left.
    br.effMass = schur > 1e-12 * std::max(kbb, 1e-300) ? 1.0 / schur : 0.0;
  }
}

// Each row moves the island's bodies by its precomputed velocity changes;
// the equality rows' share, w times the row's impulse, is added once at
// the end (only the island solve reads their impulses).
void IslandBlocks::solveBounded(int island, bool useBias,
                                const std::vector<ConstraintBlock>& blocks,
                                std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies) {
  const Island& isl = islands_[islandOf_[island]];
  const std::int32_t n = isl.size;
  const std::int32_t* rowOf = &entryRow_[isl.firstEntry];
  const std::int32_t* islandBody = &islandBodies_[isl.firstBody];
  for (std::int32_t k = isl.firstBounded; k < isl.firstBounded + isl.boundedCount; ++k) {
    const BoundedRow& br = bounded_[k];
    ConstraintRow& row = rows[br.row];
    boundedStep_[k] = 0.0;
    if (relaxSkips(row, useBias)) continue;
    const ConstraintBlock& blk = blocks[br.block];
    const double residual = rowResidual(row, useBias, bodies[blk.bodyA], bodies[blk.bodyB]);
    const double next = std::clamp(row.impulse - residual * br.effMass, row.lo, row.hi);
    const double dP = next - row.impulse;
    if (dP == 0.0) continue;
    row.impulse = next;
    boundedStep_[k] = dP;
    const Vec3* delta = &deltas_[br.deltas];
    for (std::int32_t b = 0; b < isl.bodyCount; ++b)
      addVelocity(bodies[islandBody[b]], dP * delta[2 * b], dP * delta[2 * b + 1]);
  }
  for (std::int32_t k = isl.firstBounded; k < isl.firstBounded + isl.boundedCount; ++k) {
    const double dP = boundedStep_[k];
    if (dP == 0.0) continue;
    const double* w = &weights_[bounded_[k].weights];
    for (std::int32_t i = 0; i < n; ++i)
      rows[rowOf[i]].impulse += w[i] * dP;
  }
}

void IslandBlocks::solve(int island, bool useBias, const std::vector<ConstraintBlock>& blocks,
                         std::vector<ConstraintRow>& rows, std::vector<SolverBody>& bodies) {
  const Island& isl = islands_[islandOf_[island]];
  const std::int32_t n = isl.size;
  const std::int32_t* rowOf = &entryRow_[isl.firstEntry];
  const std::int32_t* blockOf = &entryBlock_[isl.firstEntry];
  // Each island its own part of the scratch: islands may be solved at once.
  double* x = &solveScratch_[isl.firstEntry];
  for (std::int32_t i = 0; i < n; ++i) {
    const ConstraintRow& row = rows[rowOf[i]];
    const ConstraintBlock& blk = blocks[blockOf[i]];
    x[i] = relaxSkips(row, useBias)
               ? 0.0
               : -rowResidual(row, useBias, bodies[blk.bodyA], bodies[blk.bodyB]);
  }
  solveInPlace(isl, x);
  for (std::int32_t i = 0; i < n; ++i) {
    ConstraintRow& row = rows[rowOf[i]];
    const ConstraintBlock& blk = blocks[blockOf[i]];
    row.impulse += x[i];
    applyImpulse(row, x[i], bodies[blk.bodyA], bodies[blk.bodyB]);
  }
}

}  // namespace blockstep

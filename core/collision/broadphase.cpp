#include "core/collision/broadphase.h"

#include <algorithm>
#include <cmath>

namespace blockstep {

Aabb shapeAabb(const Shape& s, const ShapePose& pose, double grow) {
  Aabb box;
  if (!s.alive) return box;
  const Mat3& R = pose.rotation;
  Vec3 half = Vec3::Zero();
  Vec3 centre = pose.position;
  switch (s.kind) {
    case Shape::Kind::Sphere:
      half = Vec3::Constant(s.radius);
      break;
    case Shape::Kind::Capsule:
      half = s.halfLength * R.col(2).cwiseAbs() + Vec3::Constant(s.radius);
      break;
    case Shape::Kind::Cylinder: {
      // Along world axis i: the axis's reach, and the rim disc's, whose
      // extent is r sqrt(1 - a_i^2).
      const Vec3 a = R.col(2);
      for (int i = 0; i < 3; ++i)
        half[i] =
            s.halfLength * std::abs(a[i]) + s.radius * std::sqrt(std::max(0.0, 1.0 - a[i] * a[i]));
      break;
    }
    case Shape::Kind::Box:
      half = R.cwiseAbs() * s.halfExtents;
      break;
    case Shape::Kind::Convex: {
      const Vec3& lo = s.hull->localMin();
      const Vec3& hi = s.hull->localMax();
      centre += R * (0.5 * (lo + hi));
      half = R.cwiseAbs() * (0.5 * (hi - lo));
      break;
    }
    case Shape::Kind::Plane:
      box.lo = Vec3::Constant(-kInf);
      box.hi = Vec3::Constant(kInf);
      return box;
  }
  box.lo = centre - half - Vec3::Constant(grow);
  box.hi = centre + half + Vec3::Constant(grow);
  return box;
}

void BroadPhase::findPairs(const std::vector<Aabb>& boxes, BroadPhaseMethod method,
                           std::vector<std::pair<int, int>>& pairs) {
  pairs.clear();
  const int n = static_cast<int>(boxes.size());
  if (method == BroadPhaseMethod::Automatic) {
    method = n < 64 ? BroadPhaseMethod::AllPairs : BroadPhaseMethod::SweepAndPrune;
  }
  if (method == BroadPhaseMethod::AllPairs) {
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j)
        if (boxes[i].overlaps(boxes[j])) pairs.emplace_back(i, j);
    return;
  }
  // Sweep along the axis the boxes' centres spread most along: a pile
  // ten layers deep swept along x tested each box against its whole
  // column. The axis changes only when another spreads kAxisSwitch times
  // as far, so the order stays nearly sorted from call to call.
  Vec3 sum = Vec3::Zero(), sumSquares = Vec3::Zero();
  int counted = 0;
  for (const Aabb& box : boxes) {
    if (!(box.lo.x() <= box.hi.x()) || !box.lo.allFinite() || !box.hi.allFinite()) continue;
    const Vec3 centre = 0.5 * (box.lo + box.hi);
    sum += centre;
    sumSquares += centre.cwiseProduct(centre);
    ++counted;
  }
  bool resort = static_cast<int>(order_.size()) != n;
  if (counted > 1) {
    const Vec3 mean = sum / counted;
    const Vec3 spread = sumSquares / counted - mean.cwiseProduct(mean);
    int widest = 0;
    spread.maxCoeff(&widest);
    if (widest != axis_ && spread[widest] > kAxisSwitch * spread[axis_]) {
      axis_ = widest;
      resort = true;
    }
  }
  const int ax = axis_;
  if (resort) {
    order_.resize(n);
    for (int i = 0; i < n; ++i)
      order_[i] = i;
    std::sort(order_.begin(), order_.end(), [&](int i, int j) {
      return boxes[i].lo[ax] < boxes[j].lo[ax] || (boxes[i].lo[ax] == boxes[j].lo[ax] && i < j);
    });
  } else {
    // Insertion sort by lo along the axis: nearly sorted from the last call.
    for (int k = 1; k < n; ++k) {
      const int moving = order_[k];
      const double key = boxes[moving].lo[ax];
      int j = k - 1;
      while (j >= 0 && boxes[order_[j]].lo[ax] > key) {
        order_[j + 1] = order_[j];
        --j;
      }
      order_[j + 1] = moving;
    }
  }
  // The boxes in that order, side by side: the sweep reads each box's
  // neighbours along the axis one after another (through order_ it took
  // 5 ns a test, most of a cloth's collision).
  sorted_.resize(n);
  for (int k = 0; k < n; ++k)
    sorted_[k] = boxes[order_[k]];
  const int ay = (ax + 1) % 3, az = (ax + 2) % 3;
  for (int k = 0; k < n; ++k) {
    const Aabb& a = sorted_[k];
    if (!(a.lo.x() <= a.hi.x())) continue;  // empty: overlaps nothing
    for (int l = k + 1; l < n && sorted_[l].lo[ax] <= a.hi[ax]; ++l) {
      const Aabb& b = sorted_[l];
      // Overlapping along the axis already (b starts within a, and no
      // earlier than a).
      if (a.lo[ay] > b.hi[ay] || b.lo[ay] > a.hi[ay] || a.lo[az] > b.hi[az] || b.lo[az] > a.hi[az])
        continue;
      const int i = order_[k], j = order_[l];
      pairs.emplace_back(std::min(i, j), std::max(i, j));
    }
  }
  sortPairs(n, pairs);
}

// Counting sort by the first index, then each first index's few second
// indices in place: the pairs in all-pairs order, in linear time.
void BroadPhase::sortPairs(int n, std::vector<std::pair<int, int>>& pairs) {
  pairStart_.assign(static_cast<std::size_t>(n) + 1, 0);
  for (const auto& p : pairs)
    ++pairStart_[p.first + 1];
  for (int i = 0; i < n; ++i)
    pairStart_[i + 1] += pairStart_[i];
  sortedPairs_.resize(pairs.size());
  pairFill_.assign(pairStart_.begin(), pairStart_.end() - 1);
  for (const auto& p : pairs)
    sortedPairs_[pairFill_[p.first]++] = p;
  for (int i = 0; i < n; ++i)
    std::sort(sortedPairs_.begin() + pairStart_[i], sortedPairs_.begin() + pairStart_[i + 1]);
  pairs.swap(sortedPairs_);
}

}  // namespace blockstep

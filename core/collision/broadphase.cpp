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
  if (static_cast<int>(order_.size()) != n) {
    order_.resize(n);
    for (int i = 0; i < n; ++i)
      order_[i] = i;
  }
  // Insertion sort by lo.x: nearly sorted from the last call.
  for (int k = 1; k < n; ++k) {
    const int moving = order_[k];
    const double key = boxes[moving].lo.x();
    int j = k - 1;
    while (j >= 0 && boxes[order_[j]].lo.x() > key) {
      order_[j + 1] = order_[j];
      --j;
    }
    order_[j + 1] = moving;
  }
  // The boxes in that order, side by side: the sweep reads each box's
  // neighbours along x one after another (through order_ it took 5 ns a
  // test, most of a cloth's collision).
  sorted_.resize(n);
  for (int k = 0; k < n; ++k)
    sorted_[k] = boxes[order_[k]];
  for (int k = 0; k < n; ++k) {
    const Aabb& a = sorted_[k];
    if (!(a.lo.x() <= a.hi.x())) continue;  // empty: sorted last, overlaps nothing
    for (int l = k + 1; l < n && sorted_[l].lo.x() <= a.hi.x(); ++l) {
      const Aabb& b = sorted_[l];
      // x overlaps already (b starts within a, and no earlier than a).
      if (a.lo.y() > b.hi.y() || b.lo.y() > a.hi.y() || a.lo.z() > b.hi.z() || b.lo.z() > a.hi.z())
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

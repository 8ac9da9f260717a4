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

// Insertion sort of the boxes' order by lo along `axis`: nearly sorted
// from the last call, so about linear.
void BroadPhase::sortAlong(const std::vector<Aabb>& boxes, int axis) {
  std::vector<int>& order = orders_[axis];
  const int n = static_cast<int>(order.size());
  for (int k = 1; k < n; ++k) {
    const int moving = order[k];
    const double key = boxes[moving].lo[axis];
    int j = k - 1;
    while (j >= 0 && boxes[order[j]].lo[axis] > key) {
      order[j + 1] = order[j];
      --j;
    }
    order[j + 1] = moving;
  }
}

// How many boxes a sweep along `axis` would test: for each box, those
// after it in the order that start within its extent.
double BroadPhase::testsAlong(const std::vector<Aabb>& boxes, int axis) {
  const std::vector<int>& order = orders_[axis];
  const int n = static_cast<int>(order.size());
  starts_.resize(n);
  for (int k = 0; k < n; ++k)
    starts_[k] = boxes[order[k]].lo[axis];
  double tests = 0.0;
  for (int k = 0; k < n; ++k) {
    const Aabb& box = boxes[order[k]];
    if (!(box.lo.x() <= box.hi.x())) continue;
    tests +=
        static_cast<double>(std::upper_bound(starts_.begin() + k + 1, starts_.end(), box.hi[axis]) -
                            (starts_.begin() + k + 1));
  }
  return tests;
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
  // Sweep along the axis that leaves the fewest boxes to test: a pile ten
  // layers deep swept along x tested each box against its whole column,
  // and a landed one swept along z would test it against its whole layer.
  // Every kAxisReview calls each axis's order is sorted afresh and its
  // tests counted; in between only the swept axis's order is kept, by
  // insertion sort. (Afresh, because an axis the boxes do not spread
  // along, a sheet's thickness, comes back in no order at all, where
  // insertion sort is quadratic; every 64 calls, because at 16 the
  // reviews cost a 64 x 64 sheet's sweep 7%.)
  const bool fresh = static_cast<int>(orders_[0].size()) != n;
  if (fresh || ++sinceReview_ >= kAxisReview) {
    sinceReview_ = 0;
    double tests[3];
    for (int a = 0; a < 3; ++a) {
      std::vector<int>& order = orders_[a];
      if (fresh) {
        order.resize(n);
        for (int i = 0; i < n; ++i)
          order[i] = i;
      }
      std::sort(order.begin(), order.end(), [&](int i, int j) {
        return boxes[i].lo[a] < boxes[j].lo[a] || (boxes[i].lo[a] == boxes[j].lo[a] && i < j);
      });
      tests[a] = testsAlong(boxes, a);
    }
    // The sweep's axis, then the others by how few boxes they leave: the
    // overlap test looks at the most selective first (a flat sheet swept
    // along y and tested along its thickness first took 16% longer).
    std::sort(axes_.begin(), axes_.end(),
              [&](int i, int j) { return tests[i] < tests[j] || (tests[i] == tests[j] && i < j); });
  } else {
    sortAlong(boxes, axes_[0]);
  }
  const int ax = axes_[0];
  const std::vector<int>& order = orders_[ax];
  // The boxes in that order, side by side: the sweep reads each box's
  // neighbours along the axis one after another (through the order it
  // took 5 ns a test, most of a cloth's collision).
  sorted_.resize(n);
  for (int k = 0; k < n; ++k)
    sorted_[k] = boxes[order[k]];
  const int ay = axes_[1], az = axes_[2];
  for (int k = 0; k < n; ++k) {
    const Aabb& a = sorted_[k];
    if (!(a.lo.x() <= a.hi.x())) continue;  // empty: overlaps nothing
    for (int l = k + 1; l < n && sorted_[l].lo[ax] <= a.hi[ax]; ++l) {
      const Aabb& b = sorted_[l];
      // Overlapping along the axis already (b starts within a, and no
      // earlier than a).
      if (a.lo[ay] > b.hi[ay] || b.lo[ay] > a.hi[ay] || a.lo[az] > b.hi[az] || b.lo[az] > a.hi[az])
        continue;
      const int i = order[k], j = order[l];
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

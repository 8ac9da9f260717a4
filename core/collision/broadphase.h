// The broad phase: which pairs of shapes are close enough to be tested by
// the narrow phase. Each shape gets an axis-aligned box grown by half the
// contact margin (so pairs within the margin overlap). Two methods give
// the same pairs in the same order: all pairs, for small scenes, and
// sweep and prune along x, whose order is kept from step to step so the
// re-sort is an insertion sort over nearly sorted boxes (linear when the
// bodies move little, as they do between steps).
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/collision/shapes.h"

namespace blockstep {

struct Aabb {
  Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);  // empty
  bool overlaps(const Aabb& o) const {
    return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
  }
};

// The shape's box in the world, grown by `grow` on every side; planes are
// unbounded, dead shapes empty.
Aabb shapeAabb(const Shape& s, const ShapePose& pose, double grow);

enum class BroadPhaseMethod : std::uint8_t {
  Automatic,  // all pairs below 64 shapes, sweep and prune above
  AllPairs,
  SweepAndPrune,
};

class BroadPhase {
 public:
  // The pairs (i < j) of overlapping boxes, sorted. Empty boxes overlap
  // nothing.
  void findPairs(const std::vector<Aabb>& boxes, BroadPhaseMethod method,
                 std::vector<std::pair<int, int>>& pairs);
  // The axis sweep and prune sweeps along (0 x, 1 y, 2 z): the one that
  // left the fewest boxes to test when last reviewed.
  int sweepAxis() const { return axes_[0]; }
  // Calls between reviews of the sweep's axis.
  static constexpr int kAxisReview = 64;

 private:
  void sortPairs(int n, std::vector<std::pair<int, int>>& pairs);
  void sortAlong(const std::vector<Aabb>& boxes, int axis);
  double testsAlong(const std::vector<Aabb>& boxes, int axis);

  std::array<int, 3> axes_ = {0, 1, 2};  // the sweep's, then the others' test order
  int sinceReview_ = 0;
  // Sweep and prune: box indices by lo along each axis, kept across calls
  // (the swept axis's every call, the others' at each review).
  std::array<std::vector<int>, 3> orders_;
  std::vector<double> starts_;                    // testsAlong's scratch
  std::vector<Aabb> sorted_;                      // the boxes in that order (scratch)
  std::vector<int> pairStart_, pairFill_;         // sortPairs' scratch
  std::vector<std::pair<int, int>> sortedPairs_;  // sortPairs' scratch
};

}  // namespace blockstep

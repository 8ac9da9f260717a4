// Collects the rows one joint emits in prepare(): bounded rows (limits,
// motors) and equality rows apart, since the solver runs the bounded rows
// one by one and the equality rows as one LDL^T block (row.h says why).
#pragma once

#include <cassert>

#include "core/constraints/row.h"

namespace blockstep {

inline constexpr int kMaxEqualityRows = 6;
inline constexpr int kMaxBoundedRows = 18;  // 6 axes x (motor, lower, upper)
inline constexpr int kMaxJointSlots = kMaxEqualityRows + kMaxBoundedRows;

class RowWriter {
 public:
  ConstraintRow& equality(int slot) {
    assert(equalityCount_ < kMaxEqualityRows);
    ConstraintRow& r = equality_[equalityCount_++];
    r = ConstraintRow{};
    r.slot = static_cast<std::uint8_t>(slot);
    return r;
  }
  ConstraintRow& bounded(int slot) {
    assert(boundedCount_ < kMaxBoundedRows);
    ConstraintRow& r = bounded_[boundedCount_++];
    r = ConstraintRow{};
    r.slot = static_cast<std::uint8_t>(slot);
    return r;
  }
  void clear() { equalityCount_ = boundedCount_ = 0; }

  int equalityCount() const { return equalityCount_; }
  int boundedCount() const { return boundedCount_; }
  const ConstraintRow& equalityRow(int i) const { return equality_[i]; }
  const ConstraintRow& boundedRow(int i) const { return bounded_[i]; }

 private:
  ConstraintRow equality_[kMaxEqualityRows];
  ConstraintRow bounded_[kMaxBoundedRows];
  int equalityCount_ = 0;
  int boundedCount_ = 0;
};

}  // namespace blockstep

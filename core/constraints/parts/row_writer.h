// Collects the rows one joint emits in prepare(), straight into the
// solver's row storage: equality rows (solved together as one LDL^T block)
// and bounded rows (limits, motors: solved one by one, row.h says why).
// The joint's rows end up as [equality..., bounded...].
#pragma once

#include <cassert>

#include "core/constraints/row.h"

namespace blockstep {

inline constexpr int kMaxEqualityRows = 6;
inline constexpr int kMaxBoundedRows = 18;  // 6 axes x (motor, lower, upper)
inline constexpr int kMaxJointSlots = kMaxEqualityRows + kMaxBoundedRows;
static_assert(kMaxJointSlots <= 32, "Joint::warmSlots is a 32-bit mask of slots");

class RowWriter {
 public:
  // `rows` must have room for kMaxJointSlots rows.
  explicit RowWriter(ConstraintRow* rows) : rows_(rows) {}

  ConstraintRow& equality(int slot) {
    assert(equalityCount_ < kMaxEqualityRows);
    return fresh(rows_[equalityCount_++], slot);
  }
  ConstraintRow& bounded(int slot) {
    assert(boundedCount_ < kMaxBoundedRows);
    return fresh(rows_[kMaxEqualityRows + boundedCount_++], slot);
  }

  // Closes the gap between the equality and the bounded rows.
  void finish() {
    if (equalityCount_ == kMaxEqualityRows) return;
    for (int i = 0; i < boundedCount_; ++i) {
      rows_[equalityCount_ + i] = rows_[kMaxEqualityRows + i];
    }
  }

  int equalityCount() const { return equalityCount_; }
  int boundedCount() const { return boundedCount_; }

 private:
  static ConstraintRow& fresh(ConstraintRow& r, int slot) {
    r = ConstraintRow{};
    r.slot = static_cast<std::uint8_t>(slot);
    return r;
  }

  ConstraintRow* rows_;
  int equalityCount_ = 0;
  int boundedCount_ = 0;
};

}  // namespace blockstep

// Point-to-point part: the two anchors coincide, C = pB - pA (3 rows, one
// per world axis). Used by ball, hinge, universal, cone-twist, fixed.
#pragma once

#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/row_writer.h"

namespace blockstep {

inline void addPointRows(const JointPose& p, const Softness& softness, int firstSlot,
                         RowWriter& out) {
  for (int i = 0; i < 3; ++i) {
    ConstraintRow& row = out.equality(firstSlot + i);
    directionRow(p, Vec3::Unit(i), row);
    row.softness = &softness;
  }
}

}  // namespace blockstep

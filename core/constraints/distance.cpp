// Distance joint: keeps |pB - pA| within [minLength, maxLength]. Equal
// lengths make a rod (an equality row, a damped spring with Spring
// softness); minLength = 0 makes a rope (one-sided, never pushes).
#include <cmath>

#include "core/constraints/joint_kinds.h"
#include "core/constraints/parts/axis.h"
#include "core/constraints/parts/coordinate.h"
#include "core/world/error.h"

namespace blockstep {

void validateJoint(const DistanceJointDesc& d) {
  validateCommon(d.common, "distance");
  requireFinite(d.anchorA, "distance joint anchorA");
  requireFinite(d.anchorB, "distance joint anchorB");
  if (std::isnan(d.minLength) || std::isnan(d.maxLength) || std::isinf(d.minLength) ||
      std::isinf(d.maxLength)) {
    throw Error("distance joint lengths must be finite");
  }
  if (d.minLength >= 0.0 && d.maxLength >= 0.0 && d.minLength > d.maxLength) {
    throw Error("distance joint needs minLength <= maxLength (got " + std::to_string(d.minLength) +
                " > " + std::to_string(d.maxLength) + ")");
  }
}

JointFrames setupJoint(DistanceJointDesc& d, const Body& a, const Body& b) {
  const double length = (d.anchorB - d.anchorA).norm();
  if (d.minLength < 0.0) d.minLength = std::min(length, d.maxLength < 0.0 ? length : d.maxLength);
  if (d.maxLength < 0.0) d.maxLength = std::max(length, d.minLength);
  JointFrames f;
  f.localAnchorA = a.localPoint(d.anchorA);
  f.localAnchorB = b.localPoint(d.anchorB);
  return f;
}

void buildJointRows(const DistanceJointDesc& d, const JointPose& p, RowWriter& out) {
  const double length = p.d.norm();
  // Coincident anchors give no direction; any unit vector keeps the row
  // well formed, and the limit then pushes them apart along it.
  const Vec3 n = length > 1e-9 ? Vec3(p.d / length) : Vec3::UnitX();
  ConstraintRow rate;
  directionRow(p, n, rate);
  const Stops stops{true, d.minLength, d.maxLength};
  addCoordinateRows(rate, length, stops, d.common.softness, Motor{}, 0, out);
}

}  // namespace blockstep

// Limits and motors on one joint coordinate (an angle or a distance),
// shared by every joint kind that has them.
//
// The caller gives the coordinate's value and a row whose Jacobian is its
// rate (d value / dt = J v). A limit becomes two one-sided rows, lower
// (C = value - lo, impulse >= 0) and upper (C = hi - value, J negated,
// impulse >= 0); both stay in the solve all the time and act
// speculatively: while C > 0 the row only stops the approach that would
// cross the stop within this step (bias C / h), so a body reaches a stop
// without bouncing off it or tunnelling through it. Past the stop the row
// uses the limit's softness (ODE's StopERP / StopCFM). lo == hi locks the
// coordinate with an equality row instead. With bounce > 0 a stop that the
// coordinate reaches within the step sends it back at bounce times its
// approach speed (ODE: c = max(c, -bounce v) at an active stop; we also
// bounce when the stop is reached during the step, since speculative rows
// stop it exactly at the stop where ODE would find it a little past).
#pragma once

#include "core/constraints/joint_desc.h"
#include "core/constraints/parts/row_writer.h"

namespace blockstep {

// Three slots per coordinate: motor, lower, upper (locked uses lower).
inline constexpr int kCoordinateSlots = 3;

// A coordinate's stops: lo <= value <= hi (no stops when !enabled), and
// the restitution when it hits one.
struct Stops {
  bool enabled = false;
  double lo = 0.0, hi = 0.0;
  double bounce = 0.0;
};

// `stopSoftness` must outlive prepare(): rows keep a pointer to it.
inline void addCoordinateRows(const ConstraintRow& rate, double value, const Stops& limit,
                              const Softness& stopSoftness, const Motor& motor, int firstSlot,
                              RowWriter& out) {
  if (motor.active()) {
    ConstraintRow& m = out.bounded(firstSlot);
    m = rate;
    m.slot = static_cast<std::uint8_t>(firstSlot);
    m.C = 0.0;
    m.biasKind = RowBias::Velocity;
    m.target = motor.targetVelocity;
    m.lo = -motor.maxForce;  // a force here; prepare() turns it into an impulse bound
    m.hi = motor.maxForce;
    m.gamma = motor.cfm;  // per unit force; prepare() makes it per unit impulse
  }
  if (!limit.enabled) return;
  if (limit.lo == limit.hi) {
    ConstraintRow& e = out.equality(firstSlot + 1);
    e = rate;
    e.slot = static_cast<std::uint8_t>(firstSlot + 1);
    e.C = value - limit.lo;
    e.softness = &stopSoftness;
    return;
  }
  ConstraintRow& lower = out.bounded(firstSlot + 1);
  lower = rate;
  lower.slot = static_cast<std::uint8_t>(firstSlot + 1);
  lower.C = value - limit.lo;
  lower.biasKind = RowBias::Speculative;
  lower.softness = &stopSoftness;
  lower.lo = 0.0;
  lower.hi = kInf;
  lower.bounce = limit.bounce;

  ConstraintRow& upper = out.bounded(firstSlot + 2);
  upper = rate;
  upper.slot = static_cast<std::uint8_t>(firstSlot + 2);
  upper.linA = -rate.linA;
  upper.angA = -rate.angA;
  upper.linB = -rate.linB;
  upper.angB = -rate.angB;
  upper.C = limit.hi - value;
  upper.biasKind = RowBias::Speculative;
  upper.softness = &stopSoftness;
  upper.lo = 0.0;
  upper.hi = kInf;
  upper.bounce = limit.bounce;
}

inline void addCoordinateRows(const ConstraintRow& rate, double value, const Limit& limit,
                              const Motor& motor, int firstSlot, RowWriter& out) {
  addCoordinateRows(rate, value, Stops{limit.enabled, limit.lo, limit.hi, limit.bounce},
                    limit.softness, motor, firstSlot, out);
}

}  // namespace blockstep

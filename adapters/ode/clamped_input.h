// Values ODE steps that the core takes only within range (an ERP of 2, a
// bounce of 1.5, 5,000 quickstep iterations). Refusing the step would
// freeze a drop-in program that never checks the stepper's return value,
// so the adapter takes the nearest value in range and the plugin says once
// per world which kinds it changed.
#pragma once

namespace blockstep::ode {

enum ClampedInput : unsigned {
  kClampedSoftness = 1u << 0,       // ERP outside [0, 1] or a negative CFM
  kClampedLimitBounce = 1u << 1,    // a joint stop's bounce outside [0, 1]
  kClampedContactBounce = 1u << 2,  // a contact's bounce outside [0, 1], or bounce_vel < 0
  kClampedSubsteps = 1u << 3,       // more quickstep iterations than sub-steps allow
};
constexpr int kClampedInputKinds = 4;

// What was changed, for the message.
inline const char* clampedInputText(unsigned kind) {
  switch (kind) {
    case kClampedSoftness:
      return "an ERP outside [0, 1] or a negative CFM (world, joint, stop or contact) is taken "
             "as the nearest value in range";
    case kClampedLimitBounce:
      return "a joint stop's bounce outside [0, 1] is taken as the nearest value in range (above "
             "1 ODE's stops add energy at each bounce)";
    case kClampedContactBounce:
      return "a contact's bounce outside [0, 1] or a negative bounce_vel is taken as the nearest "
             "value in range (above 1 ODE's contacts add energy at each bounce)";
    case kClampedSubsteps:
      return "more than 2000 quickstep iterations are followed as 1000 sub-steps, blockstep's "
             "most";
    default:
      return "an input out of range was clamped";
  }
}

}  // namespace blockstep::ode

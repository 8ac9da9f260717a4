// A joint as the world stores it: the user's description, the frames
// fixed in each body, and the impulses that outlive one step (warm
// starting, feedback, breaking).
#pragma once

#include <array>
#include <cstdint>

#include "core/constraints/joint_desc.h"
#include "core/constraints/parts/joint_pose.h"
#include "core/constraints/parts/row_writer.h"

namespace blockstep {

// What a joint carries from one (sub-)step to the next besides impulses,
// and what it measured at its last sub-step, for kinds whose coordinates
// are computed in the solver: a gear's wheel angles (A's, B's; it counts
// their whole turns from one sub-step to the next) and contact points, an
// Euler motor joint's three angles.
struct JointState {
  double angle[3] = {0.0, 0.0, 0.0};                    // rad
  Vec3 contactPoint[2] = {Vec3::Zero(), Vec3::Zero()};  // world, on A's and B's rim
  double contactRadius[2] = {0.0, 0.0};
};

struct Joint {
  JointDesc desc;
  JointFrames frames;
  JointState state;
  // Accumulated impulse of each row slot at the end of the last solve
  // (warm starting), and summed over the sub-steps of the last step.
  std::array<double, kMaxJointSlots> warmImpulse{};
  std::array<double, kMaxJointSlots> stepImpulse{};
  std::uint32_t warmSlots = 0;  // bit i: warmImpulse[i] holds a value from the last solve
  double warmStepSize = 0.0;    // the step the warm impulses were solved for
  std::int32_t block = -1;      // its block in the last step, -1 if it had none
  bool alive = true;
  bool enabled = true;
  bool broken = false;
};

// A joint's force and torque on each body over the last step, world
// frame, as ODE's dJointFeedback defines them (torque about each body's
// centre of mass).
struct JointFeedback {
  Vec3 forceA = Vec3::Zero(), torqueA = Vec3::Zero();
  Vec3 forceB = Vec3::Zero(), torqueB = Vec3::Zero();
};

// How far a joint is from satisfying itself, measured from the poses
// alone: the largest linear error (m) and angular error (rad) over its
// equality rows and any limit it is past.
struct JointError {
  double linear = 0.0;
  double angular = 0.0;
};

}  // namespace blockstep

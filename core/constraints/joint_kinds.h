// Per-kind joint behaviour, one overload set per JointDesc alternative:
//   validateJoint  checks the description (throws Error),
//   setupJoint     fixes the joint's frames in both bodies at creation,
//   buildJointRows writes the joint's rows for the current pose (kinds
//                  with a JointState also advance it; the others ignore it).
// The solver dispatches to them once per joint per prepare (std::visit).
#pragma once

#include "core/body/body.h"
#include "core/constraints/joint.h"
#include "core/constraints/joint_desc.h"
#include "core/constraints/parts/joint_pose.h"
#include "core/constraints/parts/row_writer.h"

namespace blockstep {

#define BLOCKSTEP_JOINT_KIND(Desc)                               \
  void validateJoint(const Desc& d);                             \
  JointFrames setupJoint(Desc& d, const Body& a, const Body& b); \
  void buildJointRows(const Desc& d, const JointPose& p, RowWriter& out);

BLOCKSTEP_JOINT_KIND(BallJointDesc)
BLOCKSTEP_JOINT_KIND(HingeJointDesc)
BLOCKSTEP_JOINT_KIND(SliderJointDesc)
BLOCKSTEP_JOINT_KIND(FixedJointDesc)
BLOCKSTEP_JOINT_KIND(UniversalJointDesc)
BLOCKSTEP_JOINT_KIND(ConeTwistJointDesc)
BLOCKSTEP_JOINT_KIND(SixDofJointDesc)
BLOCKSTEP_JOINT_KIND(DistanceJointDesc)
BLOCKSTEP_JOINT_KIND(MotorJointDesc)
BLOCKSTEP_JOINT_KIND(PrismaticRotoideJointDesc)
BLOCKSTEP_JOINT_KIND(PrismaticUniversalJointDesc)
BLOCKSTEP_JOINT_KIND(DoubleHingeJointDesc)

template <class Desc>
void buildJointRows(const Desc& d, const JointPose& p, JointState&, RowWriter& out) {
  buildJointRows(d, p, out);
}
void validateJoint(const GearJointDesc& d);
JointFrames setupJoint(GearJointDesc& d, const Body& a, const Body& b);
void buildJointRows(const GearJointDesc& d, const JointPose& p, JointState& state, RowWriter& out);
void buildJointRows(const MotorJointDesc& d, const JointPose& p, JointState& state, RowWriter& out);

#undef BLOCKSTEP_JOINT_KIND

// The turn of one of a joint's bodies that moves none of the joint's rows
// (the solver leaves it out of its sub-step count: Solver::noteLeverArms;
// the rows are linear in a turn, so any other turn's linearization error
// asks for sub-steps):
//   Every: every turn moves some row (the default for a kind);
//   About: a turn about `axis` (unit, in that body's frame) moves none;
//   None:  no turn moves one (a ball joint anchored at the centre of mass).
struct FreeTurn {
  enum class Kind : std::uint8_t { Every, About, None };
  Kind kind = Kind::Every;
  Vec3 axis = Vec3::Zero();
};
template <class Desc>
FreeTurn freeTurn(const Desc&, const JointFrames&, bool /*bodyB*/) {
  return {};
}
FreeTurn freeTurn(const BallJointDesc& d, const JointFrames& f, bool bodyB);
FreeTurn freeTurn(const HingeJointDesc& d, const JointFrames& f, bool bodyB);
FreeTurn freeTurn(const UniversalJointDesc& d, const JointFrames& f, bool bodyB);
// A point or a direction lies on a line when it is off it by less than
// this fraction of its length.
inline constexpr double kOnLine = 1e-6;
// The free turn of a body held at `anchor` (its frame, from the centre
// of mass): about the line through the anchor, any turn at the centre.
FreeTurn turnAboutAnchor(const Vec3& anchor);
// ... and of one also held to `axis` (unit, its frame): a turn about the
// axis when the anchor lies on it, else none is free.
FreeTurn turnAboutAxle(const Vec3& axis, const Vec3& anchor);

// On updateJoint, a kind whose rows read geometry fixed at creation (not
// only the frames) keeps it from the joint as made: the caller's new
// description brings limits, motors and softness, not geometry.
template <class Desc>
void keepCreationGeometry(Desc&, const Desc&) {}
void keepCreationGeometry(MotorJointDesc& next, const MotorJointDesc& made);
void keepCreationGeometry(PrismaticUniversalJointDesc& next,
                          const PrismaticUniversalJointDesc& made);
void keepCreationGeometry(GearJointDesc& next, const GearJointDesc& made);

// Checks shared by every kind.
void validateCommon(const JointCommon& c, const char* kind);
void validateLimit(const Limit& l, const char* what);
void validateMotor(const Motor& m, const char* what);
Vec3 requireAxis(const Vec3& axis, const char* what);  // returns it normalized
void requireFinite(const Vec3& v, const char* what);

// A joint frame whose x axis is `axis`, fixed in both bodies so the two
// frames coincide now; anchors at the world point `anchor`.
JointFrames framesAt(const Body& a, const Body& b, const Vec3& anchor, const Quat& worldFrame);

}  // namespace blockstep

// The world-space quantities every constraint part reads, computed once
// per joint per (sub)step from the two bodies and the joint's local frames.
#pragma once

#include "core/math/math.h"

namespace blockstep {

// Fixed in each body at creation.
struct JointFrames {
  Vec3 localAnchorA = Vec3::Zero();  // body A frame, from A's centre of mass
  Vec3 localAnchorB = Vec3::Zero();
  Quat localFrameA = Quat::Identity();  // joint frame relative to body A
  Quat localFrameB = Quat::Identity();
};

struct JointPose {
  Vec3 rA, rB;          // anchors relative to the centres of mass, world
  Vec3 pA, pB;          // anchors, world
  Vec3 d;               // pB - pA
  Quat frameA, frameB;  // joint frames, world

  static JointPose make(const Vec3& xA, const Quat& qA, const Vec3& xB, const Quat& qB,
                        const JointFrames& f) {
    JointPose p;
    p.rA = qA * f.localAnchorA;
    p.rB = qB * f.localAnchorB;
    p.pA = xA + p.rA;
    p.pB = xB + p.rB;
    p.d = p.pB - p.pA;
    p.frameA = qA * f.localFrameA;
    p.frameB = qB * f.localFrameB;
    return p;
  }
  Vec3 axisA(int i) const { return frameA * Vec3::Unit(i); }
  Vec3 axisB(int i) const { return frameB * Vec3::Unit(i); }
};

}  // namespace blockstep

// ODE's joints in the core's terms. Each step the bridge reads every ODE
// joint through ODE's public getters into a JointRead: the core joint
// description (world anchors and axes now, limits, motors, softness), the
// vectors that fix the joint in its bodies (to notice when the program
// moves an anchor or an axis) and ODE's own joint coordinates (angles,
// positions), whose values when the core joint is made become offsets, so
// limits keep the meaning they have in ODE (the zero of
// dJointGetHingeAngle is the pose at dJointSetHingeAxis, not ours).
//
// Body order: the core's body B is ODE's body1 and body A is body2 (or
// the world), so a coordinate of B relative to A has ODE's sign (ODE's
// hinge angle rate is axis . (w1 - w2)).
#pragma once

#include <ode/ode.h>

#include "core/constraints/joint_desc.h"

namespace blockstep::ode {

// Geometry vectors of a joint, each attached to ODE's public body1
// (side 1) or body2 (side 2; the world when that body is 0).
struct JointGeometry {
  static constexpr int kMax = 4;
  int count = 0;
  Vec3 value[kMax];  // world, as ODE's getters return them
  bool isPoint[kMax] = {};
  int side[kMax] = {};  // 0: the world

  void add(const Vec3& v, bool point, int onSide) {
    value[count] = v;
    isPoint[count] = point;
    side[count] = onSide;
    ++count;
  }
};

// What the joint's rows read from the world this step.
struct JointWorldParams {
  double erp = 0.2;  // dWorldGetERP
  double cfm = 1e-5;
  // Softness of rows given as ODE (ERP, CFM): the bridge decides whether
  // a pair stays as it is or becomes its physical spring (see world_bridge.h).
  Softness (*softness)(double erp, double cfm, const void* context) = nullptr;
  const void* context = nullptr;
  unsigned* clamped = nullptr;  // ClampedInput kinds brought into range, or nullptr
  Softness of(double e, double c) const {
    return softness ? softness(e, c, context) : Softness::erpCfm(e, c);
  }
};

struct JointRead {
  JointDesc desc;
  JointGeometry geometry;
  int coordinateCount = 0;
  double coordinate[3] = {0.0, 0.0, 0.0};  // ODE's joint coordinates now
  bool hasRows = true;                     // false for dJointTypeNull
  const char* unsupported = nullptr;       // an ODE kind or mode the core cannot model
};

// Reads ODE joint j. body1/body2 are the core ids of ODE's public body1
// and body2 (kWorldBody for 0). Limits come out in ODE's coordinates.
// What the program set that ODE's getters do not give back (the
// registry records it from the interposed setters).
struct JointSetOnly {
  int lmotorRel[3] = {0, 0, 0};      // LMotor axis frames
  double plane2dVel[3] = {0, 0, 0};  // Plane2D motors x, y, angle
  double plane2dFMax[3] = {0, 0, 0};
  Vec3 amotorAxis[3];  // AMotor axes in the frames ODE keeps them in
  Vec3 eulerRef1 = Vec3::Zero(), eulerRef2 = Vec3::Zero();  // Euler mode
};

void readJoint(dJointID j, BodyId body1, BodyId body2, const JointWorldParams& world,
               const JointSetOnly& setOnly, JointRead& out);

// Moves limits from ODE's coordinates to the core's: core = ODE - offset,
// offset[i] being ODE's coordinate i when the core joint was made.
void shiftLimits(JointDesc& desc, const double offset[3]);

const char* odeJointTypeName(int type);

}  // namespace blockstep::ode

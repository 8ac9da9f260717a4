// ODE entry points the plugin defines in front of ODE's: each forwards to
// the real function (dlsym RTLD_NEXT) and tells the registry what it
// made or destroyed; the steppers go to blockstep when BLOCKSTEP_REPLACE
// asks, or to both blockstep and quickstep under BLOCKSTEP_AB (ab_mode.h). Input ODE would abort on
// or silently accept into NaN (a zero or non-finite axis, a body jointed to itself, a non-finite or
// non-positive mass) is refused here with a message, and the world stays as it was.
#include <cmath>

#include "adapters/ode/geom_mapping.h"
#include "adapters/ode/registry.h"
#include "plugin/ab_mode.h"
#include "plugin/plugin_state.h"

namespace blockstep::plugin {
void forgetWorld(dWorldID w);
}  // namespace blockstep::plugin

using blockstep::ode::Registry;
using namespace blockstep::plugin;

namespace {

bool goodAxis(const char* function, dReal x, dReal y, dReal z) {
  const double n2 = double(x) * x + double(y) * y + double(z) * z;
  if (std::isfinite(n2) && n2 > 1e-18) return true;
  say("%s(%g, %g, %g): the axis must be finite and non-zero; call ignored", function, double(x),
      double(y), double(z));
  return false;
}

bool goodPoint(const char* function, dReal x, dReal y, dReal z) {
  if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) return true;
  say("%s(%g, %g, %g): the point must be finite; call ignored", function, double(x), double(y),
      double(z));
  return false;
}

bool goodMass(const dMass* m) {
  if (!m) {
    say("dBodySetMass: null mass; call ignored");
    return false;
  }
  bool finite = std::isfinite(m->mass);
  for (int i = 0; i < 12; ++i)
    finite = finite && (i % 4 == 3 || std::isfinite(m->I[i]));
  if (!finite || !(m->mass > 0)) {
    say("dBodySetMass: mass %g is not positive and finite, or the inertia is not finite; call "
        "ignored (the body keeps its mass)",
        double(m->mass));
    return false;
  }
  const double d0 = m->I[0], d1 = m->I[5], d2 = m->I[10];
  if (!(d0 > 0 && d1 > 0 && d2 > 0)) {
    say("dBodySetMass: inertia diagonal (%g, %g, %g) must be positive; call ignored", d0, d1, d2);
    return false;
  }
  // ODE's dMassCheck, which aborts the program: the inertia about the
  // centre of mass, I + m [c]x [c]x, must be positive definite (its leading
  // minors positive, Sylvester's criterion).
  const double c0 = m->c[0], c1 = m->c[1], c2 = m->c[2], mass = m->mass;
  const double a = m->I[0] - mass * (c1 * c1 + c2 * c2), b = m->I[1] + mass * c0 * c1,
               c = m->I[2] + mass * c0 * c2, d = m->I[5] - mass * (c0 * c0 + c2 * c2),
               e = m->I[6] + mass * c1 * c2, f = m->I[10] - mass * (c0 * c0 + c1 * c1);
  const double minor2 = a * d - b * b;
  const double det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c);
  if (!(a > 0 && minor2 > 0 && det > 0)) {
    say("dBodySetMass: the inertia about the centre of mass is not positive definite; call "
        "ignored (the body keeps its mass)");
    return false;
  }
  return true;
}

// A setter of the joint ran: the bridge reads it again at the next step.
void jointChanged(dJointID j) {
  guarded("jointChanged", [&] { Registry::instance().jointChanged(j); });
}

// Damping and speed limits: a NaN (or an infinite damping scale) would
// turn every velocity of the body or world into NaN at the next step.
bool goodValue(const char* function, dReal v, bool infinityAllowed) {
  if (std::isfinite(v) || (infinityAllowed && !std::isnan(v))) return true;
  say("%s(%g): the value must be %s; call ignored", function, double(v),
      infinityAllowed ? "a number" : "finite");
  return false;
}

}  // namespace

extern "C" {

// ------------------------------------------------------------- steppers

int dWorldQuickStep(dWorldID w, dReal stepsize) {
  BLOCKSTEP_REAL(dWorldQuickStep);
  if (abMode())
    return guarded(__func__, 0, [&] {
      return abStep(w, stepsize, replace().quickStep ? AbChoice::Blockstep : AbChoice::QuickStep,
                    blockstep::ode::OdeStepper::QuickStep);
    });
  if (replace().quickStep) return blockStep(w, stepsize, real_dWorldQuickStep);
  return real_dWorldQuickStep(w, stepsize);
}

int dWorldStep(dWorldID w, dReal stepsize) {
  BLOCKSTEP_REAL(dWorldStep);
  if (abMode())
    return guarded(__func__, 0, [&] {
      return abStep(w, stepsize, replace().step ? AbChoice::Blockstep : AbChoice::Step,
                    blockstep::ode::OdeStepper::Step);
    });
  if (replace().step)
    return blockStep(w, stepsize, real_dWorldStep, blockstep::ode::OdeStepper::Step);
  return real_dWorldStep(w, stepsize);
}

// ---------------------------------------------------------------- worlds

// The registry forgets the world first: ODE's dWorldDestroy calls
// dBodyDestroy (ours) for each body, and each of those, still registered,
// had its joints looked up among all of the world's (a 128 x 128 cloth's
// world took 2.4 s to destroy, against 20 ms for its steps' frame).
void dWorldDestroy(dWorldID w) {
  BLOCKSTEP_REAL(dWorldDestroy);
  guarded(__func__, [&] { Registry::instance().worldDestroyed(w); });
  real_dWorldDestroy(w);
  forgetWorld(w);
}

// ------------------------------------------------------------ library
// dInitODE fills ODE's collider table afresh: blockstep's colliders
// (dBlockSetColliders) go in after it.

void dInitODE() {
  BLOCKSTEP_REAL(dInitODE);
  real_dInitODE();
  collidersAfterInit();
}

int dInitODE2(unsigned int flags) {
  BLOCKSTEP_REAL(dInitODE2);
  const int ok = real_dInitODE2(flags);
  if (ok) collidersAfterInit();
  return ok;
}

void dCloseODE() {
  BLOCKSTEP_REAL(dCloseODE);
  collidersBeforeClose();
  real_dCloseODE();
}

// ---------------------------------------------------------------- geoms
// A convex geom's points, which ODE keeps no copy of and has no getter
// for: blockstep's collision builds the geom's hull from them.

dGeomID dCreateConvex(dSpaceID space, const dReal* planes, unsigned planeCount, const dReal* points,
                      unsigned pointCount, const unsigned* polygons) {
  BLOCKSTEP_REAL(dCreateConvex);
  dGeomID g = real_dCreateConvex(space, planes, planeCount, points, pointCount, polygons);
  guarded(__func__,
          [&] { blockstep::ode::ConvexGeoms::instance().remember(g, points, pointCount); });
  return g;
}

void dGeomSetConvex(dGeomID g, const dReal* planes, unsigned planeCount, const dReal* points,
                    unsigned pointCount, const unsigned* polygons) {
  BLOCKSTEP_REAL(dGeomSetConvex);
  real_dGeomSetConvex(g, planes, planeCount, points, pointCount, polygons);
  guarded(__func__,
          [&] { blockstep::ode::ConvexGeoms::instance().remember(g, points, pointCount); });
}

void dGeomDestroy(dGeomID g) {
  BLOCKSTEP_REAL(dGeomDestroy);
  guarded(__func__, [&] {
    blockstep::ode::ConvexGeoms::instance().forget(g);
    blockstep::ode::RoundGeoms::instance().forget(g);
  });
  real_dGeomDestroy(g);
}

// Spheres, capsules and cylinders: a contact's round surface keeps its
// centre of curvature through the sub-steps (RoundGeoms).

dGeomID dCreateSphere(dSpaceID space, dReal radius) {
  BLOCKSTEP_REAL(dCreateSphere);
  dGeomID g = real_dCreateSphere(space, radius);
  guarded(__func__, [&] { blockstep::ode::RoundGeoms::instance().remember(g); });
  return g;
}

dGeomID dCreateCapsule(dSpaceID space, dReal radius, dReal length) {
  BLOCKSTEP_REAL(dCreateCapsule);
  dGeomID g = real_dCreateCapsule(space, radius, length);
  guarded(__func__, [&] { blockstep::ode::RoundGeoms::instance().remember(g); });
  return g;
}

dGeomID dCreateCylinder(dSpaceID space, dReal radius, dReal length) {
  BLOCKSTEP_REAL(dCreateCylinder);
  dGeomID g = real_dCreateCylinder(space, radius, length);
  guarded(__func__, [&] { blockstep::ode::RoundGeoms::instance().remember(g); });
  return g;
}

// ---------------------------------------------------------------- bodies

dBodyID dBodyCreate(dWorldID w) {
  BLOCKSTEP_REAL(dBodyCreate);
  dBodyID b = real_dBodyCreate(w);
  guarded(__func__, [&] { Registry::instance().bodyCreated(w, b); });
  return b;
}

void dBodyDestroy(dBodyID b) {
  BLOCKSTEP_REAL(dBodyDestroy);
  real_dBodyDestroy(b);
  guarded(__func__, [&] { Registry::instance().bodyDestroyed(b); });
}

void dBodySetMovedCallback(dBodyID b, void (*callback)(dBodyID)) {
  BLOCKSTEP_REAL(dBodySetMovedCallback);
  real_dBodySetMovedCallback(b, callback);
  guarded(__func__, [&] { Registry::instance().movedCallbackSet(b, callback); });
}

void dBodySetMass(dBodyID b, const dMass* mass) {
  BLOCKSTEP_REAL(dBodySetMass);
  if (goodMass(mass)) real_dBodySetMass(b, mass);
}

// Damping and speed limits of bodies and worlds.
#define BLOCKSTEP_CHECKED_VALUE(name, Owner, infinityAllowed)    \
  void name(Owner o, dReal v) {                                  \
    BLOCKSTEP_REAL(name);                                        \
    if (goodValue(#name, v, infinityAllowed)) real_##name(o, v); \
  }
BLOCKSTEP_CHECKED_VALUE(dBodySetLinearDamping, dBodyID, false)
BLOCKSTEP_CHECKED_VALUE(dBodySetAngularDamping, dBodyID, false)
BLOCKSTEP_CHECKED_VALUE(dBodySetLinearDampingThreshold, dBodyID, true)
BLOCKSTEP_CHECKED_VALUE(dBodySetAngularDampingThreshold, dBodyID, true)
BLOCKSTEP_CHECKED_VALUE(dBodySetMaxAngularSpeed, dBodyID, true)
BLOCKSTEP_CHECKED_VALUE(dWorldSetLinearDamping, dWorldID, false)
BLOCKSTEP_CHECKED_VALUE(dWorldSetAngularDamping, dWorldID, false)
BLOCKSTEP_CHECKED_VALUE(dWorldSetLinearDampingThreshold, dWorldID, true)
BLOCKSTEP_CHECKED_VALUE(dWorldSetAngularDampingThreshold, dWorldID, true)
BLOCKSTEP_CHECKED_VALUE(dWorldSetMaxAngularSpeed, dWorldID, true)

void dBodySetDamping(dBodyID b, dReal linear, dReal angular) {
  BLOCKSTEP_REAL(dBodySetDamping);
  if (goodValue("dBodySetDamping", linear, false) && goodValue("dBodySetDamping", angular, false))
    real_dBodySetDamping(b, linear, angular);
}

void dWorldSetDamping(dWorldID w, dReal linear, dReal angular) {
  BLOCKSTEP_REAL(dWorldSetDamping);
  if (goodValue("dWorldSetDamping", linear, false) && goodValue("dWorldSetDamping", angular, false))
    real_dWorldSetDamping(w, linear, angular);
}

// ---------------------------------------------------------------- joints

#define BLOCKSTEP_JOINT_CREATE(name)                                                 \
  dJointID name(dWorldID w, dJointGroupID g) {                                       \
    BLOCKSTEP_REAL(name);                                                            \
    dJointID j = real_##name(w, g);                                                  \
    guarded(__func__, [&] { Registry::instance().jointCreated(w, g, j, nullptr); }); \
    return j;                                                                        \
  }
BLOCKSTEP_JOINT_CREATE(dJointCreateBall)
BLOCKSTEP_JOINT_CREATE(dJointCreateHinge)
BLOCKSTEP_JOINT_CREATE(dJointCreateSlider)
BLOCKSTEP_JOINT_CREATE(dJointCreateHinge2)
BLOCKSTEP_JOINT_CREATE(dJointCreateUniversal)
BLOCKSTEP_JOINT_CREATE(dJointCreatePR)
BLOCKSTEP_JOINT_CREATE(dJointCreatePU)
BLOCKSTEP_JOINT_CREATE(dJointCreatePiston)
BLOCKSTEP_JOINT_CREATE(dJointCreateFixed)
BLOCKSTEP_JOINT_CREATE(dJointCreateNull)
BLOCKSTEP_JOINT_CREATE(dJointCreateAMotor)
BLOCKSTEP_JOINT_CREATE(dJointCreateLMotor)
BLOCKSTEP_JOINT_CREATE(dJointCreatePlane2D)
BLOCKSTEP_JOINT_CREATE(dJointCreateDBall)
BLOCKSTEP_JOINT_CREATE(dJointCreateDHinge)
BLOCKSTEP_JOINT_CREATE(dJointCreateTransmission)
#undef BLOCKSTEP_JOINT_CREATE

dJointID dJointCreateContact(dWorldID w, dJointGroupID g, const dContact* c) {
  BLOCKSTEP_REAL(dJointCreateContact);
  dJointID j = real_dJointCreateContact(w, g, c);
  guarded(__func__, [&] { Registry::instance().jointCreated(w, g, j, c); });
  return j;
}

void dJointDestroy(dJointID j) {
  BLOCKSTEP_REAL(dJointDestroy);
  real_dJointDestroy(j);
  guarded(__func__, [&] { Registry::instance().jointDestroyed(j); });
}

void dJointGroupEmpty(dJointGroupID g) {
  BLOCKSTEP_REAL(dJointGroupEmpty);
  real_dJointGroupEmpty(g);
  guarded(__func__, [&] { Registry::instance().groupEmptied(g); });
}

void dJointGroupDestroy(dJointGroupID g) {
  BLOCKSTEP_REAL(dJointGroupDestroy);
  real_dJointGroupDestroy(g);
  guarded(__func__, [&] { Registry::instance().groupDestroyed(g); });
}

void dJointAttach(dJointID j, dBodyID b1, dBodyID b2) {
  BLOCKSTEP_REAL(dJointAttach);
  if (b1 && b1 == b2) {
    say("dJointAttach(%p, %p, %p): a joint cannot attach a body to itself; call ignored",
        static_cast<void*>(j), static_cast<void*>(b1), static_cast<void*>(b2));
    return;
  }
  // ODE aborts on hinge2 and transmission joints given a single body.
  const int type = j ? dJointGetType(j) : 0;
  if ((type == dJointTypeHinge2 || type == dJointTypeTransmission) && (!b1 || !b2) && (b1 || b2)) {
    say("dJointAttach(%p, %p, %p): a %s joint needs two bodies; call ignored",
        static_cast<void*>(j), static_cast<void*>(b1), static_cast<void*>(b2),
        type == dJointTypeHinge2 ? "hinge2" : "transmission");
    return;
  }
  real_dJointAttach(j, b1, b2);
  // A contact joint is read afresh every step (its record holds the
  // contact), so it needs no count; an ODE program attaches each of its
  // contacts every step, and counting took two locks each.
  if (type != dJointTypeContact) jointChanged(j);
}

// Axis and point setters ODE would abort on (zero axis) or take as NaN.
#define BLOCKSTEP_CHECKED_SETTER(name, check)        \
  void name(dJointID j, dReal x, dReal y, dReal z) { \
    BLOCKSTEP_REAL(name);                            \
    if (!check(#name, x, y, z)) return;              \
    real_##name(j, x, y, z);                         \
    jointChanged(j);                                 \
  }
BLOCKSTEP_CHECKED_SETTER(dJointSetHingeAxis, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetSliderAxis, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetUniversalAxis1, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetUniversalAxis2, goodAxis)
// Deprecated in ODE 0.16, still part of its ABI.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
BLOCKSTEP_CHECKED_SETTER(dJointSetHinge2Axis1, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetHinge2Axis2, goodAxis)
#pragma GCC diagnostic pop
BLOCKSTEP_CHECKED_SETTER(dJointSetPRAxis1, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetPRAxis2, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetPUAxis1, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetPUAxis2, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetPUAxis3, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetPistonAxis, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetDHingeAxis, goodAxis)
BLOCKSTEP_CHECKED_SETTER(dJointSetBallAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetBallAnchor2, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetHingeAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetUniversalAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetHinge2Anchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetPRAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetPUAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetPistonAnchor, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetDBallAnchor1, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetDBallAnchor2, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetDHingeAnchor1, goodPoint)
BLOCKSTEP_CHECKED_SETTER(dJointSetDHingeAnchor2, goodPoint)
#undef BLOCKSTEP_CHECKED_SETTER

void dJointSetLMotorAxis(dJointID j, int anum, int rel, dReal x, dReal y, dReal z) {
  BLOCKSTEP_REAL(dJointSetLMotorAxis);
  if (!goodAxis("dJointSetLMotorAxis", x, y, z)) return;
  real_dJointSetLMotorAxis(j, anum, rel, x, y, z);
  guarded(__func__, [&] { Registry::instance().lmotorAxisSet(j, anum, rel); });
  jointChanged(j);
}

void dJointSetAMotorAxis(dJointID j, int anum, int rel, dReal x, dReal y, dReal z) {
  BLOCKSTEP_REAL(dJointSetAMotorAxis);
  if (!goodAxis("dJointSetAMotorAxis", x, y, z)) return;
  real_dJointSetAMotorAxis(j, anum, rel, x, y, z);
  const double world[3] = {x, y, z};
  guarded(__func__, [&] { Registry::instance().amotorAxisSet(j, anum, rel, world); });
  jointChanged(j);
}

void dJointSetAMotorMode(dJointID j, int mode) {
  BLOCKSTEP_REAL(dJointSetAMotorMode);
  real_dJointSetAMotorMode(j, mode);
  guarded(__func__, [&] { Registry::instance().amotorModeSet(j); });
  jointChanged(j);
}

// Plane2D's motors have setters only; the registry keeps what they set.
#define BLOCKSTEP_PLANE2D_PARAM(name, motor)                                                      \
  void name(dJointID j, int parameter, dReal value) {                                             \
    BLOCKSTEP_REAL(name);                                                                         \
    real_##name(j, parameter, value);                                                             \
    guarded(__func__, [&] { Registry::instance().plane2dParamSet(j, motor, parameter, value); }); \
    jointChanged(j);                                                                              \
  }
BLOCKSTEP_PLANE2D_PARAM(dJointSetPlane2DXParam, 0)
BLOCKSTEP_PLANE2D_PARAM(dJointSetPlane2DYParam, 1)
BLOCKSTEP_PLANE2D_PARAM(dJointSetPlane2DAngleParam, 2)
#undef BLOCKSTEP_PLANE2D_PARAM

void dJointSetHinge2Axes(dJointID j, const dReal* axis1, const dReal* axis2) {
  BLOCKSTEP_REAL(dJointSetHinge2Axes);
  if (axis1 && !goodAxis("dJointSetHinge2Axes (axis1)", axis1[0], axis1[1], axis1[2])) return;
  if (axis2 && !goodAxis("dJointSetHinge2Axes (axis2)", axis2[0], axis2[1], axis2[2])) return;
  real_dJointSetHinge2Axes(j, axis1, axis2);
  jointChanged(j);
}

// ODE's other joint setters: each is passed on and counted, so the bridge
// reads the joint again at the next step (JointRecord::changes). Every
// dJointSet* of ODE's API is interposed here or above
// (PluginJointCache.EverySetterOfOdesApiIsCounted checks the header).
#define BLOCKSTEP_COUNTED_SETTER(name, params, args) \
  void name params {                                 \
    BLOCKSTEP_REAL(name);                            \
    real_##name args;                                \
    jointChanged(j);                                 \
  }
#define BLOCKSTEP_COUNTED_PARAM(name) \
  BLOCKSTEP_COUNTED_SETTER(name, (dJointID j, int parameter, dReal value), (j, parameter, value))
BLOCKSTEP_COUNTED_PARAM(dJointSetBallParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetHingeParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetSliderParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetFixedParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetUniversalParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetHinge2Param)
BLOCKSTEP_COUNTED_PARAM(dJointSetPRParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetPUParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetPistonParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetAMotorParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetLMotorParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetDBallParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetDHingeParam)
BLOCKSTEP_COUNTED_PARAM(dJointSetTransmissionParam)
#undef BLOCKSTEP_COUNTED_PARAM
#define BLOCKSTEP_COUNTED_POINT(name) \
  BLOCKSTEP_COUNTED_SETTER(name, (dJointID j, dReal x, dReal y, dReal z), (j, x, y, z))
BLOCKSTEP_COUNTED_POINT(dJointSetPUAxisP)
BLOCKSTEP_COUNTED_POINT(dJointSetTransmissionAnchor1)
BLOCKSTEP_COUNTED_POINT(dJointSetTransmissionAnchor2)
BLOCKSTEP_COUNTED_POINT(dJointSetTransmissionAxis)
BLOCKSTEP_COUNTED_POINT(dJointSetTransmissionAxis1)
BLOCKSTEP_COUNTED_POINT(dJointSetTransmissionAxis2)
#undef BLOCKSTEP_COUNTED_POINT
#define BLOCKSTEP_COUNTED_DELTA(name)                                                             \
  BLOCKSTEP_COUNTED_SETTER(name,                                                                  \
                           (dJointID j, dReal x, dReal y, dReal z, dReal dx, dReal dy, dReal dz), \
                           (j, x, y, z, dx, dy, dz))
BLOCKSTEP_COUNTED_DELTA(dJointSetHingeAnchorDelta)
BLOCKSTEP_COUNTED_DELTA(dJointSetSliderAxisDelta)
BLOCKSTEP_COUNTED_DELTA(dJointSetPUAnchorOffset)
BLOCKSTEP_COUNTED_DELTA(dJointSetPistonAnchorOffset)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
BLOCKSTEP_COUNTED_DELTA(dJointSetPUAnchorDelta)
BLOCKSTEP_COUNTED_DELTA(dJointSetPistonAxisDelta)
#pragma GCC diagnostic pop
#undef BLOCKSTEP_COUNTED_DELTA
#define BLOCKSTEP_COUNTED_VALUE(name, type) \
  BLOCKSTEP_COUNTED_SETTER(name, (dJointID j, type value), (j, value))
BLOCKSTEP_COUNTED_VALUE(dJointSetAMotorNumAxes, int)
BLOCKSTEP_COUNTED_VALUE(dJointSetLMotorNumAxes, int)
BLOCKSTEP_COUNTED_VALUE(dJointSetDBallDistance, dReal)
BLOCKSTEP_COUNTED_VALUE(dJointSetTransmissionBacklash, dReal)
BLOCKSTEP_COUNTED_VALUE(dJointSetTransmissionMode, int)
BLOCKSTEP_COUNTED_VALUE(dJointSetTransmissionRadius1, dReal)
BLOCKSTEP_COUNTED_VALUE(dJointSetTransmissionRadius2, dReal)
BLOCKSTEP_COUNTED_VALUE(dJointSetTransmissionRatio, dReal)
#undef BLOCKSTEP_COUNTED_VALUE
BLOCKSTEP_COUNTED_SETTER(dJointSetAMotorAngle, (dJointID j, int anum, dReal angle),
                         (j, anum, angle))
BLOCKSTEP_COUNTED_SETTER(dJointSetFixed, (dJointID j), (j))
BLOCKSTEP_COUNTED_SETTER(dJointSetHingeAxisOffset,
                         (dJointID j, dReal x, dReal y, dReal z, dReal angle), (j, x, y, z, angle))
BLOCKSTEP_COUNTED_SETTER(dJointSetUniversalAxis1Offset,
                         (dJointID j, dReal x, dReal y, dReal z, dReal offset1, dReal offset2),
                         (j, x, y, z, offset1, offset2))
BLOCKSTEP_COUNTED_SETTER(dJointSetUniversalAxis2Offset,
                         (dJointID j, dReal x, dReal y, dReal z, dReal offset1, dReal offset2),
                         (j, x, y, z, offset1, offset2))
#undef BLOCKSTEP_COUNTED_SETTER

// In Euler mode ODE computes the AMotor's angles while stepping: from the
// core when blockstep stepped the world. User mode angles are the
// program's own.
dReal dJointGetAMotorAngle(dJointID j, int anum) {
  BLOCKSTEP_REAL(dJointGetAMotorAngle);
  const JointState* s = dJointGetAMotorMode(j) == dAMotorEuler && anum >= 0 && anum < 3
                            ? steppedJointState(j)
                            : nullptr;
  return s ? dReal(s->angle[anum]) : real_dJointGetAMotorAngle(j, anum);
}

// Transmission state ODE computes while stepping (wheel angles, contact
// points, radii): from the core when blockstep stepped the world. ODE's
// wheel 1 (body1) is the core's B (index 1); ODE's angle is that of the
// contact point seen from the wheel, the opposite of the wheel's turn.
// A chain's radii are the program's own settings (the adapter reads them
// through these getters): those stay ODE's.
dReal dJointGetTransmissionAngle1(dJointID j) {
  BLOCKSTEP_REAL(dJointGetTransmissionAngle1);
  const JointState* s = steppedJointState(j);
  return s ? dReal(-s->angle[1]) : real_dJointGetTransmissionAngle1(j);
}

dReal dJointGetTransmissionAngle2(dJointID j) {
  BLOCKSTEP_REAL(dJointGetTransmissionAngle2);
  const JointState* s = steppedJointState(j);
  return s ? dReal(-s->angle[0]) : real_dJointGetTransmissionAngle2(j);
}

dReal dJointGetTransmissionRadius1(dJointID j) {
  BLOCKSTEP_REAL(dJointGetTransmissionRadius1);
  const JointState* s =
      dJointGetTransmissionMode(j) == dTransmissionChainDrive ? nullptr : steppedJointState(j);
  return s ? dReal(s->contactRadius[1]) : real_dJointGetTransmissionRadius1(j);
}

dReal dJointGetTransmissionRadius2(dJointID j) {
  BLOCKSTEP_REAL(dJointGetTransmissionRadius2);
  const JointState* s =
      dJointGetTransmissionMode(j) == dTransmissionChainDrive ? nullptr : steppedJointState(j);
  return s ? dReal(s->contactRadius[0]) : real_dJointGetTransmissionRadius2(j);
}

// ODE derives the ratio from the radii while stepping, except on parallel
// axes, where it is the program's setting (which the adapter reads here).
dReal dJointGetTransmissionRatio(dJointID j) {
  BLOCKSTEP_REAL(dJointGetTransmissionRatio);
  const JointState* s =
      dJointGetTransmissionMode(j) == dTransmissionParallelAxes ? nullptr : steppedJointState(j);
  return s && s->contactRadius[0] > 0.0 ? dReal(s->contactRadius[1] / s->contactRadius[0])
                                        : real_dJointGetTransmissionRatio(j);
}

void dJointGetTransmissionContactPoint1(dJointID j, dVector3 result) {
  BLOCKSTEP_REAL(dJointGetTransmissionContactPoint1);
  const JointState* s = steppedJointState(j);
  if (!s) return real_dJointGetTransmissionContactPoint1(j, result);
  for (int k = 0; k < 3; ++k)
    result[k] = s->contactPoint[1][k];
}

void dJointGetTransmissionContactPoint2(dJointID j, dVector3 result) {
  BLOCKSTEP_REAL(dJointGetTransmissionContactPoint2);
  const JointState* s = steppedJointState(j);
  if (!s) return real_dJointGetTransmissionContactPoint2(j, result);
  for (int k = 0; k < 3; ++k)
    result[k] = s->contactPoint[0][k];
}

}  // extern "C"

// What blockstep knows of the ODE objects a program made. ODE's public API
// cannot list a world's bodies, and a contact joint does not give back its
// dContact, so the ODE entry points that create and destroy objects report
// here (the plugin's interposed functions call these after the real ODE
// call). Everything else is read through ODE's getters at each step.
//
// Every hook is idempotent and tolerates objects it never saw: ODE calls
// some of these entry points itself (dWorldDestroy calls dBodyDestroy), and
// a program may have made objects before the plugin was loaded.
#pragma once

#include <ode/ode.h>

#include <memory>
#include <mutex>
#include <vector>

#include "adapters/ode/pointer_map.h"

namespace blockstep::ode {

class WorldBridge;

struct JointRecord {
  dWorldID world = nullptr;
  dJointGroupID group = nullptr;
  std::uint32_t index = 0;  // in its world's joint list
  bool hasContact = false;
  dContact contact{};  // the contact joint's data, as given to dJointCreateContact
  // LMotor axes' frames (0 world, 1 body1, 2 body2): ODE has no getter.
  int lmotorRel[3] = {0, 0, 0};
  // Plane2D motors (x, y, angle): velocity and max force. ODE has no getter.
  double plane2dVel[3] = {0.0, 0.0, 0.0};
  double plane2dFMax[3] = {0.0, 0.0, 0.0};
  // AMotor: each axis in the frame ODE keeps it in (its m_axis), and the
  // Euler-mode reference vectors ODE derives from them when they are set
  // (reference1 in body1's frame, reference2 in body2's or the world's).
  double amotorAxis[3][3] = {};
  double eulerRef1[3] = {}, eulerRef2[3] = {};
};

struct WorldRecord {
  std::vector<dBodyID> bodies;          // in creation order (ODE steps them in reverse)
  std::vector<dJointID> joints;         // every joint, contacts included
  std::unique_ptr<WorldBridge> bridge;  // the blockstep mirror, made at the first step
};

using MovedCallback = void (*)(dBodyID);

class Registry {
 public:
  Registry();
  ~Registry();

  // The process-wide registry the plugin feeds.
  static Registry& instance();

  void bodyCreated(dWorldID world, dBodyID body);
  void bodyDestroyed(dBodyID body);
  void jointCreated(dWorldID world, dJointGroupID group, dJointID joint, const dContact* contact);
  void jointDestroyed(dJointID joint);
  void groupEmptied(dJointGroupID group);
  void groupDestroyed(dJointGroupID group);
  void worldDestroyed(dWorldID world);
  void lmotorAxisSet(dJointID joint, int axis, int rel);
  void plane2dParamSet(dJointID joint, int motor, int parameter, double value);
  void amotorAxisSet(dJointID joint, int axis, int rel, const double world[3]);
  void amotorModeSet(dJointID joint);
  void movedCallbackSet(dBodyID body, MovedCallback callback);

  // nullptr for a world never seen.
  WorldRecord* world(dWorldID world);
  WorldRecord& ensureWorld(dWorldID world);
  const JointRecord* joint(dJointID joint) const { return joints_.find(joint); }
  bool knowsBody(dBodyID body) const { return bodyWorld_.find(body) != nullptr; }
  // dBodySetMovedCallback's function (ODE has no getter), or nullptr.
  MovedCallback movedCallback(dBodyID body) const {
    const BodyRecord* r = bodyWorld_.find(body);
    return r ? r->moved : nullptr;
  }

  // Hooks and steps take this lock; one step runs at a time per process.
  std::recursive_mutex& mutex() { return mutex_; }

 private:
  void removeJoint(dJointID joint, JointRecord& record);
  static void updateEulerReferences(dJointID joint, JointRecord& record);

  std::recursive_mutex mutex_;
  PointerMap<dWorldID, std::unique_ptr<WorldRecord>> worlds_;
  struct BodyRecord {
    dWorldID world = nullptr;
    std::uint32_t index = 0;
    MovedCallback moved = nullptr;
  };
  PointerMap<dBodyID, BodyRecord> bodyWorld_;
  PointerMap<dJointID, JointRecord> joints_;
  PointerMap<dJointGroupID, std::vector<dJointID>> groups_;
};

}  // namespace blockstep::ode

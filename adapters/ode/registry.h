// What blockstep knows of the ODE objects a program made. ODE's public API
// cannot list a world's bodies, and a contact joint does not give back its
// dContact, so the ODE entry points that create and destroy objects report
// here (the plugin's interposed functions call these after the real ODE
// call). Everything else is read through ODE's getters at each step.
//
// Every hook is idempotent and tolerates objects it never saw: ODE calls
// some of these entry points itself (dWorldDestroy calls dBodyDestroy), and
// a program may have made objects before the plugin was loaded.
//
// Threads. ODE lets each thread step worlds of its own, so nothing here is
// one lock for the process. The registry's maps (which world a body, joint
// or group belongs to) have a short lock of their own; each world's record
// has its own lock, held while that world is stepped or its records change.
// Lock order: a thread holding a world's lock may take the maps' lock, never
// the other way round, so a step in one world never waits on another's.
#pragma once

#include <ode/ode.h>

#include <memory>
#include <mutex>
#include <vector>

#include "adapters/ode/pointer_map.h"

namespace blockstep::ode {

class WorldBridge;

struct JointRecord {
  dJointGroupID group = nullptr;
  std::uint32_t index = 0;  // in its world's joint list
  bool hasContact = false;
  dContact contact{};  // the contact joint's data, as given to dJointCreateContact
  // How round each of the contact's geoms (g1, g2) is at the point
  // (RoundGeoms), and the body it is on: read when the joint is made,
  // while the geoms the contact names are surely alive.
  double geomRoundness[2] = {0.0, 0.0};
  dBodyID geomBody[2] = {nullptr, nullptr};
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
  // Counts the calls of the joint's setters (every dJointSet* of ODE's
  // API, dJointAttach): the bridge reads a joint again only when this
  // moved since its last read (WorldBridge::readAll).
  std::uint32_t changes = 0;
};

using MovedCallback = void (*)(dBodyID);

struct BodyRecord {
  std::uint32_t index = 0;        // in its world's body list
  MovedCallback moved = nullptr;  // dBodySetMovedCallback's (ODE has no getter)
};

// One world's objects. Read and changed only under `mutex`.
struct WorldRecord {
  explicit WorldRecord(dWorldID w) : world(w) {}

  // Recursive: a program's moved callback or ODE's own stepper may reach
  // the plugin again on the thread that holds it.
  std::recursive_mutex mutex;
  dWorldID world;
  std::vector<dBodyID> bodies;   // in creation order (ODE steps them in reverse)
  std::vector<dJointID> joints;  // every joint, contacts included
  PointerMap<dBodyID, BodyRecord> bodyRecords;
  PointerMap<dJointID, JointRecord> jointRecords;
  PointerMap<dJointGroupID, std::vector<dJointID>> groups;  // this world's joints of each group
  std::unique_ptr<WorldBridge> bridge;  // the blockstep mirror, made at the first step
  bool destroyed = false;               // dWorldDestroy came: ODE freed the bodies listed here

  const JointRecord* joint(dJointID j) const { return jointRecords.find(j); }
  JointRecord* joint(dJointID j) { return jointRecords.find(j); }
  MovedCallback movedCallback(dBodyID b) const {
    const BodyRecord* r = bodyRecords.find(b);
    return r ? r->moved : nullptr;
  }
};

class Registry {
 public:
  Registry();
  ~Registry();

  // The process-wide registry the plugin feeds.
  static Registry& instance();

  void bodyCreated(dWorldID world, dBodyID body);
  void bodyDestroyed(dBodyID body);
  void jointCreated(dWorldID world, dJointGroupID group, dJointID joint, const dContact* contact);
  // As ODE's dJointDestroy, a joint in a group stays (its group frees it).
  void jointDestroyed(dJointID joint);
  void groupEmptied(dJointGroupID group);
  void groupDestroyed(dJointGroupID group);
  void worldDestroyed(dWorldID world);
  void lmotorAxisSet(dJointID joint, int axis, int rel);
  void plane2dParamSet(dJointID joint, int motor, int parameter, double value);
  void amotorAxisSet(dJointID joint, int axis, int rel, const double world[3]);
  void amotorModeSet(dJointID joint);
  // A setter of the joint was called (JointRecord::changes).
  void jointChanged(dJointID joint);
  void movedCallbackSet(dBodyID body, MovedCallback callback);

  // The world's record (lock its mutex to use it), nullptr for a world
  // never seen; ensureWorld makes it.
  std::shared_ptr<WorldRecord> world(dWorldID world);
  std::shared_ptr<WorldRecord> ensureWorld(dWorldID world);
  // The record of the world a joint was created in, or nullptr.
  std::shared_ptr<WorldRecord> worldOfJoint(dJointID joint);

 private:
  // With maps_ held.
  std::shared_ptr<WorldRecord> worldLocked(dWorldID world);
  const std::shared_ptr<WorldRecord>& ensureLocked(dWorldID world);
  // With the world's lock held.
  void addBody(WorldRecord& w, dBodyID body);
  void removeBody(WorldRecord& w, dBodyID body);
  void removeJoint(WorldRecord& w, dJointID joint);
  void emptyGroup(dJointGroupID group, bool forget);
  template <class F>
  void withJoint(dJointID joint, F&& f);
  static void updateEulerReferences(dJointID joint, JointRecord& record);

  // Guards the four maps below only; never held while taking a world's lock.
  std::mutex maps_;
  PointerMap<dWorldID, std::shared_ptr<WorldRecord>> worlds_;
  PointerMap<dBodyID, dWorldID> bodyWorld_;
  PointerMap<dJointID, dWorldID> jointWorld_;
  // The worlds holding joints of each group (one, nearly always).
  PointerMap<dJointGroupID, std::vector<dWorldID>> groupWorlds_;
};

}  // namespace blockstep::ode

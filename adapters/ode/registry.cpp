#include "adapters/ode/registry.h"

#include "adapters/ode/geom_mapping.h"
#include "adapters/ode/world_bridge.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace blockstep::ode {

Registry::Registry() = default;
Registry::~Registry() = default;

Registry& Registry::instance() {
  // Never destroyed: ODE objects may be destroyed by static destructors of
  // the program after ours would have run.
  static Registry* registry = new Registry();
  return *registry;
}

std::shared_ptr<WorldRecord> Registry::worldLocked(dWorldID world) {
  std::shared_ptr<WorldRecord>* w = worlds_.find(world);
  return w ? *w : nullptr;
}

std::shared_ptr<WorldRecord> Registry::world(dWorldID world) {
  std::lock_guard lock(maps_);
  return worldLocked(world);
}

const std::shared_ptr<WorldRecord>& Registry::ensureLocked(dWorldID world) {
  std::shared_ptr<WorldRecord>& w = worlds_[world];
  if (!w) w = std::make_shared<WorldRecord>(world);
  return w;
}

std::shared_ptr<WorldRecord> Registry::ensureWorld(dWorldID world) {
  std::lock_guard lock(maps_);
  return ensureLocked(world);
}

std::shared_ptr<WorldRecord> Registry::worldOfJoint(dJointID joint) {
  std::lock_guard lock(maps_);
  const dWorldID* w = jointWorld_.find(joint);
  return w ? worldLocked(*w) : nullptr;
}

namespace {

// Takes `key` out of a world's list and its records by moving the list's
// last entry into its place, that entry's record index following it.
template <class Key, class Record>
void swapRemove(std::vector<Key>& list, PointerMap<Key, Record>& records, Key key) {
  const std::uint32_t index = records.find(key)->index;
  const Key last = list.back();
  list[index] = last;
  records.find(last)->index = index;
  list.pop_back();
  records.erase(key);
}

}  // namespace

// ---------------------------------------------------------------- bodies

void Registry::addBody(WorldRecord& w, dBodyID body) {
  w.bodyRecords[body] = BodyRecord{static_cast<std::uint32_t>(w.bodies.size())};
  w.bodies.push_back(body);
}

void Registry::removeBody(WorldRecord& w, dBodyID body) {
  if (!w.bodyRecords.find(body)) return;
  if (w.bridge) w.bridge->forgetBody(body);
  swapRemove(w.bodies, w.bodyRecords, body);
}

void Registry::bodyCreated(dWorldID world, dBodyID body) {
  if (!world || !body) return;
  std::shared_ptr<WorldRecord> w, stale;
  {
    std::lock_guard lock(maps_);
    if (const dWorldID* old = bodyWorld_.find(body)) stale = worldLocked(*old);  // a reused address
    bodyWorld_[body] = world;
    w = ensureLocked(world);
  }
  if (stale) {
    std::lock_guard lock(stale->mutex);
    removeBody(*stale, body);
  }
  std::lock_guard lock(w->mutex);
  addBody(*w, body);
}

void Registry::bodyDestroyed(dBodyID body) {
  std::shared_ptr<WorldRecord> w;
  {
    std::lock_guard lock(maps_);
    const dWorldID* world = bodyWorld_.find(body);
    if (!world) return;
    w = worldLocked(*world);
    bodyWorld_.erase(body);
  }
  if (!w) return;
  std::lock_guard lock(w->mutex);
  removeBody(*w, body);
}

void Registry::movedCallbackSet(dBodyID body, MovedCallback callback) {
  std::shared_ptr<WorldRecord> w;
  {
    std::lock_guard lock(maps_);
    const dWorldID* world = bodyWorld_.find(body);
    if (!world) return;
    w = worldLocked(*world);
  }
  if (!w) return;
  std::lock_guard lock(w->mutex);
  if (BodyRecord* r = w->bodyRecords.find(body)) r->moved = callback;
}

// ---------------------------------------------------------------- joints

void Registry::jointCreated(dWorldID world, dJointGroupID group, dJointID joint,
                            const dContact* contact) {
  if (!world || !joint) return;
  std::shared_ptr<WorldRecord> w, stale;
  {
    std::lock_guard lock(maps_);
    if (const dWorldID* old = jointWorld_.find(joint))
      stale = worldLocked(*old);  // a reused address
    jointWorld_[joint] = world;
    w = ensureLocked(world);
    if (group) {
      std::vector<dWorldID>& worlds = groupWorlds_[group];
      if (std::find(worlds.begin(), worlds.end(), world) == worlds.end()) worlds.push_back(world);
    }
  }
  if (stale) {
    std::lock_guard lock(stale->mutex);
    removeJoint(*stale, joint);
  }
  std::lock_guard lock(w->mutex);
  // A record still there (an address ODE gave out again) starts over.
  JointRecord& r = w->jointRecords.fresh(joint);
  r.group = group;
  r.index = static_cast<std::uint32_t>(w->joints.size());
  r.hasContact = contact != nullptr;
  if (contact) {
    r.contact = *contact;
    const dGeomID geoms[2] = {contact->geom.g1, contact->geom.g2};
    for (int k = 0; k < 2; ++k) {
      r.geomRoundness[k] = RoundGeoms::instance().roundness(geoms[k], contact->geom.normal);
      if (r.geomRoundness[k] > 0.0) r.geomBody[k] = dGeomGetBody(geoms[k]);
    }
  }
  w->joints.push_back(joint);
  if (group) w->groups[group].push_back(joint);
}

void Registry::removeJoint(WorldRecord& w, dJointID joint) {
  if (!w.jointRecords.find(joint)) return;
  if (w.bridge) w.bridge->forgetJoint(joint);
  swapRemove(w.joints, w.jointRecords, joint);
}

void Registry::jointDestroyed(dJointID joint) {
  const std::shared_ptr<WorldRecord> w = worldOfJoint(joint);
  if (!w) return;
  std::lock_guard lock(w->mutex);
  const JointRecord* r = w->joint(joint);
  if (!r || r->group) return;  // ODE leaves a grouped joint to its group
  removeJoint(*w, joint);
  std::lock_guard maps(maps_);
  const dWorldID* world = jointWorld_.find(joint);
  if (world && *world == w->world) jointWorld_.erase(joint);
}

// Each world holding joints of the group, one at a time (a world's lock is
// never taken with the maps' held).
void Registry::emptyGroup(dJointGroupID group, bool forget) {
  for (std::size_t i = 0;; ++i) {
    std::shared_ptr<WorldRecord> w;
    {
      std::lock_guard lock(maps_);
      const std::vector<dWorldID>* worlds = groupWorlds_.find(group);
      if (!worlds || i >= worlds->size()) break;
      w = worldLocked((*worlds)[i]);
    }
    if (!w) continue;  // a destroyed world's joints are gone already
    std::lock_guard lock(w->mutex);
    std::vector<dJointID>* members = w->groups.find(group);
    if (!members) continue;
    {
      std::lock_guard maps(maps_);
      for (dJointID j : *members) {
        // A joint whose address came back as a joint of another group
        // must not be taken along.
        const JointRecord* r = w->joint(j);
        if (!r || r->group != group) continue;
        removeJoint(*w, j);
        const dWorldID* world = jointWorld_.find(j);
        if (world && *world == w->world) jointWorld_.erase(j);
      }
    }
    if (forget)
      w->groups.erase(group);  // the address may come back as another group
    else
      members->clear();  // keeps its capacity: groups are emptied every step
  }
}

void Registry::groupEmptied(dJointGroupID group) {
  emptyGroup(group, false);
}

void Registry::groupDestroyed(dJointGroupID group) {
  emptyGroup(group, true);
  std::lock_guard lock(maps_);
  groupWorlds_.erase(group);
}

template <class F>
void Registry::withJoint(dJointID joint, F&& f) {
  const std::shared_ptr<WorldRecord> w = worldOfJoint(joint);
  if (!w) return;
  std::lock_guard lock(w->mutex);
  if (JointRecord* r = w->joint(joint)) f(*r);
}

void Registry::jointChanged(dJointID joint) {
  withJoint(joint, [](JointRecord& r) { ++r.changes; });
}

void Registry::lmotorAxisSet(dJointID joint, int axis, int rel) {
  if (axis < 0 || axis > 2) return;
  withJoint(joint, [&](JointRecord& r) { r.lmotorRel[axis] = rel; });
}

void Registry::plane2dParamSet(dJointID joint, int motor, int parameter, double value) {
  if (motor < 0 || motor > 2) return;
  withJoint(joint, [&](JointRecord& r) {
    if (parameter == dParamVel) r.plane2dVel[motor] = value;
    if (parameter == dParamFMax) r.plane2dFMax[motor] = value;
  });
}

namespace {

// v = R^T w for an ODE body's rotation (its frame from the world's); the
// world (b = 0) leaves it as it is.
void toBody(dBodyID b, const double w[3], double v[3]) {
  if (!b) {
    for (int i = 0; i < 3; ++i)
      v[i] = w[i];
    return;
  }
  const dReal* R = dBodyGetRotation(b);
  for (int i = 0; i < 3; ++i)
    v[i] = R[i] * w[0] + R[4 + i] * w[1] + R[8 + i] * w[2];
}
void toWorld(dBodyID b, const double v[3], double w[3]) {
  if (!b) {
    for (int i = 0; i < 3; ++i)
      w[i] = v[i];
    return;
  }
  const dReal* R = dBodyGetRotation(b);
  for (int i = 0; i < 3; ++i)
    w[i] = R[4 * i] * v[0] + R[4 * i + 1] * v[1] + R[4 * i + 2] * v[2];
}

}  // namespace

// As ODE's setAxisValue: the axis, given in world coordinates, is kept in
// the frame of the body it is relative to (rel 1: body1, 2: body2).
void Registry::amotorAxisSet(dJointID joint, int axis, int rel, const double world[3]) {
  if (axis < 0 || axis > 2) return;
  withJoint(joint, [&](JointRecord& r) {
    const dBodyID b1 = dJointGetBody(joint, 0), b2 = dJointGetBody(joint, 1);
    double* local = r.amotorAxis[axis];
    if (rel == 1 && b1) {
      toBody(b1, world, local);
    } else if (rel == 2 && b2) {
      toBody(b2, world, local);
    } else {
      for (int i = 0; i < 3; ++i)
        local[i] = world[i];
    }
    const double n = std::sqrt(local[0] * local[0] + local[1] * local[1] + local[2] * local[2]);
    if (n > 0.0) {
      for (int i = 0; i < 3; ++i)
        local[i] /= n;
    }
    updateEulerReferences(joint, r);
  });
}

void Registry::amotorModeSet(dJointID joint) {
  withJoint(joint, [&](JointRecord& r) { updateEulerReferences(joint, r); });
}

// ODE's setEulerReferenceVectors (amotor.cpp): reference2 = axis 0 (fixed
// in body1) in body2's frame, reference1 = axis 2 (fixed in body2) in
// body1's frame, the world standing in for a missing body. Attached as
// (0, body), ODE swaps its internal order and the Euler code swaps back,
// so these public roles hold either way.
void Registry::updateEulerReferences(dJointID joint, JointRecord& r) {
  if (dJointGetAMotorMode(joint) != dAMotorEuler) return;
  const dBodyID b1 = dJointGetBody(joint, 0), b2 = dJointGetBody(joint, 1);
  if (!b1 && !b2) return;
  double w[3];
  toWorld(b1, r.amotorAxis[0], w);
  toBody(b2, w, r.eulerRef2);
  toWorld(b2, r.amotorAxis[2], w);
  toBody(b1, w, r.eulerRef1);
}

// ---------------------------------------------------------------- worlds

void Registry::worldDestroyed(dWorldID world) {
  std::shared_ptr<WorldRecord> w;
  {
    std::lock_guard lock(maps_);
    w = worldLocked(world);
    if (!w) return;
    worlds_.erase(world);
  }
  // ODE frees the world's bodies and ungrouped joints and detaches the
  // grouped ones, which dJointGroupEmpty frees later: none of them may be
  // read again, so all leave the registry now. An address another thread
  // has reused since for its own world stays that world's.
  std::lock_guard lock(w->mutex);
  w->destroyed = true;
  std::lock_guard maps(maps_);
  for (dBodyID b : w->bodies) {
    const dWorldID* of = bodyWorld_.find(b);
    if (of && *of == world) bodyWorld_.erase(b);
  }
  for (dJointID j : w->joints) {
    const dWorldID* of = jointWorld_.find(j);
    if (of && *of == world) jointWorld_.erase(j);
  }
}

}  // namespace blockstep::ode

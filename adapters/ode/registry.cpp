#include "adapters/ode/registry.h"

#include "adapters/ode/world_bridge.h"

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

WorldRecord* Registry::world(dWorldID world) {
  std::unique_ptr<WorldRecord>* w = worlds_.find(world);
  return w ? w->get() : nullptr;
}

WorldRecord& Registry::ensureWorld(dWorldID world) {
  std::unique_ptr<WorldRecord>& w = worlds_[world];
  if (!w) w = std::make_unique<WorldRecord>();
  return *w;
}

void Registry::bodyCreated(dWorldID world, dBodyID body) {
  std::lock_guard lock(mutex_);
  if (!world || !body) return;
  if (bodyWorld_.find(body)) bodyDestroyed(body);  // a reused address
  WorldRecord& w = ensureWorld(world);
  bodyWorld_[body] = BodyRecord{world, static_cast<std::uint32_t>(w.bodies.size())};
  w.bodies.push_back(body);
}

void Registry::bodyDestroyed(dBodyID body) {
  std::lock_guard lock(mutex_);
  BodyRecord* record = bodyWorld_.find(body);
  if (!record) return;
  WorldRecord* w = world(record->world);
  if (w) {
    if (w->bridge) w->bridge->forgetBody(body);
    // Swap-remove, keeping the moved body's index right.
    const dBodyID last = w->bodies.back();
    w->bodies[record->index] = last;
    bodyWorld_.find(last)->index = record->index;
    w->bodies.pop_back();
  }
  bodyWorld_.erase(body);
}

void Registry::movedCallbackSet(dBodyID body, MovedCallback callback) {
  std::lock_guard lock(mutex_);
  if (BodyRecord* r = bodyWorld_.find(body)) r->moved = callback;
}

void Registry::jointCreated(dWorldID world, dJointGroupID group, dJointID joint,
                            const dContact* contact) {
  std::lock_guard lock(mutex_);
  if (!world || !joint) return;
  if (JointRecord* old = joints_.find(joint)) removeJoint(joint, *old);  // a reused address
  WorldRecord& w = ensureWorld(world);
  JointRecord& r = joints_[joint];
  r.world = world;
  r.group = group;
  r.index = static_cast<std::uint32_t>(w.joints.size());
  r.hasContact = contact != nullptr;
  if (contact) r.contact = *contact;
  w.joints.push_back(joint);
  if (group) groups_[group].push_back(joint);
}

void Registry::removeJoint(dJointID joint, JointRecord& record) {
  if (WorldRecord* w = world(record.world)) {
    if (w->bridge) w->bridge->forgetJoint(joint);
    const dJointID last = w->joints.back();
    w->joints[record.index] = last;
    joints_.find(last)->index = record.index;
    w->joints.pop_back();
  }
  joints_.erase(joint);
}

void Registry::jointDestroyed(dJointID joint) {
  std::lock_guard lock(mutex_);
  if (JointRecord* r = joints_.find(joint)) removeJoint(joint, *r);
}

void Registry::groupEmptied(dJointGroupID group) {
  std::lock_guard lock(mutex_);
  std::vector<dJointID>* members = groups_.find(group);
  if (!members) return;
  for (dJointID j : *members) {
    // A joint destroyed on its own and its address reused by a joint of
    // another group must not be taken along.
    JointRecord* r = joints_.find(j);
    if (r && r->group == group) removeJoint(j, *r);
  }
  members->clear();  // keeps its capacity: groups are emptied every step
}

void Registry::groupDestroyed(dJointGroupID group) {
  std::lock_guard lock(mutex_);
  groupEmptied(group);
  groups_.erase(group);  // the address may come back as another group
}

void Registry::lmotorAxisSet(dJointID joint, int axis, int rel) {
  std::lock_guard lock(mutex_);
  JointRecord* r = joints_.find(joint);
  if (r && axis >= 0 && axis < 3) r->lmotorRel[axis] = rel;
}

void Registry::plane2dParamSet(dJointID joint, int motor, int parameter, double value) {
  std::lock_guard lock(mutex_);
  JointRecord* r = joints_.find(joint);
  if (!r || motor < 0 || motor > 2) return;
  if (parameter == dParamVel) r->plane2dVel[motor] = value;
  if (parameter == dParamFMax) r->plane2dFMax[motor] = value;
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
  std::lock_guard lock(mutex_);
  JointRecord* r = joints_.find(joint);
  if (!r || axis < 0 || axis > 2) return;
  const dBodyID b1 = dJointGetBody(joint, 0), b2 = dJointGetBody(joint, 1);
  double* local = r->amotorAxis[axis];
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
  updateEulerReferences(joint, *r);
}

void Registry::amotorModeSet(dJointID joint) {
  std::lock_guard lock(mutex_);
  if (JointRecord* r = joints_.find(joint)) updateEulerReferences(joint, *r);
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

void Registry::worldDestroyed(dWorldID world) {
  std::lock_guard lock(mutex_);
  WorldRecord* w = this->world(world);
  if (!w) return;
  // ODE frees the world's bodies and ungrouped joints and detaches the
  // grouped ones, which dJointGroupEmpty frees later: none of them may be
  // read again, so all leave the registry now.
  for (dBodyID b : w->bodies)
    bodyWorld_.erase(b);
  for (dJointID j : w->joints)
    joints_.erase(j);
  worlds_.erase(world);
}

}  // namespace blockstep::ode

#include "adapters/ode/world_bridge.h"

#include "adapters/ode/geom_mapping.h"

#include <algorithm>
#include <cmath>

#include "adapters/ode/body_state.h"
#include "adapters/ode/registry.h"

namespace blockstep::ode {
namespace {

// ODE's default world CFM: at or below it a row counts as rigid.
constexpr double kOdeDefaultCfm = 1e-5;
// A geometry vector that moved this far in its body's frame was moved by
// the program (dJointSet*Anchor / Axis), not by rounding.
constexpr double kGeometryTolerance = 1e-7;

bool finite3(const dReal* v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

std::string bodyLabel(dBodyID b) {
  char text[64];
  std::snprintf(text, sizeof text, "body %p", static_cast<void*>(b));
  return text;
}

std::string jointLabel(dJointID j) {
  char text[96];
  std::snprintf(text, sizeof text, "%s joint %p", j ? odeJointTypeName(dJointGetType(j)) : "a",
                static_cast<void*>(j));
  return text;
}

// Joint kinds whose read (JointRead) depends on nothing but what the
// program set through setters, the world's ERP and CFM and the step: the
// bridge need not read them again while those stay. AMotor (Euler angles,
// axes in moving frames), LMotor, Plane2D and transmissions read state of
// the step or of the registry, and are read every step.
bool readsOnlySetters(int type) {
  switch (type) {
    case dJointTypeBall:
    case dJointTypeHinge:
    case dJointTypeSlider:
    case dJointTypeFixed:
    case dJointTypeUniversal:
    case dJointTypeHinge2:
    case dJointTypePiston:
    case dJointTypePR:
    case dJointTypePU:
    case dJointTypeDBall:
    case dJointTypeDHinge:
      return true;
    default:
      return false;
  }
}

// A vector in the frame of `body` (the world frame for 0).
Vec3 inBodyFrame(dBodyID body, const Vec3& v, bool point) {
  if (!body) return v;
  const dReal* q = dBodyGetQuaternion(body);
  const Quat rotation(q[0], q[1], q[2], q[3]);
  const Vec3 rel = point ? Vec3(v - vec(dBodyGetPosition(body))) : v;
  return rotation.conjugate() * rel;
}

}  // namespace

SolverSettings BridgeSettings::fromQuickStepIterations(int iterations) {
  SolverSettings s =
      SolverSettings::subStepped(std::clamp(iterations / 2, 1, SolverSettings::kMaxSubsteps));
  s.exactContactIslandSubsteps = kExactContactIslandSubsteps;
  s.exactJointIslandSubsteps = kExactJointIslandSubsteps;
  return s;
}

WorldBridge::WorldBridge(dWorldID world) : world_(world) {
  core_.setPhysicalInertiaOnly(false);  // ODE steps any positive definite inertia
}

// ODE's rows as the program set them: a CFM above ODE's default is a
// spring the program asked for, kept as that spring at any sub-step; a
// rigid row stays (ERP, CFM), which the solver's rigid-row softness
// replaces when it runs sub-steps.
Softness WorldBridge::jointSoftness(double erp, double cfm, const void* context) {
  const auto* self = static_cast<const WorldBridge*>(context);
  // ODE steps any finite pair (an ERP of 2 overshoots, a negative CFM
  // stiffens past rigid): the nearest pair in range, said once.
  if (erp < 0.0 || erp > 1.0 || cfm < 0.0) {
    erp = std::clamp(erp, 0.0, 1.0);
    cfm = std::max(cfm, 0.0);
    self->clamped_ |= kClampedSoftness;
  }
  if (cfm > kOdeDefaultCfm && erp >= 0.0 && erp <= 1.0 && std::isfinite(cfm)) {
    return Softness::fromErpCfmAt(erp, cfm, self->step_);
  }
  return Softness::erpCfm(erp, cfm);
}

// Contacts likewise; the solver does not replace a contact's softness, so
// a rigid contact takes the rigid-row softness here. (Plain ERP at each
// sub-step with warm starting made a 6-box ODE stack hop and walk off;
// with the damped rigid-row spring it stays within 0.3 mm.)
Softness WorldBridge::contactSoftness(double erp, double cfm) const {
  const Softness s = jointSoftness(erp, cfm, this);
  if (s.mode == Softness::Mode::ErpCfm && core_.settings().rigidJointSoftness) {
    return *core_.settings().rigidJointSoftness;
  }
  return s;
}

SolverSettings WorldBridge::solverFor(OdeStepper stepper) const {
  SolverSettings s = settings_.solver;
  if (settings_.followQuickStepIterations) {
    const int iterations = dWorldGetQuickStepNumIterations(world_);
    s = stepper == OdeStepper::Step ? SolverSettings::direct()
                                    : BridgeSettings::fromQuickStepIterations(iterations);
    if (stepper == OdeStepper::QuickStep && iterations / 2 > SolverSettings::kMaxSubsteps)
      clamped_ |= kClampedSubsteps;
  }
  // Set apart from the solver: they hold whichever solver the step uses.
  if (settings_.islandBlockRows) s.islandBlockRows = *settings_.islandBlockRows;
  if (settings_.chainBlocks) s.chainBlocks = *settings_.chainBlocks;
  if (settings_.islandBlockContacts) {
    s.islandBlockContacts = *settings_.islandBlockContacts == 1;
    s.islandBlockImpacts = *settings_.islandBlockContacts == 2;
  }
  if (settings_.contactIslandRows) s.contactIslandRows = *settings_.contactIslandRows;
  if (settings_.lightBodyGroups) s.lightBodyGroups = *settings_.lightBodyGroups;
  if (settings_.loadRelativeContacts) s.loadRelativeContacts = *settings_.loadRelativeContacts;
  if (settings_.impactDepth) s.impactDepth = *settings_.impactDepth;
  if (settings_.sinkingDepth) s.sinkingDepth = *settings_.sinkingDepth;
  if (settings_.retakeTurningParts) s.retakeTurningParts = *settings_.retakeTurningParts;
  if (settings_.maxTurnPerSubstep) s.maxTurnPerSubstep = *settings_.maxTurnPerSubstep;
  if (settings_.maxSurfaceTravelPerSubstep)
    s.maxSurfaceTravelPerSubstep = *settings_.maxSurfaceTravelPerSubstep;
  if (settings_.maxTurnPerRefresh) s.maxTurnPerRefresh = *settings_.maxTurnPerRefresh;
  if (settings_.relaxCancelsDrift) s.relaxCancelsDrift = *settings_.relaxCancelsDrift;
  if (settings_.positionProjections) s.positionProjections = *settings_.positionProjections;
  if (settings_.projectionTolerance) s.projectionTolerance = *settings_.projectionTolerance;
  if (settings_.threads) s.threads = *settings_.threads;
  if (settings_.exactJointIslandSubsteps)
    s.exactJointIslandSubsteps = *settings_.exactJointIslandSubsteps;
  if (settings_.exactContactIslandSubsteps)
    s.exactContactIslandSubsteps = *settings_.exactContactIslandSubsteps;
  if (settings_.calmTouchedIslandSubsteps)
    s.calmTouchedIslandSubsteps = *settings_.calmTouchedIslandSubsteps;
  if (settings_.calmApproachSpeed) s.calmApproachSpeed = *settings_.calmApproachSpeed;
  s.recordStageEnergy = settings_.recordStageEnergy;
  s.runawayEnergyGain = settings_.runawayEnergyGain;
  s.runawaySpeed = settings_.runawaySpeed;
  return s;
}

WorldBridge::MappedBody& WorldBridge::mapBody(dBodyID body) {
  MappedBody& m = bodies_[body];
  if (m.id < 0) m.id = core_.createBody(BodyDesc{});
  return m;
}

BodyId WorldBridge::coreBody(dBodyID body) {
  return body ? mapBody(body).id : kWorldBody;
}

void WorldBridge::forgetBody(dBodyID body) {
  MappedBody* m = bodies_.find(body);
  if (!m) return;
  // The core destroys the body's joints with it; their ODE joints are
  // detached (ODE keeps them) and get new core joints when reattached.
  const BodyId id = m->id;
  if (id >= 0) {
    for (JointId joint : core_.jointsOf(id)) {
      if (MappedJoint* j = joints_.find(odeJointOf_[joint])) j->id = -1;
    }
    core_.destroyBody(id);
  }
  bodies_.erase(body);
}

void WorldBridge::forgetJoint(dJointID joint) {
  MappedJoint* m = joints_.find(joint);
  if (!m) return;
  if (m->id >= 0) core_.destroyJoint(m->id);
  joints_.erase(joint);
}

// ------------------------------------------------------------------ step

StepOutcome WorldBridge::step(const WorldRecord& record, double h, OdeStepper stepper) {
  message_.clear();
  clamped_ = 0;
  if (!(h > 0.0) || !std::isfinite(h) || h > World::kMaxStep) {
    message_ = "step size " + std::to_string(h) + " s is not in (0, " +
               std::to_string(World::kMaxStep) + "]";
    return StepOutcome::Invalid;
  }
  step_ = h;
  try {
    SolverSettings solver = solverFor(stepper);
    bool gyroscopic = false;
    for (dBodyID b : record.bodies)
      gyroscopic |= dBodyGetGyroscopicMode(b) != 0;
    solver.gyroscopic = gyroscopic;
    core_.setSettings(solver);
    core_.setContactPersistence(settings_.contactPersistence);

    if (!readAll(record)) return StepOutcome::Unsupported;
    syncBodies(record);  // throws on bad body state, before ODE is touched
  } catch (const Error& e) {
    message_ = e.what();
    return StepOutcome::Invalid;
  }

  autoDisable(record, h);
  wakeIslands(record);
  try {
    syncJoints(record);
    syncShapes();
    dVector3 g;
    dWorldGetGravity(world_, g);
    core_.setGravity(vec(g));
    core_.step(h);
  } catch (const Error& e) {
    message_ = e.what();
    return StepOutcome::Invalid;
  }
  handBackRunaways(record);
  writeBack(record);
  writeFeedback(record);
  writeContactFeedback();
  return StepOutcome::Stepped;
}

// The collision space's geoms as core shapes, made, updated (a program may
// move a static geom or resize one between steps) and removed (geoms
// destroyed, disabled or taken out of the space) to match ODE's.
void WorldBridge::syncShapes() {
  CollisionSettings& collision = core_.collisionSettings();
  collision.everySubstep = settings_.collideEverySubstep;
  geoms_.forEach([](dGeomID, MappedGeom& m) { m.seen = false; });
  collisionNote_.clear();
  if (settings_.collisionSpace) {
    dContact c{};
    c.surface = settings_.collisionSurface;
    c.geom.normal[2] = 1.0;
    const MappedContact mapped = mapContact(c, kWorldBody, kWorldBody, contactParams_);
    if (mapped.unsupported) throw Error(std::string("collision surface: ") + mapped.unsupported);
    collision.surface = mapped.manifold.surface;
    clamped_ |= mapped.clamped;
    collision.surface.softness =
        contactSoftness(collision.surface.softness.erp, collision.surface.softness.cfm);
    collision.collideConnected = false;   // as ODE programs skip dAreConnected pairs
    collision.surfaceFromShapes = false;  // the program's one surface, mu2 and all
    syncSpace(settings_.collisionSpace);
  }
  goneGeoms_.clear();
  geoms_.forEach([&](dGeomID g, MappedGeom& m) {
    if (m.seen) return;
    if (m.id >= 0 && core_.shapes()[m.id].alive) core_.removeShape(m.id);
    goneGeoms_.push_back(g);
  });
  for (dGeomID g : goneGeoms_)
    geoms_.erase(g);
}

void WorldBridge::syncSpace(dSpaceID space) {
  const int n = dSpaceGetNumGeoms(space);
  for (int i = 0; i < n; ++i) {
    const dGeomID g = dSpaceGetGeom(space, i);
    if (dGeomIsSpace(g)) {
      syncSpace(reinterpret_cast<dSpaceID>(g));
      continue;
    }
    if (!dGeomIsEnabled(g)) continue;
    MappedGeom& m = geoms_[g];
    m.seen = true;
    Shape shape;
    std::string why;
    if (!shapeOfGeom(g, coreBody(dGeomGetBody(g)), shape, why)) {
      if (collisionNote_.find(why) == std::string::npos) {
        collisionNote_ +=
            (collisionNote_.empty() ? "blockstep's collision has no shape for " : ", ");
        collisionNote_ += why;
      }
      if (m.id >= 0 && core_.shapes()[m.id].alive) core_.removeShape(m.id);
      m.id = -1;
      continue;
    }
    if (m.id >= 0 && core_.shapes()[m.id].alive) {
      core_.replaceShape(m.id, shape);
    } else {
      m.id = core_.addShape(shape);
    }
  }
}

bool WorldBridge::readAll(const WorldRecord& record) {
  contactParams_ = WorldContactParams::of(world_);
  JointWorldParams params;
  params.erp = dWorldGetERP(world_);
  params.cfm = dWorldGetCFM(world_);
  params.softness = &WorldBridge::jointSoftness;
  params.context = this;
  params.clamped = &clamped_;

  reads_.resize(record.joints.size());
  readStates_.resize(record.joints.size());
  readKey_ = {params.erp, params.cfm, step_};
  pointContacts_.clear();
  contactBodies_.clear();
  contactFeedback_.clear();
  for (std::size_t i = 0; i < record.joints.size(); ++i) {
    const dJointID j = record.joints[i];
    JointRead& read = reads_[i];
    ReadState& state = readStates_[i];
    read.hasRows = false;
    read.unsupported = nullptr;
    state = ReadState{};
    const dBodyID b1 = dJointGetBody(j, 0), b2 = dJointGetBody(j, 1);
    if ((!b1 && !b2) || !dJointIsEnabled(j)) continue;
    const JointRecord* rec = record.joint(j);
    if (rec && rec->hasContact) {
      double radius[2] = {0.0, 0.0};  // body1's and body2's surfaces
      for (int k = 0; k < 2; ++k) {
        if (rec->geomRoundness[k] <= 0.0) continue;
        if (rec->geomBody[k] == b1)
          radius[0] = rec->geomRoundness[k];
        else if (rec->geomBody[k] == b2)
          radius[1] = rec->geomRoundness[k];
      }
      ContactManifold& mapped = pointContacts_.emplace_back();
      unsigned clamped = 0;
      if (const char* unsupported =
              mapContactInto(rec->contact, coreBody(b1), coreBody(b2), contactParams_, radius[0],
                             radius[1], mapped, clamped)) {
        message_ = std::string("ODE contact mode without a blockstep mapping: ") + unsupported;
        return false;
      }
      clamped_ |= clamped;
      if (dJointFeedback* fb = dJointGetFeedback(j)) {
        contactFeedback_.push_back(
            {fb, b1, b2, mapped.bodyB, mapped.bodyA, mapped.points[0].position});
      }
      Softness& soft = mapped.surface.softness;
      soft = contactSoftness(soft.erp, soft.cfm);
      contactBodies_.push_back({b1, b2});
      continue;
    }
    if (rec) {
      state.counted = true;
      state.changes = rec->changes;
      // Unchanged since the core joint was made or updated from it: no
      // setter ran, the world's ERP, CFM and step are the same, and its
      // kind reads nothing but what setters set (and the bodies' poses,
      // which the core joint follows itself).
      const MappedJoint* m = joints_.find(j);
      if (m && m->id >= 0 && m->readValid && m->readChanges == rec->changes &&
          m->readKey == readKey_ && m->body1 == b1 && m->body2 == b2 && readsOnlySetters(m->type)) {
        read.hasRows = true;
        state.unchanged = true;
        clamped_ |= m->readClamped;
        continue;
      }
    }
    JointSetOnly setOnly;
    if (rec) {
      for (int k = 0; k < 3; ++k) {
        setOnly.lmotorRel[k] = rec->lmotorRel[k];
        setOnly.plane2dVel[k] = rec->plane2dVel[k];
        setOnly.plane2dFMax[k] = rec->plane2dFMax[k];
        setOnly.amotorAxis[k] =
            Vec3(rec->amotorAxis[k][0], rec->amotorAxis[k][1], rec->amotorAxis[k][2]);
      }
      setOnly.eulerRef1 = Vec3(rec->eulerRef1[0], rec->eulerRef1[1], rec->eulerRef1[2]);
      setOnly.eulerRef2 = Vec3(rec->eulerRef2[0], rec->eulerRef2[1], rec->eulerRef2[2]);
    }
    const unsigned clampedBefore = clamped_;
    readJoint(j, coreBody(b1), coreBody(b2), params, setOnly, read);
    state.clamped = clamped_ & ~clampedBefore;
    if (read.unsupported) {
      message_ =
          std::string("ODE ") + odeJointTypeName(dJointGetType(j)) + " joint: " + read.unsupported;
      return false;
    }
  }
  return true;
}

void WorldBridge::syncBodies(const WorldRecord& record) {
  for (dBodyID b : record.bodies) {
    const BodyId id = mapBody(b).id;
    const dReal* x = dBodyGetPosition(b);
    const dReal* q = dBodyGetQuaternion(b);
    const dReal* v = dBodyGetLinearVel(b);
    const dReal* w = dBodyGetAngularVel(b);
    const dReal* f = dBodyGetForce(b);
    const dReal* t = dBodyGetTorque(b);
    if (!finite3(x) || !finite3(v) || !finite3(w) || !finite3(f) || !finite3(t) ||
        !std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]) ||
        !std::isfinite(q[3])) {
      throw Error("ODE " + bodyLabel(b) +
                  " has a non-finite position, orientation, velocity, force or torque");
    }
    dMass mass;
    dBodyGetMass(b, &mass);
    Mat3 inertia;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        inertia(r, c) = mass.I[4 * r + c];
    const Body& now = core_.body(id);
    const bool kinematic = dBodyIsKinematic(b) != 0;
    if (now.mass != mass.mass || now.inertiaBody != inertia) {
      try {
        core_.setMass(id, mass.mass, inertia);
      } catch (const Error& e) {
        // A kinematic body's mass does not matter (ODE ignores it too).
        if (!kinematic) throw Error("ODE " + bodyLabel(b) + ": " + e.what());
      }
    }
    const BodyType type = kinematic ? BodyType::Kinematic : BodyType::Dynamic;
    if (now.type != type) core_.setType(id, type);
    core_.setPosition(id, vec(x));
    core_.setOrientation(id, Quat(q[0], q[1], q[2], q[3]));
    core_.setLinearVelocity(id, vec(v));
    core_.setAngularVelocity(id, vec(w));
    core_.addForce(id, vec(f) - now.force);
    core_.addTorque(id, vec(t) - now.torque);
    core_.setGravityEnabled(id, dBodyGetGravityMode(b) != 0);
    const double maxSpeed = dBodyGetMaxAngularSpeed(b);
    core_.setMaxAngularSpeed(id, maxSpeed >= dInfinity ? kInf : maxSpeed);
    // ODE's finite rotation mode (and axis, zero for none) and per-body
    // gyroscopic mode.
    RotationUpdate rotation;
    rotation.finite = dBodyGetFiniteRotationMode(b) != 0;
    dVector3 axis;
    dBodyGetFiniteRotationAxis(b, axis);
    rotation.axis = vec(axis);
    rotation.gyroscopic = dBodyGetGyroscopicMode(b) != 0;
    if (!rotation.axis.allFinite())
      throw Error("ODE " + bodyLabel(b) + " has a non-finite finite rotation axis");
    core_.setRotationUpdate(id, rotation);
  }
}

// ODE's dInternalHandleAutoDisabling (util.cpp): a body with joints whose
// velocities, averaged over the last N samples, stay under the thresholds
// for the idle steps and the idle time is disabled, its velocities zeroed.
void WorldBridge::autoDisable(const WorldRecord& record, double h) {
  for (dBodyID b : record.bodies) {
    BodySleep& s = mapBody(b).sleep;
    const bool enabled = dBodyIsEnabled(b) != 0;
    const int samples = dBodyGetAutoDisableAverageSamplesCount(b);
    if (s.moved && s.lastStep != h) s.moved = false;  // the step size changed
    if (!s.initialized || (s.wasDisabled && enabled) || s.sampleCount != samples) {
      // New, woken by the program, or resampled: start counting afresh.
      // ODE sets a new body's countdown from the world's defaults when it
      // is created, and dBodySetAutoDisableSteps does not restart it.
      s.stepsLeft = s.initialized ? dBodyGetAutoDisableSteps(b) : dWorldGetAutoDisableSteps(world_);
      s.timeLeft = s.initialized ? dBodyGetAutoDisableTime(b) : dWorldGetAutoDisableTime(world_);
      s.initialized = true;
      s.sampleCount = samples;
      s.linear.assign(static_cast<std::size_t>(samples), Vec3::Zero());
      s.angular.assign(static_cast<std::size_t>(samples), Vec3::Zero());
      s.next = 0;
      s.ready = false;
    }
    s.wasDisabled = !enabled;
    if (!enabled || !dBodyGetAutoDisableFlag(b) || dBodyGetNumJoints(b) == 0 || samples <= 0) {
      continue;
    }
    // ODE samples the velocities. When we stepped the body last and the
    // program has not moved it since, the sample is the smaller of its
    // velocity and its motion over that step (displacement / h): the
    // sub-stepped solver's end-of-step velocity carries the compliance of
    // its soft rows (a box resting on three ODE contact points reports
    // 4 mm/s and 0.036 rad/s while it does not move), which ODE's default
    // thresholds (0.01) would never call idle, while a box set down turns
    // 0.01 rad/s over its first step and is at rest by its end.
    Vec3 linear = vec(dBodyGetLinearVel(b)), angular = vec(dBodyGetAngularVel(b));
    const dReal* q = dBodyGetQuaternion(b);
    if (s.moved && vec(dBodyGetPosition(b)) == s.lastX &&
        Quat(q[0], q[1], q[2], q[3]).coeffs() == s.lastQ.coeffs()) {
      if (s.linearSample.squaredNorm() < linear.squaredNorm()) linear = s.linearSample;
      if (s.angularSample.squaredNorm() < angular.squaredNorm()) angular = s.angularSample;
    }
    s.linear[s.next] = linear;
    s.angular[s.next] = angular;
    if (++s.next >= samples) {
      s.next = 0;
      s.ready = true;
    }
    bool idle = false;
    if (s.ready) {
      Vec3 lin = Vec3::Zero(), ang = Vec3::Zero();
      for (int i = 0; i < samples; ++i) {
        lin += s.linear[i];
        ang += s.angular[i];
      }
      lin /= samples;
      ang /= samples;
      const double linThreshold = dBodyGetAutoDisableLinearThreshold(b);
      const double angThreshold = dBodyGetAutoDisableAngularThreshold(b);
      idle = lin.squaredNorm() <= linThreshold * linThreshold &&
             ang.squaredNorm() <= angThreshold * angThreshold;
    }
    if (idle) {
      --s.stepsLeft;
      s.timeLeft -= h;
    } else {
      s.stepsLeft = dBodyGetAutoDisableSteps(b);
      s.timeLeft = dBodyGetAutoDisableTime(b);
    }
    if (s.stepsLeft <= 0 && s.timeLeft <= 0.0) {
      dBodyDisable(b);
      dBodySetLinearVel(b, 0, 0, 0);
      dBodySetAngularVel(b, 0, 0, 0);
      s.wasDisabled = true;
    }
  }
}

// ODE's island walk (util.cpp dxProcessIslands): an enabled joint between
// an enabled and a disabled body enables the disabled one, so disabled
// bodies are woken by what touches them. Its sleep counters are kept, as
// ODE keeps them.
void WorldBridge::wakeIslands(const WorldRecord& record) {
  bool changed = true;
  while (changed) {
    changed = false;
    for (dJointID j : record.joints) {
      if (!dJointIsEnabled(j)) continue;
      const dBodyID b1 = dJointGetBody(j, 0), b2 = dJointGetBody(j, 1);
      if (!b1 || !b2) continue;
      const bool e1 = dBodyIsEnabled(b1) != 0, e2 = dBodyIsEnabled(b2) != 0;
      if (e1 == e2) continue;
      dBodyID sleeper = e1 ? b2 : b1;
      dBodyEnable(sleeper);
      changed = true;
    }
  }
  for (dBodyID b : record.bodies) {
    MappedBody& m = mapBody(b);
    const bool enabled = dBodyIsEnabled(b) != 0;
    if (!enabled) {
      // A disabled body does not move: static for this step.
      core_.setType(m.id, BodyType::Static);
    } else if (m.sleep.wasDisabled) {
      m.sleep.wasDisabled = false;
    }
  }
}

JointGeometry WorldBridge::toLocal(const JointGeometry& g, dBodyID body1, dBodyID body2) const {
  JointGeometry local = g;
  for (int i = 0; i < g.count; ++i) {
    const dBodyID on = g.side[i] == 1 ? body1 : g.side[i] == 2 ? body2 : nullptr;
    local.value[i] = inBodyFrame(on, g.value[i], g.isPoint[i]);
  }
  return local;
}

bool WorldBridge::sameGeometry(const MappedJoint& m, const JointGeometry& now) const {
  if (now.count != m.local.count) return false;
  const JointGeometry local = toLocal(now, m.body1, m.body2);
  for (int i = 0; i < now.count; ++i) {
    if ((local.value[i] - m.local.value[i]).norm() > kGeometryTolerance) return false;
  }
  return true;
}

const JointState* WorldBridge::jointState(dJointID joint) const {
  const MappedJoint* m = joints_.find(joint);
  return m && m->id >= 0 ? &core_.jointState(m->id) : nullptr;
}

void WorldBridge::makeJoint(MappedJoint& m, dJointID j, JointRead& read) {
  m.type = dJointGetType(j);
  m.body1 = dJointGetBody(j, 0);
  m.body2 = dJointGetBody(j, 1);
  m.local = toLocal(read.geometry, m.body1, m.body2);
  for (int k = 0; k < 3; ++k)
    m.offset[k] = read.coordinate[k];
  shiftLimits(read.desc, m.offset);
  m.id = core_.createJoint(read.desc);
  if (odeJointOf_.size() <= static_cast<std::size_t>(m.id)) odeJointOf_.resize(m.id + 1);
  odeJointOf_[m.id] = j;
}

void WorldBridge::syncJoints(const WorldRecord& record) {
  for (std::size_t i = 0; i < record.joints.size(); ++i) {
    const dJointID j = record.joints[i];
    JointRead& read = reads_[i];
    MappedJoint* found = joints_.find(j);
    const dBodyID b1 = dJointGetBody(j, 0), b2 = dJointGetBody(j, 1);
    const bool awake = (b1 && dBodyIsEnabled(b1)) || (b2 && dBodyIsEnabled(b2));
    if (!read.hasRows || !awake) {
      if (found && found->id >= 0) core_.setJointEnabled(found->id, false);
      continue;
    }
    MappedJoint& m = found ? *found : joints_[j];
    const ReadState& state = readStates_[i];
    if (state.unchanged) {
      core_.setJointEnabled(m.id, true);
      continue;
    }
    m.readValid = false;
    if (m.id >= 0 && (m.type != dJointGetType(j) || m.body1 != b1 || m.body2 != b2 ||
                      !sameGeometry(m, read.geometry))) {
      core_.destroyJoint(m.id);
      m.id = -1;
    }
    if (m.id < 0) {
      makeJoint(m, j, read);
    } else {
      shiftLimits(read.desc, m.offset);
      core_.updateJoint(m.id, read.desc);
      core_.setJointEnabled(m.id, true);
    }
    m.readValid = state.counted;
    m.readChanges = state.changes;
    m.readKey = readKey_;
    m.readClamped = state.clamped;
  }

  for (std::size_t i = 0; i < pointContacts_.size(); ++i) {
    const auto& [b1, b2] = contactBodies_[i];
    const bool awake = (b1 && dBodyIsEnabled(b1)) || (b2 && dBodyIsEnabled(b2));
    if (!awake) pointContacts_[i].pointCount = 0;
  }
  groupContacts(pointContacts_, manifolds_, grouping_);
  for (const ContactManifold& m : manifolds_) {
    if (m.pointCount > 0) core_.addContact(m);
  }
}

// ODE's dxStepBody damping (util.cpp): after the position update, a
// velocity above its threshold is scaled by (1 - scale).
// The islands the core's runaway guard put back, and those holding a
// body it caught within the last kHoldSteps steps: their ODE bodies keep
// the state (and the accumulated forces) they had before the step, for
// the caller to step them with ODE's stepper (a diverging island caught
// and handed back for one step diverged again at once: demo_I's star
// reached 3e10 rad/s so). The message names the newly caught ones.
void WorldBridge::handBackRunaways(const WorldRecord& record) {
  runawayBodies_.clear();
  const StepStats& stats = core_.lastStepStats();
  bool holding = false;
  for (dBodyID b : record.bodies) {
    int& held = mapBody(b).heldSteps;
    if (held > 0) {
      --held;
      holding = true;
    }
  }
  if (stats.runaways.empty() && !holding) return;
  const std::size_t capacity = core_.bodyCapacity();
  handedBack_.assign(capacity, 0);
  for (BodyId id : stats.runawayBodies) {
    handedBack_[id] = 1;
  }
  if (holding) {
    // Whole islands as ODE makes them: bodies joined by enabled joints.
    islandParent_.resize(capacity);
    for (std::size_t i = 0; i < capacity; ++i)
      islandParent_[i] = static_cast<BodyId>(i);
    auto find = [&](BodyId x) {
      while (islandParent_[x] != x)
        x = islandParent_[x] = islandParent_[islandParent_[x]];
      return x;
    };
    for (dJointID j : record.joints) {
      const dBodyID b1 = dJointGetBody(j, 0), b2 = dJointGetBody(j, 1);
      if (!b1 || !b2 || !dJointIsEnabled(j)) continue;
      islandParent_[find(mapBody(b1).id)] = find(mapBody(b2).id);
    }
    for (dBodyID b : record.bodies) {
      const MappedBody& m = mapBody(b);
      if (m.heldSteps > 0) handedBack_[find(m.id)] = 2;
    }
    for (dBodyID b : record.bodies) {
      const BodyId id = mapBody(b).id;
      if (handedBack_[find(id)] == 2) handedBack_[id] = 1;
    }
    for (std::size_t i = 0; i < capacity; ++i)
      handedBack_[i] = handedBack_[i] != 0;  // roots marked 2 above
  }
  heldIds_.clear();
  for (BodyId id : stats.runawayBodies)
    handedBack_[id] = 3;  // newly caught
  for (dBodyID b : record.bodies) {
    MappedBody& m = mapBody(b);
    if (!handedBack_[m.id]) continue;
    runawayBodies_.push_back(b);
    heldIds_.push_back(m.id);
    if (handedBack_[m.id] == 3) m.heldSteps = kHoldSteps;
  }
  core_.discardStepOf(heldIds_);
  if (stats.runaways.empty()) return;
  char text[256];
  for (const RunawayIsland& r : stats.runaways) {
    if (!message_.empty()) message_ += "; ";
    const dBodyID culprit = r.culprit >= 0 ? odeBody(record, r.culprit) : nullptr;
    if (r.nonFinite) {
      std::snprintf(text, sizeof text, "an island went non-finite (first at %s)",
                    bodyLabel(culprit).c_str());
    } else if (r.fastest > core_.settings().runawaySpeed) {
      std::snprintf(text, sizeof text,
                    "an island ran away: %s reached %.3g m/s, over the runaway speed %.3g m/s",
                    bodyLabel(culprit).c_str(), r.fastest, core_.settings().runawaySpeed);
    } else if (r.sustained) {
      std::snprintf(text, sizeof text,
                    "an island ran away: its kinetic energy and the energy of its joint errors "
                    "kept growing, to %.3g J (%.3g J in the errors) where its forces and motors "
                    "explain %.3g J (%.3gx beyond, over the last steps; most gained by %s)",
                    r.energyAfter, r.errorEnergy, r.energyExplained, r.growth,
                    bodyLabel(culprit).c_str());
    } else {
      std::snprintf(text, sizeof text,
                    "an island ran away: its kinetic energy reached %.3g J where its forces, "
                    "motors and corrections explain %.3g J (%.3gx beyond, over the last steps; "
                    "most gained by %s)",
                    r.energyAfter, r.energyExplained, r.growth, bodyLabel(culprit).c_str());
    }
    message_ += text;
    message_ += "; its bodies:";
    constexpr int kNamed = 8;  // the rest are counted
    for (int k = 0; k < r.bodyCount; ++k) {
      if (k == kNamed) {
        message_ += " and " + std::to_string(r.bodyCount - kNamed) + " more";
        break;
      }
      message_ += " " + bodyLabel(odeBody(record, stats.runawayBodies[r.firstBody + k]));
    }
    message_ += "; its joints:";
    if (r.jointCount == 0) message_ += " none";
    for (int k = 0; k < r.jointCount; ++k) {
      if (k == kNamed) {
        message_ += " and " + std::to_string(r.jointCount - kNamed) + " more";
        break;
      }
      message_ += " " + jointLabel(odeJoint(record, stats.runawayJoints[r.firstJoint + k]));
    }
  }
}

dBodyID WorldBridge::odeBody(const WorldRecord& record, BodyId id) {
  for (dBodyID b : record.bodies) {
    if (mapBody(b).id == id) return b;
  }
  return nullptr;
}

dJointID WorldBridge::odeJoint(const WorldRecord& record, JointId id) const {
  for (dJointID j : record.joints) {
    const MappedJoint* m = joints_.find(j);
    if (m && m->id == id) return j;
  }
  return nullptr;
}

bool WorldBridge::handedBack(dBodyID b) {
  return b && !runawayBodies_.empty() && handedBack_[mapBody(b).id] != 0;
}

void WorldBridge::writeBack(const WorldRecord& record) {
  movedWithCallback_.clear();
  for (dBodyID b : record.bodies) {
    if (!dBodyIsEnabled(b) || handedBack(b)) continue;
    if (record.movedCallback(b)) movedWithCallback_.push_back(b);
    const Body& body = core_.body(mapBody(b).id);
    Vec3 v = body.linearVelocity, w = body.angularVelocity;
    const double linScale = dBodyGetLinearDamping(b);
    const double linThreshold = dBodyGetLinearDampingThreshold(b);
    if (linScale != 0.0 && v.squaredNorm() > linThreshold * linThreshold) v *= 1.0 - linScale;
    const double angScale = dBodyGetAngularDamping(b);
    const double angThreshold = dBodyGetAngularDampingThreshold(b);
    if (angScale != 0.0 && w.squaredNorm() > angThreshold * angThreshold) w *= 1.0 - angScale;

    // The motion over this step, for auto-disable: ODE still holds the
    // pose the step started from.
    BodySleep& sleep = mapBody(b).sleep;
    const dReal* startQ = dBodyGetQuaternion(b);
    Quat turnQ = body.orientation * Quat(startQ[0], startQ[1], startQ[2], startQ[3]).conjugate();
    if (turnQ.w() < 0.0) turnQ.coeffs() *= -1.0;  // q and -q: the same turn, the short way
    const Eigen::AngleAxisd turn(turnQ);
    sleep.linearSample = (body.position - vec(dBodyGetPosition(b))) / step_;
    sleep.angularSample = turn.axis() * (turn.angle() / step_);

    const Quat& q = body.orientation;
    const dQuaternion oq = {q.w(), q.x(), q.y(), q.z()};
    dBodySetPosition(b, body.position.x(), body.position.y(), body.position.z());
    dBodySetQuaternion(b, oq);
    dBodySetLinearVel(b, v.x(), v.y(), v.z());
    dBodySetAngularVel(b, w.x(), w.y(), w.z());
    dBodySetForce(b, 0, 0, 0);
    dBodySetTorque(b, 0, 0, 0);
    sleep.moved = true;
    sleep.lastX = body.position;
    sleep.lastQ = body.orientation;
    sleep.lastStep = step_;
  }
}

// dJointFeedback: f1/t1 act on the joint's first attached body (ODE's
// node 0: body1, or body2 when body1 is 0), torques about its centre.
void WorldBridge::writeFeedback(const WorldRecord& record) {
  for (dJointID j : record.joints) {
    dJointFeedback* out = dJointGetFeedback(j);
    if (!out || handedBack(dJointGetBody(j, 0)) || handedBack(dJointGetBody(j, 1))) continue;
    const MappedJoint* m = joints_.find(j);
    JointFeedback fb;
    if (m && m->id >= 0) fb = core_.jointFeedback(m->id);
    // ODE's f1/t1 are on its internal first body (body2 when attached as
    // (0, body)); f2/t2, written only when there is a second body, on the
    // other. Which core side each is depends on the kind's mapping.
    const dBodyID b1 = dJointGetBody(j, 0), b2 = dJointGetBody(j, 1);
    const dBodyID first = b1 ? b1 : b2;
    const bool firstIsB =
        m && m->id >= 0 && first && common(core_.joint(m->id)).bodyB == coreBody(first);
    const Vec3 f1 = firstIsB ? fb.forceB : fb.forceA, t1 = firstIsB ? fb.torqueB : fb.torqueA;
    const Vec3 f2 = firstIsB ? fb.forceA : fb.forceB, t2 = firstIsB ? fb.torqueA : fb.torqueB;
    for (int k = 0; k < 3; ++k) {
      out->f1[k] = f1[k];
      out->t1[k] = t1[k];
      if (b1 && b2) {
        out->f2[k] = f2[k];
        out->t2[k] = t2[k];
      }
    }
  }
}

// A contact joint's dJointFeedback: its point's normal and friction
// impulses summed over the step's sub-steps, as a force at the contact
// point (torques about each body's centre). ODE's one-point contacts were
// grouped into manifolds; the point is found again by its position.
void WorldBridge::writeContactFeedback() {
  const std::vector<ContactManifold>& solved = core_.contacts();
  for (const ContactFeedback& c : contactFeedback_) {
    if (handedBack(c.body1) || handedBack(c.body2)) continue;
    Vec3 onBody1 = Vec3::Zero();
    for (const ContactManifold& m : solved) {
      const bool same = m.bodyB == c.core1 && m.bodyA == c.core2;
      const bool swapped = m.bodyA == c.core1 && m.bodyB == c.core2;
      if (!same && !swapped) continue;
      for (int i = 0; i < m.pointCount; ++i) {
        const ContactPoint& p = m.points[i];
        if ((p.position - c.position).squaredNorm() > 1e-24) continue;
        const Vec3 onB = (p.stepNormalImpulse * p.normal + p.stepTangentImpulse[0] * p.tangent1 +
                          p.stepTangentImpulse[1] * p.tangent2) /
                         step_;
        onBody1 = same ? onB : Vec3(-onB);
      }
    }
    const dBodyID first = c.body1 ? c.body1 : c.body2;  // ODE's node 0
    const Vec3 f1 = c.body1 ? onBody1 : Vec3(-onBody1);
    const Vec3 t1 = (c.position - vec(dBodyGetPosition(first))).cross(f1);
    for (int k = 0; k < 3; ++k) {
      c.out->f1[k] = f1[k];
      c.out->t1[k] = t1[k];
    }
    if (c.body1 && c.body2) {
      const Vec3 t2 = (c.position - vec(dBodyGetPosition(c.body2))).cross(-onBody1);
      for (int k = 0; k < 3; ++k) {
        c.out->f2[k] = -onBody1[k];
        c.out->t2[k] = t2[k];
      }
    }
  }
}

}  // namespace blockstep::ode

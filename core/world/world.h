// The native C++ API: a world of rigid bodies and joints, stepped by the
// block Sequential-Impulses solver.
//
//   blockstep::World world;
//   BodyDesc desc;  desc.position = {0, 0, 1};
//   BodyId bob = world.createBody(desc);
//   BallJointDesc ball;  ball.common.bodyB = bob;  ball.anchor = {0, 0, 2};
//   world.createJoint(ball);
//   for (int i = 0; i < 60; ++i) world.step(1.0 / 60.0);
//
// Every call checks its input and throws blockstep::Error with a message
// naming what was wrong; a call that throws leaves the world as it was.
#pragma once

#include <vector>

#include "core/body/body.h"
#include "core/collision/collide.h"
#include "core/collision/shapes.h"
#include "core/constraints/contact.h"
#include "core/constraints/joint.h"
#include "core/constraints/joint_desc.h"
#include "core/solver/settings.h"
#include "core/solver/solver.h"
#include "core/world/error.h"

namespace blockstep {

class World {
 public:
  // Largest step accepted, s. Longer steps are a units mistake (ms for s).
  static constexpr double kMaxStep = 1.0;

  World();

  // Bodies.
  BodyId createBody(const BodyDesc& desc);
  void destroyBody(BodyId id);  // destroys the joints attached to it too
  const Body& body(BodyId id) const;
  int bodyCount() const;  // live bodies
  // One past the largest BodyId in use (ids of destroyed bodies are reused).
  std::size_t bodyCapacity() const { return bodies_.size(); }
  void setPosition(BodyId id, const Vec3& position);
  void setOrientation(BodyId id, const Quat& orientation);  // normalized here
  void setLinearVelocity(BodyId id, const Vec3& v);
  void setAngularVelocity(BodyId id, const Vec3& w);
  void setMass(BodyId id, double mass, const Mat3& inertia);
  // setMass refuses an inertia no rigid body has (a principal moment larger
  // than the other two together) unless told otherwise: ODE steps such a
  // hand-set inertia, so its adapter takes it too. Positive definiteness is
  // required either way.
  void setPhysicalInertiaOnly(bool on) { physicalInertiaOnly_ = on; }
  void setType(BodyId id, BodyType type);
  void setGravityEnabled(BodyId id, bool enabled);
  void setDamping(BodyId id, double linear, double angular);
  void setMaxAngularSpeed(BodyId id, double maxSpeed);
  void setRotationUpdate(BodyId id, const RotationUpdate& rotation);
  void addForce(BodyId id, const Vec3& force);                            // at the centre of mass
  void addTorque(BodyId id, const Vec3& torque);                          // world frame
  void addForceAtPoint(BodyId id, const Vec3& force, const Vec3& point);  // world point

  // Joints.
  JointId createJoint(const JointDesc& desc);
  void destroyJoint(JointId id);
  const JointDesc& joint(JointId id) const;
  // Replaces limits, motors, softness and break thresholds. The bodies and
  // kind must stay those of creation (a change is refused); anchors and
  // axes stay those of creation whatever desc says (the joint's frames, and
  // any geometry its rows read, were fixed then).
  void updateJoint(JointId id, const JointDesc& desc);
  void setJointEnabled(JointId id, bool enabled);
  bool jointBroken(JointId id) const;
  void repairJoint(JointId id);  // a broken joint acts again
  int jointCount() const;        // live joints
  // Force and torque the joint applied over the last step.
  JointFeedback jointFeedback(JointId id) const;
  // How far the joint is from satisfied in the current poses.
  JointError jointError(JointId id) const;
  // What the joint carries between steps and measured last (a gear's
  // wheel angles and contact points); zeros for kinds without such state.
  const JointState& jointState(JointId id) const;
  // The live joints attached to a body (in no particular order).
  const std::vector<JointId>& jointsOf(BodyId id) const {
    static const std::vector<JointId> none;
    return static_cast<std::size_t>(id) < jointsOfBody_.size() && id >= 0 ? jointsOfBody_[id]
                                                                          : none;
  }

  // Shapes and contacts. Shapes on kWorldBody are static world geometry
  // (their local pose is their world pose). Contacts found by collision,
  // and those given by addContact (for the next step only), are solved
  // with the joints; contacts() lists the last step's with their impulses,
  // sorted by body pair.
  ShapeId addShape(const Shape& shape);
  // Puts `shape` in place of shape `id` (a caller mirroring another
  // engine's geoms updates them this way); checked as addShape checks.
  void replaceShape(ShapeId id, const Shape& shape);
  void removeShape(ShapeId id);
  const std::vector<Shape>& shapes() const { return shapes_; }
  void addContact(const ContactManifold& manifold);
  const std::vector<ContactManifold>& contacts() const { return previousContacts_; }
  CollisionSettings& collisionSettings() { return collision_; }
  // Contact points of consecutive steps closer than this (m) are the same
  // point for warm starting when the caller gives no feature ids.
  void setContactMatchDistance(double d);
  // Contact persistence (off at 0): a body pair given fewer than three
  // points that cannot hold a body up by themselves (their normals pass
  // beside its centre: a coin on its rim, a hull on a corner) keeps its
  // points of earlier steps while they stay within this distance (m) of
  // touching and of where they touched, up to four points, as Bullet's
  // persistent manifolds do. Colliders that report one deepest point a
  // step (ODE's cylinder-plane, convex-convex) otherwise rock the body from
  // point to point.
  void setContactPersistence(double distance);
  double contactPersistence() const { return persistDistance_; }

  // World settings.
  void setGravity(const Vec3& g);
  const Vec3& gravity() const { return gravity_; }
  SolverSettings& settings() { return settings_; }
  const SolverSettings& settings() const { return settings_; }
  void setSettings(const SolverSettings& s);

  // Advances the world by h seconds. Checks the world first (non-finite
  // state, bad step size) and throws on bad input, leaving the world as it
  // was. An island the step leaves non-finite or running away (energy far
  // beyond what its forces, motors and corrections explain:
  // SolverSettings::runawayEnergyGain, runawaySpeed) is put back as it was
  // before the step, and lastStepStats().runaways names it; the other
  // islands keep their step.
  void step(double h);
  const StepStats& lastStepStats() const { return stats_; }
  // Puts these bodies back as they were before the last step and drops
  // the impulses their joints and contacts would warm start from (the
  // caller steps them another way: the ODE plugin hands runaway islands to
  // ODE's stepper for a while).
  void discardStepOf(const std::vector<BodyId>& ids);
  double lastStepSize() const { return lastStep_; }

 private:
  Body& mutableBody(BodyId id);
  Joint& mutableJoint(JointId id);
  const Joint& liveJoint(JointId id) const;
  const Body& endpoint(BodyId id) const;
  void validateSettings(const SolverSettings& s) const;
  Shape checkedShape(const Shape& shape) const;
  void checkStateBeforeStep(double h) const;
  void collide(double h);         // for a step of h seconds until the next collision
  double timedCollide(double h);  // collide(h), returning the seconds it took
  void prepareContacts();
  void carryContactPoints();
  void restoreRunaways();
  void keepContactsForNextStep();
  void stepCollidingEachSubstep(double h);
  double surfaceTurnRate(const std::vector<ContactManifold>& contacts);
  // The bodies at a part's start, to take it again (retakeTurningParts).
  void savePartStart();
  void restorePartStart();

  bool physicalInertiaOnly_ = true;
  struct Saved {
    Vec3 x, v, w;
    Quat q;
  };

  std::vector<Body> bodies_;
  std::vector<Joint> joints_;
  // Per body id, its live joints: destroying a body destroys them without
  // looking through every joint (a world's bodies destroyed one by one
  // took time quadratic in its size).
  std::vector<std::vector<JointId>> jointsOfBody_;
  std::vector<BodyId> freeBodies_;
  std::uint64_t bodiesMade_ = 0;  // Body::serial of the last one made
  std::vector<JointId> freeJoints_;
  std::vector<Saved> saved_;
  std::vector<Saved> partStart_;        // collision every sub-step: the bodies before a part
  std::vector<std::uint8_t> restored_;  // marks, while discardStepOf() runs
  std::vector<Shape> shapes_;
  std::vector<ContactManifold> contacts_;          // this step's
  std::vector<ContactManifold> previousContacts_;  // the last step's, sorted by body pair
  // keepContactsForNextStep's sort: (pair key, index), and the manifolds
  // gathered in that order.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keptOrder_;
  std::vector<ContactManifold> sortedContacts_;
  std::vector<std::uint64_t> jointedPairs_;
  std::vector<std::int32_t> contactOrder_;  // this step's manifolds by body pair (prepareContacts)
  CollisionSettings collision_;
  Collider collider_;
  double matchDistance_ = 0.02;
  double persistDistance_ = 0.0;
  std::vector<std::uint8_t> carriedOld_;  // per old point: carried this step (prepareContacts)
  Body worldBody_;
  Vec3 gravity_ = Vec3(0.0, 0.0, -9.81);
  SolverSettings settings_;
  Solver solver_;
  StepStats stats_;
  // Collision every sub-step (stepCollidingEachSubstep): the contacts the
  // caller added, one part's stats, and the bodies held still after the
  // guard caught them in an earlier part, with their own type.
  std::vector<ContactManifold> callerContacts_;
  StepStats partStats_;
  std::vector<std::pair<BodyId, BodyType>> heldTypes_;
  std::vector<std::uint8_t> touching_;  // per body: in a contact of the last part (surfaceTurnRate)
  double lastStep_ = 0.0;
  int liveBodies_ = 0;
  int liveJoints_ = 0;
};

}  // namespace blockstep

#include "core/world/world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <variant>

#include <Eigen/Eigenvalues>

#include "core/constraints/joint_kinds.h"

namespace blockstep {
namespace {

std::string bodyName(BodyId id) {
  return "body " + std::to_string(id);
}
std::string jointName(JointId id) {
  return "joint " + std::to_string(id);
}

void requireFiniteVec(const Vec3& v, const std::string& what) {
  if (!v.allFinite()) throw Error(what + " is not finite");
}
// The per-body form builds its message only on failure: the ODE adapter
// sets every body's state every step, and steps must not allocate.
void requireFiniteVec(const Vec3& v, BodyId id, const char* what) {
  if (!v.allFinite()) throw Error(bodyName(id) + " " + what + " is not finite");
}

void validateInertia(double mass, const Mat3& inertia, const std::string& who,
                     bool physicalOnly = true) {
  if (!(mass > 0.0) || !std::isfinite(mass)) {
    throw Error(who + ": mass must be positive and finite, got " + std::to_string(mass));
  }
  if (!inertia.allFinite()) throw Error(who + ": inertia is not finite");
  if ((inertia - inertia.transpose()).cwiseAbs().maxCoeff() >
      1e-9 * inertia.cwiseAbs().maxCoeff()) {
    throw Error(who + ": inertia is not symmetric");
  }
  // Positive definite, and a physical body: each principal moment is at
  // most the sum of the other two (triangle inequality).
  Eigen::SelfAdjointEigenSolver<Mat3> eig(inertia);
  const Vec3 m = eig.eigenvalues();
  if (!(m.minCoeff() > 0.0)) {
    throw Error(who + ": inertia is not positive definite (smallest principal moment " +
                std::to_string(m.minCoeff()) + ")");
  }
  const double slack = 1e-6 * m.maxCoeff();
  if (physicalOnly && m[2] > m[0] + m[1] + slack) {
    throw Error(who + ": inertia violates the triangle inequality (no rigid body has it)");
  }
}

// Puts `item` in a freed slot if there is one (ids stay small and stable),
// else at the end.
template <class T, class Id>
Id storeInSlot(std::vector<T>& items, std::vector<Id>& freeSlots, const T& item) {
  if (freeSlots.empty()) {
    items.push_back(item);
    return static_cast<Id>(items.size() - 1);
  }
  const Id id = freeSlots.back();
  freeSlots.pop_back();
  items[id] = item;
  return id;
}

}  // namespace

World::World() {
  worldBody_.type = BodyType::Static;
  worldBody_.invMass = 0.0;
  worldBody_.invInertiaBody = Mat3::Zero();
}

// ---------------------------------------------------------------- bodies

namespace {
// The axis of a finite rotation: zero or a finite direction, made unit.
// `who()` names the body, only when there is an error to name it in (the
// adapter sets every body's rotation update at every step).
template <class Who>
RotationUpdate checkedRotation(const RotationUpdate& r, Who who) {
  RotationUpdate out = r;
  if (!r.axis.allFinite()) throw Error(who() + ": finite rotation axis must be finite");
  const double n = r.axis.norm();
  if (n > 0.0 && n < 1e-9) throw Error(who() + ": finite rotation axis is too short");
  if (n > 0.0) out.axis /= n;
  return out;
}
}  // namespace

BodyId World::createBody(const BodyDesc& d) {
  const std::string who = "new body";
  requireFiniteVec(d.position, who + " position");
  requireFiniteVec(d.linearVelocity, who + " linear velocity");
  requireFiniteVec(d.angularVelocity, who + " angular velocity");
  if (!isFinite(d.orientation) || d.orientation.norm() < 1e-9) {
    throw Error(who + ": orientation must be a finite, non-zero quaternion");
  }
  if (d.type == BodyType::Dynamic) validateInertia(d.mass, d.inertia, who);
  if (!(d.linearDamping >= 0.0) || !(d.angularDamping >= 0.0) || !std::isfinite(d.linearDamping) ||
      !std::isfinite(d.angularDamping)) {
    throw Error(who + ": damping must be >= 0 and finite");
  }
  if (!(d.maxAngularSpeed >= 0.0)) throw Error(who + ": max angular speed must be >= 0");

  Body b;
  b.serial = ++bodiesMade_;
  b.type = d.type;
  b.position = d.position;
  b.orientation = d.orientation.normalized();
  b.linearVelocity = d.type == BodyType::Static ? Vec3::Zero() : d.linearVelocity;
  b.angularVelocity = d.type == BodyType::Static ? Vec3::Zero() : d.angularVelocity;
  b.gravity = d.gravity;
  b.linearDamping = d.linearDamping;
  b.angularDamping = d.angularDamping;
  b.maxAngularSpeed = d.maxAngularSpeed;
  b.rotation = checkedRotation(d.rotation, [&] { return who; });
  if (d.type == BodyType::Dynamic) {
    b.mass = d.mass;
    b.invMass = 1.0 / d.mass;
    b.inertiaBody = d.inertia;
    b.invInertiaBody = d.inertia.inverse();
  } else {
    b.mass = 0.0;
    b.invMass = 0.0;
    b.inertiaBody = Mat3::Zero();
    b.invInertiaBody = Mat3::Zero();
  }
  ++liveBodies_;
  return storeInSlot(bodies_, freeBodies_, b);
}

Body& World::mutableBody(BodyId id) {
  if (id < 0 || id >= static_cast<BodyId>(bodies_.size()) || !bodies_[id].alive) {
    throw Error("no " + bodyName(id) + " in this world");
  }
  return bodies_[id];
}

const Body& World::body(BodyId id) const {
  return const_cast<World*>(this)->mutableBody(id);
}

const Body& World::endpoint(BodyId id) const {
  return id == kWorldBody ? worldBody_ : body(id);
}

int World::bodyCount() const {
  return liveBodies_;
}

void World::destroyBody(BodyId id) {
  mutableBody(id);
  for (Shape& shape : shapes_) {
    if (shape.alive && shape.body == id) shape.alive = false;
  }
  // Its contacts must not warm start a body that reuses the id.
  std::erase_if(previousContacts_,
                [id](const ContactManifold& m) { return m.bodyA == id || m.bodyB == id; });
  if (static_cast<std::size_t>(id) < jointsOfBody_.size()) {
    while (!jointsOfBody_[id].empty())
      destroyJoint(jointsOfBody_[id].back());
  }
  bodies_[id].alive = false;
  freeBodies_.push_back(id);
  --liveBodies_;
}

void World::setPosition(BodyId id, const Vec3& p) {
  requireFiniteVec(p, id, "position");
  mutableBody(id).position = p;
}

void World::setOrientation(BodyId id, const Quat& q) {
  if (!isFinite(q) || q.norm() < 1e-9) {
    throw Error(bodyName(id) + " orientation must be a finite, non-zero quaternion");
  }
  mutableBody(id).orientation = q.normalized();
}

void World::setLinearVelocity(BodyId id, const Vec3& v) {
  requireFiniteVec(v, id, "linear velocity");
  Body& b = mutableBody(id);
  if (b.type != BodyType::Static) b.linearVelocity = v;
}

void World::setAngularVelocity(BodyId id, const Vec3& w) {
  requireFiniteVec(w, id, "angular velocity");
  Body& b = mutableBody(id);
  if (b.type != BodyType::Static) b.angularVelocity = w;
}

void World::setMass(BodyId id, double mass, const Mat3& inertia) {
  Body& b = mutableBody(id);
  validateInertia(mass, inertia, bodyName(id), physicalInertiaOnly_);
  b.mass = mass;
  b.inertiaBody = inertia;
  if (b.isDynamic()) {
    b.invMass = 1.0 / mass;
    b.invInertiaBody = inertia.inverse();
  }
}

void World::setType(BodyId id, BodyType type) {
  Body& b = mutableBody(id);
  if (type == BodyType::Dynamic && !(b.mass > 0.0)) {
    throw Error(bodyName(id) + " has no mass: call setMass before making it dynamic");
  }
  b.type = type;
  if (type == BodyType::Dynamic) {
    b.invMass = 1.0 / b.mass;
    b.invInertiaBody = b.inertiaBody.inverse();
  } else {
    b.invMass = 0.0;
    b.invInertiaBody = Mat3::Zero();
    if (type == BodyType::Static) {
      b.linearVelocity.setZero();
      b.angularVelocity.setZero();
    }
  }
}

void World::setGravityEnabled(BodyId id, bool enabled) {
  mutableBody(id).gravity = enabled;
}

void World::setDamping(BodyId id, double linear, double angular) {
  if (!(linear >= 0.0) || !(angular >= 0.0) || !std::isfinite(linear) || !std::isfinite(angular)) {
    throw Error(bodyName(id) + " damping must be >= 0 and finite");
  }
  Body& b = mutableBody(id);
  b.linearDamping = linear;
  b.angularDamping = angular;
}

void World::setRotationUpdate(BodyId id, const RotationUpdate& rotation) {
  mutableBody(id).rotation = checkedRotation(rotation, [id] { return bodyName(id); });
}

void World::setMaxAngularSpeed(BodyId id, double maxSpeed) {
  if (!(maxSpeed >= 0.0)) throw Error(bodyName(id) + " max angular speed must be >= 0");
  mutableBody(id).maxAngularSpeed = maxSpeed;
}

void World::addForce(BodyId id, const Vec3& f) {
  requireFiniteVec(f, id, "force");
  mutableBody(id).force += f;
}

void World::addTorque(BodyId id, const Vec3& t) {
  requireFiniteVec(t, id, "torque");
  mutableBody(id).torque += t;
}

void World::addForceAtPoint(BodyId id, const Vec3& f, const Vec3& p) {
  requireFiniteVec(f, id, "force");
  requireFiniteVec(p, id, "force point");
  Body& b = mutableBody(id);
  b.force += f;
  b.torque += (p - b.position).cross(f);
}

// ---------------------------------------------------------------- joints

JointId World::createJoint(const JointDesc& desc) {
  JointDesc d = desc;
  std::visit([](const auto& j) { validateJoint(j); }, d);
  const JointCommon& c = common(d);
  const Body& a = endpoint(c.bodyA);
  const Body& b = endpoint(c.bodyB);
  Joint joint;
  joint.frames = std::visit([&](auto& j) { return setupJoint(j, a, b); }, d);
  if (c.anchorOnB) {
    const bool madeAtAnAnchor = std::holds_alternative<BallJointDesc>(d) ||
                                std::holds_alternative<HingeJointDesc>(d) ||
                                std::holds_alternative<UniversalJointDesc>(d) ||
                                std::holds_alternative<ConeTwistJointDesc>(d) ||
                                std::holds_alternative<SixDofJointDesc>(d) ||
                                std::holds_alternative<PrismaticRotoideJointDesc>(d) ||
                                std::holds_alternative<PrismaticUniversalJointDesc>(d);
    if (!madeAtAnAnchor || !c.anchorOnB->allFinite())
      throw Error(std::string(jointKindName(d)) + " joint: anchorOnB " +
                  (madeAtAnAnchor ? "is not finite" : "is for joints made at an anchor point"));
    joint.frames.localAnchorB = b.localPoint(*c.anchorOnB);
  }
  joint.desc = d;
  ++liveJoints_;
  const JointId id = storeInSlot(joints_, freeJoints_, joint);
  for (BodyId body : {c.bodyA, c.bodyB == c.bodyA ? kWorldBody : c.bodyB}) {
    if (body == kWorldBody) continue;
    if (jointsOfBody_.size() <= static_cast<std::size_t>(body)) jointsOfBody_.resize(body + 1);
    jointsOfBody_[body].push_back(id);
  }
  return id;
}

Joint& World::mutableJoint(JointId id) {
  if (id < 0 || id >= static_cast<JointId>(joints_.size()) || !joints_[id].alive) {
    throw Error("no " + jointName(id) + " in this world");
  }
  return joints_[id];
}

const Joint& World::liveJoint(JointId id) const {
  return const_cast<World*>(this)->mutableJoint(id);
}

void World::destroyJoint(JointId id) {
  Joint& j = mutableJoint(id);
  const JointCommon& c = common(j.desc);
  for (BodyId body : {c.bodyA, c.bodyB}) {
    if (body == kWorldBody || static_cast<std::size_t>(body) >= jointsOfBody_.size()) continue;
    std::vector<JointId>& list = jointsOfBody_[body];
    const auto at = std::find(list.begin(), list.end(), id);
    if (at != list.end()) {
      *at = list.back();
      list.pop_back();
    }
  }
  j.alive = false;
  j.block = -1;
  freeJoints_.push_back(id);
  --liveJoints_;
}

const JointDesc& World::joint(JointId id) const {
  return liveJoint(id).desc;
}

void World::updateJoint(JointId id, const JointDesc& desc) {
  Joint& j = mutableJoint(id);
  if (desc.index() != j.desc.index()) {
    throw Error(jointName(id) + " is a " + jointKindName(j.desc) +
                " joint; cannot update it as a " + jointKindName(desc) + " joint");
  }
  const JointCommon &now = common(j.desc), &next = common(desc);
  if (now.bodyA != next.bodyA || now.bodyB != next.bodyB) {
    throw Error(jointName(id) + ": its bodies cannot change (destroy it and create another)");
  }
  std::visit([](const auto& d) { validateJoint(d); }, desc);
  const JointDesc made = j.desc;
  j.desc = desc;
  std::visit(
      [&made](auto& updated) {
        keepCreationGeometry(updated, std::get<std::decay_t<decltype(updated)>>(made));
      },
      j.desc);
}

void World::setJointEnabled(JointId id, bool enabled) {
  mutableJoint(id).enabled = enabled;
}

bool World::jointBroken(JointId id) const {
  return liveJoint(id).broken;
}

void World::repairJoint(JointId id) {
  mutableJoint(id).broken = false;
}

int World::jointCount() const {
  return liveJoints_;
}

JointFeedback World::jointFeedback(JointId id) const {
  const Joint& j = liveJoint(id);
  if (lastStep_ <= 0.0) return JointFeedback{};
  return solver_.feedback(j, lastStep_);
}

const JointState& World::jointState(JointId id) const {
  return liveJoint(id).state;
}

JointError World::jointError(JointId id) const {
  const Joint& j = liveJoint(id);
  const JointCommon& c = common(j.desc);
  const Body& a = endpoint(c.bodyA);
  const Body& b = endpoint(c.bodyB);
  const JointPose pose =
      JointPose::make(a.position, a.orientation, b.position, b.orientation, j.frames);
  std::array<ConstraintRow, kMaxJointSlots> rows;
  RowWriter out(rows.data());
  JointState state = j.state;  // measuring must not advance it
  std::visit([&](const auto& d) { buildJointRows(d, pose, state, out); }, j.desc);
  out.finish();
  const int ne = out.equalityCount();
  double linSq = 0.0, angSq = 0.0, linLimit = 0.0, angLimit = 0.0;
  for (int i = 0; i < ne; ++i) {
    const ConstraintRow& r = rows[i];
    (r.angular ? angSq : linSq) += r.C * r.C;
  }
  for (int i = ne; i < ne + out.boundedCount(); ++i) {
    const ConstraintRow& r = rows[i];
    if (r.biasKind != RowBias::Speculative || r.C >= 0.0) continue;
    double& worst = r.angular ? angLimit : linLimit;
    worst = std::max(worst, -r.C);
  }
  return JointError{std::max(std::sqrt(linSq), linLimit), std::max(std::sqrt(angSq), angLimit)};
}

// ---------------------------------------------------------------- settings

void World::setGravity(const Vec3& g) {
  requireFiniteVec(g, "gravity");
  gravity_ = g;
}

void World::validateSettings(const SolverSettings& s) const {
  if (s.iterations < 1 || s.iterations > SolverSettings::kMaxIterations)
    throw Error("solver iterations must be in [1, " +
                std::to_string(SolverSettings::kMaxIterations) + "]");
  if (s.substeps < 1 || s.substeps > SolverSettings::kMaxSubsteps)
    throw Error("sub-steps must be in [1, " + std::to_string(SolverSettings::kMaxSubsteps) + "]");
  if (s.relaxIterations < 0 || s.relaxIterations > SolverSettings::kMaxIterations)
    throw Error("relax iterations must be in [0, " +
                std::to_string(SolverSettings::kMaxIterations) + "]");
  if (!(s.maxTurnPerSubstep >= 0.0) || !std::isfinite(s.maxTurnPerSubstep))
    throw Error("the turn per sub-step must be >= 0 and finite (0: a fixed sub-step count)");
  if (!(s.maxSurfaceTravelPerSubstep >= 0.0) || !std::isfinite(s.maxSurfaceTravelPerSubstep))
    throw Error("the surface travel per sub-step must be >= 0 and finite (0: the turn only)");
  if (!(s.impactDepth >= 0.0) || !std::isfinite(s.impactDepth))
    throw Error("the impact depth must be >= 0 and finite (0: no impact groups)");
  if (!(s.sinkingDepth >= 0.0) || !std::isfinite(s.sinkingDepth))
    throw Error("the sinking depth must be >= 0 and finite (0: no sinking groups)");
  if (s.threads < 0 || s.threads > SolverSettings::kMaxThreads)
    throw Error("threads must be in [0, " + std::to_string(SolverSettings::kMaxThreads) +
                "] (0: one per core)");
  if (s.maxSubstepFactor < 1 || s.maxSubstepFactor > SolverSettings::kMaxSubsteps)
    throw Error("the sub-step factor must be in [1, " +
                std::to_string(SolverSettings::kMaxSubsteps) + "]");
  if (s.rigidJointSoftness && !s.rigidJointSoftness->valid()) {
    throw Error("rigid joint softness is invalid (ERP in [0, 1], CFM >= 0, frequencies > 0)");
  }
  if (!(s.tolerance >= 0.0) || !std::isfinite(s.tolerance)) {
    throw Error("solver tolerance must be >= 0 and finite");
  }
  if (!(s.timeBudget >= 0.0) || !std::isfinite(s.timeBudget)) {
    throw Error("solver time budget must be >= 0 and finite");
  }
}

void World::setSettings(const SolverSettings& s) {
  validateSettings(s);
  settings_ = s;
}

// ---------------------------------------------------------------- step

void World::checkStateBeforeStep(double h) const {
  if (!std::isfinite(h) || !(h > 0.0) || h > kMaxStep) {
    throw Error("step size must be in (0, " + std::to_string(kMaxStep) + "] s, got " +
                std::to_string(h));
  }
  validateSettings(settings_);
  for (BodyId i = 0; i < static_cast<BodyId>(bodies_.size()); ++i) {
    const Body& b = bodies_[i];
    if (!b.alive) continue;
    if (!b.position.allFinite() || !isFinite(b.orientation) || !b.linearVelocity.allFinite() ||
        !b.angularVelocity.allFinite()) {
      throw Error(bodyName(i) + " has a non-finite position, orientation or velocity");
    }
    if (!b.force.allFinite() || !b.torque.allFinite()) {
      throw Error(bodyName(i) + " has a non-finite force or torque");
    }
  }
}

void World::step(double h) {
  checkStateBeforeStep(h);
  saved_.resize(bodies_.size());
  restored_.resize(bodies_.size(), 0);
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const Body& b = bodies_[i];
    saved_[i] = Saved{b.position, b.linearVelocity, b.angularVelocity, b.orientation};
  }
  // Sized once; a later step with the same settings does not allocate.
  if (settings_.recordResiduals)
    stats_.residuals.reserve(static_cast<std::size_t>(Solver::mostSubsteps(settings_)) *
                             settings_.iterations);
  stats_.brokenJoints.reserve(joints_.size());
  stats_.deepestFound = 0.0;

  if (collision_.everySubstep && settings_.substeps > 1) {
    stepCollidingEachSubstep(h);
  } else {
    stats_.collideSeconds = timedCollide(h);
    prepareContacts();
    solver_.step(StepInput{bodies_, joints_, contacts_, worldBody_, gravity_, h}, settings_,
                 stats_);
    keepContactsForNextStep();
  }
  lastStep_ = h;
  restoreRunaways();
}

void World::keepContactsForNextStep() {
  previousContacts_.swap(contacts_);
  contacts_.clear();
  // The collider gives pairs in shape order, often body order already. A
  // manifold is over 1 kB: sorting them in place (swaps) cost 9% of dense
  // hair's step, so the keys are sorted and each manifold moved once.
  auto byBodies = [](const ContactManifold& x, const ContactManifold& y) {
    return bodyPairKey(x.bodyA, x.bodyB) < bodyPairKey(y.bodyA, y.bodyB);
  };
  if (std::is_sorted(previousContacts_.begin(), previousContacts_.end(), byBodies)) return;
  keptOrder_.clear();
  for (std::size_t i = 0; i < previousContacts_.size(); ++i) {
    const ContactManifold& m = previousContacts_[i];
    keptOrder_.emplace_back(bodyPairKey(m.bodyA, m.bodyB), static_cast<std::uint32_t>(i));
  }
  std::sort(keptOrder_.begin(), keptOrder_.end());
  sortedContacts_.clear();
  for (const auto& [key, i] : keptOrder_)
    sortedContacts_.push_back(previousContacts_[i]);
  previousContacts_.swap(sortedContacts_);
}

// Collision every sub-step: the step runs in parts of one sub-step each,
// each colliding the shapes where the bodies now are, so a fast body
// meets what is in front of it at the sub-step's resolution rather than
// the frame's (cloth cells at 60 Hz reach 50 mm into a cube between two
// frame collisions). A part is the settings' sub-step, or shorter (down
// to maxSubstepFactor times) while a body in contact turns fast
// (surfaceTurnRate). A part whose own solve spins a touching body up past
// that turn is taken again from its start, shorter, once
// (SolverSettings::retakeTurningParts): its contacts were linearized
// where the body was, and it turned through what it touches within that
// very part. So is a part (at its length) whose solve sent a shape
// farther than its collision reached (Collider::outranReach): a body
// struck or spun up went into one it had no contact with; taken again,
// each shape reaches as far as its solved speed carries it, so those
// contacts come in speculatively. Contacts the caller added (addContact)
// hold for every part; forces act on every part; contacts push out of
// penetration no faster than over the whole step (Solver::penetrationRate). An island
// the guard catches in one part is put back as it was before the whole
// step and held still (made static) for the parts that remain.
void World::stepCollidingEachSubstep(double h) {
  const double nominal = h / settings_.substeps;
  SolverSettings part = settings_;
  part.substeps = 1;
  callerContacts_.assign(contacts_.begin(), contacts_.end());
  stats_.iterations = 0;
  stats_.collideSeconds = stats_.solveSeconds = stats_.stepSeconds = 0.0;
  stats_.residuals.clear();
  stats_.stageEnergy.clear();
  stats_.brokenJoints.clear();
  stats_.runaways.clear();
  stats_.runawayBodies.clear();
  stats_.runawayJoints.clear();
  stats_.retakenParts = 0;
  stats_.sinkingGroups = 0;
  heldTypes_.clear();
  double done = 0.0;
  double longest = nominal / Solver::substepsAt(part, nominal, surfaceTurnRate(previousContacts_));
  const double shortest = nominal / Solver::mostSubsteps(part);
  bool retaken = false;
  int k = 0;
  for (bool last = false; !last; ++k) {
    // The part: the remaining time in equal parts no longer than the
    // turn allows (Solver::substepsAt: nominal / factor at the most).
    const double remaining = h - done;
    const double pieces = std::max(1.0, std::ceil(remaining / longest - 1e-9));
    last = pieces <= 1.0;
    const double hp = last ? remaining : remaining / pieces;
    if (settings_.timeBudget > 0.0) part.timeBudget = settings_.timeBudget * hp / h;
    if (k > 0) contacts_.assign(callerContacts_.begin(), callerContacts_.end());
    const double collideSeconds = timedCollide(hp);
    prepareContacts();
    StepInput in{bodies_, joints_, contacts_, worldBody_, gravity_, hp};
    in.penetrationStep = h;
    in.nominalSubstep = nominal;
    in.firstFreshContact = static_cast<std::int32_t>(callerContacts_.size());
    in.clearForces = false;  // every part's; cleared after the last
    if (settings_.retakeTurningParts) savePartStart();
    solver_.step(in, part, partStats_);
    // A retaken part's time counts too.
    stats_.collideSeconds += collideSeconds;
    stats_.solveSeconds += partStats_.solveSeconds;
    stats_.stepSeconds += partStats_.stepSeconds;
    const double turnRate = surfaceTurnRate(contacts_);
    const bool mayRetake = settings_.retakeTurningParts && !retaken &&
                           partStats_.runaways.empty() && partStats_.brokenJoints.empty();
    const bool turnedPast =
        hp > shortest * (1.0 + 1e-9) && turnRate * hp > settings_.maxTurnPerSubstep;
    // Called first: it keeps the solved speeds for the retaken part's reach.
    const bool outran = mayRetake && collider_.outranReach(shapes_, bodies_, collision_, hp);
    if (mayRetake && (turnedPast || outran)) {
      restorePartStart();
      retaken = true;
      ++stats_.retakenParts;
      longest = nominal / Solver::substepsAt(part, nominal, turnRate);
      last = false;
      continue;
    }
    retaken = false;
    done += hp;
    keepContactsForNextStep();
    longest = nominal / Solver::substepsAt(part, nominal, turnRate);

    stats_.iterations += partStats_.iterations;
    stats_.sinkingGroups += partStats_.sinkingGroups;
    stats_.islands = partStats_.islands;
    stats_.blocks = partStats_.blocks;
    stats_.rows = partStats_.rows;
    for (ResidualSample r : partStats_.residuals) {
      r.substep = k - stats_.retakenParts;
      stats_.residuals.push_back(r);
    }
    // Each part is one sub-step of the whole step (a retaken one's
    // samples are left out, as its motion is).
    for (StageEnergySample e : partStats_.stageEnergy) {
      e.substep = k - stats_.retakenParts;
      stats_.stageEnergy.push_back(e);
    }
    stats_.brokenJoints.insert(stats_.brokenJoints.end(), partStats_.brokenJoints.begin(),
                               partStats_.brokenJoints.end());
    if (partStats_.runaways.empty()) continue;
    const auto bodyBase = static_cast<std::int32_t>(stats_.runawayBodies.size());
    const auto jointBase = static_cast<std::int32_t>(stats_.runawayJoints.size());
    for (RunawayIsland island : partStats_.runaways) {
      island.firstBody += bodyBase;
      island.firstJoint += jointBase;
      stats_.runaways.push_back(island);
    }
    stats_.runawayBodies.insert(stats_.runawayBodies.end(), partStats_.runawayBodies.begin(),
                                partStats_.runawayBodies.end());
    stats_.runawayJoints.insert(stats_.runawayJoints.end(), partStats_.runawayJoints.begin(),
                                partStats_.runawayJoints.end());
    discardStepOf(partStats_.runawayBodies);
    for (BodyId id : partStats_.runawayBodies) {
      heldTypes_.emplace_back(id, bodies_[id].type);
      bodies_[id].type = BodyType::Static;
    }
  }
  stats_.substeps = k - stats_.retakenParts;
  for (StageEnergySample& e : stats_.stageEnergy)
    e.substeps = stats_.substeps;
  for (const auto& [id, type] : heldTypes_)
    bodies_[id].type = type;
  for (Body& b : bodies_) {
    b.force.setZero();
    b.torque.setZero();
  }
}

void World::savePartStart() {
  partStart_.resize(bodies_.size());
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const Body& b = bodies_[i];
    partStart_[i] = Saved{b.position, b.linearVelocity, b.angularVelocity, b.orientation};
  }
}

void World::restorePartStart() {
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    Body& b = bodies_[i];
    b.position = partStart_[i].x;
    b.orientation = partStart_[i].q;
    b.linearVelocity = partStart_[i].v;
    b.angularVelocity = partStart_[i].w;
  }
}

// The fastest turn (rad/s) of a body in contact, counting only turns that
// move its surfaces: not a centred sphere's, nor a centred capsule's or
// cylinder's about its own axis (a rolling wheel). A part's contacts are
// found where the bodies are at its start and solved linearized there; a
// body that turns far before the next collision brings other points of
// its surface into the bodies it touches. In the 1,000-shape pile a 152 g
// cylinder pinched between two balls, tumbling at 50-100 rad/s (0.1-0.2
// rad a sub-step), went 41 mm deep, and an 87 g one at 390 rad/s 14 mm.
// Its geometry's travel counts too (turningGeometrySpeed): a part holds
// it to maxSurfaceTravelPerSubstep, so a shape whose features move
// faster than that over maxTurnPerSubstep counts its turn as much faster.
// 0 when the settings do not limit the turn (maxTurnPerSubstep 0).
double World::surfaceTurnRate(const std::vector<ContactManifold>& contacts) {
  if (settings_.maxTurnPerSubstep <= 0.0) return 0.0;
  touching_.assign(bodies_.size(), 0);
  for (const ContactManifold& m : contacts) {
    if (m.bodyA != kWorldBody) touching_[m.bodyA] = 1;
    if (m.bodyB != kWorldBody) touching_[m.bodyB] = 1;
  }
  // A feature moving at speed s travels as far in a part as a turn of
  // s / travel * maxTurnPerSubstep would turn (0: the turn only).
  const double travel = settings_.maxSurfaceTravelPerSubstep;
  const double turnPerSpeed = travel > 0.0 ? settings_.maxTurnPerSubstep / travel : 0.0;
  double fastest = 0.0;
  for (const Shape& shape : shapes_) {
    if (!shape.alive || shape.body == kWorldBody || !touching_[shape.body]) continue;
    const Body& b = bodies_[shape.body];
    if (!b.alive || !b.isDynamic()) continue;
    Vec3 w = b.angularVelocity;
    const bool centred = shape.localPosition.isZero();
    if (centred && shape.kind == Shape::Kind::Sphere) continue;
    if (centred && (shape.kind == Shape::Kind::Capsule || shape.kind == Shape::Kind::Cylinder)) {
      const Vec3 axis = (b.orientation * shape.localOrientation) * Vec3::UnitZ();
      w -= w.dot(axis) * axis;
    }
    fastest = std::max(fastest, w.norm());
    if (turnPerSpeed > 0.0)
      fastest = std::max(
          fastest, turnPerSpeed * turningGeometrySpeed(shape, b.orientation, b.angularVelocity));
  }
  return fastest;
}

void World::restoreRunaways() {
  if (!stats_.runaways.empty()) discardStepOf(stats_.runawayBodies);
}

void World::discardStepOf(const std::vector<BodyId>& ids) {
  if (ids.empty() || saved_.size() != bodies_.size()) return;
  restored_.resize(bodies_.size(), 0);
  for (BodyId id : ids) {
    Body& b = bodies_[id];
    b.position = saved_[id].x;
    b.orientation = saved_[id].q;
    b.linearVelocity = saved_[id].v;
    b.angularVelocity = saved_[id].w;
    restored_[id] = 1;
  }
  auto restored = [&](BodyId id) { return id != kWorldBody && restored_[id]; };
  for (Joint& j : joints_) {
    const JointCommon& c = common(j.desc);
    if (j.alive && (restored(c.bodyA) || restored(c.bodyB))) j.warmSlots = 0;
  }
  for (ContactManifold& m : previousContacts_) {
    if (!restored(m.bodyA) && !restored(m.bodyB)) continue;
    for (ContactPoint& p : m.points) {
      p.normalImpulse = 0.0;
      p.tangentImpulse[0] = p.tangentImpulse[1] = 0.0;
    }
    m.rollingImpulse[0] = m.rollingImpulse[1] = m.rollingImpulse[2] = 0.0;
  }
  for (BodyId id : ids)
    restored_[id] = 0;
}

}  // namespace blockstep

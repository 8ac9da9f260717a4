// The particle steppers on a comparison scene: each body becomes a point
// mass at its centre with the radius of its shape, each ball joint a
// distance constraint between the two centres (or from one centre to the
// world anchor), each body-less plane, sphere and box a static shape; the
// same pairs collide as under ODE (category and collide bits). What a
// particle cannot stand for (hinges, fixed joints, bodies colliding with
// one another) is refused, not approximated.
//
// Measured as the other steppers are where the meaning carries over: the
// joint separation is |length - rest| of each distance constraint (the gap
// two rigid half-links meeting at the joint would show), the penetration
// is the deepest particle inside a shape at the frame's start, the energy
// is translational, and the solve time is the whole step (its contact
// search included). Positions and velocities are written back to the ODE
// bodies each frame, so drift and the finite-state check read them.
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "adapters/ode/body_state.h"
#include "compare/ode/runner.h"
#include "compare/pbd/particles.h"

namespace blockstep::compare {

namespace {

// The radius of the sphere a body's first shape is taken for.
double particleRadius(dBodyID body) {
  dGeomID g = dBodyGetFirstGeom(body);
  if (!g) return 0.0;
  switch (dGeomGetClass(g)) {
    case dSphereClass:
      return dGeomSphereGetRadius(g);
    case dCapsuleClass: {
      dReal r, len;
      dGeomCapsuleGetParams(g, &r, &len);
      return r;
    }
    case dCylinderClass: {
      dReal r, len;
      dGeomCylinderGetParams(g, &r, &len);
      return r;
    }
    case dBoxClass: {
      dVector3 sides;
      dGeomBoxGetLengths(g, sides);
      return 0.5 * std::min({sides[0], sides[1], sides[2]});
    }
    default:
      throw std::invalid_argument("a body's shape has no particle radius (class " +
                                  std::to_string(dGeomGetClass(g)) + ")");
  }
}

pbd::StaticShape staticShape(dGeomID g) {
  pbd::StaticShape s;
  switch (dGeomGetClass(g)) {
    case dPlaneClass: {
      dVector4 p;
      dGeomPlaneGetParams(g, p);
      s.kind = pbd::StaticShape::Kind::Plane;
      s.normal = Vec3(p[0], p[1], p[2]);
      s.offset = p[3];
      return s;
    }
    case dSphereClass:
      s.kind = pbd::StaticShape::Kind::Sphere;
      s.centre = ode::vec(dGeomGetPosition(g));
      s.radius = dGeomSphereGetRadius(g);
      return s;
    case dBoxClass: {
      dVector3 sides;
      dGeomBoxGetLengths(g, sides);
      s.kind = pbd::StaticShape::Kind::Box;
      s.centre = ode::vec(dGeomGetPosition(g));
      s.halfExtents = 0.5 * Vec3(sides[0], sides[1], sides[2]);
      const dReal* R = dGeomGetRotation(g);  // 3 x 4, row major
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k)
          s.rotation(i, k) = R[4 * i + k];
      return s;
    }
    default:
      throw std::invalid_argument("a static shape of class " + std::to_string(dGeomGetClass(g)) +
                                  " has no particle collider (plane, sphere and box have)");
  }
}

// ODE's own test of whether two geoms may collide.
bool bitsCollide(dGeomID a, dGeomID b) {
  return (dGeomGetCategoryBits(a) & dGeomGetCollideBits(b)) ||
         (dGeomGetCategoryBits(b) & dGeomGetCollideBits(a));
}

// Builds the particle system for the scene; throws what it cannot stand for.
pbd::ParticleSystem particlesOf(const Scene& scene) {
  pbd::ParticleSystem ps;
  std::unordered_map<dBodyID, int> index;
  for (dBodyID b : scene.bodies()) {
    dMass m;
    dBodyGetMass(b, &m);
    index[b] = ps.addParticle(ode::vec(dBodyGetPosition(b)), ode::vec(dBodyGetLinearVel(b)), m.mass,
                              particleRadius(b));
  }
  for (const JointRecord& j : scene.joints()) {
    if (j.kind != JointKind::Ball)
      throw std::invalid_argument("it has hinge or fixed joints (a particle has no rotation)");
    if (j.body2) {
      ps.addDistance(index.at(j.body1), index.at(j.body2));
    } else {
      ps.addPin(index.at(j.body1), Vec3(j.anchor2[0], j.anchor2[1], j.anchor2[2]));
    }
  }
  std::vector<dGeomID> statics, moving;
  const int n = dSpaceGetNumGeoms(scene.space());
  for (int i = 0; i < n; ++i) {
    dGeomID g = dSpaceGetGeom(scene.space(), i);
    (dGeomGetBody(g) ? moving : statics).push_back(g);
  }
  for (dGeomID g : statics)
    ps.addShape(staticShape(g));
  // Bodies that ODE would collide with one another have no counterpart.
  for (std::size_t a = 0; a < moving.size(); ++a) {
    for (std::size_t b = a + 1; b < moving.size(); ++b) {
      dBodyID ba = dGeomGetBody(moving[a]), bb = dGeomGetBody(moving[b]);
      if (bitsCollide(moving[a], moving[b]) && !dAreConnected(ba, bb))
        throw std::invalid_argument(
            "its bodies collide with one another (particles here only "
            "meet static shapes)");
    }
  }
  for (dGeomID g : moving) {
    std::uint64_t mask = 0;
    for (std::size_t k = 0; k < statics.size(); ++k)
      if (bitsCollide(g, statics[k])) mask |= std::uint64_t{1} << k;
    const int i = index.at(dGeomGetBody(g));
    ps.setCollisionMask(i, mask);
  }
  return ps;
}

}  // namespace

RunResult runParticles(Scene& scene, const Stepper& stepper, const RunOptions& options) {
  RunResult r;
  r.startEnergy = scene.kineticEnergy() + scene.potentialEnergy();
  r.scene = scene.name();
  r.stepper = stepper.label;
  r.framesAsked = options.frames;
  pbd::ParticleSystem ps;
  try {
    ps = particlesOf(scene);
  } catch (const std::invalid_argument& e) {
    r.stoppedBecause = std::string("not run: ") + e.what();
    return r;
  }
  const dWorldID w = scene.world();
  pbd::Settings settings;
  settings.mode = stepper.xpbd ? pbd::Settings::Mode::Xpbd : pbd::Settings::Mode::Pbd;
  settings.iterations = stepper.iterations;
  settings.substeps = stepper.substeps;
  // The joints' own softness as a spring: ODE reads (ERP, CFM) at step h
  // as k = ERP / (h CFM), so the compliance 1 / k is h CFM / ERP.
  const double erp = dWorldGetERP(w), cfm = dWorldGetCFM(w);
  settings.compliance = erp > 0.0 ? options.dt * cfm / erp : 0.0;
  settings.friction = 0.6;  // the scenes' contact surface
  dVector3 g;
  dWorldGetGravity(w, g);
  settings.gravity = ode::vec(g);
  settings.linearDamping = dWorldGetLinearDamping(w);

  r.frames.reserve(options.frames);
  recordPoses(scene, 0, options, r);
  const auto start = Clock::now();
  for (int f = 0; f < options.frames; ++f) {
    FrameRecord rec;
    rec.penetration = ps.deepestContact(&rec.contacts);
    // Found and projected in every iteration: each contact is one the
    // step acts on.
    rec.heldPenetration = rec.penetration;
    // Contacts are found and projected inside the iterations: the whole
    // step counts as solve time (none as collision), the rigid steppers'
    // collision not being counted in theirs.
    const auto t0 = Clock::now();
    ps.step(options.dt, settings);
    rec.solveSeconds = seconds(t0, Clock::now());
    double sumSq = 0.0;
    rec.joints.separation = ps.maxDistanceError(&sumSq);
    rec.joints.separationSumSq = sumSq;
    rec.joints.joints = ps.constraintCount();
    rec.kineticEnergy = ps.kineticEnergy();
    for (std::size_t i = 0; i < scene.bodies().size(); ++i) {
      const Vec3& x = ps.position(static_cast<int>(i));
      const Vec3& v = ps.velocity(static_cast<int>(i));
      dBodySetPosition(scene.bodies()[i], x.x(), x.y(), x.z());
      dBodySetLinearVel(scene.bodies()[i], v.x(), v.y(), v.z());
      dBodySetAngularVel(scene.bodies()[i], 0, 0, 0);
    }
    rec.potentialEnergy = scene.potentialEnergy();
    r.frames.push_back(rec);
    recordPoses(scene, f + 1, options, r);
    if (options.onFrame) options.onFrame(f + 1, seconds(start, Clock::now()));
    if (!ps.finite()) {
      r.exploded = true;
      r.stoppedBecause = "non-finite state at frame " + std::to_string(f);
      break;
    }
  }
  summarize(r, scene, options);
  return r;
}

}  // namespace blockstep::compare

// ODE contacts mapped onto the core behave as ODE's own direct solver
// (dWorldStep) steps them: restitution, Approx1 friction, force-limited
// friction; and the mapping reads every surface mode it claims.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "adapters/ode/contact_mapping.h"
#include "core/body/mass.h"
#include "core/world/world.h"
#include "support/ode_library.h"

namespace blockstep {
namespace {

const auto* const kOde = ::testing::AddGlobalTestEnvironment(new test::OdeLibrary);

constexpr double kStep = 1.0 / 240.0;

// One body (a sphere or a box) on the ground plane z = 0, stepped twice
// from the same start: by ODE (dCollide + contact joints + dWorldStep) and
// by the core with the same contacts mapped. `probe` reads both.
struct Twin {
  dWorldID odeWorld;
  dSpaceID space;
  dGeomID plane, odeGeom, coreGeom;
  dBodyID odeBody;
  dJointGroupID group;
  World core;
  BodyId coreBody;
  dSurfaceParameters surface{};

  Twin(bool sphere, const Vec3& position, const Vec3& velocity) {
    odeWorld = dWorldCreate();
    dWorldSetGravity(odeWorld, 0, 0, -9.81);
    dWorldSetERP(odeWorld, 0.2);
    dWorldSetCFM(odeWorld, 1e-5);
    space = dHashSpaceCreate(0);
    plane = dCreatePlane(space, 0, 0, 1, 0);
    group = dJointGroupCreate(0);
    odeBody = dBodyCreate(odeWorld);
    dMass mass;
    if (sphere) {
      dMassSetSphereTotal(&mass, 1.0, 0.1);
      odeGeom = dCreateSphere(0, 0.1);
      coreGeom = dCreateSphere(0, 0.1);
    } else {
      dMassSetBoxTotal(&mass, 1.0, 0.5, 0.5, 0.5);
      odeGeom = dCreateBox(0, 0.5, 0.5, 0.5);
      coreGeom = dCreateBox(0, 0.5, 0.5, 0.5);
    }
    dBodySetMass(odeBody, &mass);
    dGeomSetBody(odeGeom, odeBody);
    dBodySetPosition(odeBody, position.x(), position.y(), position.z());
    dBodySetLinearVel(odeBody, velocity.x(), velocity.y(), velocity.z());

    BodyDesc d;
    d.position = position;
    d.linearVelocity = velocity;
    d.mass = 1.0;
    d.inertia = sphere ? sphereMass(1.0, 0.1).inertia : boxMass(1.0, Vec3(0.5, 0.5, 0.5)).inertia;
    coreBody = core.createBody(d);
    // The direct solver's answer: many sweeps, cold, like dWorldStep.
    core.setSettings(SolverSettings::paper(50));
  }
  ~Twin() {
    dJointGroupDestroy(group);
    dGeomDestroy(odeGeom);
    dGeomDestroy(coreGeom);
    dSpaceDestroy(space);
    dWorldDestroy(odeWorld);
  }

  void step() {
    dContact contacts[8];
    const int n = dCollide(odeGeom, plane, 8, &contacts[0].geom, sizeof(dContact));
    for (int i = 0; i < n; ++i) {
      contacts[i].surface = surface;
      dJointAttach(dJointCreateContact(odeWorld, group, &contacts[i]), odeBody, 0);
    }
    dWorldStep(odeWorld, kStep);
    dJointGroupEmpty(group);

    const Body& b = core.body(coreBody);
    dGeomSetPosition(coreGeom, b.position.x(), b.position.y(), b.position.z());
    const dQuaternion q = {b.orientation.w(), b.orientation.x(), b.orientation.y(),
                           b.orientation.z()};
    dGeomSetQuaternion(coreGeom, q);
    const int m = dCollide(coreGeom, plane, 8, &contacts[0].geom, sizeof(dContact));
    const auto params = ode::WorldContactParams::of(odeWorld);
    for (int i = 0; i < m; ++i) {
      contacts[i].surface = surface;
      const ode::MappedContact mapped = ode::mapContact(contacts[i], coreBody, kWorldBody, params);
      ASSERT_EQ(mapped.unsupported, nullptr);
      core.addContact(mapped.manifold);
    }
    core.step(kStep);
  }
  Vec3 odeVelocity() const {
    const dReal* v = dBodyGetLinearVel(odeBody);
    return Vec3(v[0], v[1], v[2]);
  }
  Vec3 odePosition() const {
    const dReal* p = dBodyGetPosition(odeBody);
    return Vec3(p[0], p[1], p[2]);
  }
};

TEST(OdeContacts, BounceMatchesDWorldStep) {
  Twin twin(true, Vec3(0, 0, 1.1), Vec3::Zero());
  twin.surface.mode = dContactBounce | dContactApprox1;
  twin.surface.mu = 0.5;
  twin.surface.bounce = 0.5;
  twin.surface.bounce_vel = 0.1;
  double odeApex = 0.0, coreApex = 0.0;
  bool odeUp = false, coreUp = false;
  for (int i = 0; i < 480; ++i) {  // 2 s: the drop and the first rebound
    twin.step();
    odeUp |= twin.odeVelocity().z() > 0.5;
    coreUp |= twin.core.body(twin.coreBody).linearVelocity.z() > 0.5;
    if (odeUp) odeApex = std::max(odeApex, twin.odePosition().z());
    if (coreUp) coreApex = std::max(coreApex, twin.core.body(twin.coreBody).position.z());
  }
  // Dropped 1 m onto the ground at e = 0.5: back up about 0.25 m.
  EXPECT_NEAR(odeApex - 0.1, 0.25, 0.03);
  EXPECT_NEAR(coreApex, odeApex, 0.02 * (odeApex - 0.1));
}

void expectSameSlide(int mode, double mu) {
  Twin twin(false, Vec3(0, 0, 0.25), Vec3(2, 0, 0));
  twin.surface.mode = mode;
  twin.surface.mu = mu;
  for (int i = 0; i < 120; ++i)
    twin.step();  // 0.5 s of sliding
  const double odeV = twin.odeVelocity().x();
  const double coreV = twin.core.body(twin.coreBody).linearVelocity.x();
  EXPECT_NEAR(coreV, odeV, 0.01 * (2.0 - odeV)) << "mode " << mode;
}

TEST(OdeContacts, Approx1FrictionMatchesDWorldStep) {
  // Friction scaled by the normal force: slows at mu g = 2.94 m/s^2.
  expectSameSlide(dContactApprox1, 0.3);
}

TEST(OdeContacts, ForceLimitedFrictionMatchesDWorldStep) {
  // Without Approx1, ODE's mu is a force limit per friction row (N), here
  // shared by the box's four contact points.
  expectSameSlide(0, 0.3);
}

TEST(OdeContacts, MappingReadsEverySurfaceMode) {
  dContact c{};
  c.geom.pos[0] = 1;
  c.geom.normal[2] = 1;
  c.geom.depth = 0.01;
  c.fdir1[0] = 1;
  c.surface.mode = dContactMu2 | dContactFDir1 | dContactBounce | dContactSoftERP |
                   dContactSoftCFM | dContactMotion1 | dContactMotion2 | dContactMotionN |
                   dContactSlip1 | dContactSlip2 | dContactApprox1;
  c.surface.mu = 0.4;
  c.surface.mu2 = 0.7;
  c.surface.bounce = 0.3;
  c.surface.bounce_vel = 0.2;
  c.surface.soft_erp = 0.5;
  c.surface.soft_cfm = 0.01;
  c.surface.motion1 = 1;
  c.surface.motion2 = 2;
  c.surface.motionN = 3;
  c.surface.slip1 = 0.1;
  c.surface.slip2 = 0.2;
  ode::WorldContactParams w;
  w.surfaceLayer = 0.001;
  w.maxCorrectingVelocity = 5.0;
  const ode::MappedContact mapped = ode::mapContact(c, 3, kWorldBody, w);
  const ContactManifold& m = mapped.manifold;
  EXPECT_EQ(mapped.unsupported, nullptr);
  EXPECT_EQ(m.bodyA, kWorldBody);  // ODE's body2
  EXPECT_EQ(m.bodyB, 3);           // ODE's body1, pushed along +normal
  EXPECT_EQ(m.points[0].separation, -0.01);
  EXPECT_EQ(m.surface.friction, ContactSurface::Friction::Box);
  EXPECT_EQ(m.surface.mu, 0.4);
  EXPECT_EQ(m.surface.mu2, 0.7);
  EXPECT_EQ(m.surface.frictionDir1, Vec3(1, 0, 0));
  EXPECT_EQ(m.surface.restitution, 0.3);
  EXPECT_EQ(m.surface.restitutionThreshold, 0.2);
  EXPECT_EQ(m.surface.softness.erp, 0.5);
  EXPECT_EQ(m.surface.softness.cfm, 0.01);
  EXPECT_EQ(m.surface.motion1, 1);
  EXPECT_EQ(m.surface.motion2, 2);
  EXPECT_EQ(m.surface.motionN, 3);
  EXPECT_EQ(m.surface.slip1, 0.1);
  EXPECT_EQ(m.surface.slip2, 0.2);
  EXPECT_EQ(m.surface.slop, 0.001);
  EXPECT_EQ(m.surface.maxCorrectingVelocity, 5.0);

  c.surface.mode = dContactApprox1_1;  // one direction scaled, the other not
  EXPECT_NE(ode::mapContact(c, 3, kWorldBody, w).unsupported, nullptr);
}

TEST(OdeContacts, PointsOfOnePairAndSurfaceBecomeOneManifold) {
  // Four ODE contacts of a box on the ground, then one with another
  // surface and one of another pair: three manifolds, the first of four
  // points.
  dContact c{};
  c.geom.normal[2] = 1;
  c.surface.mode = dContactApprox1;
  c.surface.mu = 0.5;
  const ode::WorldContactParams w;
  std::vector<ContactManifold> in, out;
  for (int k = 0; k < 4; ++k) {
    c.geom.pos[0] = k & 1 ? 0.25 : -0.25;
    c.geom.pos[1] = k & 2 ? 0.25 : -0.25;
    in.push_back(ode::mapContact(c, 0, kWorldBody, w).manifold);
  }
  c.surface.mu = 0.9;
  in.push_back(ode::mapContact(c, 0, kWorldBody, w).manifold);
  c.surface.mu = 0.5;
  in.push_back(ode::mapContact(c, 1, kWorldBody, w).manifold);
  ode::groupContacts(in, out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].pointCount, 4);
  EXPECT_EQ(out[1].pointCount, 1);
  EXPECT_EQ(out[2].bodyB, 1);
}

}  // namespace
}  // namespace blockstep

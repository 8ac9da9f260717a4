// Nothing allocates on the heap per step in an ODE program running on the
// plugin once its scene has warmed up: the registry hooks called for every
// contact joint ODE makes, the bridge's reading and mapping, the core step
// and the write-back. Counted with a replaced global operator new. ODE's
// own collision code allocates with operator new too (about 39 times per
// frame in this scene, with its own quickstep as well), so the count is
// taken around what is ours: the step, and the registry hooks that
// dJointCreateContact, dJointAttach and dJointGroupEmpty run.
#include <gtest/gtest.h>
#include <ode/ode.h>

#include <vector>

#include "blockstep/blockstep_ode.h"
#include "support/allocation_counter.h"

namespace {

dWorldID world;
dJointGroupID contacts;

void nearCallback(void*, dGeomID a, dGeomID b) {
  dContact contact[4];
  const int n = dCollide(a, b, 4, &contact[0].geom, sizeof(dContact));
  for (int i = 0; i < n; ++i) {
    contact[i].surface.mode = dContactApprox1;
    contact[i].surface.mu = 0.6;
    dJointAttach(dJointCreateContact(world, contacts, &contact[i]), dGeomGetBody(a),
                 dGeomGetBody(b));
  }
}

TEST(PluginNoAllocation, FramesAllocateNothingAfterWarmUp) {
  dInitODE2(0);
  dBlockStepSetReplace("none");
  world = dWorldCreate();
  dWorldSetGravity(world, 0, 0, -9.81);
  dSpaceID space = dHashSpaceCreate(0);
  contacts = dJointGroupCreate(0);
  dCreatePlane(space, 0, 0, 1, 0);
  // A 5-box stack (contacts made and emptied every frame), a hinge chain
  // with stops and a motor, and a jointed pair with feedback.
  std::vector<dBodyID> bodies;
  auto box = [&](double x, double z, double side) {
    dBodyID b = dBodyCreate(world);
    dMass m;
    dMassSetBoxTotal(&m, 1.0, side, side, side);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, 0.0, z);
    bodies.push_back(b);
    return b;
  };
  for (int i = 0; i < 5; ++i)
    dGeomSetBody(dCreateBox(space, 0.5, 0.5, 0.5), box(0, 0.25 + 0.5 * i, 0.5));
  dBodyID prev = nullptr;
  for (int i = 0; i < 6; ++i) {
    dBodyID link = box(3.0 + 0.3 * (i + 1), 3.0, 0.1);
    dJointID j = dJointCreateHinge(world, 0);
    dJointAttach(j, link, prev);
    dJointSetHingeAnchor(j, 3.0 + 0.3 * i, 0.0, 3.0);
    dJointSetHingeAxis(j, 0, 1, 0);
    dJointSetHingeParam(j, dParamLoStop, -1.0);
    dJointSetHingeParam(j, dParamHiStop, 1.0);
    dJointSetHingeParam(j, dParamFMax, 0.1);
    prev = link;
  }
  dJointFeedback feedback{};
  dJointSetFeedback(dJointCreateFixed(world, 0), &feedback);
  long ours = 0;
  auto frame = [&](bool count) {
    dSpaceCollide(space, nullptr, &nearCallback);
    const long before = blockstep::test::allocationCount();
    ASSERT_EQ(dWorldBlockStep(world, 1.0 / 60.0), 1) << dWorldGetBlockStepMessage(world);
    dJointGroupEmpty(contacts);
    if (count) ours += blockstep::test::allocationCount() - before;
  };
  for (int i = 0; i < 60; ++i)
    frame(false);
  for (int i = 0; i < 30; ++i)
    frame(true);
  EXPECT_EQ(ours, 0);

  // The hooks alone: 40 contact joints made, attached and emptied per
  // round (ODE takes their memory from the group's arena, not from new).
  dContact contact{};
  contact.geom.normal[2] = 1.0;
  contact.surface.mode = dContactApprox1;
  auto round = [&] {
    for (int k = 0; k < 40; ++k) {
      dJointAttach(dJointCreateContact(world, contacts, &contact), bodies[k % 5], nullptr);
    }
    dJointGroupEmpty(contacts);
  };
  for (int i = 0; i < 5; ++i)
    round();
  const long before = blockstep::test::allocationCount();
  for (int i = 0; i < 20; ++i)
    round();
  EXPECT_EQ(blockstep::test::allocationCount() - before, 0);

  dJointGroupDestroy(contacts);
  dSpaceDestroy(space);
  dWorldDestroy(world);
  dCloseODE();
}

// blockstep colliding the space itself every sub-step: boxes stacked,
// a capsule and a cylinder on the ground, shapes synced from the geoms
// every step.
TEST(PluginNoAllocation, OwnCollisionEverySubstepAllocatesNothingAfterWarmUp) {
  dInitODE2(0);
  dWorldID w = dWorldCreate();
  dWorldSetGravity(w, 0, 0, -9.81);
  dWorldSetBlockSubsteppedSolver(w, 4);
  dSpaceID space = dHashSpaceCreate(0);
  dCreatePlane(space, 0, 0, 1, 0);
  auto body = [&](dGeomID g, double x, double z) {
    dBodyID b = dBodyCreate(w);
    dMass m;
    dMassSetBoxTotal(&m, 1.0, 0.5, 0.5, 0.5);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, 0.0, z);
    dGeomSetBody(g, b);
  };
  for (int i = 0; i < 3; ++i)
    body(dCreateBox(space, 0.5, 0.5, 0.5), 0.0, 0.25 + 0.5 * i);
  body(dCreateCapsule(space, 0.1, 0.4), 2.0, 0.4);
  body(dCreateCylinder(space, 0.2, 0.3), 4.0, 0.15);
  dSurfaceParameters surface{};
  surface.mode = dContactApprox1;
  surface.mu = 0.6;
  dWorldSetBlockCollision(w, space, &surface, dBlockCollideEverySubstep);
  for (int i = 0; i < 60; ++i)
    ASSERT_EQ(dWorldBlockStep(w, 1.0 / 60.0), 1) << dWorldGetBlockStepMessage(w);
  const long before = blockstep::test::allocationCount();
  for (int i = 0; i < 30; ++i)
    ASSERT_EQ(dWorldBlockStep(w, 1.0 / 60.0), 1);
  EXPECT_EQ(blockstep::test::allocationCount() - before, 0);
  dSpaceDestroy(space);
  dWorldDestroy(w);
  dCloseODE();
}

TEST(PluginNoAllocation, TheCounterSeesAllocations) {
  const long before = blockstep::test::allocationCount();
  std::vector<int> v;
  v.reserve(100);
  EXPECT_GE(v.capacity(), 100u);  // used, so the allocation stays
  EXPECT_GE(blockstep::test::allocationCount() - before, 1);
}

}  // namespace

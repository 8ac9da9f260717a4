/* An ODE program that knows nothing of blockstep: plain ODE calls only.
 * The plugin tests run it with and without LD_PRELOAD=libblockstep_ode.so.
 * It steps a hanging 10-link ball-joint chain with a heavy end, a 6-box
 * stack on a plane, and a hinge pendulum, all with dWorldQuickStep at 20
 * iterations, and prints what a reader checks:
 *   chain_gap_mm      largest gap of any chain joint (anchor1 vs anchor2)
 *   stack_drift_mm    how far the top box moved sideways
 *   stack_sink_mm     how far the top box sank
 *   pendulum_energy   relative change of the pendulum's energy (no friction) */
#include <math.h>
#include <ode/ode.h>
#include <stdio.h>

static dWorldID world;
static dJointGroupID contacts;

static void near_callback(void* data, dGeomID a, dGeomID b) {
  (void)data;
  dContact contact[4];
  int n = dCollide(a, b, 4, &contact[0].geom, sizeof(dContact));
  for (int i = 0; i < n; ++i) {
    contact[i].surface.mode = dContactApprox1;
    contact[i].surface.mu = 0.6;
    dJointID j = dJointCreateContact(world, contacts, &contact[i]);
    dJointAttach(j, dGeomGetBody(a), dGeomGetBody(b));
  }
}

static dBodyID make_box(double x, double y, double z, double mass, double side) {
  dBodyID b = dBodyCreate(world);
  dMass m;
  dMassSetBoxTotal(&m, mass, side, side, side);
  dBodySetMass(b, &m);
  dBodySetPosition(b, x, y, z);
  return b;
}

int main(void) {
  const double h = 1.0 / 60.0;
  dInitODE2(0);
  world = dWorldCreate();
  dWorldSetGravity(world, 0, 0, -9.81);
  dWorldSetQuickStepNumIterations(world, 20);
  dSpaceID space = dHashSpaceCreate(0);
  contacts = dJointGroupCreate(0);
  dCreatePlane(space, 0, 0, 1, 0);

  /* Chain: 10 links of 0.1 kg hanging from (5, 0, 3), a 10 kg end, swinging. */
  dJointID chain[10];
  dBodyID prev = 0;
  for (int i = 0; i < 10; ++i) {
    dBodyID link = make_box(5.0 + 0.2 * (i + 1), 0.0, 3.0, i == 9 ? 10.0 : 0.1, 0.1);
    chain[i] = dJointCreateBall(world, 0);
    dJointAttach(chain[i], link, prev);
    dJointSetBallAnchor(chain[i], 5.0 + 0.2 * i, 0.0, 3.0);
    prev = link;
  }

  /* Stack of 6 half-metre boxes. */
  dBodyID top = 0;
  for (int i = 0; i < 6; ++i) {
    top = make_box(-5.0, 0.0, 0.25 + 0.5 * i, 1.0, 0.5);
    dGeomID g = dCreateBox(space, 0.5, 0.5, 0.5);
    dGeomSetBody(g, top);
  }

  /* Pendulum on a hinge, 1 m, from horizontal. */
  dBodyID bob = make_box(0.0, 5.0, 2.0, 1.0, 0.2);
  dJointID hinge = dJointCreateHinge(world, 0);
  dJointAttach(hinge, bob, 0);
  dJointSetHingeAnchor(hinge, -1.0, 5.0, 2.0);
  dJointSetHingeAxis(hinge, 0, 1, 0);
  const double energy0 = 9.81 * 2.0;

  double gap = 0.0;
  for (int f = 0; f < 180; ++f) {
    dSpaceCollide(space, 0, &near_callback);
    dWorldQuickStep(world, h);
    dJointGroupEmpty(contacts);
    for (int i = 0; i < 10; ++i) {
      dVector3 a1, a2;
      dJointGetBallAnchor(chain[i], a1);
      dJointGetBallAnchor2(chain[i], a2);
      double d = sqrt((a1[0] - a2[0]) * (a1[0] - a2[0]) + (a1[1] - a2[1]) * (a1[1] - a2[1]) +
                      (a1[2] - a2[2]) * (a1[2] - a2[2]));
      if (d > gap) gap = d;
    }
  }
  const dReal* p = dBodyGetPosition(top);
  const dReal* bp = dBodyGetPosition(bob);
  const dReal* bv = dBodyGetLinearVel(bob);
  const double energy = 9.81 * bp[2] + 0.5 * (bv[0] * bv[0] + bv[1] * bv[1] + bv[2] * bv[2]);
  printf("chain_gap_mm=%.4f stack_drift_mm=%.4f stack_sink_mm=%.4f pendulum_energy=%.4f\n",
         gap * 1e3, hypot(p[0] + 5.0, p[1]) * 1e3, (2.75 - p[2]) * 1e3,
         (energy - energy0) / energy0);
  dJointGroupDestroy(contacts);
  dSpaceDestroy(space);
  dWorldDestroy(world);
  dCloseODE();
  return 0;
}

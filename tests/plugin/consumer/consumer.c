/* A C program using the installed blockstep header and library: a hinge
 * pendulum stepped by dWorldBlockStep; prints "ok" when it swung, held its
 * hinge and was stepped by blockstep. */
#include <blockstep/blockstep_ode.h>
#include <math.h>
#include <stdio.h>

int main(void) {
  dInitODE2(0);
  dWorldID w = dWorldCreate();
  dWorldSetGravity(w, 0, 0, -9.81);
  dBodyID b = dBodyCreate(w);
  dMass m;
  dMassSetBoxTotal(&m, 1.0, 0.2, 0.2, 0.2);
  dBodySetMass(b, &m);
  dBodySetPosition(b, 0.5, 0.0, 1.0);
  dJointID j = dJointCreateHinge(w, 0);
  dJointAttach(j, b, 0);
  dJointSetHingeAnchor(j, 0.0, 0.0, 1.0);
  dJointSetHingeAxis(j, 0.0, 1.0, 0.0);
  for (int i = 0; i < 30; ++i) {
    if (!dWorldBlockStep(w, 1.0 / 60.0)) return 1;
  }
  dVector3 a1, a2;
  dJointGetHingeAnchor(j, a1);
  dJointGetHingeAnchor2(j, a2);
  const double gap = fabs(a1[0] - a2[0]) + fabs(a1[1] - a2[1]) + fabs(a1[2] - a2[2]);
  dBlockStepStats stats;
  dWorldGetBlockStepStats(w, &stats);
  const int ok =
      gap < 1e-3 && fabs(dJointGetHingeAngle(j)) > 0.1 && stats.stepper == dBlockStepperBlockstep;
  printf("%s\n", ok ? "ok" : "FAILED");
  dWorldDestroy(w);
  dCloseODE();
  return ok ? 0 : 1;
}

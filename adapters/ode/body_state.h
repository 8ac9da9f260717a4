// One ODE body's state (pose and velocities), taken and put back: what a
// step that must be undone or repeated from the same state keeps; and its
// kinetic energy; ODE's vectors as the core's.
#pragma once

#include <ode/ode.h>

#include "core/math/math.h"

namespace blockstep::ode {

inline Vec3 vec(const dReal* v) {
  return Vec3(v[0], v[1], v[2]);
}

struct OdeBodyState {
  dBodyID body = nullptr;
  dVector3 position{}, linear{}, angular{};
  dQuaternion orientation{};

  static OdeBodyState of(dBodyID b) {
    OdeBodyState s;
    s.body = b;
    for (int i = 0; i < 3; ++i) {
      s.position[i] = dBodyGetPosition(b)[i];
      s.linear[i] = dBodyGetLinearVel(b)[i];
      s.angular[i] = dBodyGetAngularVel(b)[i];
    }
    for (int i = 0; i < 4; ++i)
      s.orientation[i] = dBodyGetQuaternion(b)[i];
    return s;
  }

  void putBack() const {
    dBodySetPosition(body, position[0], position[1], position[2]);
    dBodySetQuaternion(body, orientation);
    dBodySetLinearVel(body, linear[0], linear[1], linear[2]);
    dBodySetAngularVel(body, angular[0], angular[1], angular[2]);
  }
};

// A body's kinetic energy, translation and rotation (the inertia in the
// body's frame, as ODE keeps it).
inline double kineticEnergy(dBodyID b) {
  dMass m;
  dBodyGetMass(b, &m);
  const dReal* v = dBodyGetLinearVel(b);
  const dReal* worldW = dBodyGetAngularVel(b);
  dVector3 w;
  dBodyVectorFromWorld(b, worldW[0], worldW[1], worldW[2], w);
  double rotational = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k)
      rotational += w[i] * m.I[i * 4 + k] * w[k];
  return 0.5 * m.mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 0.5 * rotational;
}

}  // namespace blockstep::ode

// One ODE body's state (pose and velocities), taken and put back: what a
// step that must be undone or repeated from the same state keeps.
#pragma once

#include <ode/ode.h>

namespace blockstep::ode {

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

}  // namespace blockstep::ode

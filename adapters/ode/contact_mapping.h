// ODE's contacts in the core's terms: one dContact (a contact joint's
// data) becomes a one-point ContactManifold with the same meaning, read
// from ODE 0.16's joints/contact.cpp (getInfo2):
// - the contact pushes body1 along +normal, so the core's body B (pushed
//   along +normal) is ODE's body1 and body A is body2 (or the world);
// - depth beyond the world's contact surface layer is removed at ERP / h
//   (soft_erp with dContactSoftERP), capped by the world's max correcting
//   velocity; CFM is soft_cfm with dContactSoftCFM, else the world's;
// - bounce applies when the approach speed exceeds bounce_vel;
// - friction rows are bounded by +-mu as a force, or by +-mu times the
//   normal force with dContactApprox1 (mu2 with dContactMu2, direction
//   fdir1 with dContactFDir1);
// - motion1/2 are body1's velocity relative to body2 along the friction
//   directions, motionN along the normal; slip1/2 are the friction rows' CFM.
#pragma once

#include <ode/ode.h>
#include "adapters/ode/clamped_input.h"

#include <cstdint>
#include <utility>
#include <vector>

#include "core/constraints/contact.h"

namespace blockstep::ode {

// The world settings a contact reads (dWorldGetERP, dWorldGetCFM,
// dWorldGetContactMaxCorrectingVel, dWorldGetContactSurfaceLayer).
struct WorldContactParams {
  double erp = 0.2;
  double cfm = 1e-5;
  double maxCorrectingVelocity = dInfinity;
  double surfaceLayer = 0.0;

  static WorldContactParams of(dWorldID world);
};

struct MappedContact {
  ContactManifold manifold;
  // Set when the contact uses an ODE mode the core does not model; the
  // caller must then step that world with ODE and say so.
  const char* unsupported = nullptr;
  unsigned clamped = 0;  // ClampedInput kinds brought into range
};

// body1 and body2 as attached to the contact joint (kWorldBody for 0);
// radius1 and radius2 how round their surfaces are at the point
// (ContactPoint::radiusA; 0: not known to be round).
MappedContact mapContact(const dContact& contact, BodyId body1, BodyId body2,
                         const WorldContactParams& world, double radius1 = 0.0,
                         double radius2 = 0.0);
// The same written into `m`, a default-made manifold (contacts come every
// step: no copy of the manifold), adding to `clamped`; returns what
// MappedContact::unsupported would hold.
const char* mapContactInto(const dContact& contact, BodyId body1, BodyId body2,
                           const WorldContactParams& world, double radius1, double radius2,
                           ContactManifold& m, unsigned& clamped);

// ODE makes one contact joint per point. Points of the same body pair and
// the same surface are one manifold for the core (up to four points, each
// along its own normal), so they are solved as one block instead of point
// by point: a ball dropped into a groove lands on both walls at once
// instead of being kicked sideways by the wall solved first. With rolling
// or spinning resistance (about one normal) only points whose normals
// agree within about 2.5 degrees are grouped. Merges `in` (one-point manifolds, in
// ODE's order) into `out`, which is cleared first: each point joins the
// first manifold of its pair (in the order they were made) with room,
// and the manifolds come out in the order of their first points.
void groupContacts(const std::vector<ContactManifold>& in, std::vector<ContactManifold>& out);

// The same with the caller's scratch, kept from step to step: a pile of
// 1,000 bodies gives thousands of points, and scanning every manifold made
// so far for each took 12% of its step.
struct ContactGrouping {
  std::vector<std::pair<std::uint64_t, std::int32_t>> byPair;  // (body pair, point)
  std::vector<std::int32_t> pairManifolds;                     // the current pair's, in `manifolds`
  // Each manifold to make: the inputs whose points it takes, the one it
  // began with first (its body pair, normal and surface).
  struct Made {
    std::int32_t inputs[kMaxManifoldPoints] = {};
    int inputCount = 0;
    int pointCount = 0;
  };
  std::vector<Made> manifolds;
};
void groupContacts(const std::vector<ContactManifold>& in, std::vector<ContactManifold>& out,
                   ContactGrouping& scratch);

}  // namespace blockstep::ode

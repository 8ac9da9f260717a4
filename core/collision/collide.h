// The collide stage: contact manifolds for every touching pair of shapes.
#pragma once

#include <cstdint>
#include <vector>

#include "core/collision/broadphase.h"
#include "core/collision/shapes.h"
#include "core/constraints/contact.h"

namespace blockstep {

struct CollisionSettings {
  // Speculative reach (m). Each shape reaches as far as its body can move
  // before the next collision, (|v| + |w| r) h with r the shape's farthest
  // point from the body's centre, plus restingMargin / 2; a pair gets
  // contact points within the sum of its two reaches, never more than
  // margin. A fixed reach of `margin` gave each 8 mm capsule of a dense
  // hair bundle the manifolds of some 19 neighbours (9,700 manifolds where
  // 1,000 touched), and the solver swept them all every sub-step.
  double margin = 0.02;
  double restingMargin = 0.004;
  // Bodies joined by a joint collide only when this is set.
  bool collideConnected = false;
  // Box against box by the separating-axis test with face clipping (the
  // comparison path the paper describes), or, when false, by GJK/EPA and
  // feature clipping like every other convex pair.
  bool boxBoxBySat = true;
  BroadPhaseMethod broadPhase = BroadPhaseMethod::Automatic;
  // Collide before every sub-step (SolverSettings::substeps) rather than
  // once per step: contacts follow the bodies at the sub-step's rate.
  bool everySubstep = false;
  // Mix each pair's friction and bounce from its two shapes (below); when
  // false every manifold keeps `surface` exactly (an ODE program's one
  // contact surface, second friction coefficient included).
  bool surfaceFromShapes = true;
  // Every manifold starts from this surface; friction mixes as
  // sqrt(muA muB) and restitution as max(eA, eB) of the two shapes.
  // Rigid normals (CFM 0: ODE's CFM is a compliance in m/N, so heavy
  // bodies would sink by CFM times their load; a 100 kg box on a 1 kg one
  // sank 2.5 mm more with ODE's 1e-5) and a 5 mm slop so resting contacts
  // do not jitter. Contacts given through World::addContact keep theirs.
  ContactSurface surface = defaultSurface();

  static ContactSurface defaultSurface() {
    ContactSurface s;
    s.softness = Softness::erpCfm(0.2, 0.0);
    s.slop = 0.005;
    s.restitutionThreshold = 0.2;
    return s;
  }
};

// One pair of shapes at these poses: fills m's normal and points (up to
// four, each within `margin` of touching) and returns their count, the
// normal pointing from the first shape to the second, or from the second
// to the first when `swapped` comes back set (the kinds were put in the
// order the collision routines take). The poses place the shapes (their
// bodies and local poses are not read); a plane is placed by its own
// normal and offset.
int collideShapes(const Shape& s1, const ShapePose& p1, const Shape& s2, const ShapePose& p2,
                  double margin, bool boxBoxBySat, ContactManifold& m, bool& swapped);

// How fast the shape's geometry moves (m/s) while its body turns at `w`
// (world) about its centre of mass: the fastest of a box's corners, a
// capsule's segment ends, a cylinder's rims, a ball's centre; a hull's
// farthest point from the centre of mass (a bound). A round surface
// spinning about itself moves nothing it touches, so it counts for
// nothing here. 0 for a plane.
double turningGeometrySpeed(const Shape& s, const Quat& bodyOrientation, const Vec3& w);

// How round a shape's surface is where it touches along `normal`
// (ContactPoint::radiusA): a sphere's and a capsule's radius everywhere, a
// cylinder's (its axis given) along its side but not on its flat ends or
// their rims, 0 for every other kind.
double surfaceRoundness(Shape::Kind kind, double radius, const Vec3& axis, const Vec3& normal);

// The collide stage. Keeps its buffers (poses, boxes, pairs, the sweep's
// order) from step to step, so a warmed-up scene allocates nothing.
class Collider {
 public:
  // Appends the manifolds of all touching pairs to `out`, for a step of
  // h seconds until the next collision (it sets the reach). `jointed`
  // holds sorted keys (bodyPairKey) of pairs that do not collide.
  void collide(const std::vector<Shape>& shapes, const std::vector<Body>& bodies,
               const CollisionSettings& settings, const std::vector<std::uint64_t>& jointed,
               double h, std::vector<ContactManifold>& out);
  // After a solve over the h seconds of the last collide: whether a shape
  // moved farther than that collide's reach for it (its contacts did not
  // cover its path: a body the solve struck or spun up can go into one it
  // had no contact with). The next collide only reaches at least as far
  // as the speeds now (for the part taken again).
  bool outranReach(const std::vector<Shape>& shapes, const std::vector<Body>& bodies,
                   const CollisionSettings& settings, double h);

 private:
  std::vector<ShapePose> poses_;
  std::vector<double> reach_;
  std::vector<double> farthest_;     // each shape's farthest point from its body's centre
  std::vector<double> solvedSpeed_;  // outranReach's speeds, for the next collide only
  std::vector<Aabb> boxes_;
  std::vector<std::pair<int, int>> pairs_;
  BroadPhase broadPhase_;
};

inline std::uint64_t bodyPairKey(BodyId a, BodyId b) {
  const auto lo = static_cast<std::uint32_t>(std::min(a, b));
  const auto hi = static_cast<std::uint32_t>(std::max(a, b));
  return (static_cast<std::uint64_t>(lo) << 32) | hi;
}

}  // namespace blockstep

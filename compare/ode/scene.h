// The comparison's scenes, written once with ODE's API (bodies, geoms,
// joints, dSpaceCollide with contact joints), so every stepper gets the
// same input and the same collision (../shared/SCENES.md gives them).
//
// Each joint is recorded with its geometry at build time (anchor in each
// body, the free axis of a hinge, the bodies' relative rotation), so its
// error is measured the same way whatever steps the world.
#pragma once

#include <ode/ode.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/collision/shapes.h"

namespace blockstep::compare {

enum class JointKind { Ball, Hinge, Fixed, Hinge2 };

struct JointRecord {
  dJointID joint = nullptr;
  JointKind kind = JointKind::Ball;
  dBodyID body1 = nullptr;
  dBodyID body2 = nullptr;  // nullptr: the world
  dVector3 anchor1{};       // in body1's frame
  dVector3 anchor2{};       // in body2's frame (world point when body2 is the world)
  dVector3 axis1{};         // hinge: the free axis in body1's frame; hinge2: the steering axis
  dVector3 axis2{};         // hinge: the same axis in body2's frame; hinge2: the axle in body2's
  dQuaternion relative0{};  // body2 in body1's frame at build time (fixed joints)
};

// How a replay draws what the bodies stand for, beyond their own shapes:
// cloth cells as one surface (a grid of bodies, row by row), hair
// segments as curves through their strands' bodies. Indices into
// Scene::bodies().
struct DrawHints {
  int surfaceColumns = 0;    // 0: no surface
  std::vector<int> surface;  // rows x surfaceColumns bodies
  std::vector<std::vector<int>> strands;
};

// What one frame's joints look like: the largest separation of the two
// anchor points (m; a hinge2's across its steering axis, along which its
// suspension gives by design) and the largest angular error (rad: a
// hinge's axes apart, a fixed joint's relative rotation, a hinge2's axle
// off square with its steering axis).
struct JointError {
  double separation = 0.0;
  double angle = 0.0;
  double separationSumSq = 0.0;  // over all joints, for an RMS
  int joints = 0;
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  dWorldID world() const { return world_; }
  dSpaceID space() const { return space_; }
  const std::string& name() const { return name_; }
  const std::vector<dBodyID>& bodies() const { return bodies_; }
  const std::vector<JointRecord>& joints() const { return joints_; }

  // One frame's collision: contact joints into the scene's group (at most
  // 8 per geom pair, with the scene's contact surface, none between
  // jointed bodies). Returns the deepest contact (m) as ODE's colliders
  // give it.
  double collide();
  // The deepest contact of the last collide(), m, with each pair that
  // holds a cylinder or a convex hull measured as the least distance that
  // separates the two shapes (libccd's GJK and EPA on the shapes' exact
  // support functions). ODE's colliders for those pairs estimate the
  // depth with libccd's MPR along a direction of its own choosing, which
  // can be far deeper than the shapes overlap: a capsule pressing a small
  // cylinder 6.7 mm deep came out 9.4 mm. Kept apart from collide() so
  // the measure costs no stepper collision time.
  double deepestContact();
  // The deepest of those contacts (measured the same way) whose geom pair
  // also touched at the collide() before: contacts the stepper has had a
  // step to act on. The deepest contact over a run mostly says how fast
  // a body met the ground between two collisions (found at most its speed
  // times the step deep, whatever the stepper does); this says how far
  // the stepper let it sink on. Set by deepestContact().
  double deepestHeldContact() const { return deepestHeld_; }
  // The geom pairs of the last collide() deeper than `depth` (m, measured
  // as deepestContact() does), deepest first, each with what a study of
  // why asks first: how deep, whether it was held, and both bodies' mass
  // and motion (a static geom has no body).
  struct DeepPair {
    double depth = 0.0;
    bool held = false;
    dGeomID a = nullptr, b = nullptr;
  };
  std::vector<DeepPair> pairsDeeperThan(double depth) const;
  // One line per geom of a DeepPair: its class, its body's mass, position,
  // velocity and angular velocity.
  static std::string describeGeom(dGeomID g);
  void clearContacts() { dJointGroupEmpty(contacts_); }
  int contactCount() const { return contactCount_; }
  JointError jointError() const;
  double kineticEnergy() const;
  // Of gravity, -m g . x summed over the bodies gravity acts on, J.
  double potentialEnergy() const;
  // The body whose drift the scene reports (stacks: the top box), or null.
  dBodyID probe() const { return probe_; }
  // Every contact's surface: dContactApprox1 with mu 0.6 unless the scene
  // sets its own (Newton's cradle: elastic and frictionless).
  const dSurfaceParameters& contactSurface() const { return surface_; }
  void setContactSurface(const dSurfaceParameters& s) { surface_ = s; }
  const DrawHints& drawHints() const { return draw_; }
  DrawHints& drawHints() { return draw_; }
  const dReal* probeStart() const { return probeStart_; }

  // Building (scenes.cpp).
  void setName(std::string name) { name_ = std::move(name); }
  // A body of `mass` at (x, y, z); a zero mass leaves ODE's default for the
  // caller to replace.
  dBodyID addBody(const dMass& mass, double x, double y, double z);
  void addGeom(dGeomID geom, dBodyID body);
  // A convex geom, the hull of `points` (x, y, z each, in the body's
  // frame), on `body`; its mass properties at `density` (kg/m^3) about
  // its centre of mass, which must be the body's origin, in `mass`. The
  // scene keeps the planes, points and polygons ODE reads from.
  dGeomID addConvex(const std::vector<double>& points, dBodyID body, double density, dMass* mass);
  // The hull vertices of a convex geom made by addConvex (x, y, z each),
  // or nullptr.
  const std::vector<dReal>* convexPoints(dGeomID geom) const;
  dJointID ball(dBodyID b1, dBodyID b2, double x, double y, double z);
  dJointID hinge(dBodyID b1, dBodyID b2, const dVector3 anchor, const dVector3 axis);
  dJointID fixed(dBodyID b1, dBodyID b2);
  // A wheel joint: body2 turns about `axle` (in body2) and steers about
  // `steering` (in body1); ODE's hinge2.
  dJointID hinge2(dBodyID b1, dBodyID b2, const dVector3 anchor, const dVector3 steering,
                  const dVector3 axle);
  void setProbe(dBodyID b);

 private:
  static void nearCallback(void* data, dGeomID a, dGeomID b);
  JointRecord& record(dJointID j, JointKind kind, dBodyID b1, dBodyID b2, const dReal* anchor);

  std::string name_;
  dWorldID world_ = nullptr;
  dSpaceID space_ = nullptr;
  dJointGroupID contacts_ = nullptr;
  std::vector<dBodyID> bodies_;
  std::vector<JointRecord> joints_;
  struct ConvexData {
    dGeomID geom = nullptr;
    std::vector<dReal> planes, points;
    std::vector<unsigned> polygons;
    std::shared_ptr<const ConvexHull> hull;
  };
  // A geom pair that touched at the last collide(), with ODE's depth;
  // round pairs (a cylinder or a convex hull, not on a plane) have their
  // depth measured again by deepestContact().
  struct TouchingPair {
    dGeomID a = nullptr, b = nullptr;  // pairKey(a) < pairKey(b)
    double odeDepth = 0.0;
    bool round = false;
  };
  // The least separating distance of a round pair (libccd GJK + EPA), or
  // its ODE depth where the geoms are not shapes the core knows.
  double leastDepth(const TouchingPair& pair) const;
  // A pair's depth as the runner measures it: the least for round pairs,
  // ODE's for the rest.
  double measuredDepth(const TouchingPair& pair) const;
  // Whether the pair touched at the collide() before the last one.
  bool touchingBefore(const TouchingPair& pair) const;
  bool coreShape(dGeomID g, Shape& out) const;
  std::vector<TouchingPair> touching_;
  // A geom's and a pair's identity, as numbers (ordered).
  static std::uintptr_t pairKey(dGeomID g) { return reinterpret_cast<std::uintptr_t>(g); }
  static std::pair<std::uintptr_t, std::uintptr_t> pairKey(const TouchingPair& p) {
    return {pairKey(p.a), pairKey(p.b)};
  }
  // The pairs touching at the last collide() and at the one before it,
  // ordered. keepTouching() orders the last one's (once per collide()).
  std::vector<std::pair<std::uintptr_t, std::uintptr_t>> touchingLast_, touchingBefore_;
  bool touchingKept_ = true;  // touchingLast_ holds the last collide()'s pairs
  void keepTouching();
  std::vector<std::unique_ptr<ConvexData>> convexData_;
  dBodyID probe_ = nullptr;
  DrawHints draw_;
  dSurfaceParameters surface_{};
  dVector3 probeStart_{};
  int contactCount_ = 0;
  double deepestOde_ = 0.0;   // over every pair, as ODE's colliders give it
  double deepestHeld_ = 0.0;  // deepestHeldContact()
};

// The scenes of SCENES.md by name (size: cloth's N; 0 for the default).
// Throws std::invalid_argument naming the accepted scenes.
std::unique_ptr<Scene> makeScene(const std::string& name, int size = 0);
const std::vector<std::string>& sceneNames();
// A line saying what a built-in scene is ("" for an unknown name).
std::string sceneSummary(const std::string& name);

}  // namespace blockstep::compare

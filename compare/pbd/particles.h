// The paper's position-based baseline (section 7, figures 3 and 7; its
// reference [12], Mueller et al.'s position based dynamics): point masses
// joined by distance constraints, colliding with static shapes, stepped on
// positions alone. The comparison runs it on the same layout as the rigid
// cloth and hair (one particle per body, one distance constraint per ball
// joint) to show what the paper measured: PBD is far cheaper, at the price
// of rotations, rigid-body contacts and stiffness that depends on the
// iteration count.
//
// Two variants:
//  - PBD: each constraint projected fully (stiffness 1) in Gauss-Seidel
//    order, `iterations` times per sub-step. The stiffness one gets
//    depends on the iteration count and the step.
//  - XPBD (Macklin et al. 2016): the same projection with a compliance
//    alpha (m/N) and an accumulated multiplier per constraint, so a
//    constraint acts as a spring of stiffness 1/alpha whatever the step
//    and iteration count. Compliance 0 is rigid; with several sub-steps of
//    one iteration it is "small steps" XPBD (Macklin et al. 2019).
// Contacts are projected in the same loop (a particle pushed out of a
// shape along its normal, its sideways motion over the sub-step held by
// static friction up to mu times the push and slowed by it beyond).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/math/math.h"

namespace blockstep::pbd {

// A shape that does not move (its own frame: centre and rotation).
struct StaticShape {
  enum class Kind { Plane, Sphere, Box } kind = Kind::Plane;
  Vec3 normal = Vec3::UnitZ();  // plane: unit normal, points p with n.p >= offset are outside
  double offset = 0.0;
  Vec3 centre = Vec3::Zero();  // sphere, box
  Mat3 rotation = Mat3::Identity();
  double radius = 0.0;              // sphere
  Vec3 halfExtents = Vec3::Zero();  // box
};

struct Settings {
  enum class Mode { Pbd, Xpbd } mode = Mode::Pbd;
  int iterations = 20;      // per sub-step
  int substeps = 1;         // per frame
  double compliance = 0.0;  // XPBD: m/N of every distance constraint
  double friction = 0.6;    // Coulomb coefficient against the static shapes
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);
  double linearDamping = 0.0;  // fraction of the velocity taken off per step (as ODE)
};

class ParticleSystem {
 public:
  // Returns the particle's index. mass <= 0 or infinite: it does not move.
  int addParticle(const Vec3& position, const Vec3& velocity, double mass, double radius);
  // Keeps particles a and b at their present distance.
  void addDistance(int a, int b);
  // Keeps particle a at its present distance from a fixed point (0: pinned there).
  void addPin(int a, const Vec3& point);
  // A shape the particles whose mask has bit `shapeCount()` collide with.
  void addShape(const StaticShape& shape);
  // Which shapes particle i collides with (bit k: the k-th shape added).
  void setCollisionMask(int i, std::uint64_t mask) { mask_[i] = mask; }
  int shapeCount() const { return static_cast<int>(shapes_.size()); }
  int particleCount() const { return static_cast<int>(x_.size()); }
  int constraintCount() const { return static_cast<int>(constraints_.size()); }

  // One frame of dt.
  void step(double dt, const Settings& settings);

  const Vec3& position(int i) const { return x_[i]; }
  const Vec3& velocity(int i) const { return v_[i]; }
  // Largest |length - rest| over the distance constraints (m), and the
  // sum of squares for an RMS.
  double maxDistanceError(double* sumSquares = nullptr) const;
  // Deepest particle inside a shape it collides with (m, 0 if none).
  double deepestContact(int* contacts = nullptr) const;
  double kineticEnergy() const;
  bool finite() const;

 private:
  struct Constraint {
    int a = 0, b = -1;  // b < 0: a fixed point
    Vec3 point = Vec3::Zero();
    double rest = 0.0;
    double lambda = 0.0;  // XPBD's accumulated multiplier over the sub-step
  };
  // Depth of a sphere of radius r at p inside the shape (> 0: inside)
  // and the outward normal there.
  double depth(const StaticShape& s, const Vec3& p, double r, Vec3& normal) const;
  void projectDistances(double h, const Settings& settings);
  void projectContacts(double mu);

  std::vector<Vec3> x_, v_, p_;  // position, velocity, predicted position
  std::vector<double> invMass_, radius_;
  std::vector<std::uint64_t> mask_;
  std::vector<Constraint> constraints_;
  std::vector<StaticShape> shapes_;
};

}  // namespace blockstep::pbd

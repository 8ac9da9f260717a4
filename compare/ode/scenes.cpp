// The scenes of ../shared/SCENES.md, built with ODE's API.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <random>
#include <stdexcept>

#include "compare/ode/scene.h"
#include "core/collision/convex_hull.h"

namespace blockstep::compare {

namespace {

constexpr double kLinkLength = 0.1;  // chain links

// 50 capsule links (r 0.01 m, 0.1 m long, 0.1 kg; the last 10 kg, or
// endMass) on ball joints from a world pin at z = 6: hanging, or released
// horizontally.
void buildChain(Scene& s, bool horizontal, double endMass = 10.0) {
  constexpr int kLinks = 50;
  constexpr double kPinZ = 6.0;
  dBodyID previous = nullptr;
  s.drawHints().strands.emplace_back();  // links without geoms: drawn as one curve
  for (int i = 0; i < kLinks; ++i) {
    s.drawHints().strands.back().push_back(i);
    dMass m;
    const double mass = i == kLinks - 1 ? endMass : 0.1;
    dMassSetCapsuleTotal(&m, mass, horizontal ? 1 : 3, 0.01, kLinkLength - 0.02);
    const double along = (i + 0.5) * kLinkLength;
    dBodyID b =
        horizontal ? s.addBody(m, along, 0.0, kPinZ) : s.addBody(m, 0.0, 0.0, kPinZ - along);
    const double joint = i * kLinkLength;
    if (horizontal) {
      s.ball(b, previous, joint, 0.0, kPinZ);
    } else {
      s.ball(b, previous, 0.0, 0.0, kPinZ - joint);
    }
    previous = b;
  }
}

void groundPlane(Scene& s) {
  dCreatePlane(s.space(), 0, 0, 1, 0);
}

dBodyID box(Scene& s, double mass, double sx, double sy, double sz, double x, double y, double z) {
  dMass m;
  dMassSetBoxTotal(&m, mass, sx, sy, sz);
  dBodyID b = s.addBody(m, x, y, z);
  s.addGeom(dCreateBox(s.space(), sx, sy, sz), b);
  return b;
}

// A capsule along z (the body's own axis).
dBodyID capsule(Scene& s, double mass, double r, double len, double x, double y, double z) {
  dMass m;
  dMassSetCapsuleTotal(&m, mass, 3, r, len);
  dBodyID b = s.addBody(m, x, y, z);
  s.addGeom(dCreateCapsule(s.space(), r, len), b);
  return b;
}

// 10 boxes of 0.5 m, 1 kg, exactly touching on the plane.
void buildStack(Scene& s) {
  groundPlane(s);
  dBodyID top = nullptr;
  for (int i = 0; i < 10; ++i)
    top = box(s, 1.0, 0.5, 0.5, 0.5, 0.0, 0.0, 0.25 + 0.5 * i);
  s.setProbe(top);
}

// A base of 20 boxes (0.5 m, 1 kg, 0.525 apart), each row half a box in.
void buildPyramid(Scene& s) {
  groundPlane(s);
  constexpr int kBase = 20;
  dBodyID top = nullptr;
  for (int row = 0; row < kBase; ++row) {
    const int n = kBase - row;
    for (int i = 0; i < n; ++i) {
      top = box(s, 1.0, 0.5, 0.5, 0.5, (i - 0.5 * (n - 1)) * 0.525, 0.0, 0.25 + 0.5 * row);
    }
  }
  s.setProbe(top);
}

// A random convex hull: 10 points of a normal cloud (sigma 0.06 m) about
// its centre of mass, which becomes the body's origin.
std::vector<double> randomHullPoints(std::mt19937& rng, double sigma) {
  std::normal_distribution<double> gauss(0.0, sigma);
  std::vector<Vec3> cloud(10);
  for (Vec3& p : cloud)
    p = Vec3(gauss(rng), gauss(rng), gauss(rng));
  const ConvexHull hull = ConvexHull::fromPoints(cloud);
  const Vec3 centre = hullMass(hull, 1.0).centre;
  std::vector<double> points;
  for (const Vec3& v : hull.vertices())
    points.insert(points.end(), {v.x() - centre.x(), v.y() - centre.y(), v.z() - centre.z()});
  return points;
}

dBodyID convexBody(Scene& s, const std::vector<double>& points, double density, double x, double y,
                   double z) {
  dMass m;
  dMassSetZero(&m);
  dBodyID b = s.addBody(m, x, y, z);  // the mass once the hull gives it
  s.addConvex(points, b, density, &m);
  dBodySetMass(b, &m);
  return b;
}

// `count` random convex hulls (500 kg/m^3) dropped in a loose column onto
// the plane: what ODE's one-point convex contacts leave rocking. Each is
// placed where its bounding sphere clears the ground and the hulls before
// it (placed by height alone, two started 64 mm into each other, and
// every stepper's deepest contact was that).
void buildHulls(Scene& s, int count) {
  groundPlane(s);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> place(-0.6, 0.6);
  struct Placed {
    double x, y, z, radius;
  };
  std::vector<Placed> placed;
  for (int i = 0; i < count; ++i) {
    const std::vector<double> points = randomHullPoints(rng, 0.06);
    double radius = 0.0;
    for (std::size_t k = 0; k < points.size(); k += 3)
      radius = std::max(radius, std::hypot(points[k], points[k + 1], points[k + 2]));
    Placed p{0.0, 0.0, std::max(0.2 + 0.15 * i / 4, radius + 0.01), radius};
    for (int tries = 1;; ++tries) {
      p.x = place(rng), p.y = place(rng);
      const bool clear = std::none_of(placed.begin(), placed.end(), [&](const Placed& q) {
        return std::hypot(p.x - q.x, p.y - q.y, p.z - q.z) < p.radius + q.radius;
      });
      if (clear) break;
      if (tries % 20 == 0) p.z += 0.05;  // a crowded height: go up
    }
    placed.push_back(p);
    convexBody(s, points, 500.0, p.x, p.y, p.z);
  }
}

// `layers` layers of 10 x 10 shapes, 0.5 m apart, each a box, sphere,
// capsule, cylinder or convex hull of 0.05-0.4 m (500 kg/m^3), in random
// turns, dropped onto the plane: 1,000 shapes at the default 10 layers.
void buildPile(Scene& s, int layers) {
  groundPlane(s);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> size(0.05, 0.4), unit(-1.0, 1.0);
  constexpr double kDensity = 500.0;
  for (int layer = 0; layer < layers; ++layer) {
    for (int i = 0; i < 100; ++i) {
      const double x = (i % 10 - 4.5) * 0.5, y = (i / 10 - 4.5) * 0.5, z = 0.3 + 0.5 * layer;
      dMass m;
      dBodyID b = nullptr;
      const unsigned kind = rng() % 5;
      switch (kind) {
        case 0: {
          const double sx = size(rng), sy = size(rng), sz = size(rng);
          dMassSetBox(&m, kDensity, sx, sy, sz);
          b = s.addBody(m, x, y, z);
          s.addGeom(dCreateBox(s.space(), sx, sy, sz), b);
          break;
        }
        case 1: {
          const double r = size(rng) / 2;
          dMassSetSphere(&m, kDensity, r);
          b = s.addBody(m, x, y, z);
          s.addGeom(dCreateSphere(s.space(), r), b);
          break;
        }
        case 2:
        case 3: {
          const double r = size(rng) / 4, len = size(rng) * 0.75;
          const bool cap = kind == 2;
          if (cap) {
            dMassSetCapsule(&m, kDensity, 3, r, len);
          } else {
            dMassSetCylinder(&m, kDensity, 3, r, len);
          }
          b = s.addBody(m, x, y, z);
          s.addGeom(cap ? dCreateCapsule(s.space(), r, len) : dCreateCylinder(s.space(), r, len),
                    b);
          break;
        }
        default:
          b = convexBody(s, randomHullPoints(rng, 0.07), kDensity, x, y, z);
          break;
      }
      dQuaternion q = {1.0, unit(rng), unit(rng), unit(rng)};
      dNormalize4(q);
      dBodySetQuaternion(b, q);
    }
  }
}

// Where a ragdoll stands: turned `yaw` about z, then moved by (x, y, z).
struct Placement {
  double yaw = 0.0, x = 0.0, y = 0.0, z = 0.0;
  void point(double px, double py, double pz, dVector3 out) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    out[0] = c * px - s * py + x;
    out[1] = s * px + c * py + y;
    out[2] = pz + z;
  }
  void direction(double px, double py, double pz, dVector3 out) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    out[0] = c * px - s * py;
    out[1] = s * px + c * py;
    out[2] = pz;
  }
};

// Pelvis, torso, head and two thighs: hinges with stops at the waist and
// hips, a ball at the neck. Returns the torso.
dBodyID buildRagdollAt(Scene& s, const Placement& at) {
  dMatrix3 turn;
  dRFromAxisAndAngle(turn, 0, 0, 1, at.yaw);
  auto part = [&](dBodyID b) {
    const dReal* p = dBodyGetPosition(b);
    dVector3 q;
    at.point(p[0], p[1], p[2], q);
    dBodySetPosition(b, q[0], q[1], q[2]);
    dBodySetRotation(b, turn);
    return b;
  };
  const double pelvisZ = 1.2;
  dBodyID pelvis = part(box(s, 10.0, 0.30, 0.20, 0.20, 0.0, 0.0, pelvisZ));
  const double torsoZ = pelvisZ + 0.10 + 0.20;
  dBodyID torso = part(box(s, 15.0, 0.34, 0.20, 0.40, 0.0, 0.0, torsoZ));
  const double neckZ = torsoZ + 0.20;
  dBodyID head = part(capsule(s, 5.0, 0.08, 0.14, 0.0, 0.0, neckZ + 0.08 + 0.07));
  const double hipZ = pelvisZ - 0.10;
  const double thighZ = hipZ - 0.06 - 0.19;
  dBodyID left = part(capsule(s, 7.0, 0.06, 0.38, -0.08, 0.0, thighZ));
  dBodyID right = part(capsule(s, 7.0, 0.06, 0.38, 0.08, 0.0, thighZ));
  dVector3 xAxis, waist, neck;
  at.direction(1, 0, 0, xAxis);
  at.point(0, 0, pelvisZ + 0.10, waist);
  dJointID w = s.hinge(pelvis, torso, waist, xAxis);
  dJointSetHingeParam(w, dParamLoStop, -0.3);
  dJointSetHingeParam(w, dParamHiStop, 0.8);
  at.point(0.0, 0.0, neckZ, neck);
  s.ball(torso, head, neck[0], neck[1], neck[2]);
  for (auto [thigh, x] : {std::pair{left, -0.08}, std::pair{right, 0.08}}) {
    dVector3 hip;
    at.point(x, 0.0, hipZ, hip);
    dJointID h = s.hinge(pelvis, thigh, hip, xAxis);
    dJointSetHingeParam(h, dParamLoStop, -1.2);
    dJointSetHingeParam(h, dParamHiStop, 0.5);
  }
  return torso;
}

// One ragdoll thrown at (0.5, 0.2, 0) m/s, the torso turning.
void buildRagdoll(Scene& s) {
  groundPlane(s);
  dBodyID torso = buildRagdollAt(s, Placement{});
  for (dBodyID b : s.bodies())
    dBodySetLinearVel(b, 0.5, 0.2, 0.0);
  dBodySetAngularVel(torso, 1.0, 2.0, 0.0);
}

// Eight ragdolls dropped upright in pairs side by side, each pair 1.5 m
// above the last (a ragdoll stands 1.3 m) and turned a quarter from it,
// onto the plane and one another: bodies of different ragdolls meet and
// hinge limits hold under load.
void buildRagdollPile(Scene& s) {
  groundPlane(s);
  for (int k = 0; k < 8; ++k) {
    const int layer = k / 2;
    const double side = k % 2 == 0 ? -0.25 : 0.25;
    Placement at;
    at.yaw = layer * M_PI / 2 + 0.1 * (k % 2);
    at.x = layer % 2 == 0 ? side : 0.05 * layer;
    at.y = layer % 2 == 0 ? 0.05 * layer : side;
    at.z = 0.1 + 1.5 * layer;
    buildRagdollAt(s, at);
  }
}

// Newton's cradle: five 1 kg balls of 0.05 m radius, each hanging 0.5 m
// below a hinge to the world (axis y), touching in a row along x; the
// first is raised 30 degrees and let go. Contacts are elastic (bounce 1)
// and frictionless, as a cradle's steel is near enough: the last ball
// should swing out as high as the first fell, the three between still.
void buildNewtonsCradle(Scene& s) {
  constexpr int kBalls = 5;
  constexpr double kRadius = 0.05, kLength = 0.5, kPivotZ = 1.0, kRaised = M_PI / 6;
  for (int i = 0; i < kBalls; ++i) {
    const double px = (i - 0.5 * (kBalls - 1)) * 2 * kRadius;
    const double swing = i == 0 ? -kRaised : 0.0;
    dMass m;
    dMassSetSphereTotal(&m, 1.0, kRadius);
    dBodyID b =
        s.addBody(m, px + kLength * std::sin(swing), 0.0, kPivotZ - kLength * std::cos(swing));
    s.addGeom(dCreateSphere(s.space(), kRadius), b);
    const dVector3 pivot = {px, 0.0, kPivotZ}, axis = {0, 1, 0};
    s.hinge(b, nullptr, pivot, axis);
  }
  dSurfaceParameters surface{};
  surface.mode = dContactBounce;
  surface.mu = 0.0;
  surface.bounce = 1.0;
  surface.bounce_vel = 0.0;
  s.setContactSurface(surface);
}

// A car on four hinge2 wheels (ODE's demo_buggy, made life-size): a 2 x 1
// x 0.3 m chassis of 150 kg, wheels of 0.3 m radius and 10 kg on sprung
// suspensions (ERP 0.4, CFM 1e-3), steering locked, every wheel driven to
// 10 rad/s (3 m/s) with up to 40 N m, over four static bumps 8 cm high
// and into a pile of six loose 0.25 m boxes.
void buildCar(Scene& s) {
  groundPlane(s);
  constexpr double kWheelR = 0.3, kChassisZ = kWheelR + 0.25;
  dBodyID chassis = box(s, 150.0, 2.0, 1.0, 0.3, 0.0, 0.0, kChassisZ);
  for (const auto& [x, y] : {std::pair{0.7, 0.6}, {0.7, -0.6}, {-0.7, 0.6}, {-0.7, -0.6}}) {
    dMass m;
    dMassSetSphereTotal(&m, 10.0, kWheelR);
    dBodyID wheel = s.addBody(m, x, y, kWheelR);
    s.addGeom(dCreateSphere(s.space(), kWheelR), wheel);
    const dVector3 anchor = {x, y, kWheelR}, steering = {0, 0, 1}, axle = {0, 1, 0};
    dJointID j = s.hinge2(chassis, wheel, anchor, steering, axle);
    dJointSetHinge2Param(j, dParamLoStop, 0.0);
    dJointSetHinge2Param(j, dParamHiStop, 0.0);
    dJointSetHinge2Param(j, dParamSuspensionERP, 0.4);
    dJointSetHinge2Param(j, dParamSuspensionCFM, 1e-3);
    dJointSetHinge2Param(j, dParamVel2, -10.0);  // with this axle, rolls the car towards +x
    dJointSetHinge2Param(j, dParamFMax2, 40.0);
  }
  for (int k = 0; k < 4; ++k) {
    dGeomID bump = dCreateBox(s.space(), 0.3, 3.0, 0.08);
    dGeomSetPosition(bump, 2.0 + 1.5 * k, 0.0, 0.04);
  }
  for (int k = 0; k < 6; ++k) {
    const int row = k < 3 ? 0 : 1;
    box(s, 2.0, 0.25, 0.25, 0.25, 9.0 + 0.3 * row, -0.3 + 0.3 * (k % 3), 0.125 + 0.25 * row);
  }
  s.setProbe(chassis);
}

// A plank bridge: twenty 1 kg planks (0.3 x 1.2 x 0.05 m) hinged edge to
// edge across a 6 m gap, each end hinged to the world, with a 100 kg
// crate (0.5 m) dropped from 0.3 m onto its middle: a 100:1 load hanging
// on light hinges. Planks do not collide with one another.
void buildBridge(Scene& s) {
  constexpr int kPlanks = 20;
  constexpr double kLength = 0.3, kZ = 2.0;
  const dVector3 axis = {0, 1, 0};
  dBodyID previous = nullptr;
  const double x0 = -0.5 * kPlanks * kLength;
  for (int i = 0; i < kPlanks; ++i) {
    dBodyID plank = box(s, 1.0, kLength, 1.2, 0.05, x0 + (i + 0.5) * kLength, 0.0, kZ);
    dGeomID g = dBodyGetFirstGeom(plank);
    dGeomSetCategoryBits(g, 2);
    dGeomSetCollideBits(g, 1);
    const dVector3 edge = {x0 + i * kLength, 0.0, kZ};
    s.hinge(plank, previous, edge, axis);
    previous = plank;
  }
  const dVector3 end = {x0 + kPlanks * kLength, 0.0, kZ};
  s.hinge(previous, nullptr, end, axis);
  dBodyID crate = box(s, 100.0, 0.5, 0.5, 0.5, 0.0, 0.0, kZ + 0.025 + 0.25 + 0.3);
  dGeomSetCategoryBits(dBodyGetFirstGeom(crate), 1);
  dGeomSetCollideBits(dBodyGetFirstGeom(crate), ~0u);
}

// N x N boxes of 0.05 m and 0.01 kg, 0.05 m apart at z = 1.5, ball joints
// at the edge midpoints of neighbours, two corners pinned to the world;
// a static 0.6 m cube below and the ground.
void buildCloth(Scene& s, int n) {
  groundPlane(s);
  dGeomID cube = dCreateBox(s.space(), 0.6, 0.6, 0.6);
  dGeomSetPosition(cube, 0.0, 0.0, 0.7);
  constexpr double kCell = 0.05, kZ = 1.5;
  std::vector<dBodyID> cells(static_cast<std::size_t>(n) * n);
  auto at = [&](int i, int j) -> dBodyID& { return cells[static_cast<std::size_t>(i) * n + j]; };
  auto coord = [&](int i) { return (i - 0.5 * (n - 1)) * kCell; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      at(i, j) = box(s, 0.01, kCell, kCell, kCell, coord(i), coord(j), kZ);
  // Cells collide with the cube and the ground only: one space holds
  // them, so cloth-cloth pairs are told apart by category bits.
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      dGeomID g = dBodyGetFirstGeom(at(i, j));
      dGeomSetCategoryBits(g, 2);
      dGeomSetCollideBits(g, 1);
      if (i + 1 < n) s.ball(at(i, j), at(i + 1, j), coord(i) + 0.5 * kCell, coord(j), kZ);
      if (j + 1 < n) s.ball(at(i, j), at(i, j + 1), coord(i), coord(j) + 0.5 * kCell, kZ);
    }
  }
  // Drawn as one surface: body i * n + j is cell (i, j).
  s.drawHints().surfaceColumns = n;
  for (std::size_t k = 0; k < cells.size(); ++k)
    s.drawHints().surface.push_back(static_cast<int>(k));
  s.ball(at(0, 0), nullptr, coord(0), coord(0), kZ);
  s.ball(at(n - 1, 0), nullptr, coord(n - 1), coord(0), kZ);
}

// 5 x 5 x 5 boxes of 0.1 m and 0.1 kg, fixed to their axis neighbours
// (300 joints), the lattice turned 0.4 rad about (1, 1, 0), centred at
// z = 1, dropped on the plane.
void buildSoftCube(Scene& s) {
  groundPlane(s);
  constexpr int kN = 5;
  constexpr double kSize = 0.1;
  dMatrix3 R;
  dRFromAxisAndAngle(R, 1, 1, 0, 0.4);
  std::vector<dBodyID> cells(kN * kN * kN);
  auto at = [&](int i, int j, int k) -> dBodyID& { return cells[(i * kN + j) * kN + k]; };
  for (int i = 0; i < kN; ++i) {
    for (int j = 0; j < kN; ++j) {
      for (int k = 0; k < kN; ++k) {
        const dVector3 local = {(i - 2) * kSize, (j - 2) * kSize, (k - 2) * kSize};
        dVector3 p;
        dMultiply0_331(p, R, local);
        dBodyID b = box(s, 0.1, kSize, kSize, kSize, p[0], p[1], p[2] + 1.0);
        dBodySetRotation(b, R);
        dGeomID g = dBodyGetFirstGeom(b);
        dGeomSetCategoryBits(g, 2);
        dGeomSetCollideBits(g, 1);
        at(i, j, k) = b;
      }
    }
  }
  for (int i = 0; i < kN; ++i) {
    for (int j = 0; j < kN; ++j) {
      for (int k = 0; k < kN; ++k) {
        if (i + 1 < kN) s.fixed(at(i, j, k), at(i + 1, j, k));
        if (j + 1 < kN) s.fixed(at(i, j, k), at(i, j + 1, k));
        if (k + 1 < kN) s.fixed(at(i, j, k), at(i, j, k + 1));
      }
    }
  }
}

// A static head sphere (r 0.1 m at z = 1.6) with 64 strands of 16
// capsules (r 4 mm, 2 cm long, 1 g) on ball joints, rooted by a ball pin
// at Fibonacci points of the upper half of the head and standing straight
// out along its normal. Capsules collide with the head, the root ones not;
// hair-hair pairs only with strandContacts (the paper's figure 6: "each
// strand can collide with others"), jointed neighbours never.
void buildHair(Scene& s, bool strandContacts) {
  constexpr int kStrands = 64, kSegments = 16;
  constexpr double kHeadR = 0.1, kHeadZ = 1.6, kSegLen = 0.02, kSegR = 0.004;
  dGeomID head = dCreateSphere(s.space(), kHeadR);
  dGeomSetPosition(head, 0.0, 0.0, kHeadZ);
  dGeomSetCategoryBits(head, 1);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < kStrands; ++k) {
    const double z = 1.0 - (k + 0.5) / kStrands;  // upper half: cos of the polar angle
    const double r = std::sqrt(1.0 - z * z);
    const double n[3] = {r * std::cos(golden * k), r * std::sin(golden * k), z};
    dQuaternion q;  // the capsule's z axis along n
    const double angle = std::acos(std::min(1.0, z));
    if (angle > 1e-12) {
      dQFromAxisAndAngle(q, -n[1], n[0], 0.0, angle);  // axis z x n
    } else {
      dQSetIdentity(q);
    }
    dBodyID previous = nullptr;
    s.drawHints().strands.emplace_back();
    for (int i = 0; i < kSegments; ++i) {
      s.drawHints().strands.back().push_back(static_cast<int>(s.bodies().size()));
      auto along = [&](double d, int c) { return (c == 2 ? kHeadZ : 0.0) + n[c] * (kHeadR + d); };
      const double mid = (i + 0.5) * kSegLen;
      dMass m;
      dMassSetCapsuleTotal(&m, 0.001, 3, kSegR, kSegLen - 2 * kSegR);
      dBodyID b = s.addBody(m, along(mid, 0), along(mid, 1), along(mid, 2));
      dBodySetQuaternion(b, q);
      dGeomID g = dCreateCapsule(s.space(), kSegR, kSegLen - 2 * kSegR);
      s.addGeom(g, b);
      // ODE pairs two geoms when either's category meets the other's
      // collide bits, so the root keeps no category either: with category
      // 2 the head's full mask still took it, and a root lying along the
      // head, pinned at the surface, had to sink its cap 3.9 mm: the
      // contact and the pin could not both hold.
      dGeomSetCategoryBits(g, i == 0 ? 0 : 2);
      dGeomSetCollideBits(g, i == 0 ? 0 : strandContacts ? 3 : 1);
      const double joint = i * kSegLen;
      s.ball(b, previous, along(joint, 0), along(joint, 1), along(joint, 2));
      previous = b;
    }
  }
}

// The paper's figure 4, a sheet of fabric rolled up: 32 x 16 spheres
// (r 20 mm, 10 g) 50 mm apart on ball joints, their first row pinned to
// the front of a roller (a 2 kg capsule, r 80 mm, along y, its axle
// 0.3 m up: high enough for the whole roll to clear the ground) hinged to
// the world and driven at 4 rad/s with up to 100 N m. The sheet runs from
// the roller down at 45 degrees to the plane and lies on it; the roller
// drags it in and winds it round, layer on layer: cells collide with the
// ground, the roller and every cell but their joint neighbours, and
// friction holds the layers.
void buildClothRoll(Scene& s) {
  groundPlane(s);
  constexpr int kLong = 32, kWide = 16;
  constexpr double kCell = 0.05, kCellR = 0.02, kRollerR = 0.08, kAxleZ = 0.3;
  dBodyID roller = capsule(s, 2.0, kRollerR, kWide * kCell, 0.0, 0.0, kAxleZ);
  dMatrix3 R;
  dRFromAxisAndAngle(R, 1, 0, 0, -M_PI / 2);  // the capsule's z axis along world y
  dBodySetRotation(roller, R);
  const dVector3 centre = {0.0, 0.0, kAxleZ}, axle = {0, 1, 0};
  dJointID drive = s.hinge(roller, nullptr, centre, axle);
  // Negative about +y: the roller's front (+x) side goes up, taking the
  // pinned row up and over.
  dJointSetHingeParam(drive, dParamVel, -4.0);
  dJointSetHingeParam(drive, dParamFMax, 100.0);
  // Row i's centre (x, z): down the slope from the roller's front, then
  // along the plane.
  std::vector<double> rowX(kLong), rowZ(kLong);
  rowX[0] = kRollerR + kCellR, rowZ[0] = kAxleZ;
  for (int i = 1; i < kLong; ++i) {
    const double down = std::min(kCell * M_SQRT1_2, rowZ[i - 1] - kCellR);
    rowZ[i] = rowZ[i - 1] - down;
    rowX[i] = rowX[i - 1] + std::sqrt(kCell * kCell - down * down);
  }
  std::vector<dBodyID> cells(static_cast<std::size_t>(kLong) * kWide);
  auto at = [&](int i, int j) -> dBodyID& {
    return cells[static_cast<std::size_t>(i) * kWide + j];
  };
  auto y = [&](int j) { return (j - 0.5 * (kWide - 1)) * kCell; };
  s.drawHints().surfaceColumns = kWide;
  for (int i = 0; i < kLong; ++i) {
    for (int j = 0; j < kWide; ++j) {
      dMass m;
      dMassSetSphereTotal(&m, 0.01, kCellR);
      at(i, j) = s.addBody(m, rowX[i], y(j), rowZ[i]);
      s.drawHints().surface.push_back(static_cast<int>(s.bodies().size()) - 1);
      dGeomID g = dCreateSphere(s.space(), kCellR);
      s.addGeom(g, at(i, j));
      dGeomSetCategoryBits(g, 2);
      dGeomSetCollideBits(g, 3);
    }
  }
  for (int i = 0; i < kLong; ++i) {
    for (int j = 0; j < kWide; ++j) {
      if (i + 1 < kLong)
        s.ball(at(i, j), at(i + 1, j), 0.5 * (rowX[i] + rowX[i + 1]), y(j),
               0.5 * (rowZ[i] + rowZ[i + 1]));
      if (j + 1 < kWide) s.ball(at(i, j), at(i, j + 1), rowX[i], y(j) + 0.5 * kCell, rowZ[i]);
    }
  }
  for (int j = 0; j < kWide; ++j)
    s.ball(at(0, j), roller, rowX[0], y(j), rowZ[0]);
  s.setProbe(at(kLong - 1, kWide / 2));  // the free edge: how far it was wound in
}

// A mass ratio carried through contacts: a 1 kg plank (2 m x 0.3 m x
// 0.05 m) laid across two fixed supports 1.6 m apart, and a 1000 kg block
// (0.4 m) set on its middle, everything exactly touching. Nothing should
// move: the plank's contacts carry 1001 kg, the block's 1000 kg.
void buildPlankLoad(Scene& s) {
  groundPlane(s);
  constexpr double kSupportH = 0.5, kPlankH = 0.05, kBlock = 0.4;
  for (double x : {-0.8, 0.8}) {
    dGeomID support = dCreateBox(s.space(), 0.2, 0.4, kSupportH);
    dGeomSetPosition(support, x, 0.0, 0.5 * kSupportH);
  }
  box(s, 1.0, 2.0, 0.3, kPlankH, 0.0, 0.0, kSupportH + 0.5 * kPlankH);
  dBodyID block =
      box(s, 1000.0, kBlock, kBlock, kBlock, 0.0, 0.0, kSupportH + kPlankH + 0.5 * kBlock);
  s.setProbe(block);
}

// demo_I's construction: a light anchor (a 0.1 m box of 0.1 kg) carrying
// ten heavier particles (0.1-1.1 kg, within 0.5 m) on ball joints, its
// centre of mass at the anchor, spinning free of gravity: per-joint
// Gauss-Seidel diverges on it. Masses and places come from a fixed
// sequence, so every run builds the same star.
void buildStar(Scene& s) {
  dWorldSetGravity(s.world(), 0, 0, 0);
  constexpr int kParticles = 10;
  std::uint32_t state = 12345;  // a small linear congruential sequence in [0, 1)
  auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) / double(1 << 24);
  };
  double mass[kParticles], p[kParticles][3], centre[3] = {0, 0, 0}, total = 0.0;
  for (int i = 0; i < kParticles; ++i) {
    mass[i] = next() + 0.1;
    for (double& c : p[i])
      c = next() - 0.5;
    total += mass[i];
    for (int k = 0; k < 3; ++k)
      centre[k] += mass[i] * p[i][k];
  }
  const double anchorZ = 1.0;
  dMass m;
  dMassSetBoxTotal(&m, 0.1, 0.1, 0.1, 0.1);
  dBodyID anchor = s.addBody(m, 0.0, 0.0, anchorZ);
  for (int i = 0; i < kParticles; ++i) {
    double at[3];
    for (int k = 0; k < 3; ++k)
      at[k] = p[i][k] - centre[k] / total;
    dMassSetBoxTotal(&m, mass[i], 0.1, 0.1, 0.1);
    dBodyID b = s.addBody(m, at[0], at[1], at[2] + anchorZ);
    s.ball(anchor, b, at[0], at[1], at[2] + anchorZ);
  }
  // The whole star turning about a skew axis at 1 rad/s.
  const double w[3] = {0.3, 0.5, 0.8};
  for (dBodyID b : s.bodies()) {
    const dReal* x = dBodyGetPosition(b);
    const double r[3] = {x[0], x[1], x[2] - anchorZ};
    dBodySetLinearVel(b, w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2],
                      w[0] * r[1] - w[1] * r[0]);
    dBodySetAngularVel(b, w[0], w[1], w[2]);
  }
}

using Builder = std::function<void(Scene&, int)>;

struct SceneKind {
  Builder build;
  const char* summary;  // a line for --help
};

const std::map<std::string, SceneKind>& builders() {
  static const std::map<std::string, SceneKind> all = {
      {"chain",
       {[](Scene& s, int) { buildChain(s, false); },
        "50 capsule links of 0.1 kg on ball joints, the last 10 kg, hanging from a pin"}},
      {"chain_swing",
       {[](Scene& s, int) { buildChain(s, true); }, "the same chain released horizontally"}},
      {"chain_heavy",
       {[](Scene& s, int) { buildChain(s, false, 100.0); },
        "the hanging chain with a 100 kg end: links 1000 times lighter than their load"}},
      {"chain_heavy_swing",
       {[](Scene& s, int) { buildChain(s, true, 100.0); },
        "chain_swing with a 100 kg end: links 1000 times lighter than the load they whip"}},
      {"plank_load",
       {[](Scene& s, int) { buildPlankLoad(s); },
        "a 1000 kg block on a 1 kg plank across two supports (1000:1 through contacts)"}},
      {"stack", {[](Scene& s, int) { buildStack(s); }, "10 boxes of 0.5 m, 1 kg, on the plane"}},
      {"pyramid",
       {[](Scene& s, int) { buildPyramid(s); },
        "a pyramid of boxes on a base of 20 (0.5 m, 1 kg)"}},
      {"ragdoll",
       {[](Scene& s, int) { buildRagdoll(s); },
        "pelvis, torso, head and two thighs on hinges with stops and a ball, thrown"}},
      {"cloth",
       {[](Scene& s, int n) { buildCloth(s, n > 0 ? n : 32); },
        "N x N boxes on ball joints (--size, 32), two corners pinned, falling on a cube"}},
      {"softcube",
       {[](Scene& s, int) { buildSoftCube(s); },
        "5 x 5 x 5 boxes on 300 fixed joints, dropped turned on the plane"}},
      {"hair",
       {[](Scene& s, int) { buildHair(s, false); },
        "64 strands of 16 capsules on ball joints standing out of a head sphere"}},
      {"hair_touching",
       {[](Scene& s, int) { buildHair(s, true); },
        "hair with strand-strand contacts (the paper's figure 6)"}},
      {"cloth_roll",
       {[](Scene& s, int) { buildClothRoll(s); },
        "32 x 16 spheres on ball joints wound onto a driven roller, layer on layer "
        "(the paper's figure 4: self-collision and friction)"}},
      {"ragdoll_pile",
       {[](Scene& s, int) { buildRagdollPile(s); },
        "eight ragdolls dropped in turned pairs onto the plane and one another"}},
      {"cradle",
       {[](Scene& s, int) { buildNewtonsCradle(s); },
        "Newton's cradle: five balls on hinges, elastic frictionless contacts, one raised"}},
      {"car",
       {[](Scene& s, int) { buildCar(s); },
        "a 150 kg car on four driven hinge2 wheels over bumps into loose boxes"}},
      {"bridge",
       {[](Scene& s, int) { buildBridge(s); },
        "20 one-kilogram planks hinged across a gap, a 100 kg crate dropped on the middle"}},
      {"hulls",
       {[](Scene& s, int n) { buildHulls(s, n > 0 ? n : 100); },
        "100 random convex hulls (size: their count) dropped in a loose column onto the plane"}},
      {"pile",
       {[](Scene& s, int n) { buildPile(s, n > 0 ? n : 10); },
        "1,000 boxes, spheres, capsules, cylinders and convex hulls (size: layers of 100) "
        "dropped onto the plane"}},
      {"star",
       {[](Scene& s, int) { buildStar(s); },
        "ODE's demo_I: a 0.1 kg anchor carrying ten heavier particles on ball joints, spinning"}},
  };
  return all;
}

}  // namespace

const std::vector<std::string>& sceneNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& [name, build] : builders())
      n.push_back(name);
    return n;
  }();
  return names;
}

std::string sceneSummary(const std::string& name) {
  const auto it = builders().find(name);
  return it == builders().end() ? std::string() : it->second.summary;
}

std::unique_ptr<Scene> makeScene(const std::string& name, int size) {
  const auto it = builders().find(name);
  if (it == builders().end()) {
    std::string accepted;
    for (const std::string& n : sceneNames())
      accepted += (accepted.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown scene '" + name + "' (accepted: " + accepted + ")");
  }
  if (size < 0 || size > 256)
    throw std::invalid_argument("scene size " + std::to_string(size) + " is not in 0..256");
  auto scene = std::make_unique<Scene>();
  scene->setName(name == "cloth" ? "cloth" + std::to_string(size > 0 ? size : 32) : name);
  it->second.build(*scene, size);
  return scene;
}

}  // namespace blockstep::compare

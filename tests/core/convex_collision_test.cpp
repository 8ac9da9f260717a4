// GJK/EPA and feature-clipped manifolds between convex shapes, against
// closed forms and against the separating-axis path for boxes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "core/collision/convex_hull.h"
#include "core/collision/gjk_epa.h"
#include "core/collision/manifold.h"
#include "core/collision/narrowphase.h"

namespace blockstep {
namespace {

constexpr double kMargin = 0.02;

ShapePose at(const Vec3& position, const Quat& q = Quat::Identity()) {
  return ShapePose{position, q.toRotationMatrix()};
}

Quat about(const Vec3& axis, double angle) {
  return Quat(Eigen::AngleAxisd(angle, axis.normalized()));
}

double deepest(const ContactManifold& m) {
  double s = kInf;
  for (int i = 0; i < m.pointCount; ++i)
    s = std::min(s, m.points[i].separation);
  return s;
}

// The least overlap of two shapes' projections over 20,000 directions (a
// Fibonacci sphere), m: never less than their true depth (the overlap
// along any direction bounds it), negative where one separates them. An
// answer GJK and EPA are checked against without either of them.
double leastProjectedOverlap(const Shape& a, const ShapePose& pa, const Shape& b,
                             const ShapePose& pb) {
  const PosedConvex A(a, pa), B(b, pb);
  double least = kInf;
  constexpr int kDirections = 20000;
  for (int i = 0; i < kDirections; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / kDirections, r = std::sqrt(1.0 - z * z);
    const double phi = i * 2.399963229728653;  // the golden angle
    const Vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    least =
        std::min(least, A.coreSupport(d).dot(d) - B.coreSupport(-d).dot(d) + A.radius + B.radius);
  }
  return least;
}

std::shared_ptr<const ConvexHull> boxHull(const Vec3& half) {
  std::vector<Vec3> corners;
  for (int c = 0; c < 8; ++c)
    corners.push_back(Vec3(c & 1 ? half.x() : -half.x(), c & 2 ? half.y() : -half.y(),
                           c & 4 ? half.z() : -half.z()));
  return std::make_shared<const ConvexHull>(ConvexHull::fromPoints(corners));
}

// Depth and normal to 1e-6 relative, as the closed form gives them.
void expectContact(const ContactManifold& m, int points, double separation, const Vec3& normal) {
  ASSERT_EQ(m.pointCount, points);
  EXPECT_NEAR(deepest(m), separation, 1e-6 * std::abs(separation) + 1e-12);
  EXPECT_LT((m.normal - normal).norm(), 1e-6) << m.normal.transpose();
}

TEST(ConvexCollision, SpheresThroughGjkMatchTheClosedForm) {
  const Shape a = Shape::sphere(0, 1.0), b = Shape::sphere(1, 0.5);
  const Vec3 centre(1.2, 0.4, -0.3);
  ContactManifold m;
  collideConvex(a, at(Vec3::Zero()), b, at(centre), kMargin, m);
  expectContact(m, 1, centre.norm() - 1.5, centre.normalized());
  // Apart within the margin: a speculative point with its true gap.
  const Vec3 near = centre.normalized() * 1.51;
  collideConvex(a, at(Vec3::Zero()), b, at(near), kMargin, m);
  expectContact(m, 1, 0.01, centre.normalized());
  EXPECT_EQ(collideConvex(a, at(Vec3::Zero()), b, at(centre.normalized() * 1.6), kMargin, m), 0);
}

TEST(ConvexCollision, SphereAgainstBoxFaceAndEdgeMatchTheClosedForm) {
  const Shape box = Shape::box(0, Vec3(0.5, 0.4, 0.3)), ball = Shape::sphere(1, 0.2);
  ContactManifold m;
  // Over the top face, 0.05 deep.
  collideConvex(box, at(Vec3::Zero()), ball, at(Vec3(0.1, -0.2, 0.45)), kMargin, m);
  expectContact(m, 1, -0.05, Vec3::UnitZ());
  // Beside the edge along y at (0.5, *, 0.3): the normal points from the
  // edge to the centre.
  const Vec3 edge(0.5, 0.1, 0.3), offset = Vec3(1, 0, 1).normalized() * 0.15;
  collideConvex(box, at(Vec3::Zero()), ball, at(edge + offset), kMargin, m);
  expectContact(m, 1, 0.15 - 0.2, offset.normalized());
  // Turned boxes agree with the fast path.
  const Quat q = about(Vec3(1, 2, 3), 0.8);
  const Vec3 c = q * Vec3(0.3, 0.1, 0.45);
  ContactManifold fast;
  collideBoxSphere(box, at(Vec3::Zero(), q), ball, at(c), kMargin, fast);
  collideConvex(box, at(Vec3::Zero(), q), ball, at(c), kMargin, m);
  expectContact(m, 1, fast.points[0].separation, fast.normal);
}

TEST(ConvexCollision, BoxOnBoxFaceGivesFourPointsLikeTheSeparatingAxisPath) {
  const Shape lower = Shape::box(0, Vec3(1, 1, 0.5)), upper = Shape::box(1, Vec3(0.3, 0.2, 0.25));
  const Quat turn = about(Vec3::UnitZ(), 0.4);
  const ShapePose pl = at(Vec3::Zero()), pu = at(Vec3(0.1, 0.2, 0.74), turn);
  ContactManifold gjk, sat;
  collideConvex(lower, pl, upper, pu, kMargin, gjk);
  collideBoxes(lower, pl, upper, pu, kMargin, sat);
  expectContact(gjk, 4, -0.01, Vec3::UnitZ());
  ASSERT_EQ(sat.pointCount, 4);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(gjk.points[i].separation, -0.01, 1e-12);
    double closest = kInf;
    for (int j = 0; j < 4; ++j)
      closest = std::min(closest, (gjk.points[i].position - sat.points[j].position).norm());
    EXPECT_LT(closest, 1e-9) << "GJK point " << i << " is not a SAT point";
  }
  // The same boxes as hulls: the same manifold.
  const Shape hullLower = Shape::convex(0, boxHull(Vec3(1, 1, 0.5)));
  const Shape hullUpper = Shape::convex(1, boxHull(Vec3(0.3, 0.2, 0.25)));
  ContactManifold hulls;
  collideConvex(hullLower, pl, hullUpper, pu, kMargin, hulls);
  expectContact(hulls, 4, -0.01, Vec3::UnitZ());
  // Apart by 5 mm: four speculative points at +5 mm, from GJK's distance.
  collideConvex(lower, pl, upper, at(Vec3(0.1, 0.2, 0.755), turn), kMargin, gjk);
  expectContact(gjk, 4, 0.005, Vec3::UnitZ());
  EXPECT_NEAR(gjk.points[3].separation, 0.005, 1e-12);
}

// The area of the manifold's points as a polygon (on a plane z = const).
double supportArea(const ContactManifold& m) {
  std::vector<Vec3> p;
  for (int i = 0; i < m.pointCount; ++i)
    p.push_back(m.points[i].position);
  const Vec3 c = std::accumulate(p.begin(), p.end(), Vec3(Vec3::Zero())) / p.size();
  std::sort(p.begin(), p.end(), [&](const Vec3& a, const Vec3& b) {
    return std::atan2(a.y() - c.y(), a.x() - c.x()) < std::atan2(b.y() - c.y(), b.x() - c.x());
  });
  double area = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i)
    area += 0.5 * (p[i] - c).cross(p[(i + 1) % p.size()] - c).z();
  return area;
}

TEST(ConvexCollision, ABoxHangingOverALargeBoxsEdgeIsFoundByTheSeparatingAxisPath) {
  // A 50 mm cloth cell pulled over the edge of the 0.6 m cube (the poses
  // the core held, cloth32 at 10 sub-steps): it is 9.8 mm into the
  // cube's side. The separating-axis test took the cell's face by its
  // tie-break, clipped the wrong face of the cube, found no point, and
  // the cell went on sinking through the side unseen.
  const Shape cell = Shape::box(0, Vec3(0.025, 0.025, 0.025));
  const Shape cube = Shape::box(1, Vec3(0.3, 0.3, 0.3));
  const ShapePose cellPose{
      Vec3(-0.30705353155128917, 0.32695431126242824, 0.79770795254230598),
      (Mat3() << 0.71327047877101979, -0.44590590340670544, -0.5407523919695687,
       0.68294517083652972, 0.26870605639911904, 0.67925175663040926, -0.15757892544634072,
       -0.85379446037174733, 0.49618938087558195)
          .finished()};
  const ShapePose cubePose = at(Vec3(0.0, 0.0, 0.7));
  const double overlap = leastProjectedOverlap(cell, cellPose, cube, cubePose);
  ASSERT_GT(overlap, 0.009);
  ContactManifold sat, gjk;
  ASSERT_GT(collideBoxes(cell, cellPose, cube, cubePose, 0.0047, sat), 0);
  ASSERT_GT(collideConvex(cell, cellPose, cube, cubePose, 0.0047, gjk), 0);
  // Deep (the sampled directions bound the depth from above), and as
  // GJK/EPA finds it: across the cube's vertical edge the cell hangs over.
  EXPECT_LT(deepest(sat), -0.009);
  EXPECT_GE(deepest(sat), -overlap);
  EXPECT_NEAR(deepest(sat), deepest(gjk), 1e-9);
  EXPECT_LT((sat.normal - gjk.normal).norm(), 1e-9) << sat.normal.transpose();
}

TEST(ConvexCollision, ABoxOnABoxOfItsSizeTurnedAHairRestsOnItsFourCorners) {
  // Turned 1e-7 rad, the upper box's bottom edges cross the lower box's
  // top edges at points anywhere along them, and clipping keeps those
  // beside the corners: the four kept must span the whole face (0.25 m^2),
  // not three corners and a point along an edge.
  const Shape box = Shape::box(0, Vec3(0.25, 0.25, 0.25));
  for (double turn : {1e-7, -3e-7, 2e-6}) {
    const ShapePose lower = at(Vec3::Zero());
    const ShapePose upper = at(Vec3(2e-8, -1e-8, 0.4999), about(Vec3::UnitZ(), turn));
    ContactManifold sat, gjk;
    collideBoxes(box, lower, box, upper, kMargin, sat);
    collideConvex(box, lower, box, upper, kMargin, gjk);
    for (const ContactManifold* m : {&sat, &gjk}) {
      ASSERT_EQ(m->pointCount, 4);
      EXPECT_GT(supportArea(*m), 0.999 * 0.25) << "turned " << turn;
    }
  }
}

TEST(ConvexCollision, ClippedPointsKeepTheirFeatureIdsWhileTheBoxSlides) {
  // A box sliding across a larger one, and a hull box on a hull: each
  // corner's point keeps its id from one position to the next (warm
  // starting follows the corner, however far it moved), the ids of one
  // manifold differ, and a corner that leaves the face takes its id away.
  const Shape lower = Shape::box(0, Vec3(1, 1, 0.5)), upper = Shape::box(1, Vec3(0.3, 0.2, 0.25));
  const Shape hullLower = Shape::convex(0, boxHull(Vec3(1, 1, 0.5)));
  const Shape hullUpper = Shape::convex(1, boxHull(Vec3(0.3, 0.2, 0.25)));
  const Quat turn = about(Vec3::UnitZ(), 0.4);
  for (int kind = 0; kind < 3; ++kind) {
    auto collideAt = [&](double x, ContactManifold& m) {
      const ShapePose pl = at(Vec3::Zero()), pu = at(Vec3(x, 0.2, 0.74), turn);
      if (kind == 0) return collideBoxes(lower, pl, upper, pu, kMargin, m);
      if (kind == 1) return collideConvex(lower, pl, upper, pu, kMargin, m);
      return collideConvex(hullLower, pl, hullUpper, pu, kMargin, m);
    };
    ContactManifold before, after;
    ASSERT_EQ(collideAt(0.0, before), 4);
    ASSERT_EQ(collideAt(0.05, after), 4);  // 50 mm on: beyond position matching's 20 mm
    for (int i = 0; i < 4; ++i) {
      EXPECT_NE(before.points[i].feature, 0u);
      for (int j = 0; j < i; ++j)
        EXPECT_NE(before.points[i].feature, before.points[j].feature);
      int same = -1;
      for (int j = 0; j < 4; ++j)
        if (after.points[j].feature == before.points[i].feature) same = j;
      ASSERT_GE(same, 0) << "kind " << kind << ": point " << i << " lost its id";
      EXPECT_LT((after.points[same].position - before.points[i].position - Vec3(0.05, 0, 0)).norm(),
                1e-9);
    }
    // Past the lower box's edge at x = 1 the corners there are cut: the
    // points on the edge are new features.
    ContactManifold over;
    ASSERT_EQ(collideAt(0.8, over), 4);
    int kept = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        kept += over.points[i].feature == before.points[j].feature;
    EXPECT_LT(kept, 4) << "kind " << kind;
  }
}

// Five vertices of a hull within the ground's margin, as a heap left one
// (world frame, m; their separations): two sunk about 7 mm, two touching,
// one 0.3 mm above. By their spread alone the second deep one lost its
// place to the one above; left out it sank, came back at the next
// collision in place of the first, and the hull rocked between the two
// every few steps at up to 27 mm/s. With four touching, the four are
// those, the deepest first; with fewer, the spread still chooses.
TEST(ConvexCollision, ReducingToFourPrefersPointsThatTouchToPointsApart) {
  const Vec3 pos[5] = {Vec3(1.1685, -0.0953, 0), Vec3(1.0009, -0.0505, 0), Vec3(1.0343, 0.0951, 0),
                       Vec3(0.9668, -0.0122, 0), Vec3(1.0624, 0.0432, 0)};
  const double sep[5] = {0.0, -0.00731, 0.0, 0.00033, -0.00654};
  int keep[4];
  ASSERT_EQ(reduceToFour(pos, sep, 5, keep), 4);
  EXPECT_EQ(keep[0], 1);
  std::sort(keep + 1, keep + 4);
  EXPECT_EQ(keep[1], 0);
  EXPECT_EQ(keep[2], 2);
  EXPECT_EQ(keep[3], 4);
  // Only three touching: the one apart competes by its spread again.
  const double fewer[5] = {0.0, -0.00731, 0.001, 0.00033, -0.00654};
  ASSERT_EQ(reduceToFour(pos, fewer, 5, keep), 4);
  EXPECT_NE(std::find(keep, keep + 4, 3), keep + 4);
  // A face flat on a face: corners and points between them a few
  // micrometres either side of touching all touch, and the four kept span
  // the patch: the far corner 5 um apart among them (taken for apart, it
  // was left out for points along one side, and a spinning hull rocked
  // onto it 7.8 mm deep in the pile).
  const Vec3 flat[6] = {Vec3(0, 0, 0),   Vec3(0.2, 0, 0),     Vec3(0.2, 0.1, 0),
                        Vec3(0, 0.1, 0), Vec3(0.05, 0.02, 0), Vec3(0.02, 0.08, 0)};
  const double flatSep[6] = {-3e-5, -2e-5, 5e-6, -1e-5, -2.5e-5, -2e-5};
  ASSERT_EQ(reduceToFour(flat, flatSep, 6, keep), 4);
  std::sort(keep, keep + 4);
  EXPECT_EQ(keep[0], 0);
  EXPECT_EQ(keep[1], 1);
  EXPECT_EQ(keep[2], 2);
  EXPECT_EQ(keep[3], 3);
}

TEST(ConvexCollision, CrossedBoxEdgesGiveOnePointAtTheClosedFormDepth) {
  // A's top is an edge along x at height sqrt(1/2); B's bottom an edge
  // along y at B's height minus sqrt(1/2): they cross, 30 mm deep.
  const double h = std::sqrt(0.5);
  const Shape a = Shape::box(0, Vec3(0.5, 0.5, 0.5)), b = Shape::box(1, Vec3(0.5, 0.5, 0.5));
  const ShapePose pa = at(Vec3::Zero(), about(Vec3::UnitX(), kPi / 4));
  const ShapePose pb = at(Vec3(0.05, -0.02, 2 * h - 0.03), about(Vec3::UnitY(), kPi / 4));
  ContactManifold m;
  collideConvex(a, pa, b, pb, kMargin, m);
  expectContact(m, 1, -0.03, Vec3::UnitZ());
  // The edges cross at A's edge (y = 0) under B's (x = 0.05), midway in depth.
  EXPECT_LT((m.points[0].position - Vec3(0.05, 0, h - 0.015)).norm(), 1e-6);
}

TEST(ConvexCollision, CapsuleOnABoxLiesOnTwoPointsOrTipsOnOne) {
  const double r = 0.1, length = 0.6;
  const Shape box = Shape::box(0, Vec3(1, 1, 0.5)), capsule = Shape::capsule(1, r, length);
  const Quat lying = about(Vec3::UnitY(), kPi / 2);  // axis along x
  ContactManifold m;
  collideConvex(box, at(Vec3::Zero()), capsule, at(Vec3(0.2, 0.1, 0.5 + r - 0.02), lying), kMargin,
                m);
  expectContact(m, 2, -0.02, Vec3::UnitZ());
  EXPECT_NEAR(std::abs(m.points[0].position.x() - m.points[1].position.x()), length, 1e-9);
  // Tipped by 20 degrees: the low end alone, at its closed-form depth.
  const double tilt = 20.0 * kPi / 180.0;
  const double centreHeight = 0.5 + r + 0.5 * length * std::sin(tilt) - 0.015;
  collideConvex(box, at(Vec3::Zero()), capsule,
                at(Vec3(0, 0, centreHeight), about(Vec3::UnitY(), kPi / 2 + tilt)), kMargin, m);
  expectContact(m, 1, -0.015, Vec3::UnitZ());
  // Through the plane path as well.
  const Shape ground = Shape::plane(Vec3::UnitZ(), 0.5);
  collideConvexPlane(ground, capsule, at(Vec3(0.2, 0.1, 0.5 + r - 0.02), lying), kMargin, m);
  expectContact(m, 2, -0.02, Vec3::UnitZ());
}

// The distance between two segments by golden-section search over A's
// parameter (the distance from a point of A to segment B is convex in it),
// written apart from the collider's own closest-point routine.
double segmentDistance(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  auto toB = [&](double s) {
    const Vec3 p = a0 + s * (a1 - a0), d = b1 - b0;
    const double t =
        d.squaredNorm() > 0.0 ? std::clamp((p - b0).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    return (b0 + t * d - p).norm();
  };
  double lo = 0.0, hi = 1.0;
  const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int i = 0; i < 200; ++i) {
    const double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo);
    (toB(x1) < toB(x2) ? hi : lo) = toB(x1) < toB(x2) ? x2 : x1;
  }
  return std::min({toB(0.5 * (lo + hi)), toB(0.0), toB(1.0)});
}

void coreSegment(const Shape& s, const ShapePose& p, Vec3& start, Vec3& end) {
  const Vec3 half =
      s.kind == Shape::Kind::Capsule ? Vec3(s.halfLength * p.rotation.col(2)) : Vec3::Zero();
  start = p.position - half;
  end = p.position + half;
}

TEST(ConvexCollision, CapsulesAndSpheresTouchAtTheirSegmentsClosestPoints) {
  // 2,000 random pairs of a capsule with a capsule or a sphere, near
  // touching: the deepest point is the segments' distance less the radii
  // (to 1e-9 m), and GJK/EPA on the same pair agrees to 1e-6; every point
  // has a unit normal from A toward B and lies within the margin; never
  // more than four.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), size(0.02, 0.15);
  int compared = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Shape a = trial % 3 == 0 ? Shape::sphere(0, size(rng))
                                   : Shape::capsule(0, size(rng), 4.0 * size(rng));
    const Shape b = Shape::capsule(1, size(rng), 4.0 * size(rng));
    const Vec3 axisA(unit(rng), unit(rng), unit(rng)), axisB(unit(rng), unit(rng), unit(rng));
    const ShapePose pa = at(Vec3::Zero(), about(axisA, 3.0 * unit(rng)));
    // B placed so that the cores come within the radii give or take 30 mm.
    const Vec3 offset = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
    ShapePose pb = at(0.5 * (a.halfLength + b.halfLength) * offset, about(axisB, 3.0 * unit(rng)));
    Vec3 a0, a1, b0, b1;
    coreSegment(a, pa, a0, a1);
    coreSegment(b, pb, b0, b1);
    const double gap = segmentDistance(a0, a1, b0, b1) - a.radius - b.radius;
    pb.position += (0.03 * unit(rng) - gap) * offset;
    coreSegment(b, pb, b0, b1);
    const double exact = segmentDistance(a0, a1, b0, b1) - a.radius - b.radius;
    ContactManifold m;
    const int n = collideRoundSegments(a, pa, b, pb, kMargin, m);
    if (exact > kMargin) {
      EXPECT_EQ(n, 0);
      continue;
    }
    ASSERT_GE(n, 1);
    ASSERT_LE(n, kMaxManifoldPoints);
    EXPECT_NEAR(m.points[0].separation, exact, 1e-9) << "trial " << trial;
    EXPECT_NEAR(deepest(m), exact, 1e-9) << "trial " << trial;
    // Each point: midway between a point of A's surface over its core and
    // one of B's, along its normal from A toward B.
    for (int i = 0; i < n; ++i) {
      const ContactPoint& p = m.points[i];
      EXPECT_NEAR(p.normal.norm(), 1.0, 1e-9);
      EXPECT_LE(p.separation, kMargin);
      const Vec3 onA = p.position - (a.radius + 0.5 * p.separation) * p.normal;
      const Vec3 onB = p.position + (b.radius + 0.5 * p.separation) * p.normal;
      EXPECT_LT(segmentDistance(onA, onA, a0, a1), 1e-9) << "trial " << trial;
      EXPECT_LT(segmentDistance(onB, onB, b0, b1), 1e-9) << "trial " << trial;
    }
    if (exact > -0.5 * std::min(a.radius, b.radius)) {
      ContactManifold viaGjk;
      ASSERT_GE(collideConvex(a, pa, b, pb, kMargin, viaGjk), 1);
      EXPECT_NEAR(deepest(viaGjk), exact, 1e-6) << "trial " << trial;
      ++compared;
    }
  }
  EXPECT_GT(compared, 500);
}

// How far x lies from a cylinder's side (the tube of its radius about its
// axis), and whether it lies between the cylinder's ends; for a capsule,
// how far outside it x lies (a capsule's end is the sphere about its
// segment's end, and a point of that sphere may lie inside the capsule).
double offSide(const Shape& s, const ShapePose& p, const Vec3& x, bool& within) {
  const Vec3 axis = p.rotation.col(2);
  const double along = (x - p.position).dot(axis);
  within = std::abs(along) <= s.halfLength + 1e-9;
  if (s.kind == Shape::Kind::Capsule) {
    within = true;
    const double t = std::clamp(along, -s.halfLength, s.halfLength);
    return std::max(0.0, (x - p.position - t * axis).norm() - s.radius);
  }
  return std::abs((x - p.position - along * axis).norm() - s.radius);
}

TEST(ConvexCollision, CylinderSidesTouchAtTheirClosestPointsAndTheirRims) {
  // 2,000 random pairs of a cylinder with a cylinder or a capsule, lying
  // at up to 30 degrees to one another (the rod levered along a cylinder
  // in the pile) or crossing at any angle, within 15 mm of touching
  // (apart or into one another) where their sides are nearest. Where the sides
  // meet, every point lies on both shapes' sides, at its own separation
  // along a unit normal, and is never deeper than the pair's projections
  // overlap along some direction (the least over 20,000: nothing is
  // deeper than the whole pair); the closest points agree with GJK/EPA on
  // the same pair. Where a cap or rim is nearest the answer is left to
  // GJK/EPA (-1).
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), size(0.02, 0.12);
  int sides = 0, agreed = 0, withRims = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Shape a = Shape::cylinder(0, size(rng), 4.0 * size(rng));
    const Shape b = trial % 3 == 0 ? Shape::capsule(1, size(rng), 4.0 * size(rng))
                                   : Shape::cylinder(1, size(rng), 4.0 * size(rng));
    const Vec3 axisA = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
    const ShapePose pa = at(Vec3::Zero(), Quat::FromTwoVectors(Vec3::UnitZ(), axisA));
    Vec3 across = axisA.cross(Vec3(unit(rng), unit(rng), unit(rng))).normalized();
    const double turn = trial % 2 == 0 ? 0.5 * unit(rng) : 3.0 * unit(rng);
    const Vec3 axisB = about(axisA.cross(across), turn) * axisA;
    ShapePose pb = at(
        0.5 * a.halfLength * unit(rng) * axisA + (a.radius + b.radius + 0.01 * unit(rng)) * across,
        Quat::FromTwoVectors(Vec3::UnitZ(), axisB));
    pb.position += 0.5 * b.halfLength * unit(rng) * axisB;
    ContactManifold m;
    int n = collideRoundSegments(a, pa, b, pb, 1.0, m);
    if (n < 0) continue;
    // Moved along the closest points' normal to within 15 mm of touching.
    pb.position += (0.015 * unit(rng) - m.points[0].separation) * m.normal;
    n = collideRoundSegments(a, pa, b, pb, kMargin, m);
    if (n < 0) continue;
    ContactManifold viaGjk;
    const int gjk = collideConvex(a, pa, b, pb, kMargin, viaGjk);
    if (n == 0) {
      EXPECT_EQ(gjk, 0) << "trial " << trial;
      continue;
    }
    ++sides;
    ASSERT_LE(n, kMaxManifoldPoints);
    const double leastOverlap = leastProjectedOverlap(a, pa, b, pb);
    for (int i = 0; i < n; ++i) {
      const ContactPoint& p = m.points[i];
      EXPECT_NEAR(p.normal.norm(), 1.0, 1e-9);
      EXPECT_LE(p.separation, kMargin);
      EXPECT_GE(p.separation, -leastOverlap - 1e-9) << "trial " << trial;
      bool withinA, withinB;
      EXPECT_LT(offSide(a, pa, p.position - 0.5 * p.separation * p.normal, withinA), 1e-9)
          << "trial " << trial << " point " << i;
      EXPECT_LT(offSide(b, pb, p.position + 0.5 * p.separation * p.normal, withinB), 1e-9)
          << "trial " << trial << " point " << i;
      EXPECT_TRUE(withinA && withinB) << "trial " << trial << " point " << i;
      withRims += p.feature == 2 || p.feature == 3 ? 1 : 0;
    }
    ASSERT_GE(gjk, 1) << "trial " << trial;
    agreed += std::abs(m.points[0].separation - deepest(viaGjk)) < 1e-6 ? 1 : 0;
  }
  std::printf("  %d pairs side to side (%d closest points as GJK/EPA's, %d rim points)\n", sides,
              agreed, withRims);
  EXPECT_GT(sides, 400);
  EXPECT_GT(agreed, 0.9 * sides);
  EXPECT_GT(withRims, 100);
}

TEST(ConvexCollision, CapsulesAtASmallAngleHoldAtTheirEndsToo) {
  // B along x; A 10 degrees off it, h above, crossing over B's centre.
  // Besides the crossing, A's two ends are points of their own, each at
  // its closed-form distance from B's segment: a pair touching at one
  // point as it turned see-sawed about it. Crossed square, the ends are
  // far: one point.
  const double r = 0.05, halfLength = 0.2, h = 2 * r - 0.002, angle = 10.0 * kPi / 180.0;
  const Shape a = Shape::capsule(0, r, 2 * halfLength), b = Shape::capsule(1, r, 2 * halfLength);
  const Quat alongX = about(Vec3::UnitY(), kPi / 2);
  const ShapePose pb = at(Vec3::Zero(), alongX);
  const ShapePose pa = at(Vec3(0, 0, h), about(Vec3::UnitZ(), angle) * alongX);
  ContactManifold m;
  ASSERT_EQ(collideRoundSegments(a, pa, b, pb, 0.05, m), 3);
  EXPECT_NEAR(m.points[0].separation, -0.002, 1e-12);
  EXPECT_LT((m.normal - -Vec3::UnitZ()).norm(), 1e-12);
  const double endSeparation =
      std::hypot(halfLength * std::sin(angle), h) - 2 * r;  // 37.4 mm apart
  for (int i = 1; i < 3; ++i) {
    EXPECT_NEAR(m.points[i].separation, endSeparation, 1e-12);
    EXPECT_NEAR(std::abs(m.points[i].position.x()), halfLength * std::cos(angle), 1e-12);
  }
  ASSERT_EQ(collideRoundSegments(a, at(Vec3(0, 0, h), about(Vec3::UnitZ(), kPi / 2) * alongX), b,
                                 pb, 0.05, m),
            1);
  // Side by side, overlapping over 0.3 m: the overlap's two ends (and
  // not A's end beyond B's, 40 mm apart).
  ASSERT_EQ(collideRoundSegments(a, at(Vec3(0.1, 0, h), alongX), b, pb, kMargin, m), 2);
  for (int i = 0; i < 2; ++i)
    EXPECT_NEAR(m.points[i].separation, -0.002, 1e-12);
  EXPECT_NEAR(std::abs(m.points[0].position.x() - m.points[1].position.x()), 0.3, 1e-12);
  // A short fat capsule across a long one at 5 degrees: the crossing, both
  // of its ends and both ends of the long one are within the margin. Four
  // are kept, the crossing first; a fifth went past the manifold's room.
  const Shape fat = Shape::capsule(0, 0.1, 0.4), shortFat = Shape::capsule(1, 0.1, 0.2);
  ASSERT_EQ(collideRoundSegments(
                fat, at(Vec3::Zero(), alongX), shortFat,
                at(Vec3(0, 0, 0.19), about(Vec3::UnitZ(), 5.0 * kPi / 180.0) * alongX), kMargin, m),
            4);
  EXPECT_NEAR(m.points[0].separation, -0.01, 1e-12);
}

TEST(ConvexCollision, CylinderOnAPlaneStandsOnItsCapOrTouchesAtItsRim) {
  const double r = 0.3, length = 0.8;
  const Shape ground = Shape::plane(Vec3::UnitZ(), 0.0), cylinder = Shape::cylinder(1, r, length);
  ContactManifold m;
  collideConvexPlane(ground, cylinder, at(Vec3(1, 2, 0.5 * length - 0.01)), kMargin, m);
  expectContact(m, 4, -0.01, Vec3::UnitZ());
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(m.points[i].separation, -0.01, 1e-12);
    EXPECT_NEAR((m.points[i].position - Vec3(1, 2, -0.005)).norm(), r, 1e-12);
  }
  // Tilted by 60 degrees: the lowest rim point, r sin + l/2 cos below the
  // centre (its neighbours on the rim are beyond the margin).
  const double tilt = kPi / 3;
  const double low = r * std::sin(tilt) + 0.5 * length * std::cos(tilt);
  collideConvexPlane(ground, cylinder, at(Vec3(0, 0, low - 0.012), about(Vec3::UnitX(), tilt)),
                     kMargin, m);
  expectContact(m, 1, -0.012, Vec3::UnitZ());
  // On its side: the side line, two points.
  collideConvexPlane(ground, cylinder, at(Vec3(0, 0, r - 0.004), about(Vec3::UnitX(), kPi / 2)),
                     kMargin, m);
  expectContact(m, 2, -0.004, Vec3::UnitZ());
}

TEST(ConvexCollision, CrossedCylindersTouchAtOnePointWhereTheirSidesCross) {
  // A thin cylinder lying across a fat one, both on their sides, the thin
  // one's axis turned 70 degrees from the fat one's: their side lines cross
  // at one point, 12 mm deep. Clipping one side line to the other's ends
  // kept the thin one's whole side line (two points 8 cm either side of
  // the crossing, where nothing touches): a resting pile's pair stayed
  // 12.7 mm deep while the solver turned the thin one about its own axis.
  const double bigR = 0.063, bigL = 0.186, thinR = 0.016, thinL = 0.168, depth = 0.012;
  const Shape fat = Shape::cylinder(0, bigR, bigL), thin = Shape::cylinder(1, thinR, thinL);
  const Quat fatLying = about(Vec3::UnitY(), kPi / 2);  // axis along x
  const Quat thinLying = about(Vec3::UnitZ(), 70.0 * kPi / 180.0) * about(Vec3::UnitY(), kPi / 2);
  const Vec3 crossing(0.03, 0.0, bigR - 0.5 * depth);
  ContactManifold m;
  collideConvex(fat, at(Vec3::Zero(), fatLying), thin,
                at(Vec3(0.03, 0.0, bigR + thinR - depth), thinLying), kMargin, m);
  expectContact(m, 1, -depth, Vec3::UnitZ());
  EXPECT_LT((m.points[0].position - crossing).head<2>().norm(), 1e-6)
      << m.points[0].position.transpose();
  // Side by side along the same axis they touch along a line: two points,
  // at the ends of the shorter one. (EPA's normal between two curved
  // sides in line contact is 3 mrad off, and its depth 1.3 um: its
  // polytope meets the line at a slant.)
  collideConvex(fat, at(Vec3::Zero(), fatLying), thin,
                at(Vec3(0.005, 0.0, bigR + thinR - depth), fatLying), kMargin, m);
  ASSERT_EQ(m.pointCount, 2);
  EXPECT_NEAR(deepest(m), -depth, 1e-5);
  EXPECT_LT((m.normal - Vec3::UnitZ()).norm(), 0.01);
  EXPECT_NEAR(std::abs(m.points[0].position.x() - m.points[1].position.x()), thinL, 1e-4);
}

TEST(ConvexCollision, CylinderOnABoxThroughEpaStandsOnFourPoints) {
  const Shape box = Shape::box(0, Vec3(1, 1, 0.5)), cylinder = Shape::cylinder(1, 0.3, 0.8);
  ContactManifold m;
  collideConvex(box, at(Vec3::Zero()), cylinder, at(Vec3(0.1, 0, 0.5 + 0.4 - 0.01)), kMargin, m);
  expectContact(m, 4, -0.01, Vec3::UnitZ());
}

TEST(ConvexCollision, ShapesBarelyOverlappingGetTheNormalFromAToB) {
  // A cylinder resting against a box's side in the 1,000-shape pile (the
  // poses as ODE held them), moved by up to a micrometre: the cores
  // overlap by nanometres or not at all. EPA's normal came out reversed
  // for 125 of these 2000 (from the cylinder back into the box), and the
  // points clipped along it were 275 mm deep: the push-out flung the
  // resting cylinder at 5 m/s.
  auto rotation = [](const double(&r)[9]) {
    Mat3 m;
    m << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
    return m;
  };
  const Shape box =
      Shape::box(0, 0.5 * Vec3(0.19780017402319805, 0.26590297527817075, 0.22731381966012632));
  const Shape cylinder = Shape::cylinder(1, 0.038291174536225589, 0.19690094323370011);
  const ShapePose boxPose{
      Vec3(1.6649365376725065, -1.5799533533906982, 0.14019032405625151),
      rotation({0.50157292646774176, 0.8437047842297104, 0.19127685825128843, -0.8651153594422486,
                0.48919013749499568, 0.11076291904214444, -0.0001195478764532687,
                -0.22103222942712533, 0.97526649653455222})};
  const ShapePose cylinderPose{
      Vec3(1.7939911174813115, -1.6638213235185717, 0.10234325064621244),
      rotation({0.078843305175189227, -0.99119922858150988, 0.10633824565259509,
                0.99450669800088831, 0.08557333495055941, 0.060279614935808232,
                -0.068848826136847951, 0.10100145347894283, 0.99250115643999071})};
  const Vec3 faceNormal = boxPose.rotation.col(0);  // the box's side the cylinder leans on
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> unit(-0.5, 0.5);
  int reversed = 0;
  double deepest = 0.0;
  for (int t = 0; t < 2000; ++t) {
    const double scale = t % 2 ? 1e-8 : 1e-6;
    ShapePose moved = cylinderPose;
    moved.position += scale * Vec3(unit(rng), unit(rng), unit(rng));
    ContactManifold m;
    const int n = collideConvex(box, boxPose, cylinder, moved, 0.005, m);
    if (n == 0) continue;
    reversed += m.normal.dot(faceNormal) < 0.99;
    for (int i = 0; i < n; ++i)
      deepest = std::min(deepest, m.points[i].separation);
  }
  EXPECT_EQ(reversed, 0);
  EXPECT_GT(deepest, -1e-5);
}

TEST(ConvexCollision, AHullVertexPastABoxFacesEdgeKeepsItsDepth) {
  // A box landing on a spinning hull in the 1,000-shape pile (the poses
  // the core held): they overlap 31.8 mm (EPA; the separating-axis test
  // over every face normal and edge pair gives the same), but the hull's
  // deepest vertex lies beyond the box face's edge, and the points clipped
  // from the face said 3.4 to 11.9 mm apart. The box sank 38 mm into it.
  const Shape box =
      Shape::box(0, Vec3(0.17431462201042272, 0.10769658591543266, 0.082580133969190228));
  const std::vector<Vec3> corners = {
      Vec3(0.023565075194278421, 0.048245791067070651, -0.06646731386679057),
      Vec3(0.12125086443119494, -0.0036435974105098849, -0.049908644688727813),
      Vec3(0.044405110029719544, -0.082600844694432421, -0.058596401830346673),
      Vec3(0.072707906982014014, -0.10958520559958525, 0.031378979341108754),
      Vec3(-0.11213028632803899, -0.0011607340600667121, 0.036607217829049646),
      Vec3(-0.082714798399997166, 0.020599160708417191, -0.066735085845434083),
      Vec3(-0.064644985745514361, 0.10211622344924004, 0.10069464463953975),
      Vec3(0.036713613765446004, -0.061203887850165249, 0.054410017910451261),
      Vec3(0.10151658168256736, -0.078214152088119451, -0.042278310733730298),
      Vec3(-0.041389970812370995, 0.10438685188792599, 0.067020616665986368)};
  const Shape hull =
      Shape::convex(1, std::make_shared<const ConvexHull>(ConvexHull::fromPoints(corners)));
  const ShapePose boxPose =
      ShapePose{Vec3(-0.86785056372784886, -2.1803479711870448, 0.3044623393544606),
                (Mat3() << -0.5583705547007054, -0.8103810019045401, -0.17749635318907286,
                 0.043378076667018872, -0.24218384952536809, 0.96926019493928672,
                 -0.8284567979731331, 0.53350690228081166, 0.17038109962914283)
                    .finished()};
  const ShapePose hullPose =
      ShapePose{Vec3(-0.92364048808838217, -2.1708661456292866, 0.072676634871256154),
                (Mat3() << 0.63436279146072772, 0.76611230081578463, 0.10322689256631742,
                 -0.77231500504765482, 0.62233171596151915, 0.12740788157187058,
                 0.033367376108919065, -0.16054649746143881, 0.9864641100235072)
                    .finished()};
  ContactManifold m;
  ASSERT_GT(collideConvex(box, boxPose, hull, hullPose, 0.015, m), 0);
  EXPECT_NEAR(deepest(m), -0.0317693, 1e-6);
  EXPECT_LT((m.normal - Vec3(-0.584553, 0.272408, -0.764259)).norm(), 1e-5);
}

TEST(ConvexCollision, AHullRestingOnABoxFaceIsNotTakenForDeep) {
  // A hull resting 10 um against a box's face in the 1,000-shape pile
  // (the poses the core held at 40 sub-steps, frame 109): libccd's EPA
  // stopped on a far face, 160 mm deep, the line of centres said 149 mm,
  // and the push-out threw the 0.55 kg hull out at 23 m/s (279 J gained
  // in a frame). The box face's normal is the least overlap.
  const Shape box =
      Shape::box(0, Vec3(0.084850242920509675, 0.15065116685799493, 0.16642529588307675));
  const std::vector<Vec3> points = {
      Vec3(-0.017249901787736312, 0.028395295581848223, -0.085661174626580072),
      Vec3(0.11481474765333638, -0.11693603476509146, -0.022809746772327361),
      Vec3(0.014504690567599086, -0.061805047228626869, -0.0084113601587858643),
      Vec3(0.10232766229283438, -0.052372187942228171, 0.051094949127616709),
      Vec3(0.094355594663826023, -0.0085131473731015501, 0.079128483579983686),
      Vec3(-0.1439987140060201, 0.043255508903431217, 0.012708959218964694),
      Vec3(-0.014901955634196058, 0.058052107642579912, 0.060167026433930945),
      Vec3(-0.079003173517952302, 0.066146794546027676, -0.076579667068536153),
      Vec3(-0.07435228953291978, 0.054461603473011967, 0.018293626818192271),
      Vec3(0.11435121321569934, -0.048143251773182683, 0.047949845534797725)};
  const Shape hull =
      Shape::convex(1, std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points)));
  const ShapePose boxPose =
      ShapePose{Vec3(0.24851312156129435, 0.92560803852716667, 0.18585834617489033),
                (Mat3() << 0.32834895997073033, -0.13141323468982452, 0.93537025943446417,
                 0.93825975640802772, 0.15953115693197994, -0.30695022311946984,
                 -0.10888337793845332, 0.97840705829235564, 0.17568163903040879)
                    .finished()};
  const ShapePose hullPose =
      ShapePose{Vec3(0.10081023939923481, 0.81678611767979326, 0.12252878427908045),
                (Mat3() << -0.99696991512563349, -0.076380752814921002, -0.014729865369838467,
                 -0.021763056566593206, 0.092082523454556031, 0.99551352489211353,
                 -0.074681709295294607, 0.99281760131137242, -0.093465784237153127)
                    .finished()};
  ContactManifold m;
  ASSERT_EQ(collideConvex(box, boxPose, hull, hullPose, kMargin, m), 4);
  // Never deeper than the least overlap over 20,000 directions, and as
  // the separating-axis test along the box's face normal gives it.
  EXPECT_GE(deepest(m), -leastProjectedOverlap(box, boxPose, hull, hullPose) - 1e-9);
  EXPECT_NEAR(deepest(m), -1.0e-5, 2e-6);
  EXPECT_LT((m.normal - Vec3(-0.3283, -0.9383, 0.1089)).norm(), 1e-3) << m.normal.transpose();
}

TEST(ConvexCollision, EpaEndsOnACylinderStandingAgainstABoxSide) {
  // A cylinder standing against a box's side in the 1,000-shape pile, the
  // two resting 10 um into one another (the poses the core held): libccd's
  // EPA, which has no bound of its own, refined the round side for
  // minutes. It is now cut short, and the box's face gives the depth.
  const Shape box =
      Shape::box(0, Vec3(0.10162115803318023, 0.08528480672879013, 0.090373515977195867));
  const Shape cylinder = Shape::cylinder(1, 0.088011004432431095, 2.0 * 0.096984145661911519);
  const ShapePose boxPose{
      Vec3(0.36623756808856522, -2.793293685649755, 0.090363508197429554),
      (Mat3() << -0.98402068134948273, 0.17805420151318541, 4.5778985744025549e-08,
       0.17805420151318718, 0.98402068134948251, 3.808142511245428e-08, -3.8266911002442051e-08,
       4.5624050638652607e-08, -0.99999999999999845)
          .finished()};
  const ShapePose cylinderPose{
      Vec3(0.17647237499673146, -2.7769565407933561, 0.096956327328627689),
      (Mat3() << -0.22325306819484791, -0.9747604975096128, 0.00020009097697240065,
       -0.97476051792518292, 0.22325306669742251, -3.0073667470574642e-05, -1.535630116201581e-05,
       -0.00020175482288045047, -0.99999997952958775)
          .finished()};
  const CorePenetration deep =
      corePenetration(PosedConvex(box, boxPose), PosedConvex(cylinder, cylinderPose));
  ASSERT_TRUE(deep.found);
  EXPECT_NEAR(deep.depth, 1.0e-5, 1e-6);
  EXPECT_LE(deep.depth, leastProjectedOverlap(box, boxPose, cylinder, cylinderPose));
  // The face's normal, or one as shallow: the cylinder stands 2e-4 rad off
  // square to the face, and the cross product of its axis with a box edge
  // (tried once EPA is cut short) overlaps no more.
  std::printf("  depth %.9g normal off the face's by %.3g\n", deep.depth,
              (deep.normal - Vec3(-0.98402068134948273, 0.17805420151318718, 0.0)).norm());
  EXPECT_LT((deep.normal - Vec3(-0.98402068134948273, 0.17805420151318718, 0.0)).norm(), 3e-4);
  // The side along the face: two points, at that depth.
  ContactManifold m;
  ASSERT_EQ(collideConvex(box, boxPose, cylinder, cylinderPose, kMargin, m), 2);
  EXPECT_NEAR(deepest(m), -deep.depth, 1e-7);
}

TEST(ConvexCollision, CapsulesNearCylindersAreNotTakenForOverlapping) {
  // Capsules beside cylinders in the 1,000-shape pile (the poses the core
  // held). GJK's support points on the cylinder's round side bunched up
  // 1e-7 m apart; the flat tetrahedron they made was taken for one
  // holding the origin, so the cores (50-93 mm apart) counted as
  // overlapping and the contact came out a whole radius deep: 17 such
  // pairs in 106 frames, each flung apart. The depth is checked against
  // the least overlap of the two shapes' projections over 20,000
  // directions (never less than the true depth, within 0.2 mm of it).
  struct Pair {
    Shape cylinder;
    ShapePose cylinderPose;
    Shape capsule;
    ShapePose capsulePose;
  };
  const Pair pairs[] = {
      {Shape::cylinder(0, 0.094412140940109149, 2 * 0.10126523848951802),
       ShapePose{Vec3(2.6430245438259483, 0.23707306489483873, 0.1588134117796231),
                 (Mat3() << -0.88085286970865306, 0.29084376366813913, 0.37350786746919051,
                  -0.24428144584019293, 0.39657756673785105, -0.88490271147652733,
                  -0.40549327632434995, -0.87071013471512826, -0.27827875262065449)
                     .finished()},
       Shape::capsule(1, 0.050495739861964442, 2 * 0.086220684376369788),
       ShapePose{Vec3(2.6777218947160013, 0.4362127135171211, 0.076526561125663625),
                 (Mat3() << 0.67647892573588564, 0.54319377903986144, 0.49730954288814583,
                  -0.58062306993580493, -0.02203300626738347, 0.81387431295817614,
                  0.45304868799450643, -0.83931821441406596, 0.30048597514566389)
                     .finished()}},
      {Shape::cylinder(0, 0.047177406716817541, 2 * 0.088078245380548051),
       ShapePose{Vec3(-1.8342750323304045, 0.75053828447093029, 0.14751752574016241),
                 (Mat3() << -0.33276544869554381, -0.61447764627932999, 0.71532117148695329,
                  -0.37722501176938789, 0.78195494140359068, 0.49623357414638136,
                  -0.8642733633810763, -0.10470764937444429, -0.49200392428560935)
                     .finished()},
       Shape::capsule(1, 0.067233879344840458, 2 * 0.053476699527878063),
       ShapePose{Vec3(-1.9691044525596237, 0.74561068310587908, 0.06963448902210459),
                 (Mat3() << -0.51269469608284846, -0.83649854701437776, 0.1934278404246676,
                  -0.061781606820837998, -0.18876204212310888, -0.98007750944103866,
                  0.85634524677092183, -0.51443082362582893, 0.045097073480440564)
                     .finished()}},
      {Shape::cylinder(0, 0.084910622234571353, 2 * 0.074859947754192635),
       ShapePose{Vec3(0.48585338653203142, -1.4806904265009919, 0.10578132753704299),
                 (Mat3() << 0.67488469174251309, -0.3923545524096157, 0.62497084576407502,
                  -0.25534047236312596, 0.67044603114425927, 0.6966371813909209,
                  -0.69233799261992601, -0.62973012038996612, 0.3522897663126906)
                     .finished()},
       Shape::capsule(1, 0.092614590958607385, 2 * 0.074015131826601355),
       ShapePose{Vec3(0.71013748228706397, -1.6029356447861338, 0.09250399358700602),
                 (Mat3() << -0.43295698088080314, 0.47416030199419157, 0.7666291546239008,
                  -0.51532076481906175, 0.56759733234406606, -0.64208860577197369,
                  -0.739589590281581, -0.6730566665063773, -0.0014005778972003835)
                     .finished()}}};
  for (const Pair& p : pairs) {
    const double leastOverlap =
        leastProjectedOverlap(p.cylinder, p.cylinderPose, p.capsule, p.capsulePose);
    ContactManifold m;
    const int n = collideConvex(p.cylinder, p.cylinderPose, p.capsule, p.capsulePose, kMargin, m);
    if (leastOverlap < -kMargin) {
      EXPECT_EQ(n, 0) << "apart by " << -leastOverlap;
      continue;
    }
    ASSERT_GT(n, 0);
    EXPECT_NEAR(deepest(m), -leastOverlap, 2e-4);
  }
}

TEST(ConvexCollision, ABoxEdgeJustTouchingAHullEdgeIsNotTakenForDeep) {
  // A box's edge just touching a hull's edge in the 1,000-shape pile (the
  // poses the core held): libccd's EPA ended at depth 0 on a face whose
  // normal the two overlap 91 mm along, the points clipped along it came
  // out 91 mm deep, and the push-out threw a 15 kg box up (37 J in a
  // frame). The least overlap is along the cross product of the two
  // edges, which no face normal gives.
  const Shape box =
      Shape::box(0, Vec3(0.10855275020991639, 0.044742140582026212, 0.063021010832531768));
  const std::vector<Vec3> points = {
      Vec3(-0.028360245360491202, 0.10190294354957979, -0.099779275255383909),
      Vec3(0.031102024228016549, -0.013476634744978875, 0.20308994104130146),
      Vec3(0.084800000935768546, -0.032032822381896142, -0.01411611268524441),
      Vec3(-0.077413786452541655, -0.044681329006340267, -0.049135985617192179),
      Vec3(0.048613001206808823, 0.016678592371632217, -0.08975619081431542),
      Vec3(-0.060404368644511264, 0.020591861138954129, -0.031045165079584346),
      Vec3(-0.025500083614753841, -0.062975633917837615, -0.040876798060849956)};
  const Shape hull =
      Shape::convex(1, std::make_shared<const ConvexHull>(ConvexHull::fromPoints(points)));
  const ShapePose boxPose =
      at(Vec3(-1.0967463092321665, 0.1360132466226818, 0.044732139242971321),
         Quat(-0.11102448128594013, 0.11102448911813155, -0.69833628299286177, 0.69833628233606715)
             .normalized());
  const ShapePose hullPose =
      at(Vec3(-1.3239223785238496, 0.051079769272001939, 0.037395570330486287),
         Quat(0.19396271610999036, 0.36772974773955081, 0.65152019954762841, -0.63456656622300878)
             .normalized());
  const double leastOverlap = leastProjectedOverlap(box, boxPose, hull, hullPose);
  ContactManifold m;
  ASSERT_GT(collideConvex(box, boxPose, hull, hullPose, kMargin, m), 0);
  EXPECT_GE(deepest(m), -leastOverlap - 1e-9);
  EXPECT_LT(leastOverlap, 1e-4);  // the sampled directions come within 0.1 mm of touching
  EXPECT_NEAR(deepest(m), 0.0, 1e-6);
  EXPECT_GT(m.normal.dot(Vec3(-0.7637, -0.2481, -0.5960)), 0.999) << m.normal.transpose();
}

TEST(ConvexCollision, ABoxOnItsEdgeAlongARodHoldsAtBothEnds) {
  // A box on its edge (turned 45 degrees about x) over a rod pitched 2 or
  // 5 degrees off along it, the rod's high end 1 mm into the edge. No
  // face of the box lies within 25 degrees of the normal, so the box
  // touches by its edge, which clips against the rod's side line: a point
  // at each end, the low one 8.8 or 23.4 mm apart (a speculative point).
  // With one point in the pile an 11 kg box falling at 6 m/s onto a
  // spinning 0.64 kg rod (2.7 degrees) see-sawed about it, and its edge's
  // other end went 15.7 mm into the rod; an 8.9 kg box on a 0.36 kg rod
  // at 4.4 degrees, 11.7 mm.
  const double radius = 0.038, halfLength = 0.14;
  const Shape rod = Shape::cylinder(1, radius, 2.0 * halfLength);
  const Vec3 half(0.188, 0.09, 0.09);
  const Shape box = Shape::box(0, half), hull = Shape::convex(0, boxHull(half));
  for (const double degrees : {2.0, 5.0}) {
    const double theta = degrees * kPi / 180.0, margin = 0.03;
    const Vec3 axis(std::cos(theta), 0.0, std::sin(theta));
    const ShapePose rodPose = at(Vec3::Zero(), Quat::FromTwoVectors(Vec3::UnitZ(), axis));
    const double highEnd = halfLength * std::sin(theta) + radius * std::cos(theta);
    const double edgeHeight = highEnd - 0.001;
    const ShapePose boxPose =
        at(Vec3(0.0, 0.0, edgeHeight + half.y() * std::sqrt(2.0)), about(Vec3::UnitX(), kPi / 4));
    // The low end's gap along the normal (z): the side line's drop over
    // the rod's length, less the 1 mm at the high end.
    const double lowGap = 2.0 * halfLength * std::sin(theta) - 0.001;
    for (const Shape* edge : {&box, &hull}) {
      SCOPED_TRACE(std::string(edge->kind == Shape::Kind::Box ? "box" : "hull") + " at " +
                   std::to_string(degrees) + " degrees");
      ContactManifold m;
      ASSERT_EQ(collideConvex(*edge, boxPose, rod, rodPose, margin, m), 2);
      // 1 mm along z, where the rim's top meets the edge (no sampled
      // direction overlaps less).
      EXPECT_NEAR(deepest(m), -0.001, 1e-9);
      EXPECT_GE(deepest(m), -leastProjectedOverlap(*edge, boxPose, rod, rodPose));
      EXPECT_LT((m.normal + Vec3::UnitZ()).norm(), 1e-6) << m.normal.transpose();  // box to rod
      const double shallow = std::max(m.points[0].separation, m.points[1].separation);
      EXPECT_NEAR(shallow, lowGap, 1e-9);
      // Both on the edge (y = 0 at the edge's height, within the gap's
      // tilt) and at the rod's two ends.
      for (int i = 0; i < 2; ++i) {
        const Vec3 onEdge = m.points[i].position - 0.5 * m.points[i].separation * m.normal;
        EXPECT_NEAR(onEdge.y(), 0.0, 1e-9) << i;
        EXPECT_NEAR(onEdge.z(), edgeHeight, 1e-9) << i;
      }
      EXPECT_NEAR(std::abs(m.points[0].position.x() - m.points[1].position.x()),
                  2.0 * halfLength * std::cos(theta), 2.0 * radius * std::sin(theta) + 1e-6);
    }
  }
  // Turned 5 degrees about z instead (level, crossing the edge in plan
  // view): the ends lie beside the edge, over the box's sloping faces,
  // where nothing touches. One point, where they cross, 1 mm deep.
  const ShapePose level = at(
      Vec3::Zero(), Quat::FromTwoVectors(Vec3::UnitZ(), Vec3(std::cos(0.087), std::sin(0.087), 0)));
  const ShapePose boxPose =
      at(Vec3(0.0, 0.0, radius - 0.001 + half.y() * std::sqrt(2.0)), about(Vec3::UnitX(), kPi / 4));
  ContactManifold m;
  ASSERT_EQ(collideConvex(box, boxPose, rod, level, 0.03, m), 1);
  EXPECT_NEAR(m.points[0].separation, -0.001, 1e-9);
}

TEST(ConvexCollision, ACylinderStandingAgainstABoxEdgeIsNotTakenForDeep) {
  // An upright cylinder resting against a box lying on its side in the
  // 1,000-shape pile, both still (the poses the core held): EPA ended on a
  // face whose normal they overlap 17.5 mm along, and neither the line of
  // centres, the faces' normals nor the edges' cross products is the
  // direction from the box's edge to the cylinder's side. Collided again
  // with the bodies as still, the pair came out 0.14 mm apart, then 17.5
  // mm deep, then touching.
  const Shape box =
      Shape::box(0, Vec3(0.13643486320602077, 0.11781439462784943, 0.18429109446735595));
  const Shape cylinder = Shape::cylinder(1, 0.086418661076112818, 2.0 * 0.11765246669184419);
  const ShapePose boxPose =
      at(Vec3(2.2622882737118482, 2.2511173803194247, 0.13634946946397006),
         Quat(0.58460820136988112, -0.39794421377466138, -0.58451832325936703, -0.39775869995312169)
             .normalized());
  const ShapePose cylinderPose = at(
      Vec3(2.1440801717814382, 1.9957337666394539, 0.11766567010129829),
      Quat(9.57259639549877e-05, 0.86808194570036679, -0.49642090220223495, -0.00011934121036545466)
          .normalized());
  const double leastOverlap = leastProjectedOverlap(box, boxPose, cylinder, cylinderPose);
  ContactManifold m;
  ASSERT_GT(collideConvex(box, boxPose, cylinder, cylinderPose, kMargin, m), 0);
  std::printf("  deepest %.3f mm, least sampled overlap %.3f mm\n", 1e3 * deepest(m),
              1e3 * leastOverlap);
  EXPECT_GE(deepest(m), -leastOverlap - 1e-9);
  EXPECT_GT(deepest(m), -1e-4);
  // And touching, not taken for apart: GJK finds the two overlapping.
  ASSERT_TRUE(
      coreDistance(PosedConvex(box, boxPose), PosedConvex(cylinder, cylinderPose)).overlapping);
  EXPECT_LE(deepest(m), 0.0);
}

TEST(ConvexCollision, RoundShapesTouchingAtTheirSidesKeepTheirDepth) {
  // Two cylinders, and a hull against a cylinder, 0.4-0.5 mm into one
  // another in the 1,000-shape pile (the poses the core held). Where a
  // GJK step made no progress it kept the new simplex's points with the
  // old |v|: the hull-cylinder normal came out 4.9 long and its points
  // 53 mm deep; and EPA ended the cylinders' on a face 84 mm deep. No
  // point may be deeper than the shapes' projections overlap along some
  // direction (the least over 20,000 directions: 0.9 mm for the
  // cylinders, whose least overlap, along the line of their centres, is
  // 0.4 um), and the normal is a unit vector.
  struct Pair {
    Shape a;
    ShapePose poseA;
    Shape b;
    ShapePose poseB;
  };
  const Pair pairs[] = {
      {Shape::cylinder(0, 0.053098083220534678, 2 * 0.028214380442391364),
       ShapePose{Vec3(0.96062807919285387, -0.71376768417783065, 0.055059667196851167),
                 (Mat3() << 0.46388891641798169, -0.26023298707963527, 0.84680922624884114,
                  -0.65987568107342243, 0.53627087629525882, 0.52628664505704681,
                  -0.59107627151869124, -0.80292735641098034, 0.077048696124183635)
                     .finished()},
       Shape::cylinder(1, 0.095949435680564507, 2 * 0.14022283224360677),
       ShapePose{Vec3(1.098268091328251, -0.70523692708055241, 0.095537236174095347),
                 (Mat3() << -0.52021115569444865, 0.67131552398301708, -0.52793543236881968,
                  -0.32461781849377935, 0.41634225721528406, 0.84928346079104933,
                  0.78993900106741477, 0.61318397901142951, 0.0013350941259773208)
                     .finished()}},
      {Shape::convex(
           0, std::make_shared<const ConvexHull>(ConvexHull::fromPoints(
                  {Vec3(-0.17327545811154041, 0.048871715642833852, 0.021500413918940069),
                   Vec3(0.020787618517745229, -0.10131387463763156, -0.1303354370535047),
                   Vec3(0.087392934537900549, -0.050917590917697486, 0.13078459385291946),
                   Vec3(0.062375206632455132, 0.078235380693292139, 0.0061452953835917021),
                   Vec3(-0.024430294851438772, 0.071118681851882276, 0.047915865221472537),
                   Vec3(0.053530642205475945, 0.016219876643375413, -0.099214420852164309),
                   Vec3(0.030733655519688138, -0.018998108059499141, 0.10655921652513295)}))),
       ShapePose{Vec3(3.0860518376290949, 1.2489813506491192, 0.086696793190992924),
                 (Mat3() << -0.67203334351512511, -0.69349426658802016, -0.25968613250119094,
                  -0.63585627001674849, 0.72014254550688062, -0.27763558495131402,
                  0.37954971885679217, -0.021457314846326708, -0.92492248029514101)
                     .finished()},
       Shape::cylinder(1, 0.078833459832747144, 2 * 0.088793148940880834),
       ShapePose{Vec3(3.117992391675446, 1.4652084792674707, 0.078823384374719391),
                 (Mat3() << -0.43066729245042756, -0.70967570770672239, 0.5575715856321769,
                  -0.28926487198385925, -0.47666750145280812, -0.83012886162022947,
                  0.85489854196248272, -0.51879522255866928, 8.4950995171695354e-07)
                     .finished()}}};
  for (const Pair& p : pairs) {
    const double leastOverlap = leastProjectedOverlap(p.a, p.poseA, p.b, p.poseB);
    ContactManifold m;
    ASSERT_GT(collideConvex(p.a, p.poseA, p.b, p.poseB, 0.005, m), 0);
    EXPECT_NEAR(m.normal.norm(), 1.0, 1e-9);
    EXPECT_GE(deepest(m), -leastOverlap - 1e-6);
  }
}

TEST(ConvexCollision, DegenerateContactsGiveFiniteAnswers) {
  ContactManifold m;
  auto finite = [&m] {
    bool ok = m.normal.allFinite() && std::abs(m.normal.norm() - 1.0) < 1e-9;
    for (int i = 0; i < m.pointCount; ++i)
      ok = ok && m.points[i].position.allFinite() && std::isfinite(m.points[i].separation);
    return ok;
  };
  // Boxes exactly touching face to face.
  const Shape a = Shape::box(0, Vec3(0.5, 0.5, 0.5)), b = Shape::box(1, Vec3(0.5, 0.5, 0.5));
  EXPECT_EQ(collideConvex(a, at(Vec3::Zero()), b, at(Vec3(0, 0, 1)), kMargin, m), 4);
  EXPECT_TRUE(finite());
  EXPECT_NEAR(deepest(m), 0.0, 1e-12);
  // Concentric spheres, and capsules whose segments cross.
  const Shape s1 = Shape::sphere(0, 0.5), s2 = Shape::sphere(1, 0.3);
  EXPECT_EQ(collideConvex(s1, at(Vec3::Zero()), s2, at(Vec3::Zero()), kMargin, m), 1);
  EXPECT_TRUE(finite());
  EXPECT_NEAR(deepest(m), -0.8, 1e-12);
  const Shape c1 = Shape::capsule(0, 0.1, 1.0), c2 = Shape::capsule(1, 0.1, 1.0);
  EXPECT_EQ(collideConvex(c1, at(Vec3::Zero()), c2, at(Vec3::Zero(), about(Vec3::UnitX(), 1.0)),
                          kMargin, m),
            1);
  EXPECT_TRUE(finite());
  // A needle hull through a box's corner, and a box inside a box.
  std::vector<Vec3> needle = {Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, 1e-3, 0), Vec3(0, 0, 1e-3)};
  const Shape n =
      Shape::convex(1, std::make_shared<const ConvexHull>(ConvexHull::fromPoints(needle)));
  EXPECT_GE(collideConvex(a, at(Vec3::Zero()), n, at(Vec3(0.5, 0.5, 0.45)), kMargin, m), 1);
  EXPECT_TRUE(finite());
  const Shape small = Shape::box(1, Vec3(0.1, 0.1, 0.1));
  EXPECT_GE(collideConvex(a, at(Vec3::Zero()), small, at(Vec3(0.05, 0, 0)), kMargin, m), 1);
  EXPECT_TRUE(finite());
  EXPECT_LT(deepest(m), -0.3);
}

TEST(ConvexCollision, GjkEndsExactlyOnPolytopesAndWithinTwentyStepsOnACylinder) {
  const Shape box = Shape::box(0, Vec3(0.5, 0.4, 0.3));
  const Shape hull = Shape::convex(1, boxHull(Vec3(0.2, 0.3, 0.1)));
  const PosedConvex a(box, at(Vec3::Zero(), about(Vec3(1, 1, 0), 0.3)));
  const PosedConvex b(hull, at(Vec3(1.5, 0.7, 0.2), about(Vec3(0, 1, 1), 1.1)));
  const CoreDistance d = coreDistance(a, b);
  ASSERT_FALSE(d.overlapping);
  // The closest points lie on the shapes and their gap is the distance:
  // every support along the gap's direction is no closer.
  const Vec3 n = (d.pointB - d.pointA) / d.distance;
  EXPECT_NEAR(a.coreSupport(n).dot(n), d.pointA.dot(n), 1e-12);
  EXPECT_NEAR(b.coreSupport(-n).dot(n), d.pointB.dot(n), 1e-12);
  EXPECT_LT(d.iterations, 10);
  const Shape cylinder = Shape::cylinder(1, 0.3, 0.5);
  const PosedConvex c(cylinder, at(Vec3(0.7, 0.8, 0.9), about(Vec3(1, 0, 1), 0.6)));
  const CoreDistance e = coreDistance(a, c);
  ASSERT_FALSE(e.overlapping);
  const Vec3 m = (e.pointB - e.pointA) / e.distance;
  EXPECT_NEAR(c.coreSupport(-m).dot(m), e.pointB.dot(m), 1e-6 * e.distance);
  EXPECT_LE(e.iterations, 20);
}

}  // namespace
}  // namespace blockstep

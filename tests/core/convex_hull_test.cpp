// Convex hulls from points and the mass properties of polyhedra and
// compound bodies, against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/collision/convex_hull.h"
#include "core/world/error.h"

namespace blockstep {
namespace {

std::vector<Vec3> boxCorners(const Vec3& half, const Vec3& centre = Vec3::Zero(),
                             const Quat& q = Quat::Identity()) {
  std::vector<Vec3> points;
  for (int c = 0; c < 8; ++c) {
    const Vec3 local((c & 1 ? 1 : -1) * half.x(), (c & 2 ? 1 : -1) * half.y(),
                     (c & 4 ? 1 : -1) * half.z());
    points.push_back(centre + q * local);
  }
  return points;
}

void expectNear(const Mat3& a, const Mat3& b, double tolerance) {
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), tolerance) << "got\n" << a << "\nexpected\n" << b;
}

TEST(ConvexHull, BoxFromItsCornersHasSixSquareFacesWhateverElseIsGiven) {
  const Vec3 half(0.5, 0.2, 0.3);
  const Quat q = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  std::vector<Vec3> points = boxCorners(half, Vec3(1, -2, 0.5), q);
  // Duplicates, an interior point, a point on a face and one on an edge
  // are not vertices of the hull.
  points.push_back(points[3]);
  points.push_back(Vec3(1, -2, 0.5));
  points.insert(points.begin(), Vec3(1, -2, 0.5) + q * Vec3(0.5, 0.0, 0.1));
  points.insert(points.begin() + 2, Vec3(1, -2, 0.5) + q * Vec3(0.5, 0.2, 0.0));
  const ConvexHull hull = ConvexHull::fromPoints(points);
  EXPECT_EQ(hull.vertices().size(), 8u);
  ASSERT_EQ(hull.faces().size(), 6u);
  for (const ConvexHull::Face& f : hull.faces()) {
    EXPECT_EQ(f.count, 4);
    // Normals along the box's axes, outward, vertices on the face's plane.
    const Vec3 local = q.inverse() * f.normal;
    EXPECT_NEAR(local.cwiseAbs().maxCoeff(), 1.0, 1e-12);
    const Vec3 centre(1, -2, 0.5);
    EXPECT_GT(f.offset - f.normal.dot(centre), 0.0);
    for (int k = 0; k < f.count; ++k)
      EXPECT_NEAR(f.normal.dot(hull.faceVertex(f, k)), f.offset, 1e-12);
    // Counter-clockwise seen from outside.
    const Vec3 turn = (hull.faceVertex(f, 1) - hull.faceVertex(f, 0))
                          .cross(hull.faceVertex(f, 2) - hull.faceVertex(f, 1));
    EXPECT_GT(turn.dot(f.normal), 0.0);
  }
}

TEST(ConvexHull, BoxMassPropertiesMatchTheClosedForm) {
  const Vec3 sides(1.0, 0.4, 0.6);
  const Vec3 centre(0.3, 0.1, -0.2);
  const ConvexHull hull = ConvexHull::fromPoints(boxCorners(sides / 2, centre));
  const double density = 250.0;
  const MassProperties m = hullMass(hull, density);
  const double volume = sides.prod();
  EXPECT_NEAR(hullVolume(hull), volume, 1e-14);
  EXPECT_NEAR(m.mass, density * volume, 1e-11);
  EXPECT_LT((m.centre - centre).norm(), 1e-14);
  expectNear(m.inertia, boxMass(density * volume, sides).inertia, 1e-12);
}

TEST(ConvexHull, RegularTetrahedronInertiaIsMassTimesEdgeSquaredOverTwenty) {
  // Corners of a cube, alternate: edge sqrt(2) s for half side s.
  const double s = 0.4;
  const std::vector<Vec3> points = {Vec3(s, s, s), Vec3(s, -s, -s), Vec3(-s, s, -s),
                                    Vec3(-s, -s, s)};
  const ConvexHull hull = ConvexHull::fromPoints(points);
  EXPECT_EQ(hull.faces().size(), 4u);
  const double edge = std::sqrt(2.0) * 2 * s;
  const double volume = edge * edge * edge / (6.0 * std::sqrt(2.0));
  EXPECT_NEAR(hullVolume(hull), volume, 1e-14);
  const MassProperties m = hullMass(hull, 1000.0);
  EXPECT_LT(m.centre.norm(), 1e-14);
  expectNear(m.inertia, m.mass * edge * edge / 20.0 * Mat3::Identity(), 1e-12);
}

TEST(ConvexHull, TriangularPrismMassMatchesTheClosedForm) {
  // Equilateral triangle of side a in the xy plane, centroid on the z axis,
  // extruded over length L: Izz = m a^2 / 12, Ixx = Iyy = m a^2 / 24 + m L^2 / 12.
  const double a = 0.3, L = 1.1;
  std::vector<Vec3> points;
  for (int k = 0; k < 3; ++k) {
    const double angle = 2.0 * kPi * k / 3.0;
    const Vec3 corner(a / std::sqrt(3.0) * std::cos(angle), a / std::sqrt(3.0) * std::sin(angle),
                      0);
    points.push_back(corner + Vec3(0, 0, L / 2));
    points.push_back(corner - Vec3(0, 0, L / 2));
  }
  const ConvexHull hull = ConvexHull::fromPoints(points);
  ASSERT_EQ(hull.faces().size(), 5u);
  int triangles = 0, quads = 0;
  for (const ConvexHull::Face& f : hull.faces())
    (f.count == 3 ? triangles : quads) += 1;
  EXPECT_EQ(triangles, 2);
  EXPECT_EQ(quads, 3);
  const MassProperties m = hullMass(hull, 1.0);
  EXPECT_NEAR(m.mass, std::sqrt(3.0) / 4.0 * a * a * L, 1e-14);
  Mat3 expected = Mat3::Zero();
  expected.diagonal() = m.mass * Vec3(a * a / 24 + L * L / 12, a * a / 24 + L * L / 12, a * a / 12);
  expectNear(m.inertia, expected, 1e-14);
}

TEST(ConvexHull, FineHullOfASphereApproachesTheSphere) {
  // 2,000 points of a Fibonacci lattice on a sphere of radius r: the hull
  // is inscribed, so its volume is a little below the sphere's; its
  // inertia is isotropic, 2/5 m r^2 within the same approximation.
  const double r = 0.5;
  const int n = 2000;
  std::vector<Vec3> points;
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double ring = std::sqrt(1.0 - z * z);
    const double phi = i * kPi * (3.0 - std::sqrt(5.0));
    points.push_back(r * Vec3(ring * std::cos(phi), ring * std::sin(phi), z));
  }
  const ConvexHull hull = ConvexHull::fromPoints(points);
  EXPECT_EQ(hull.vertices().size(), static_cast<std::size_t>(n));
  const double sphere = 4.0 / 3.0 * kPi * r * r * r;
  const double volume = hullVolume(hull);
  EXPECT_LT(volume, sphere);
  EXPECT_GT(volume, 0.997 * sphere);
  const MassProperties m = hullMass(hull, 1.0);
  EXPECT_LT(m.centre.norm(), 1e-4 * r);
  expectNear(m.inertia / (m.mass * r * r), 0.4 * Mat3::Identity(), 0.4 * 3e-3);
}

TEST(ConvexHull, RandomCloudIsEnclosedAndSupportIsTheFarthestPoint) {
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss;
  std::vector<Vec3> points;
  for (int i = 0; i < 500; ++i)
    points.push_back(Vec3(gauss(rng), 0.3 * gauss(rng), 2.0 * gauss(rng)));
  const ConvexHull hull = ConvexHull::fromPoints(points);
  for (const ConvexHull::Face& f : hull.faces())
    for (const Vec3& p : points)
      EXPECT_LE(f.normal.dot(p) - f.offset, 1e-9);
  for (int i = 0; i < 50; ++i) {
    const Vec3 d(gauss(rng), gauss(rng), gauss(rng));
    double most = -kInf;
    for (const Vec3& p : points)
      most = std::max(most, p.dot(d));
    EXPECT_NEAR(hull.vertices()[hull.supportVertex(d)].dot(d), most, 1e-12);
  }
}

TEST(ConvexHull, LatticeAndPolygonalPrismKeepTheirFlatFacesWhole) {
  // A 6 x 6 x 6 lattice: every face point is coplanar with many others,
  // the hard case for an incremental hull. Its hull is the cube.
  std::vector<Vec3> lattice;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < 6; ++k)
        lattice.push_back(Vec3(i, j, k) * 0.2);
  const ConvexHull cube = ConvexHull::fromPoints(lattice);
  EXPECT_EQ(cube.vertices().size(), 8u);
  EXPECT_EQ(cube.faces().size(), 6u);
  EXPECT_NEAR(hullVolume(cube), 1.0, 1e-12);
  // A 24-sided prism (a cylinder's hull): two 24-gons and 24 quads.
  std::vector<Vec3> prism;
  for (int k = 0; k < 24; ++k) {
    const double angle = 2.0 * kPi * k / 24.0;
    prism.push_back(Vec3(std::cos(angle), std::sin(angle), 0.5));
    prism.push_back(Vec3(std::cos(angle), std::sin(angle), -0.5));
  }
  const ConvexHull cylinder = ConvexHull::fromPoints(prism);
  ASSERT_EQ(cylinder.faces().size(), 26u);
  int caps = 0;
  for (const ConvexHull::Face& f : cylinder.faces())
    caps += f.count == 24;
  EXPECT_EQ(caps, 2);
  EXPECT_NEAR(hullVolume(cylinder), 0.5 * 24 * std::sin(2 * kPi / 24), 1e-12);
}

TEST(ConvexHull, NeedleStillHasItsVolume) {
  // A 1000:1 needle of square section.
  const Vec3 half(1.0, 1e-3, 1e-3);
  const ConvexHull hull = ConvexHull::fromPoints(boxCorners(half));
  EXPECT_EQ(hull.faces().size(), 6u);
  EXPECT_NEAR(hullVolume(hull), 8.0 * half.prod(), 1e-15);
}

TEST(ConvexHull, DegenerateCloudsAreRefusedWithTheirReason) {
  auto message = [](const std::vector<Vec3>& points) {
    try {
      ConvexHull::fromPoints(points);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}).find("at least 4"),
            std::string::npos);
  EXPECT_NE(message({Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0)}).find("coincide"),
            std::string::npos);
  EXPECT_NE(message({Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2), Vec3(3, 3, 3)}).find("collinear"),
            std::string::npos);
  // A flat square: coplanar, however many points.
  std::vector<Vec3> flat = boxCorners(Vec3(1, 1, 1));
  for (Vec3& p : flat)
    p.z() = 0.25;
  EXPECT_NE(message(flat).find("coplanar"), std::string::npos);
  std::vector<Vec3> bad = boxCorners(Vec3(1, 1, 1));
  bad[5].y() = std::nan("");
  EXPECT_NE(message(bad).find("point 5 is not finite"), std::string::npos);
  EXPECT_THROW(hullMass(ConvexHull::fromPoints(boxCorners(Vec3(1, 1, 1))), 0.0), Error);
}

TEST(CompoundMass, TwoBoxesSideBySideAreOneLongBox) {
  const Vec3 sides(0.5, 0.2, 0.3);
  const MassProperties half = boxMass(2.0, sides);
  // Turned a quarter about z, each half is a 0.2 x 0.5 x 0.3 box; side by
  // side along y they make a 0.2 x 1.0 x 0.3 box centred at (1, 0.5, 0).
  const Quat quarter(Eigen::AngleAxisd(kPi / 2, Vec3::UnitZ()));
  const MassProperties whole = combineMass(
      {MassPart{half, Vec3(1, 0.25, 0), quarter}, MassPart{half, Vec3(1, 0.75, 0), quarter}});
  EXPECT_NEAR(whole.mass, 4.0, 1e-15);
  EXPECT_LT((whole.centre - Vec3(1, 0.5, 0)).norm(), 1e-15);
  expectNear(whole.inertia, boxMass(4.0, Vec3(0.2, 1.0, 0.3)).inertia, 1e-14);
  // A hull's own centre counts: a box hull off its frame's origin.
  const ConvexHull offBox = ConvexHull::fromPoints(boxCorners(sides / 2, Vec3(0, 0, 1)));
  const MassProperties lifted = combineMass({MassPart{hullMass(offBox, 100.0)}});
  EXPECT_LT((lifted.centre - Vec3(0, 0, 1)).norm(), 1e-14);
  EXPECT_THROW(combineMass({}), Error);
  EXPECT_THROW(combineMass({MassPart{MassProperties{}}}), Error);
}

}  // namespace
}  // namespace blockstep

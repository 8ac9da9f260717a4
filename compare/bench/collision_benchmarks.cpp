// Google Benchmark over the core's collision: the broad phase (all pairs
// against sweep and prune at 100, 1,000 and 10,000 shapes, a flat sheet
// and a tall column) and the narrow
// phase (the exact fast paths against GJK/EPA on the same pairs).
#include <benchmark/benchmark.h>

#include <random>

#include "core/collision/broadphase.h"
#include "core/collision/narrowphase.h"

namespace {

using namespace blockstep;

// The timed loop of the broad-phase benchmarks: every shape but planes
// moved a little between calls, as bodies move between steps, then its
// box and the pairs.
void sweepMoving(benchmark::State& state, BroadPhaseMethod method, const std::vector<Shape>& shapes,
                 std::vector<ShapePose>& poses, std::mt19937& rng,
                 std::uniform_real_distribution<double>& jiggle) {
  std::vector<Aabb> boxes(shapes.size());
  std::vector<std::pair<int, int>> pairs;
  BroadPhase phase;
  for (auto _ : state) {
    for (std::size_t i = 0; i < shapes.size(); ++i) {
      if (shapes[i].kind != Shape::Kind::Plane)
        poses[i].position += Vec3(jiggle(rng), jiggle(rng), jiggle(rng));
      boxes[i] = shapeAabb(shapes[i], poses[i], 0.01);
    }
    phase.findPairs(boxes, method, pairs);
    benchmark::DoNotOptimize(pairs.data());
  }
  state.counters["pairs"] = static_cast<double>(pairs.size());
  state.counters["axis"] = phase.sweepAxis();
}

// n boxes of 0.2-0.5 m at a constant density (about one neighbour each).
void broadPhase(benchmark::State& state, BroadPhaseMethod method) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(1);
  const double side = std::cbrt(static_cast<double>(n)) * 0.8;
  std::uniform_real_distribution<double> place(0.0, side), size(0.1, 0.25), jiggle(-0.002, 0.002);
  std::vector<Shape> shapes;
  std::vector<ShapePose> poses;
  for (int i = 0; i < n; ++i) {
    shapes.push_back(Shape::box(0, Vec3(size(rng), size(rng), size(rng))));
    poses.push_back(ShapePose{Vec3(place(rng), place(rng), place(rng)), Mat3::Identity()});
  }
  sweepMoving(state, method, shapes, poses, rng, jiggle);
}
BENCHMARK_CAPTURE(broadPhase, all_pairs, BroadPhaseMethod::AllPairs)
    ->Arg(100)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(broadPhase, sweep_and_prune, BroadPhaseMethod::SweepAndPrune)
    ->Arg(100)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMicrosecond);

// A sheet of n x n boxes of 5 cm touching side by side in the x-y plane
// (a cloth lying flat), with a ground plane: one axis alone leaves a whole
// row of the sheet for each box to test.
void broadPhaseSheet(benchmark::State& state, BroadPhaseMethod method) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> jiggle(-0.0005, 0.0005);
  std::vector<Shape> shapes;
  std::vector<ShapePose> poses;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      shapes.push_back(Shape::box(0, Vec3(0.025, 0.025, 0.005)));
      poses.push_back(ShapePose{Vec3(0.05 * i, 0.05 * j, 1.0), Mat3::Identity()});
    }
  }
  shapes.push_back(Shape::plane(Vec3::UnitZ(), 0.0));
  poses.push_back(ShapePose{Vec3::Zero(), Mat3::Identity()});
  sweepMoving(state, method, shapes, poses, rng, jiggle);
}
BENCHMARK_CAPTURE(broadPhaseSheet, sweep_and_prune, BroadPhaseMethod::SweepAndPrune)
    ->Arg(32)
    ->Arg(64)
    ->Unit(benchmark::kMicrosecond);

// The pile's column before it lands: layers of 10 x 10 boxes 0.5 m apart
// on a 5 m square, n / 100 layers high, with a ground plane. Swept along x,
// each box meets a tenth of the column; along z, its own layer.
void broadPhaseColumn(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jiggle(-0.002, 0.002);
  std::vector<Shape> shapes;
  std::vector<ShapePose> poses;
  for (int i = 0; i < n; ++i) {
    shapes.push_back(Shape::box(0, Vec3(0.15, 0.15, 0.15)));
    poses.push_back(ShapePose{Vec3((i % 10) * 0.5, (i / 10 % 10) * 0.5, 0.3 + (i / 100) * 0.5),
                              Mat3::Identity()});
  }
  shapes.push_back(Shape::plane(Vec3::UnitZ(), 0.0));
  poses.push_back(ShapePose{Vec3::Zero(), Mat3::Identity()});
  sweepMoving(state, BroadPhaseMethod::SweepAndPrune, shapes, poses, rng, jiggle);
}
BENCHMARK(broadPhaseColumn)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);

ShapePose at(const Vec3& p, double angle = 0.0) {
  // Turned about z only: face on face, the gap is the given one.
  return ShapePose{p, Quat(Eigen::AngleAxisd(angle, Vec3::UnitZ())).toRotationMatrix()};
}

std::shared_ptr<const ConvexHull> boxHull() {
  std::vector<Vec3> corners;
  for (int c = 0; c < 8; ++c)
    corners.push_back(0.5 * Vec3(c & 1 ? 1 : -1, c & 2 ? 1 : -1, c & 4 ? 1 : -1));
  return std::make_shared<const ConvexHull>(ConvexHull::fromPoints(corners));
}

using Collide = int (*)(const Shape&, const ShapePose&, const Shape&, const ShapePose&, double,
                        ContactManifold&);

void pair(benchmark::State& state, Collide collide, Shape a, Shape b, double gap) {
  const ShapePose pa = at(Vec3::Zero()), pb = at(Vec3(0.05, 0.02, 1.0 + gap), 0.3);
  ContactManifold m;
  for (auto _ : state) {
    benchmark::DoNotOptimize(collide(a, pa, b, pb, 0.02, m));
  }
  state.counters["points"] = m.pointCount;
}
const Shape kBox = Shape::box(0, Vec3(0.5, 0.5, 0.5));
const Shape kBall = Shape::sphere(0, 0.5);
const Shape kCapsule = Shape::capsule(0, 0.25, 0.5);
// Penetrating by 5 mm (a resting contact: EPA) and apart by 5 mm (GJK).
BENCHMARK_CAPTURE(pair, box_box_sat_deep, collideBoxes, kBox, kBox, -0.005);
BENCHMARK_CAPTURE(pair, box_box_gjk_epa_deep, collideConvex, kBox, kBox, -0.005);
BENCHMARK_CAPTURE(pair, box_box_gjk_apart, collideConvex, kBox, kBox, 0.005);
BENCHMARK_CAPTURE(pair, hull_hull_epa_deep, collideConvex, Shape::convex(0, boxHull()),
                  Shape::convex(0, boxHull()), -0.005);
BENCHMARK_CAPTURE(
    pair, box_sphere_fast,
    [](const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb, double margin,
       ContactManifold& m) { return collideBoxSphere(a, pa, b, pb, margin, m); },
    kBox, kBall, -0.005);
BENCHMARK_CAPTURE(pair, box_sphere_gjk, collideConvex, kBox, kBall, -0.005);
BENCHMARK_CAPTURE(pair, box_capsule_gjk, collideConvex, kBox, kCapsule, -0.005);
// Cap on cap, and a sphere on a cap: segments' closest points against GJK/EPA.
BENCHMARK_CAPTURE(pair, capsule_capsule_fast, collideRoundSegments, kCapsule, kCapsule, -0.005);
BENCHMARK_CAPTURE(pair, capsule_capsule_gjk, collideConvex, kCapsule, kCapsule, -0.005);
BENCHMARK_CAPTURE(pair, sphere_capsule_fast, collideRoundSegments, kBall, kCapsule, -0.005);
BENCHMARK_CAPTURE(pair, sphere_capsule_gjk, collideConvex, kBall, kCapsule, -0.005);

// Two cylinders (or a capsule on a cylinder) lying across one another at
// 0.3 rad, side on side, 5 mm deep: the sides' closest points and rims
// against GJK/EPA.
void sides(benchmark::State& state, Collide collide, Shape a, Shape b) {
  const Quat lying(Eigen::AngleAxisd(0.5 * kPi, Vec3::UnitY()));
  const ShapePose pa{Vec3::Zero(), lying.toRotationMatrix()};
  const ShapePose pb{Vec3(0.05, 0.02, a.radius + b.radius - 0.005),
                     (Quat(Eigen::AngleAxisd(0.3, Vec3::UnitZ())) * lying).toRotationMatrix()};
  ContactManifold m;
  for (auto _ : state) {
    benchmark::DoNotOptimize(collide(a, pa, b, pb, 0.02, m));
  }
  state.counters["points"] = m.pointCount;
}
const Shape kCylinder = Shape::cylinder(0, 0.1, 1.0);
BENCHMARK_CAPTURE(sides, cylinder_cylinder_fast, collideRoundSegments, kCylinder, kCylinder);
BENCHMARK_CAPTURE(sides, cylinder_cylinder_gjk, collideConvex, kCylinder, kCylinder);
BENCHMARK_CAPTURE(sides, capsule_cylinder_fast, collideRoundSegments, kCapsule, kCylinder);
BENCHMARK_CAPTURE(sides, capsule_cylinder_gjk, collideConvex, kCapsule, kCylinder);

}  // namespace

BENCHMARK_MAIN();

// The solvability oracle (oracle.h): the grid search at a given radius, and the exact 2D
// bottleneck against hand-made worlds whose gaps are known and a brute-force grid on random ones.
#include "thicket/sim/oracle.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sim_test_support.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/world.h"

namespace {

using thicket::sim::bottleneckClearance;
using thicket::sim::checkSolvable;
using thicket::sim::Cylinder;
using thicket::sim::GroundTruth;
using thicket::sim::OracleResult;
using thicket::sim::World;
using thicket::sim::testing::generated;

// An empty 15 × 10 × 5 m world flown along y = 5 at 1.5 m, like `paper`.
World emptyWorld() {
  World world;
  world.bounds_max = {15, 10, 5};
  world.start = {1, 5, 1.5};
  world.goal = {14, 5, 1.5};
  world.robot_radius = 0.5;
  return world;
}

// Checks a solvable result: starts and ends at the world's start and goal, has the length it
// reports, and keeps the sphere clear along every segment (sampled at 1 cm). The oracle is
// conservative, so the whole sphere clears the obstacles, not just to within a grid cell.
void expectValidPath(const World& world, const OracleResult& result) {
  ASSERT_TRUE(result.solvable) << result.reason;
  EXPECT_TRUE(result.reason.empty());
  ASSERT_GE(result.path.size(), 2u);
  EXPECT_EQ(result.path.front(), world.start);
  EXPECT_EQ(result.path.back(), world.goal);
  const GroundTruth truth(world);
  double length = 0;
  for (size_t k = 0; k + 1 < result.path.size(); ++k) {
    const Eigen::Vector3d a = result.path[k];
    const Eigen::Vector3d b = result.path[k + 1];
    length += (b - a).norm();
    const int samples = static_cast<int>(std::ceil((b - a).norm() / 0.01)) + 1;
    for (int s = 0; s <= samples; ++s) {
      const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(s) / samples);
      ASSERT_GE(truth.distance(p), world.robot_radius - 1e-9) << "at " << p.transpose();
      ASSERT_LE(p.z(), world.bounds_max.z() - world.robot_radius + 1e-12);
    }
  }
  EXPECT_NEAR(result.path_length, length, 1e-9);
}

// A row of overlapping cylinders across the world at x = 7.5 (radius 0.3 every 0.4 m) with a gap
// of exactly `gap` between the surfaces of the two middle ones, centred on y = 5.
World wall(double height, double gap) {
  World world = emptyWorld();
  for (double offset = gap / 2 + 0.3; offset < 5.3; offset += 0.4) {
    world.cylinders.push_back({7.5, 5 - offset, 0.3, height});
    world.cylinders.push_back({7.5, 5 + offset, 0.3, height});
  }
  return world;
}

TEST(Oracle, EmptyWorldIsSolvable) {
  const World world = emptyWorld();
  const OracleResult result = checkSolvable(GroundTruth(world));
  expectValidPath(world, result);
  EXPECT_GE(result.path_length, (world.goal - world.start).norm());
  EXPECT_LE(result.path_length, (world.goal - world.start).norm() + 0.1);
}

TEST(Oracle, TallWallIsUnsolvable) {
  const OracleResult result = checkSolvable(GroundTruth(wall(5.0, 0.0)));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("cannot be reached"), std::string::npos) << result.reason;
  EXPECT_TRUE(result.path.empty());
}

TEST(Oracle, TwoMetreGapIsSolvable) {
  const World world = wall(5.0, 2.0);
  const OracleResult result = checkSolvable(GroundTruth(world));
  expectValidPath(world, result);
  EXPECT_LE(result.path.back().z(), 1.5);  // through the gap, not over the wall
}

TEST(Oracle, GapNarrowerThanTheRobotIsUnsolvable) {
  const OracleResult result = checkSolvable(GroundTruth(wall(5.0, 0.9)));
  EXPECT_FALSE(result.solvable);
  // A little wider than the robot: the margin the grid needs (2 r + 3 cells) is enough.
  expectValidPath(wall(5.0, 1.2), checkSolvable(GroundTruth(wall(5.0, 1.2))));
}

TEST(Oracle, ShortWallIsFlownOver) {
  const World world = wall(2.0, 0.0);
  const OracleResult result = checkSolvable(GroundTruth(world));
  expectValidPath(world, result);
  const double highest =
      std::max_element(result.path.begin(), result.path.end(), [](const auto& a, const auto& b) {
        return a.z() < b.z();
      })->z();
  EXPECT_GE(highest, 2.0 + world.robot_radius);
  // 4.2 m would need a flight altitude of 4.7 m, above the 4.5 m ceiling for a 0.5 m sphere.
  EXPECT_FALSE(checkSolvable(GroundTruth(wall(4.2, 0.0))).solvable);
}

TEST(Oracle, EndpointsInCollisionAreUnsolvable) {
  World world = emptyWorld();
  world.cylinders = {{1.2, 5, 0.5, 3}};
  OracleResult result = checkSolvable(GroundTruth(world));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("start is in collision"), std::string::npos) << result.reason;

  world = emptyWorld();
  world.goal.y() = 9.7;  // 0.3 m from the wall
  result = checkSolvable(GroundTruth(world));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("goal is in collision"), std::string::npos) << result.reason;

  world = emptyWorld();
  world.goal.z() = 4.8;
  result = checkSolvable(GroundTruth(world));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("goal altitude 4.8 m is outside [0.5, 4.5] m"), std::string::npos)
      << result.reason;

  world = emptyWorld();
  world.bounds_max.z() = 0.9;
  world.start.z() = world.goal.z() = 0.45;
  result = checkSolvable(GroundTruth(world));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("lower than the robot's diameter"), std::string::npos)
      << result.reason;
}

TEST(Oracle, StartTooCloseForTheGridIsReported) {
  // The start clears the cylinder by 2 cm, its 5 cm grid cell does not: conservatively
  // unsolvable. A 1 cm grid sees the passage.
  World world = emptyWorld();
  world.cylinders = {{2.02, 5, 0.5, 5}};
  EXPECT_GE(GroundTruth(world).distance(world.start), world.robot_radius);
  const OracleResult result = checkSolvable(GroundTruth(world));
  EXPECT_FALSE(result.solvable);
  EXPECT_NE(result.reason.find("start's grid cell is blocked"), std::string::npos) << result.reason;
  expectValidPath(world, checkSolvable(GroundTruth(world), {0.01}));
}

TEST(Oracle, RefusesBadResolution) {
  const GroundTruth truth(emptyWorld());
  EXPECT_THROW(checkSolvable(truth, {0.0}), std::invalid_argument);
  EXPECT_THROW(checkSolvable(truth, {1e-6}), std::invalid_argument);
}

TEST(Oracle, GeneratedWorldsPathsAreClear) {
  int solvable = 0;
  int unsolvable = 0;
  for (const auto& [scenario, density] :
       {std::pair{"paper", 0.2}, std::pair{"paper", 0.5}, std::pair{"eth", 0.5}}) {
    for (uint64_t seed = 1; seed <= 6; ++seed) {
      const World world = generated(scenario, density, seed);
      const OracleResult result = checkSolvable(GroundTruth(world));
      if (result.solvable) {
        ++solvable;
        expectValidPath(world, result);
      } else {
        ++unsolvable;
        EXPECT_NE(result.reason.find("cannot be reached"), std::string::npos) << result.reason;
      }
    }
  }
  EXPECT_GT(solvable, 0);
  std::printf("generated worlds: %d solvable, %d unsolvable\n", solvable, unsolvable);
}

TEST(Oracle, RefusesBadRadius) {
  const GroundTruth truth(emptyWorld());
  EXPECT_THROW(checkSolvable(truth, {0.05, -0.1}), std::invalid_argument);
  EXPECT_THROW(checkSolvable(truth, {0.05, std::nan("")}), std::invalid_argument);
}

// Cylinders to the ceiling with a 1.18 m gap: a 0.5 m sphere gets through, a 0.6 m one does not,
// and the bottleneck is half the gap whatever the radius tested.
TEST(Oracle, TestsTheRadiusAsked) {
  const World world = wall(5.0, 1.18);
  const GroundTruth truth(world);
  const OracleResult collision = checkSolvable(truth);
  expectValidPath(world, collision);
  EXPECT_FALSE(collision.needs_overflight);
  EXPECT_NEAR(collision.bottleneck_m, 0.59, 1e-9);
  EXPECT_TRUE(checkSolvable(truth, {0.05, 0.5}).solvable);  // the robot radius, given

  const OracleResult planning = checkSolvable(truth, {0.05, 0.6});
  EXPECT_FALSE(planning.solvable);
  EXPECT_NE(planning.reason.find("cannot be reached"), std::string::npos) << planning.reason;
  EXPECT_FALSE(planning.needs_overflight);
  EXPECT_NEAR(planning.bottleneck_m, 0.59, 1e-9);

  // The start's clearance counts at the radius tested: 0.55 m from a cylinder.
  World near = emptyWorld();
  near.cylinders = {{1, 6.05, 0.5, 5}};
  EXPECT_TRUE(checkSolvable(GroundTruth(near), {0.01}).solvable);
  const OracleResult too_close = checkSolvable(GroundTruth(near), {0.01, 0.6});
  EXPECT_NE(too_close.reason.find("start is in collision"), std::string::npos) << too_close.reason;
}

// A chain of cylinders from wall to wall lower than the ceiling allows: flown over, never around.
TEST(Oracle, LowChainNeedsOverflight) {
  const World closed = wall(2.0, 0.0);
  const OracleResult over = checkSolvable(GroundTruth(closed));
  expectValidPath(closed, over);
  EXPECT_TRUE(over.needs_overflight);
  EXPECT_EQ(over.bottleneck_m, 0.0);  // the chain's cylinders overlap

  // A gap narrower than the sphere: still only over it; one wider: through it.
  const OracleResult narrow = checkSolvable(GroundTruth(wall(2.0, 0.9)));
  EXPECT_TRUE(narrow.solvable);
  EXPECT_TRUE(narrow.needs_overflight);
  EXPECT_NEAR(narrow.bottleneck_m, 0.45, 1e-9);
  const OracleResult wide = checkSolvable(GroundTruth(wall(2.0, 1.6)));
  EXPECT_TRUE(wide.solvable);
  EXPECT_FALSE(wide.needs_overflight);
  EXPECT_NEAR(wide.bottleneck_m, 0.8, 1e-9);

  // Unsolvable is never "needs overflight", and the bottleneck is still reported.
  const OracleResult tall = checkSolvable(GroundTruth(wall(5.0, 0.9)));
  EXPECT_FALSE(tall.solvable);
  EXPECT_FALSE(tall.needs_overflight);
  EXPECT_NEAR(tall.bottleneck_m, 0.45, 1e-9);
}

// ---- the bottleneck on hand-made worlds ----

// A 15 × 3.3 m corridor, start and goal on y = 1.65, with two cylinders of radius 0.5 across it
// at x = 7.5, each touching a wall: the gap between them is 1.3 m.
TEST(Bottleneck, TwoCylindersAcrossACorridor) {
  World world = emptyWorld();
  world.bounds_max.y() = 3.3;
  world.start.y() = world.goal.y() = 1.65;
  world.cylinders = {{7.5, 0.5, 0.5, 1.0}, {7.5, 2.8, 0.5, 1.0}};
  EXPECT_NEAR(bottleneckClearance(world), 0.65, 1e-12);
  const OracleResult result = checkSolvable(GroundTruth(world));
  EXPECT_TRUE(result.solvable);
  EXPECT_FALSE(result.needs_overflight);
  EXPECT_NEAR(result.bottleneck_m, 0.65, 1e-12);
  // The disc must also fit at the start: 0.4 m from the wall.
  world.start.y() = 0.4;
  EXPECT_NEAR(bottleneckClearance(world), 0.4, 1e-12);
  // Inside an obstacle: 0.
  world.start = {7.5, 0.5, 1.5};
  EXPECT_EQ(bottleneckClearance(world), 0.0);
}

TEST(Bottleneck, EmptyWorldIsLimitedByTheEndpoints) {
  World world = emptyWorld();
  EXPECT_NEAR(bottleneckClearance(world), 1.0, 1e-12);  // the start is 1 m from the x = 0 wall
  world.start.x() = 3;
  world.goal = {12, 8.5, 1.5};
  EXPECT_NEAR(bottleneckClearance(world), 1.5, 1e-12);
}

// Cylinders of radius 0.2 along the polyline through `corners`, the first at its start, the
// surfaces of the i-th and the next gap(i) apart along the polyline (closer across a corner).
std::vector<Cylinder> chain(const std::vector<Eigen::Vector2d>& corners,
                            const std::function<double(size_t)>& gap) {
  std::vector<Cylinder> cylinders;
  double along = 0;   // arc length of the next centre
  double passed = 0;  // arc length at corners[k]
  for (size_t k = 0; k + 1 < corners.size(); ++k) {
    const Eigen::Vector2d leg = corners[k + 1] - corners[k];
    for (; along <= passed + leg.norm(); along += 0.4 + gap(cylinders.size() - 1)) {
      const Eigen::Vector2d c = corners[k] + (along - passed) * leg.normalized();
      cylinders.push_back({c.x(), c.y(), 0.2, 5});
    }
    passed += leg.norm();
  }
  return cylinders;
}

// A chain from wall to wall separates start from goal only when they are on different sides of
// it; the disc then gets through its widest gap, whatever the narrower gaps of the chain.
TEST(Bottleneck, WallToWallChainsSeparateOnlyStartAndGoalOnDifferentSides) {
  const auto gaps = [](size_t i) { return i == 7 ? 0.8 : 0.3; };  // one gap of 0.8 m
  World world = emptyWorld();
  // Across the world at x = 7.5, from the bottom wall to the top wall.
  world.cylinders = chain({{7.5, -0.3}, {7.5, 10.3}}, gaps);
  ASSERT_GT(world.cylinders.size(), 8u);
  EXPECT_NEAR(bottleneckClearance(world), 0.4, 1e-9);

  // Along the world at y = 8, from the left wall to the right: start and goal both below it.
  world.cylinders = chain({{-0.3, 8}, {15.3, 8}}, gaps);
  EXPECT_NEAR(bottleneckClearance(world), 1.0, 1e-9);  // the endpoints' clearance

  // A U from the bottom wall around [10, 12] × [0, 7] and back: around neither...
  world.cylinders = chain({{10, -0.3}, {10, 7}, {12, 7}, {12, -0.3}}, gaps);
  EXPECT_NEAR(bottleneckClearance(world), 1.0, 1e-9);
  // ...until the goal is inside it.
  world.goal = {11, 3, 1.5};
  EXPECT_NEAR(bottleneckClearance(world), 0.4, 1e-9);
  // A U around the start from the left wall, open to the goal: the goal outside again.
  world.goal = {14, 5, 1.5};
  world.cylinders = chain({{-0.3, 3}, {3, 3}, {3, 7}, {-0.3, 7}}, gaps);
  EXPECT_NEAR(bottleneckClearance(world), 0.4, 1e-9);
}

// A closed ring of cylinders around the start, clear of every wall.
TEST(Bottleneck, RingAroundTheStart) {
  World world = emptyWorld();
  world.bounds_max.x() = 20;
  world.start = {5, 5, 1.5};
  world.goal = {18, 5, 1.5};
  const int count = 30;
  const double ring = 2.5;
  for (int k = 0; k < count; ++k) {
    const double angle = 2 * std::numbers::pi * k / count;
    world.cylinders.push_back({5 + ring * std::cos(angle), 5 + ring * std::sin(angle), 0.2, 5});
  }
  // Neighbouring centres are 2 ring sin(π / count) apart, twice that once one is removed.
  const double pitch = 2 * ring * std::sin(std::numbers::pi / count);
  EXPECT_NEAR(bottleneckClearance(world), (pitch - 0.4) / 2, 1e-9);
  world.cylinders.erase(world.cylinders.begin() + 10);
  const double open = 2 * ring * std::sin(2 * std::numbers::pi / count) - 0.4;
  EXPECT_NEAR(bottleneckClearance(world), open / 2, 1e-9);
  // The same ring around the goal instead.
  std::swap(world.start, world.goal);
  EXPECT_NEAR(bottleneckClearance(world), open / 2, 1e-9);
}

// ---- the bottleneck against a brute-force grid ----

// Distance in the xy plane from (x, y) to the nearest wall or cylinder (all of them blocking).
double clearance2d(const World& w, double x, double y) {
  double d = std::min(
      {x - w.bounds_min.x(), w.bounds_max.x() - x, y - w.bounds_min.y(), w.bounds_max.y() - y});
  for (const Cylinder& c : w.cylinders) d = std::min(d, std::hypot(x - c.x, y - c.y) - c.radius);
  return d;
}

// 2D clearance of every cell centre of a `res` grid over the world (all cylinders blocking).
struct ClearanceGrid {
  int nx = 0, ny = 0;
  double res = 0;
  std::vector<double> clearance;

  ClearanceGrid(const World& w, double resolution) : res(resolution) {
    nx = static_cast<int>(std::ceil((w.bounds_max.x() - w.bounds_min.x()) / res));
    ny = static_cast<int>(std::ceil((w.bounds_max.y() - w.bounds_min.y()) / res));
    clearance.resize(static_cast<size_t>(nx) * ny);
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        clearance[static_cast<size_t>(j) * nx + i] =
            clearance2d(w, w.bounds_min.x() + (i + 0.5) * res, w.bounds_min.y() + (j + 0.5) * res);
      }
    }
  }

  // Whether the cells whose centre clearance is at least `threshold` connect the cells of a and
  // b (8-connected).
  bool connects(const World& w, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                double threshold) const {
    const auto cellOf = [&](const Eigen::Vector3d& p) {
      const int i = std::clamp(static_cast<int>((p.x() - w.bounds_min.x()) / res), 0, nx - 1);
      const int j = std::clamp(static_cast<int>((p.y() - w.bounds_min.y()) / res), 0, ny - 1);
      return static_cast<size_t>(j) * nx + i;
    };
    const size_t from = cellOf(a), to = cellOf(b);
    std::vector<char> seen(clearance.size(), 0);
    if (clearance[from] < threshold) return false;
    std::queue<size_t> open;
    open.push(from);
    seen[from] = 1;
    while (!open.empty()) {
      const size_t cell = open.front();
      open.pop();
      if (cell == to) return true;
      const int i = static_cast<int>(cell % nx), j = static_cast<int>(cell / nx);
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int ni = i + di, nj = j + dj;
          if (ni < 0 || nj < 0 || ni >= nx || nj >= ny) continue;
          const size_t next = static_cast<size_t>(nj) * nx + ni;
          if (seen[next] || clearance[next] < threshold) continue;
          seen[next] = 1;
          open.push(next);
        }
      }
    }
    return false;
  }
};

// A random 8 × 5 m world: 20 to 50 cylinders of radius 0.1 to 0.6 anywhere (a few beyond the
// walls), start and goal anywhere at least 5 cm from every obstacle.
World randomWorld(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  World world;
  world.bounds_max = {8, 5, 5};
  world.robot_radius = 0.3;
  const int count = 20 + static_cast<int>(u(rng) * 30);
  for (int k = 0; k < count; ++k) {
    world.cylinders.push_back(
        {-0.3 + 8.6 * u(rng), -0.3 + 5.6 * u(rng), 0.1 + 0.5 * u(rng), u(rng) < 0.5 ? 1.0 : 5.0});
  }
  const auto place = [&](double x0, double x1) {
    for (;;) {
      const Eigen::Vector3d p(x0 + (x1 - x0) * u(rng), 0.2 + 4.6 * u(rng), 1.5);
      if (clearance2d(world, p.x(), p.y()) >= 0.05) return p;
    }
  };
  // Most flights cross the world's length like the benchmark's; some go anywhere.
  const bool across = u(rng) < 0.7;
  world.start = place(0.2, across ? 1.5 : 7.8);
  world.goal = place(across ? 6.5 : 0.2, 7.8);
  return world;
}

// A path of clearance ρ passes through cells whose centres clear ρ − h (h: half the cell
// diagonal), 8-connected; cells whose centres clear ρ + h hold only points that clear ρ. So the
// cells clearing c* − h connect start and goal, and those clearing c* + h + ε do not: they would
// give a path of clearance c* + ε.
TEST(Bottleneck, MatchesABruteForceGridOnRandomWorlds) {
  constexpr double kRes = 0.02;
  const double h = kRes * std::sqrt(0.5);
  std::mt19937_64 rng(17);
  int limited_by_a_ring = 0;
  for (int n = 0; n < 80; ++n) {
    const World world = randomWorld(rng);
    const double c = bottleneckClearance(world);
    SCOPED_TRACE("world " + std::to_string(n) + ": c* = " + std::to_string(c));
    const ClearanceGrid grid(world, kRes);
    // The endpoints' own cells decide near c* = their clearance; compare the rest.
    EXPECT_TRUE(grid.connects(world, world.start, world.goal, c - h - 1e-6));
    EXPECT_FALSE(grid.connects(world, world.start, world.goal, c + h + 1e-3));
    const double endpoints = std::min(clearance2d(world, world.start.x(), world.start.y()),
                                      clearance2d(world, world.goal.x(), world.goal.y()));
    EXPECT_LE(c, endpoints + 1e-12);
    limited_by_a_ring += c < endpoints - 1e-9;
  }
  std::printf("%d of 80 worlds limited by a ring of obstacles\n", limited_by_a_ring);
  EXPECT_GT(limited_by_a_ring, 20);
}

}  // namespace

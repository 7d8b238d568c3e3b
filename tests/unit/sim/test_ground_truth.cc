#include "thicket/sim/ground_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "thicket/sim/world.h"

namespace {

using thicket::sim::checkSolvable;
using thicket::sim::Cylinder;
using thicket::sim::GroundTruth;
using thicket::sim::OracleResult;
using thicket::sim::World;

const std::string kWorldsDir = std::string(THICKET_SOURCE_DIR) + "/config/worlds";

World generated(const std::string& scenario, double density, uint64_t seed) {
  const auto spec = thicket::sim::loadScenario(scenario, kWorldsDir);
  EXPECT_TRUE(spec.ok()) << spec.error();
  const auto world = thicket::sim::generateWorld(*spec, density, seed);
  EXPECT_TRUE(world.ok()) << world.error();
  return *world;
}

// An empty 15 × 10 × 5 m world flown along y = 5 at 1.5 m, like `paper`.
World emptyWorld() {
  World world;
  world.bounds_max = {15, 10, 5};
  world.start = {1, 5, 1.5};
  world.goal = {14, 5, 1.5};
  world.robot_radius = 0.5;
  return world;
}

// Signed distance to the solid {horizontal <= 0, z <= top}, where `horizontal` is the signed
// horizontal distance to its side (positive outside): outside, the distance to its closest point;
// inside, minus the distance to the nearer of side and top. Cylinders and walls rest on the ground,
// so their bottoms are not surfaces: the solids extend downwards.
double columnDistance(double horizontal, double z, double top) {
  if (horizontal <= 0 && z <= top) return -std::min(-horizontal, top - z);
  return std::hypot(std::max(horizontal, 0.0), std::max(z - top, 0.0));
}

// Every primitive in turn: the ground, four walls, all cylinders.
double bruteForceDistance(const World& w, const Eigen::Vector3d& p) {
  double best = p.z() - w.bounds_min.z();
  for (const double inside : {p.x() - w.bounds_min.x(), w.bounds_max.x() - p.x(),
                              p.y() - w.bounds_min.y(), w.bounds_max.y() - p.y()}) {
    best = std::min(best, columnDistance(inside, p.z(), w.bounds_max.z()));
  }
  for (const Cylinder& c : w.cylinders) {
    best = std::min(
        best, columnDistance(std::hypot(p.x() - c.x, p.y() - c.y) - c.radius, p.z(), c.height));
  }
  return best;
}

Eigen::Vector3d randomPoint(std::mt19937_64& rng, const World& w, double margin) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Eigen::Vector3d lo = w.bounds_min - Eigen::Vector3d::Constant(margin);
  const Eigen::Vector3d hi = w.bounds_max + Eigen::Vector3d::Constant(margin);
  return {lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y()),
          lo.z() + u(rng) * (hi.z() - lo.z())};
}

TEST(GroundTruth, MatchesBruteForce) {
  for (const auto& [scenario, density] : {std::pair{"forest50", 0.2}, std::pair{"eth", 0.5}}) {
    const World world = generated(scenario, density, 11);
    const GroundTruth truth(world);
    std::mt19937_64 rng(3);
    int inside = 0;
    for (int n = 0; n < 10000; ++n) {
      const Eigen::Vector3d p = randomPoint(rng, world, 1.0);
      const double expected = bruteForceDistance(world, p);
      ASSERT_NEAR(truth.distance(p), expected, 1e-9) << scenario << " at " << p.transpose();
      inside += expected < 0;
    }
    EXPECT_GT(inside, 100);  // the sample reaches inside obstacles too
  }
}

// One cylinder of radius 1 and height 3 at (5, 5) in a 10 × 10 × 5 m world.
World oneCylinder() {
  World world;
  world.bounds_max = {10, 10, 5};
  world.cylinders = {{5, 5, 1, 3}};
  return world;
}

TEST(GroundTruth, AnalyticCases) {
  const GroundTruth truth(oneCylinder());
  struct Case {
    const char* what;
    Eigen::Vector3d p;
    double distance;
    Eigen::Vector3d gradient;
  };
  const Case cases[] = {
      {"beside the cylinder", {7, 5, 2}, 1.0, {1, 0, 0}},
      {"beside, along -y", {5, 3.5, 2.9}, 0.5, {0, -1, 0}},
      {"above the cap", {5.3, 5, 4}, 1.0, {0, 0, 1}},
      {"diagonal to the rim", {6.3, 5, 3.4}, 0.5, {0.6, 0, 0.8}},
      {"inside, nearest the cap", {5.2, 5, 2.5}, -0.5, {0, 0, 1}},
      {"inside, nearest the side", {5.8, 5, 1}, -0.2, {1, 0, 0}},
      {"inside, low: the bottom rests on the ground", {5.5, 5, 0.1}, -0.5, {1, 0, 0}},
      {"near a wall", {0.3, 2, 1}, 0.3, {1, 0, 0}},
      {"near the far y wall", {2, 9.6, 1}, 0.4, {0, -1, 0}},
      {"beyond a wall", {-0.2, 2, 1}, -0.2, {1, 0, 0}},
      {"above a wall's top edge", {0.3, 2, 5.4}, 0.5, {0.6, 0, 0.8}},
      {"near the ground", {2, 2, 0.4}, 0.4, {0, 0, 1}},
      {"below the ground", {2, 2, -0.3}, -0.3, {0, 0, 1}},
  };
  for (const Case& c : cases) {
    Eigen::Vector3d gradient;
    EXPECT_NEAR(truth.distance(c.p, &gradient), c.distance, 1e-12) << c.what;
    EXPECT_NEAR((gradient - c.gradient).norm(), 0.0, 1e-12)
        << c.what << ": " << gradient.transpose();
    EXPECT_EQ(truth.distance(c.p), truth.distance(c.p, &gradient)) << c.what;
  }
}

TEST(GroundTruth, GradientMatchesFiniteDifferences) {
  const World world = generated("paper", 0.5, 4);
  const GroundTruth truth(world);
  std::mt19937_64 rng(5);
  const double h = 1e-6;
  int checked = 0;
  for (int n = 0; n < 2000; ++n) {
    const Eigen::Vector3d p = randomPoint(rng, world, 0.5);
    Eigen::Vector3d gradient;
    const double d = truth.distance(p, &gradient);
    Eigen::Vector3d central;
    bool smooth = true;  // skip points within h of a kink (ties between obstacles, inner edges)
    for (int axis = 0; axis < 3; ++axis) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(axis) * h;
      const double forward = (truth.distance(p + e) - d) / h;
      const double backward = (d - truth.distance(p - e)) / h;
      smooth &= std::abs(forward - backward) < 1e-4;
      central[axis] = (forward + backward) / 2;
    }
    if (!smooth) continue;
    ++checked;
    EXPECT_NEAR(gradient.norm(), 1.0, 1e-12);
    EXPECT_NEAR((gradient - central).norm(), 0.0, 1e-5) << "at " << p.transpose();
  }
  EXPECT_GT(checked, 1900);
}

TEST(GroundTruth, PathClearance) {
  const GroundTruth truth(oneCylinder());
  const std::vector<Eigen::Vector3d> path = {{2, 5, 1}, {3.5, 5, 1}, {3.8, 5, 1}, {3.8, 5, 1}};
  size_t argmin = 99;
  EXPECT_NEAR(truth.pathClearance(path, &argmin), 0.2, 1e-12);
  EXPECT_EQ(argmin, 2u);  // the first of the two nearest
  EXPECT_EQ(truth.pathClearance({}, &argmin), std::numeric_limits<double>::infinity());
  EXPECT_EQ(argmin, 2u);  // untouched
}

TEST(GroundTruth, RefusesInvalidWorlds) {
  World world = oneCylinder();
  world.cylinders[0].radius = -1;
  EXPECT_THROW(GroundTruth{world}, std::invalid_argument);
  world = oneCylinder();
  world.bounds_max.x() = 0;
  EXPECT_THROW(GroundTruth{world}, std::invalid_argument);
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

}  // namespace

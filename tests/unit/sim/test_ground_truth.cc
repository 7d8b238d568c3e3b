#include "thicket/sim/ground_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "sim_test_support.h"
#include "thicket/sim/world.h"

namespace {

using thicket::sim::Cylinder;
using thicket::sim::GroundTruth;
using thicket::sim::World;
using thicket::sim::testing::generated;

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

}  // namespace

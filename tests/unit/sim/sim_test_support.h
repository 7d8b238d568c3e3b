// Worlds and trajectories the simulator tests share.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "thicket/common/polynomial_trajectory.h"
#include "thicket/sim/world.h"

namespace thicket::sim::testing {

/// The world of (scenario, density, seed) from the source tree's config/worlds.
inline World generated(const std::string& scenario, double density, uint64_t seed) {
  const auto spec = loadScenario(scenario, std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  EXPECT_TRUE(spec.ok()) << spec.error();
  const auto world = generateWorld(*spec, density, seed);
  EXPECT_TRUE(world.ok()) << world.error();
  return *world;
}

/// A 20 x 10 x 5 m box, start (1, 5, 1.5), goal (10, 5, 1.5), robot radius 0.5.
inline World corridor(std::vector<Cylinder> cylinders = {}) {
  World world;
  world.scenario = "corridor";
  world.bounds_min = Eigen::Vector3d(0, 0, 0);
  world.bounds_max = Eigen::Vector3d(20, 10, 5);
  world.start = Eigen::Vector3d(1, 5, 1.5);
  world.goal = Eigen::Vector3d(10, 5, 1.5);
  world.robot_radius = 0.5;
  world.cylinders = std::move(cylinders);
  return world;
}

/// A cubic from `from` to `to`, at rest at both ends, over `duration` seconds.
inline polynomial_trajectory_t restToRest(int64_t start_utime, const Eigen::Vector3d& from,
                                          const Eigen::Vector3d& to, double duration) {
  const Eigen::Vector3d d = to - from;
  PolynomialSegment segment{duration, Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, 4)};
  segment.coefficients.col(0) = from;
  segment.coefficients.col(2) = 3 * d / (duration * duration);
  segment.coefficients.col(3) = -2 * d / (duration * duration * duration);
  return PolynomialTrajectory::create(start_utime, {segment})->toLcm(0, 1);
}

}  // namespace thicket::sim::testing

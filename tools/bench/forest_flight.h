// The benchmark world of docs/benchmark.md, forest50 at density 0.2, and level poses a vehicle
// could fly through it: shared by the benchmarks and the tests that measure on the same frames.
// THICKET_SOURCE_DIR must name the source tree.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "thicket/common/geometry.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/world.h"

namespace thicket::bench {

inline sim::World forest50(uint64_t seed) {
  auto spec = sim::loadScenario("forest50", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  if (!spec) throw std::runtime_error(spec.error());
  return *sim::generateWorld(*spec, 0.2, seed);
}

/// forest50 at density 0.2, seed 1: built once.
inline const sim::World& forest() {
  static const sim::World world = forest50(1);
  return world;
}

/// `count` poses every `step` metres along the start-goal diagonal at the start's height, facing
/// the goal, skipping those within the robot radius of a tree.
inline std::vector<Pose> flightPoses(double step, size_t count) {
  const sim::World& world = forest();
  const sim::GroundTruth truth(world);
  const Eigen::Vector3d direction = (world.goal - world.start).normalized();
  std::vector<Pose> poses;
  for (double s = step; poses.size() < count; s += step) {
    const Eigen::Vector3d p = world.start + s * direction;
    if ((p - world.start).norm() > (world.goal - world.start).norm()) {
      throw std::runtime_error("flightPoses: the diagonal is too short for that many poses");
    }
    if (truth.distance(p) > world.robot_radius) {
      poses.push_back(Pose::fromYaw(p, std::atan2(direction.y(), direction.x())));
    }
  }
  return poses;
}

}  // namespace thicket::bench

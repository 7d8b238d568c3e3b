// The simulator's ground-truth world (docs/benchmark.md): vertical cylinders ("trees") standing on
// a ground plane at z = 0, inside walls on the x/y boundary. Generated from (scenario, density,
// seed) with a fully specified generator, so the same triple gives the same world on any machine.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/expected.h"

namespace thicket::sim {

/// A vertical cylinder on the ground: axis at (x, y), from z = 0 to z = height.
struct Cylinder {
  double x = 0;
  double y = 0;
  double radius = 0;
  double height = 0;
};

/// How a scenario's worlds are drawn (config/worlds/<name>.yaml).
struct ScenarioSpec {
  std::string name;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();          // world extent from the origin [m]
  Eigen::Vector2d obstacle_min = Eigen::Vector2d::Zero();  // region cylinder axes are drawn in [m]
  Eigen::Vector2d obstacle_max = Eigen::Vector2d::Zero();
  double radius_min = 0.1, radius_max = 0.5;  // uniform [m]
  double height_min = 2.0, height_max = 5.0;  // uniform [m]
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  double robot_radius = 0.5;
  /// No cylinder surface comes closer than this to the start or goal (xy distance) [m], so that
  /// every trial starts and ends in free space.
  double keep_clear = 1.0;
};

struct World {
  std::string scenario;
  double density = 0;  // cylinders per m^2 of the obstacle region
  uint64_t seed = 0;
  Eigen::Vector3d bounds_min = Eigen::Vector3d::Zero();  // ground at bounds_min.z() = 0
  Eigen::Vector3d bounds_max =
      Eigen::Vector3d::Zero();  // walls at the x/y bounds; z = height limit
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  double robot_radius = 0.5;
  std::vector<Cylinder> cylinders;
};

/// The scenario `name_or_path` names: a bare name ("paper") is read from
/// `<worlds_dir>/<name>.yaml`; anything containing '/' or ending in ".yaml" is a file path. The
/// scenario's name is the file's stem. Refuses unreadable files, unknown keys and wrong types (as
/// thicket::loadParams does) and inconsistent scenarios: empty sizes, an obstacle region outside
/// the world, min > max ranges, a robot taller than the world, or a start or goal less than the
/// robot radius from the ground, the walls or the height limit.
Expected<ScenarioSpec> loadScenario(const std::string& name_or_path, const std::string& worlds_dir);

/// A world of floor(density × obstacle region area) cylinders drawn from `spec` with `seed`; the
/// same (spec, density, seed) gives a bitwise identical world on every conforming C++ platform
/// (the recipe is in world.cc). Cylinders may overlap, as trees do. Refuses an inconsistent spec
/// (see loadScenario), a negative or non-finite density, more than a million cylinders, and specs
/// where a cylinder clear of the start and goal cannot be drawn in 1000 attempts.
Expected<World> generateWorld(const ScenarioSpec& spec, double density, uint64_t seed);

/// The world as one JSON object, for plots and logs: scenario, density, seed, bounds_min,
/// bounds_max, start, goal, robot_radius and cylinders [{x, y, radius, height}]. Doubles are
/// printed with 17 significant digits, so they parse back exactly; the seed is a 64-bit integer
/// (exact in Python, rounded above 2^53 by JavaScript numbers).
std::string worldToJson(const World& world);

}  // namespace thicket::sim

#include "thicket/sim/world.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <nlohmann/json.hpp>

#include "thicket/common/params.h"

namespace thicket::sim {
namespace {

// A world larger than this is a typo in the density, not a benchmark.
constexpr double kMaxCylinders = 1e6;
// Draws per cylinder before a spec whose keep-clear zones cover the region is refused.
constexpr int kMaxAttemptsPerCylinder = 1000;

// The YAML form of a ScenarioSpec: Params has no 2D vectors, so the region corners are read as
// two-element sequences and checked in toSpec.
struct ScenarioFile {
  ScenarioSpec spec;
  std::vector<double> obstacle_min;
  std::vector<double> obstacle_max;

  void declare(Params& p) {
    p("size", spec.size, "world extent from the origin, x y z [m]");
    p("obstacle_min", obstacle_min, "lower corner of the region cylinder axes are drawn in [m]");
    p("obstacle_max", obstacle_max, "upper corner of that region [m]");
    p("radius_min", spec.radius_min, "cylinder radius, drawn uniformly [m]", Range::positive());
    p("radius_max", spec.radius_max, "[m]", Range::positive());
    p("height_min", spec.height_min, "cylinder height, drawn uniformly [m]", Range::positive());
    p("height_max", spec.height_max, "[m]", Range::positive());
    p("start", spec.start, "where the vehicle starts [m]");
    p("goal", spec.goal, "where it must go [m]");
    p("robot_radius", spec.robot_radius, "radius of the sphere the vehicle must fit in [m]",
      Range::positive());
    p("keep_clear", spec.keep_clear,
      "no cylinder surface comes closer than this to the start or goal (xy) [m]",
      Range::atLeast(0));
  }
};

std::string format(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

// Appended piece by piece: GCC 12 at -O3 warns falsely (-Wrestrict) on "(" + std::string.
std::string format(const Eigen::Vector2d& v) {
  std::string text = "(";
  text += format(v.x());
  text += ", ";
  text += format(v.y());
  return text += ")";
}

std::string format(const Eigen::Vector3d& v) {
  std::string text = "(";
  text += format(v.x());
  text += ", ";
  text += format(v.y());
  text += ", ";
  text += format(v.z());
  return text += ")";
}

// Why `spec` cannot be used; empty when it can.
std::string scenarioError(const ScenarioSpec& s) {
  const bool finite = s.size.allFinite() && s.obstacle_min.allFinite() &&
                      s.obstacle_max.allFinite() && s.start.allFinite() && s.goal.allFinite() &&
                      std::isfinite(s.radius_min) && std::isfinite(s.radius_max) &&
                      std::isfinite(s.height_min) && std::isfinite(s.height_max) &&
                      std::isfinite(s.robot_radius) && std::isfinite(s.keep_clear);
  if (!finite) return "non-finite value";
  if ((s.size.array() <= 0).any()) return "size " + format(s.size) + " must be positive";
  if ((s.obstacle_min.array() >= s.obstacle_max.array()).any()) {
    return "obstacle_min " + format(s.obstacle_min) + " must be below obstacle_max " +
           format(s.obstacle_max) + " in x and y";
  }
  if ((s.obstacle_min.array() < 0).any() ||
      (s.obstacle_max.array() > s.size.head<2>().array()).any()) {
    return "obstacle region " + format(s.obstacle_min) + " to " + format(s.obstacle_max) +
           " is not inside the world (0, 0) to " + format(Eigen::Vector2d(s.size.head<2>()));
  }
  if (!(s.radius_min > 0 && s.radius_min <= s.radius_max)) {
    return "need 0 < radius_min <= radius_max, got " + format(s.radius_min) + " and " +
           format(s.radius_max);
  }
  if (!(s.height_min > 0 && s.height_min <= s.height_max)) {
    return "need 0 < height_min <= height_max, got " + format(s.height_min) + " and " +
           format(s.height_max);
  }
  if (!(s.robot_radius > 0 && 2 * s.robot_radius <= s.size.z())) {
    return "robot_radius " + format(s.robot_radius) + " must be positive and fit under the " +
           "world height " + format(s.size.z());
  }
  if (s.keep_clear < 0) return "keep_clear " + format(s.keep_clear) + " must be >= 0";
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(s.robot_radius);
  for (const auto& [what, p] : {std::pair{"start", s.start}, std::pair{"goal", s.goal}}) {
    if ((p.array() < margin.array()).any() || (p.array() > (s.size - margin).array()).any()) {
      return std::string(what) + " " + format(p) + " must be at least robot_radius " +
             format(s.robot_radius) + " from the ground, the walls and the height limit of the " +
             "world " + format(s.size);
    }
  }
  return "";
}

Expected<ScenarioSpec> toSpec(ScenarioFile file) {
  for (const auto& [key, corner] : {std::pair{"obstacle_min", &file.obstacle_min},
                                    std::pair{"obstacle_max", &file.obstacle_max}}) {
    if (corner->size() != 2) {
      return unexpected(std::string(key) + " must be [x, y], got " +
                        std::to_string(corner->size()) + " values");
    }
  }
  file.spec.obstacle_min = Eigen::Vector2d(file.obstacle_min[0], file.obstacle_min[1]);
  file.spec.obstacle_max = Eigen::Vector2d(file.obstacle_max[0], file.obstacle_max[1]);
  const std::string error = scenarioError(file.spec);
  if (!error.empty()) return unexpected(error);
  return file.spec;
}

// 64-bit FNV-1a.
uint64_t fnv1a(const std::string& text) {
  uint64_t hash = 0xcbf29ce484222325ull;
  for (const char c : text) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 0x100000001b3ull;
  }
  return hash;
}

}  // namespace

Expected<ScenarioSpec> loadScenario(const std::string& name_or_path,
                                    const std::string& worlds_dir) {
  const bool is_path = name_or_path.find('/') != std::string::npos ||
                       std::filesystem::path(name_or_path).extension() == ".yaml";
  const std::string path = is_path ? name_or_path : worlds_dir + "/" + name_or_path + ".yaml";
  ScenarioFile file;
  try {
    file = loadParams<ScenarioFile>(path);
  } catch (const ParamError& e) {
    return unexpected(e.what());
  }
  file.spec.name = std::filesystem::path(path).stem().string();
  Expected<ScenarioSpec> spec = toSpec(std::move(file));
  if (!spec) return unexpected(path + ": " + spec.error());
  return spec;
}

// The recipe, which any implementation can follow to draw the same worlds:
//  1. engine: std::mt19937_64 (its output sequence is fixed by the C++ standard) seeded with
//     seed XOR FNV-1a-64(scenario name) (offset basis 0xcbf29ce484222325, prime 0x100000001b3,
//     over the name's bytes), so scenarios sharing a seed still get unrelated worlds.
//  2. u = (engine() >> 11) * 2^-53, a double in [0, 1); uniform(a, b) = fma(b - a, u, a) in IEEE
//     double (std::uniform_real_distribution is implementation-defined, and an explicit fma leaves
//     the compiler no choice about contracting a + (b - a) * u).
//  3. count = floor(density * width * depth + 1e-9) for the obstacle region, multiplied in that
//     order (the 1e-9 keeps e.g. 0.57 * 10 * 10 = 56.99999999999999 from losing a cylinder).
//  4. Per cylinder, in order: x = uniform(min.x, max.x), y = uniform(min.y, max.y),
//     radius = uniform(radius_min, radius_max), height = uniform(height_min, height_max). If
//     fma(dx, dx, dy * dy) < (keep_clear + radius)^2, with (dx, dy) from the start or the goal to
//     the axis, all four are discarded and drawn again.
// Changing any step changes every world: do it deliberately and update the golden test.
Expected<World> generateWorld(const ScenarioSpec& spec, double density, uint64_t seed) {
  if (const std::string error = scenarioError(spec); !error.empty()) {
    return unexpected("scenario '" + spec.name + "': " + error);
  }
  if (!std::isfinite(density) || density < 0) {
    return unexpected("density " + format(density) + " must be finite and >= 0");
  }
  const Eigen::Vector2d extent = spec.obstacle_max - spec.obstacle_min;
  const double expected_count = density * extent.x() * extent.y();  // apart: no fma contraction
  const double count = std::floor(expected_count + 1e-9);
  if (count > kMaxCylinders) {
    return unexpected("density " + format(density) + " gives " + format(count) +
                      " cylinders, more than " + format(kMaxCylinders));
  }

  std::mt19937_64 engine(seed ^ fnv1a(spec.name));
  const auto uniform = [&engine](double lo, double hi) {
    const double u = static_cast<double>(engine() >> 11) * 0x1.0p-53;
    return std::fma(hi - lo, u, lo);
  };
  const auto tooClose = [&spec](const Cylinder& c) {
    const double reach = spec.keep_clear + c.radius;
    for (const Eigen::Vector3d& p : {spec.start, spec.goal}) {
      const double dx = c.x - p.x();
      const double dy = c.y - p.y();
      if (std::fma(dx, dx, dy * dy) < reach * reach) return true;
    }
    return false;
  };

  World world;
  world.scenario = spec.name;
  world.density = density;
  world.seed = seed;
  world.bounds_max = spec.size;
  world.start = spec.start;
  world.goal = spec.goal;
  world.robot_radius = spec.robot_radius;
  world.cylinders.reserve(static_cast<size_t>(count));
  for (size_t i = 0; i < static_cast<size_t>(count); ++i) {
    Cylinder c;
    int attempts = 0;
    do {
      if (attempts++ == kMaxAttemptsPerCylinder) {
        return unexpected("scenario '" + spec.name + "': no place for cylinder " +
                          std::to_string(i) + " clear of the start and goal in " +
                          std::to_string(kMaxAttemptsPerCylinder) + " draws (keep_clear " +
                          format(spec.keep_clear) + " too large for the obstacle region?)");
      }
      c.x = uniform(spec.obstacle_min.x(), spec.obstacle_max.x());
      c.y = uniform(spec.obstacle_min.y(), spec.obstacle_max.y());
      c.radius = uniform(spec.radius_min, spec.radius_max);
      c.height = uniform(spec.height_min, spec.height_max);
    } while (tooClose(c));
    world.cylinders.push_back(c);
  }
  return world;
}

std::string worldToJson(const World& world) {
  using Json = nlohmann::ordered_json;
  const auto vector = [](const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); };
  Json cylinders = Json::array();
  for (const Cylinder& c : world.cylinders) {
    cylinders.push_back({{"x", c.x}, {"y", c.y}, {"radius", c.radius}, {"height", c.height}});
  }
  const Json json = {{"scenario", world.scenario},
                     {"density", world.density},
                     {"seed", world.seed},
                     {"bounds_min", vector(world.bounds_min)},
                     {"bounds_max", vector(world.bounds_max)},
                     {"start", vector(world.start)},
                     {"goal", vector(world.goal)},
                     {"robot_radius", world.robot_radius},
                     {"cylinders", cylinders}};
  return json.dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace thicket::sim

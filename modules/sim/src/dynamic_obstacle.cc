#include "thicket/sim/dynamic_obstacle.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "thicket/common/time.h"

namespace thicket::sim {
namespace {

// "DYNAMIC1": the obstacle's draws are unrelated to the world's, which the same seed drives.
constexpr uint64_t kDrawSalt = 0x44594e414d494331;
// A path chord with less horizontal extent than this is vertical: it has no horizontal direction.
constexpr double kMinHorizontalChord = 1e-6;  // [m]

std::string format(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

}  // namespace

void DynamicObstacleOptions::declare(Params& p) {
  p("enabled", enabled,
    "a cylinder appears in the flight path during the trial, placed by draws from the world "
    "seed");
  p("appear_time", appear_time,
    "earliest appearance, at the first frame at or after it with enough committed path ahead "
    "[s after the trial start]",
    Range::atLeast(0));
  p("distance_ahead_min", distance_ahead_min,
    "its axis stands this much path length along the committed trajectory ahead of the vehicle, "
    "drawn uniformly from [min, max]; min must exceed radius + the robot radius [m]",
    Range::positive());
  p("distance_ahead_max", distance_ahead_max, "[m]; at least distance_ahead_min",
    Range::positive());
  p("lateral_offset", lateral_offset,
    "largest horizontal offset of the axis from the path, drawn uniformly from [-this, this] [m]",
    Range::atLeast(0));
  p("radius", radius, "[m]", Range::positive());
  p("height", height, "[m]; 0: the world's height limit, so that it cannot be flown over",
    Range::atLeast(0));
}

std::string dynamicObstacleError(const DynamicObstacleOptions& o, double robot_radius) {
  if (!(o.appear_time >= 0 && std::isfinite(o.appear_time))) {
    return "appear_time must be finite and >= 0";
  }
  if (!(o.radius > 0 && std::isfinite(o.radius))) return "radius must be finite and > 0";
  if (!(o.height >= 0 && std::isfinite(o.height))) return "height must be finite and >= 0";
  if (!(o.lateral_offset >= 0 && std::isfinite(o.lateral_offset))) {
    return "lateral_offset must be finite and >= 0";
  }
  if (!(o.distance_ahead_max >= o.distance_ahead_min && std::isfinite(o.distance_ahead_max))) {
    return "distance_ahead_max (" + format(o.distance_ahead_max) +
           ") must be finite and >= distance_ahead_min (" + format(o.distance_ahead_min) + ")";
  }
  // The axis is at least distance_ahead_min from the vehicle along the path, so this keeps the
  // vehicle clear of the obstacle where the path runs straight.
  if (!(o.distance_ahead_min > o.radius + robot_radius)) {
    return "distance_ahead_min (" + format(o.distance_ahead_min) + " m) must exceed radius (" +
           format(o.radius) + " m) + the robot radius (" + format(robot_radius) +
           " m), or the vehicle would be inside the obstacle when it appears";
  }
  return {};
}

DynamicObstacleDraw drawDynamicObstacle(const DynamicObstacleOptions& options,
                                        uint64_t world_seed) {
  std::mt19937_64 engine(world_seed ^ kDrawSalt);
  const auto uniform = [&engine](double lo, double hi) {
    const double u = static_cast<double>(engine() >> 11) * 0x1.0p-53;
    return std::fma(hi - lo, u, lo);
  };
  DynamicObstacleDraw draw;
  draw.distance_ahead = uniform(options.distance_ahead_min, options.distance_ahead_max);
  draw.lateral_offset = uniform(-options.lateral_offset, options.lateral_offset);
  return draw;
}

std::optional<Eigen::Vector2d> dynamicObstacleAxis(const PolynomialTrajectory& trajectory,
                                                   int64_t utime, const DynamicObstacleDraw& draw,
                                                   double sample_period) {
  if (!(sample_period > 0) || !std::isfinite(sample_period)) {
    throw std::invalid_argument("dynamicObstacleAxis: sample_period must be positive and finite");
  }
  const double t0 = toSeconds(utime - trajectory.startUtime());
  const double end = trajectory.duration();
  if (t0 >= end) return std::nullopt;
  Eigen::Vector3d previous = trajectory.evaluate(t0);
  double travelled = 0;
  for (int64_t i = 1;; ++i) {
    const double t = std::min(t0 + static_cast<double>(i) * sample_period, end);
    const Eigen::Vector3d position = trajectory.evaluate(t);
    const Eigen::Vector3d chord = position - previous;
    const double length = chord.norm();
    if (length > 0 && travelled + length >= draw.distance_ahead) {
      const Eigen::Vector3d foot = previous + (draw.distance_ahead - travelled) / length * chord;
      const Eigen::Vector2d along = chord.head<2>();
      const double horizontal = along.norm();
      const Eigen::Vector2d left =
          horizontal > kMinHorizontalChord
              ? Eigen::Vector2d(Eigen::Vector2d(-along.y(), along.x()) / horizontal)
              : Eigen::Vector2d::UnitY();
      return Eigen::Vector2d(foot.head<2>() + draw.lateral_offset * left);
    }
    travelled += length;
    previous = position;
    if (t >= end) return std::nullopt;
  }
}

}  // namespace thicket::sim

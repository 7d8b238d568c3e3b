// A dynamic obstacle: one vertical cylinder that appears in the vehicle's flight path during a
// trial, so that a test can block a committed trajectory without warning (the planner's re-check
// of its committed trajectory and its emergency stop). Where it stands relative to the path is
// drawn once per trial from the world seed; SimNode decides when it appears (the first frame at or
// after appear_time with enough committed path ahead) and adds it to the world.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "thicket/common/params.h"
#include "thicket/common/polynomial_trajectory.h"
#include "thicket/sim/world.h"

namespace thicket::sim {

struct DynamicObstacleOptions {
  bool enabled = false;
  /// Earliest appearance [s after the trial start]: it appears at the first frame at or after
  /// this time whose committed trajectory has at least the drawn distance of path left and does
  /// not wind back toward the vehicle (its surface at least distance_ahead_min - radius from the
  /// vehicle), before that frame is rendered.
  double appear_time = 5.0;
  /// Where its axis goes: this much path length along the committed trajectory from the vehicle,
  /// drawn uniformly from [min, max] [m]. The minimum must exceed radius + the robot radius.
  double distance_ahead_min = 2.0;
  double distance_ahead_max = 2.5;
  /// Largest sideways offset of the axis from the path, horizontal and perpendicular to the path
  /// there, drawn uniformly from [-this, this] [m]. Below radius + the robot radius the vehicle
  /// cannot pass it without leaving the path.
  double lateral_offset = 0.25;
  double radius = 0.5;  ///< [m]
  /// [m]; 0: the world's height limit (bounds_max.z), so that it cannot be flown over.
  double height = 0;

  void declare(Params& p);
};

/// Why the options cannot place an obstacle in a world with this robot radius (a non-positive
/// radius or distance, distance_ahead_max < distance_ahead_min, distance_ahead_min not beyond
/// radius + robot_radius, negative times, offsets or heights), empty when they can.
std::string dynamicObstacleError(const DynamicObstacleOptions& options, double robot_radius);

/// What a trial's obstacle draws: fixed for the whole trial, however long its appearance waits.
struct DynamicObstacleDraw {
  double distance_ahead = 0;  ///< path length from the vehicle to the axis' foot on the path [m]
  double lateral_offset = 0;  ///< toward the left of the path direction, negative to the right [m]
};

/// The draw for a world seed. The recipe: std::mt19937_64 seeded with world_seed XOR
/// 0x44594e414d494331 ("DYNAMIC1", so that it does not follow the world's own draws), u =
/// (engine() >> 11) * 2^-53, uniform(a, b) = fma(b - a, u, a) as in generateWorld; first
/// distance_ahead = uniform(min, max), then lateral_offset = uniform(-lateral, lateral).
DynamicObstacleDraw drawDynamicObstacle(const DynamicObstacleOptions& options, uint64_t world_seed);

/// Where the drawn obstacle's axis stands (x, y) if it appears at `utime` on `trajectory`: its
/// foot is draw.distance_ahead of path length along the trajectory from its position at utime
/// (the path sampled every sample_period seconds and straight in between, as the vehicle executes
/// and measures it), and the axis is draw.lateral_offset from there, to the left of the
/// horizontal direction of the path there (along world y where the path is vertical). nullopt
/// when less path than that remains after utime. Throws std::invalid_argument for a
/// non-positive sample_period.
std::optional<Eigen::Vector2d> dynamicObstacleAxis(const PolynomialTrajectory& trajectory,
                                                   int64_t utime, const DynamicObstacleDraw& draw,
                                                   double sample_period);

/// A dynamic obstacle that has appeared, as the simulator reports it.
struct AppearedObstacle {
  Cylinder cylinder;
  int64_t utime = 0;  ///< when it appeared: the time of the first frame that shows it [us]
  int64_t frame = 0;  ///< that frame's number, 0 for the trial's first frame
  /// Smallest ground-truth distance from the vehicle's centre to its surface since it appeared,
  /// over the vehicle's state then and every executed sample after [m]. Below the robot radius
  /// the vehicle hit it.
  double min_clearance = 0;
};

}  // namespace thicket::sim

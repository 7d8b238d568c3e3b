// The emergency stop: when a new map blocks the rest of the committed trajectory, the planner
// commits at once a trajectory from the reference state to rest. Candidates are minimum-jerk
// stops (one 9th-order segment from the start state to rest, the end position free) of growing
// duration, from the shortest that keeps the speed and acceleration limits: the first whose every
// acceptance sample clears the map (known, at least robot radius + clearance margin) wins, so the
// vehicle stops as early as it can inside certified free space. When none does, the shortest one
// is taken: the hardest stop the limits allow.
//
// The retreat: a vehicle that stands at the edge of the clearance margin (or inside it, where a
// new map put it) can find every optimized plan refused, each dipping a millimetre below where it
// starts. The retreat backs it straight out instead: along each of the 26 directions to the
// neighbours of a cube, in 5 cm steps up to 1 m, every point known and no closer to an obstacle
// than the acceptance lets a flight from this start come, the first point `beyond` more than the
// required clearance (a ridge between two trees is left along the ridge, where an ascent of the
// gradient would zigzag across it). The shortest of those ways out, the farthest from obstacles
// among equals, whose minimum-jerk flight from the start state to rest keeps the limits and passes
// the acceptance is flown. In a pinch where no way gets that far within 1 m, the way to the point
// farthest from obstacles is flown instead, when it gains at least 2 cm: the next cycle starts
// there.
#pragma once

#include <cstdint>
#include <optional>

#include "thicket/common/polynomial_trajectory.h"
#include "thicket/local_planner/loco.h"

namespace thicket::local_planner {

struct Stop {
  PolynomialTrajectory trajectory;
  /// Every acceptance sample clears the field; false: the hardest stop, not certified.
  bool certified = false;
  /// From the start to where it comes to rest [m].
  double distance = 0;
};

/// A stop from `start` at `utime` on `field`, with `options`' limits and required clearance
/// (robot_radius + clearance_margin). Throws std::invalid_argument on a non-finite start.
Stop planStop(int64_t utime, const TrajectoryState& start, const DistanceField& field,
              const LocoOptions& options);

struct Retreat {
  PolynomialTrajectory trajectory;
  double from_distance = 0;  ///< the field's distance at the start [m]
  double to_distance = 0;    ///< ... and where it ends [m]
};

/// The retreat from `start` (see the header), or nothing: the start is unknown or already `beyond`
/// outside the margin, or no way out passes. Throws std::invalid_argument on a
/// non-finite start or a `beyond` that is not finite and positive.
std::optional<Retreat> planRetreat(int64_t utime, const TrajectoryState& start,
                                   const DistanceField& field, const LocoOptions& options,
                                   double beyond);

}  // namespace thicket::local_planner

// The emergency stop: when a new map blocks the rest of the committed trajectory, the planner
// commits at once a trajectory from the reference state to rest. Candidates are minimum-jerk
// stops (one 9th-order segment from the start state to rest, the end position free) of growing
// duration, from the shortest that keeps the speed and acceleration limits: the first whose every
// acceptance sample clears the map (known, at least robot radius + clearance margin) wins, so the
// vehicle stops as early as it can inside certified free space. When none does, the shortest one
// is taken: the hardest stop the limits allow.
#pragma once

#include <cstdint>

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

}  // namespace thicket::local_planner

// Goal finding (docs/design.md §1): the goal the optimizer aims at this cycle. The tracked goal is
// projected onto the planning horizon sphere around the start; when that point is not free it is
// moved, either back along the straight line toward the start, or up the ESDF gradient (away from
// obstacles) with a straight-line step wherever the gradient gives no direction (unknown space, a
// flat field) or would carry it behind the start (the plane through the start across the
// direction to the goal): a horizon goal behind the vehicle would fly it away from its goal.
#pragma once

#include <string>

#include <Eigen/Core>

#include "thicket/common/params.h"
#include "thicket/local_planner/loco.h"

namespace thicket::local_planner {

struct GoalFinderOptions {
  double horizon = 3.0;  ///< r_p: the planning horizon [m]
  /// "line": straight-line backtracking; "gradient": gradient ascent of the ESDF distance.
  std::string method = "gradient";
  double step = 0.2;  ///< one step, a voxel [m]
  int max_steps = 20;

  void declare(Params& p);
};

struct FoundGoal {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool free = false;  ///< false: no free point was found within max_steps (position: the last)
  int steps = 0;
  bool projected = false;  ///< the goal was beyond the horizon
};

class GoalFinder {
 public:
  /// A point is free when it is known with distance >= free_distance (the clearance loco
  /// accepts, so a trajectory can end there) [m]. Throws std::invalid_argument on a bad option.
  GoalFinder(GoalFinderOptions options, double free_distance);
  const GoalFinderOptions& options() const { return options_; }

  /// The horizon goal for a start and a goal. Throws std::invalid_argument on non-finite input.
  FoundGoal find(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                 const DistanceField& field) const;

 private:
  bool isFree(const EsdfSample& sample) const;

  GoalFinderOptions options_;
  double free_distance_;
};

}  // namespace thicket::local_planner

#include "thicket/local_planner/goal_finder.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace thicket::local_planner {

void GoalFinderOptions::declare(Params& p) {
  p("horizon", horizon, "r_p: goals are projected onto this sphere around the start [m]",
    Range::positive());
  p.choice("method", method, {"line", "gradient"},
           "moves a horizon goal out of collision: straight-line backtracking or ESDF gradient "
           "ascent");
  p("step", step, "step length of the search [m]", Range::positive());
  p("max_steps", max_steps, "steps before the search gives up", Range::between(0, 1000));
}

GoalFinder::GoalFinder(GoalFinderOptions options, double free_distance)
    : options_(std::move(options)), free_distance_(free_distance) {
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("GoalFinder: " + error);
  }
  if (!(std::isfinite(free_distance_) && free_distance_ > 0)) {
    throw std::invalid_argument("GoalFinder: the free distance must be positive and finite");
  }
}

bool GoalFinder::isFree(const EsdfSample& sample) const {
  return sample.known && sample.distance >= free_distance_;
}

FoundGoal GoalFinder::find(const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                           const DistanceField& field) const {
  if (!start.allFinite() || !goal.allFinite()) {
    throw std::invalid_argument("GoalFinder::find: start and goal must be finite");
  }
  FoundGoal found;
  const Eigen::Vector3d offset = goal - start;
  found.projected = offset.norm() > options_.horizon;
  found.position =
      found.projected ? Eigen::Vector3d(start + offset.normalized() * options_.horizon) : goal;
  EsdfSample sample = field(found.position);
  while (!isFree(sample) && found.steps < options_.max_steps) {
    const Eigen::Vector3d back = start - found.position;
    // Gradient ascent, unless it would carry the goal behind the start (where the soft goal
    // would pull the vehicle away from its goal): then a step back along the line.
    std::optional<Eigen::Vector3d> ascent;
    if (options_.method == "gradient" && sample.known && sample.gradient.norm() > 1e-6) {
      ascent = found.position + options_.step * sample.gradient.normalized();
    }
    if (ascent && (*ascent - start).dot(offset) >= 0) {
      found.position = *ascent;
    } else if (back.norm() > 1e-9) {
      // Straight-line backtracking, never past the start.
      found.position += std::min(options_.step, back.norm()) * back.normalized();
    } else {
      break;  // at the start with no gradient: nowhere to go
    }
    ++found.steps;
    sample = field(found.position);
  }
  found.free = isFree(sample);
  return found;
}

}  // namespace thicket::local_planner

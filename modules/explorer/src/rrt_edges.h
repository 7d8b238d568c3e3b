// Internal to the explorer library: how RRT* (rrt_star.cc) checks and prices its tree's edges in a
// 3-D RealVectorStateSpace; tested on its own against OMPL's DiscreteMotionValidator and
// PathLengthOptimizationObjective.
#pragma once

#include <utility>

#include <ompl/base/MotionValidator.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <Eigen/Core>

#include "motion_neighbors.h"

namespace thicket::explorer::detail {

inline Eigen::Vector3d statePosition(const ompl::base::State* state) {
  const double* v = state->as<ompl::base::RealVectorStateSpace::StateType>()->values;
  return {v[0], v[1], v[2]};
}

/// OMPL's DiscreteMotionValidator's answer: an edge is free when its end is and so is every state
/// j / n of the way from its start (0 < j < n, n the space's validSegmentCount, each state
/// interpolated as RealVectorStateSpace::interpolate does). OMPL's checks them in bisection
/// order from a std::queue it allocates per edge, each through the SpaceInformation's
/// std::function; this checks the same states from the start on, calling free(position)
/// directly, so that consecutive lookups fall in the same map block. The first occupied state
/// ends either walk, so both answer the same.
template <class Free>
class EdgeValidator final : public ompl::base::MotionValidator {
 public:
  EdgeValidator(const ompl::base::SpaceInformationPtr& si, Free free)
      : ompl::base::MotionValidator(si), free_(std::move(free)) {}

  bool checkMotion(const ompl::base::State* s1, const ompl::base::State* s2) const override {
    // The end first, as OMPL's: most edges RRT* tries that are blocked end in an obstacle.
    bool ok = free_(statePosition(s2));
    if (ok) {
      const int n = segments(s1, s2);
      ok = firstOccupied(s1, s2, n) == n;
    }
    ++(ok ? valid_ : invalid_);
    return ok;
  }

  // OMPL's RRT* does not ask for the last valid state; answered as OMPL's validator does.
  bool checkMotion(const ompl::base::State* s1, const ompl::base::State* s2,
                   std::pair<ompl::base::State*, double>& last_valid) const override {
    const int n = segments(s1, s2);
    const int j = firstOccupied(s1, s2, n);
    if (j == n && free_(statePosition(s2))) {
      ++valid_;
      return true;
    }
    last_valid.second = static_cast<double>(j - 1) / static_cast<double>(n);
    if (last_valid.first != nullptr) {
      si_->getStateSpace()->interpolate(s1, s2, last_valid.second, last_valid.first);
    }
    ++invalid_;
    return false;
  }

 private:
  int segments(const ompl::base::State* s1, const ompl::base::State* s2) const {
    return static_cast<int>(si_->getStateSpace()->validSegmentCount(s1, s2));
  }

  // The first j in [1, n) whose state j / n of the way is occupied, or n: each state interpolated
  // with RealVectorStateSpace::interpolate's arithmetic.
  int firstOccupied(const ompl::base::State* s1, const ompl::base::State* s2, int n) const {
    const Eigen::Vector3d a = statePosition(s1), b = statePosition(s2);
    for (int j = 1; j < n; ++j) {
      const double t = static_cast<double>(j) / static_cast<double>(n);
      Eigen::Vector3d p;
      for (int i = 0; i < 3; ++i) p[i] = a[i] + (b[i] - a[i]) * t;
      if (!free_(p)) return j;
    }
    return n;
  }

  Free free_;
};

/// PathLengthOptimizationObjective with the edge's length computed here (spaceDistance: the same
/// bits as RealVectorStateSpace::distance), rather than through the SpaceInformation and the
/// space's virtual distance: RRT* prices an edge to each of its hundreds of neighbours per
/// iteration.
class EdgeLengthObjective final : public ompl::base::PathLengthOptimizationObjective {
 public:
  using ompl::base::PathLengthOptimizationObjective::PathLengthOptimizationObjective;

  ompl::base::Cost motionCost(const ompl::base::State* s1,
                              const ompl::base::State* s2) const override {
    return ompl::base::Cost(spaceDistance(statePosition(s1), statePosition(s2)));
  }
};

}  // namespace thicket::explorer::detail

// Internal to the explorer library: the strategies that live in their own files, and the draws and
// free-space tests the strategies share.
#pragma once

#include <memory>
#include <optional>
#include <random>

#include <Eigen/Core>

#include "thicket/explorer/goal_selector.h"

namespace thicket::explorer::detail {

using Rng = std::mt19937_64;

/// The exploration gain of a map's voxel size: built on first use, rebuilt when the size changes.
class GainCache {
 public:
  explicit GainCache(const GainOptions& options) : options_(options) {}
  const ExplorationGain& forVoxelSize(double voxel_size) {
    if (!gain_ || gain_->voxelSize() != voxel_size) gain_.emplace(options_, voxel_size);
    return *gain_;
  }

 private:
  GainOptions options_;
  std::optional<ExplorationGain> gain_;
};

/// rrt_star_optimistic (optimistic) or rrt_star_conservative; rrt_star.cc.
std::unique_ptr<GoalSelector> makeRrtStar(const ExplorerOptions& options, bool optimistic);
/// nbvp; nbvp.cc.
std::unique_ptr<GoalSelector> makeNbvp(const ExplorerOptions& options);

/// local_exploration, the paper's strategy; local_exploration.cc.
std::unique_ptr<GoalSelector> makeLocalExploration(const ExplorerOptions& options);
/// frontier_memory; frontier_memory.cc.
std::unique_ptr<GoalSelector> makeFrontierMemory(const ExplorerOptions& options);

/// `strategy` behind a look-around (look_around.cc): the first stuck request at each place is
/// answered with a turn in place.
std::unique_ptr<GoalSelector> lookAround(const ExplorerOptions& options,
                                         std::unique_ptr<GoalSelector> strategy);

/// Inside the flight volume (bounds included).
bool inFlightVolume(const ExplorerOptions& options, const Eigen::Vector3d& p);

/// A uniform point in the ball of `radius` around `center`, inside the flight volume; nothing
/// after `max_draws` draws outside it.
std::optional<Eigen::Vector3d> drawInBall(Rng& rng, const Eigen::Vector3d& center, double radius,
                                          const ExplorerOptions& options, int max_draws);

/// Known in the ESDF (unknown space is occupied) with at least `clearance`, in the flight volume.
bool esdfFree(const ExplorerOptions& options, const EsdfLayer& esdf, const Eigen::Vector3d& p,
              double clearance);

/// esdfFree at both ends and at most every `step` between them.
bool esdfSegmentFree(const ExplorerOptions& options, const EsdfLayer& esdf,
                     const Eigen::Vector3d& a, const Eigen::Vector3d& b, double clearance,
                     double step);

/// The clearance a tree grown from `start` in the ESDF keeps: min_clearance, or the start's own
/// clearance when it has less (a vehicle stuck near an obstacle must still leave), but never less
/// than half of min_clearance. Nothing when the start is unknown or closer than that.
std::optional<double> treeClearance(const ExplorerOptions& options, const EsdfLayer& esdf,
                                    const Eigen::Vector3d& start);

/// Observed in the TSDF (weight >= gain.min_weight), outside surfaces, and esdfFree with
/// min_clearance: a point the planner can fly to and stop at.
bool observedFree(const ExplorerOptions& options, const MapView& maps, const Eigen::Vector3d& p);

}  // namespace thicket::explorer::detail

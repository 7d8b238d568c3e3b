// Hand-built maps for the explorer's tests: space observed inside a box, with obstacles given by
// their signed distance, and unknown everywhere else.
#pragma once

#include <algorithm>
#include <functional>

#include <Eigen/Core>

#include "thicket/common/voxel_layer.h"
#include "thicket/explorer/goal_selector.h"

namespace thicket::explorer {

constexpr double kVoxel = 0.2;

struct HandMap {
  TsdfLayer tsdf{kVoxel};
  EsdfLayer esdf{kVoxel};
  MapView view() const { return {&tsdf, &esdf}; }
};

/// Signed distance to the obstacles [m], negative inside them.
using ObstacleDistance = std::function<double(const Eigen::Vector3d&)>;

/// Every voxel of [lo, hi] observed: the TSDF holds the obstacle distance (truncated at 0.8 m), the
/// ESDF the distance to the nearest obstacle or to the box's boundary, whichever is nearer
/// (beyond the boundary the planner sees no free space). No obstacles when `obstacles` is empty.
inline HandMap observedBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                           const ObstacleDistance& obstacles = {}) {
  HandMap map;
  const VoxelIndex a = map.tsdf.voxelIndex(lo), b = map.tsdf.voxelIndex(hi);
  for (int x = a.x(); x <= b.x(); ++x) {
    for (int y = a.y(); y <= b.y(); ++y) {
      for (int z = a.z(); z <= b.z(); ++z) {
        const Eigen::Vector3d c = map.tsdf.voxelCenter({x, y, z});
        const double obstacle = obstacles ? obstacles(c) : 1e9;
        map.tsdf.allocateVoxel({x, y, z}) =
            TsdfVoxel{static_cast<float>(std::clamp(obstacle, -0.8, 0.8)), 1.0f};
        const double boundary = std::min((c - lo).minCoeff(), (hi - c).minCoeff());
        EsdfVoxel& e = map.esdf.allocateVoxel({x, y, z});
        e.distance = static_cast<float>(std::min(obstacle, boundary));
        e.observed = true;
      }
    }
  }
  return map;
}

/// The options of `strategy` with a fixed seed.
inline ExplorerOptions optionsFor(const std::string& strategy) {
  ExplorerOptions o;
  o.strategy = strategy;
  o.seed = 3;
  return o;
}

/// Stuck at (0, 0, 1.5) on a goal 20 m ahead along x.
inline ExplorationRequest request(int64_t cycle) {
  ExplorationRequest r;
  r.cycle = cycle;
  r.start = Eigen::Vector3d(0, 0, 1.5);
  r.goal = Eigen::Vector3d(20, 0, 1.5);
  return r;
}

}  // namespace thicket::explorer

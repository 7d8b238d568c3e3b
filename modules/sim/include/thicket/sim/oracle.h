// The solvability oracle: whether a trial could have succeeded at all at a given robot radius, and
// how narrow a world's passages are (docs/benchmark.md).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/sim/ground_truth.h"
#include "thicket/sim/world.h"

namespace thicket::sim {

/// How checkSolvable searches.
struct OracleOptions {
  /// Edge of the xy grid cells searched [m]. Finer finds narrower passages and costs
  /// quadratically more (forest50 at 0.05 m: 1000 × 1000 cells).
  double resolution = 0.05;
  /// The radius of the sphere tested [m]; 0 tests the world's robot_radius (the collision
  /// radius). The benchmark also tests the radius the planner demands: robot radius plus its
  /// acceptance margin.
  double radius = 0.0;
};

struct OracleResult {
  bool solvable = false;
  /// Length of `path` [m]; 0 when unsolvable.
  double path_length = 0.0;
  /// A collision-free path from start to goal, for debugging: up from the start to one flight
  /// altitude, along the shortest 8-connected path of grid cell centres, down to the goal.
  std::vector<Eigen::Vector3d> path;
  /// Why the world is unsolvable; empty when solvable.
  std::string reason;
  /// bottleneckClearance() of the world, whatever the radius tested [m].
  double bottleneck_m = 0.0;
  /// Solvable, but not in 2D: every way from start to goal flies over a cylinder (bottleneck_m
  /// is less than the radius tested).
  bool needs_overflight = false;
};

/// The 2D bottleneck clearance c* [m]: the largest radius of a disc that can travel in the xy
/// plane from start to goal when every cylinder blocks whatever its height, inside the walls; 0
/// when start or goal is inside an obstacle. It is the smaller of the start's and the goal's
/// clearance and half the narrowest gap that closes a ring of obstacles (cylinders, walls)
/// around start but not goal or the other way round, e.g. a chain across the world from wall to
/// wall. Exact: the pairwise gaps are joined in ascending order (union-find) until one closes
/// such a ring. `world` must be one GroundTruth accepts.
double bottleneckClearance(const World& world);

/// Whether a sphere of options.radius can get from start to goal, keeping its centre in
/// z ∈ [r, bounds_max.z − r] and its surface inside the walls; with the bottleneck, whether that
/// needs flying over a cylinder.
///
/// Every obstacle rises from the ground, so the free altitudes above a point (x, y) form a single
/// interval [lo(x, y), bounds_max.z − r]: raising a free sphere never brings it closer to a
/// cylinder or the ground. Two free neighbouring columns therefore connect through their tops,
/// and the 3D question is 2D connectivity of the columns whose interval is not empty. The search
/// runs on a grid of cells, blocking a cell when any point of it might be too close (its centre's
/// clearance minus half the cell diagonal), so the answer is conservative: "solvable" is always
/// truly solvable, but passages less than about 2·r + 3·resolution wide may be missed. Start or
/// goal in collision or outside the altitude band is unsolvable with a reason. Throws
/// std::invalid_argument for a non-positive resolution or one giving more than 10^8 cells, or a
/// negative or non-finite radius.
OracleResult checkSolvable(const GroundTruth& ground_truth, const OracleOptions& options = {});

}  // namespace thicket::sim

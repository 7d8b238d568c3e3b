// Exact distances to a World's obstacles, for collision checks and clearance metrics, and the
// solvability oracle that says whether a trial could have succeeded at all (BENCHMARK.md).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/sim/world.h"

namespace thicket::sim {

/// The analytic signed distance field of a World. The obstacles are the ground (z <= 0), four
/// walls outside the x/y bounds up to the height limit bounds_max.z, and the solid cylinders with
/// flat tops. Nothing is above: the height limit constrains flight, it is not an obstacle.
/// Thread-safe for concurrent queries.
class GroundTruth {
 public:
  /// Throws std::invalid_argument for non-finite or empty bounds, a negative robot radius, or
  /// cylinders with non-finite values or a negative radius.
  explicit GroundTruth(const World& world);

  /// Euclidean distance from a finite point p to the nearest obstacle surface, exact outside the
  /// obstacles (including the rounded region around a cylinder's top rim). Inside one it is
  /// negative: minus the depth into the obstacle p is deepest in (a cylinder's or wall's bottom
  /// rests on the ground and is no way out), which for overlapping obstacles can be less than the
  /// depth into their union. `gradient`, when given, receives the unit direction in which the
  /// distance grows fastest (at ties between obstacles, that of any of them).
  double distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient = nullptr) const;

  /// The smallest distance() over `points`, +infinity for none; `argmin`, when given and points
  /// is not empty, receives the index of the first point attaining it.
  double pathClearance(const std::vector<Eigen::Vector3d>& points, size_t* argmin = nullptr) const;

  const World& world() const { return world_; }

 private:
  World world_;
  // Cylinders bucketed by the cell of a uniform xy grid their axis is in, cell by cell (CSR):
  // those of cell (i, j) are cells_[cell_begin_[j * nx_ + i] .. cell_begin_[j * nx_ + i + 1]).
  Eigen::Vector2d grid_origin_ = Eigen::Vector2d::Zero();
  double cell_size_ = 1.0;
  int nx_ = 0;
  int ny_ = 0;
  std::vector<size_t> cell_begin_;
  std::vector<Cylinder> cells_;
  double max_radius_ = 0.0;
};

/// Signed distance from p to the surface of one cylinder alone, as GroundTruth::distance measures
/// it (the cylinder extends below the ground, which hides it there): for per-obstacle clearances.
double cylinderDistance(const Cylinder& cylinder, const Eigen::Vector3d& p);

/// How checkSolvable searches.
struct OracleOptions {
  /// Edge of the xy grid cells searched [m]. Finer finds narrower passages and costs
  /// quadratically more (forest50 at 0.05 m: 1000 × 1000 cells).
  double resolution = 0.05;
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
};

/// Whether a sphere of the world's robot_radius can get from start to goal, keeping its centre in
/// z ∈ [r, bounds_max.z − r] and its surface inside the walls.
///
/// Every obstacle rises from the ground, so the free altitudes above a point (x, y) form a single
/// interval [lo(x, y), bounds_max.z − r]: raising a free sphere never brings it closer to a
/// cylinder or the ground. Two free neighbouring columns therefore connect through their tops,
/// and the 3D question is 2D connectivity of the columns whose interval is not empty. The search
/// runs on a grid of cells, blocking a cell when any point of it might be too close (its centre's
/// clearance minus half the cell diagonal), so the answer is conservative: "solvable" is always
/// truly solvable, but passages less than about 2·r + 3·resolution wide may be missed. Start or
/// goal in collision or outside the altitude band is unsolvable with a reason. Throws
/// std::invalid_argument for a non-positive resolution or one giving more than 10^8 cells.
OracleResult checkSolvable(const GroundTruth& ground_truth, const OracleOptions& options = {});

}  // namespace thicket::sim

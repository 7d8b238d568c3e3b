// Exact distances to a World's obstacles, for collision checks, clearance metrics and the
// solvability oracle (oracle.h).
#pragma once

#include <cstddef>
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

}  // namespace thicket::sim

#include "thicket/sim/ground_truth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "grid_cell.h"

namespace thicket::sim {
namespace {

// Edge of the cylinder buckets [m], a few tree diameters. Query time barely changes between 0.5 and
// 2 m on the benchmark forests.
constexpr double kCellSize = 1.0;
// Cylinders spread over kilometres get coarser cells rather than a huge grid.
constexpr double kMaxCellsPerSide = 1024;

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Signed distance to the solid {a <= 0 and b <= 0}, where a and b are the signed distances to two
// perpendicular planes (positive outside). Every obstacle is such a solid once it is extended
// below the ground, which the ground hides anyway: a cylinder is {side <= 0, top <= 0}, a wall
// {inner face <= 0, top <= 0}.
double corner(double a, double b) {
  return (a > 0 && b > 0) ? std::sqrt(a * a + b * b) : std::max(a, b);
}

// The gradient of corner(a, b), given the unit gradients of a and b.
Eigen::Vector3d cornerGradient(double a, double b, const Eigen::Vector3d& grad_a,
                               const Eigen::Vector3d& grad_b) {
  if (a > 0 && b > 0) return (a * grad_a + b * grad_b) / std::sqrt(a * a + b * b);
  return a >= b ? grad_a : grad_b;
}

}  // namespace

GroundTruth::GroundTruth(const World& world) : world_(world) {
  if (!world_.bounds_min.allFinite() || !world_.bounds_max.allFinite() ||
      (world_.bounds_min.array() >= world_.bounds_max.array()).any()) {
    throw std::invalid_argument("GroundTruth: world bounds must be finite with min < max");
  }
  if (!(world_.robot_radius >= 0 && std::isfinite(world_.robot_radius))) {
    throw std::invalid_argument("GroundTruth: robot_radius must be finite and >= 0");
  }
  if (world_.cylinders.empty()) return;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInfinity);
  Eigen::Vector2d hi = -lo;
  for (const Cylinder& c : world_.cylinders) {
    if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.height) ||
        !(c.radius >= 0 && std::isfinite(c.radius))) {
      throw std::invalid_argument("GroundTruth: cylinders must be finite with radius >= 0");
    }
    lo = lo.cwiseMin(Eigen::Vector2d(c.x, c.y));
    hi = hi.cwiseMax(Eigen::Vector2d(c.x, c.y));
    max_radius_ = std::max(max_radius_, c.radius);
  }
  grid_origin_ = lo;
  cell_size_ = std::max(kCellSize, (hi - lo).maxCoeff() / kMaxCellsPerSide);
  nx_ = static_cast<int>((hi.x() - lo.x()) / cell_size_) + 1;
  ny_ = static_cast<int>((hi.y() - lo.y()) / cell_size_) + 1;

  // Counting sort of the cylinders by cell.
  const auto cellOf = [this](const Cylinder& c) {
    return static_cast<size_t>(cellIndex(c.y, grid_origin_.y(), cell_size_, ny_)) * nx_ +
           cellIndex(c.x, grid_origin_.x(), cell_size_, nx_);
  };
  cell_begin_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (const Cylinder& c : world_.cylinders) ++cell_begin_[cellOf(c) + 1];
  for (size_t i = 1; i < cell_begin_.size(); ++i) cell_begin_[i] += cell_begin_[i - 1];
  cells_.resize(world_.cylinders.size());
  std::vector<size_t> next(cell_begin_.begin(), cell_begin_.end() - 1);
  for (const Cylinder& c : world_.cylinders) cells_[next[cellOf(c)]++] = c;
}

double GroundTruth::distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient) const {
  const Eigen::Vector3d& lo = world_.bounds_min;
  const Eigen::Vector3d& hi = world_.bounds_max;

  // The ground and the walls first: they bound the answer, which ends the cylinder search early.
  // Wall distance grows with the distance to the nearest wall plane, so only that wall matters.
  const std::array<double, 4> wall_offsets = {p.x() - lo.x(), hi.x() - p.x(), p.y() - lo.y(),
                                              hi.y() - p.y()};
  const int wall = static_cast<int>(std::min_element(wall_offsets.begin(), wall_offsets.end()) -
                                    wall_offsets.begin());
  const double wall_distance = corner(wall_offsets[wall], p.z() - hi.z());
  const double ground_distance = p.z() - lo.z();
  const bool wall_nearer = wall_distance < ground_distance;
  double best = wall_nearer ? wall_distance : ground_distance;
  const Cylinder* best_cylinder = nullptr;

  const auto visit = [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) {
      const Cylinder& c = cells_[k];
      const double dx = p.x() - c.x;
      const double dy = p.y() - c.y;
      const double rho2 = dx * dx + dy * dy;
      // The side alone keeps this cylinder at least sqrt(rho2) - radius (>= -radius) away.
      const double reach = best + c.radius;
      if (reach <= 0 || rho2 >= reach * reach) continue;
      const double d = corner(std::sqrt(rho2) - c.radius, p.z() - c.height);
      if (d < best) {
        best = d;
        best_cylinder = &c;
      }
    }
  };
  // Rows of cells are contiguous in cells_, so a run of cells in a row is one range.
  const auto visitRow = [&](int j, int i0, int i1) {
    const size_t row = static_cast<size_t>(j) * nx_;
    visit(cell_begin_[row + i0], cell_begin_[row + i1 + 1]);
  };

  if (!cells_.empty()) {
    // Search square rings of cells around p's cell outward. Every cylinder in ring k >= 1 has its
    // axis at least (k - 1) cells plus p's margin to its own cell's border away in xy, so once
    // that minus the largest radius reaches the best distance, no further ring can improve it.
    const int ci = cellIndex(p.x(), grid_origin_.x(), cell_size_, nx_);
    const int cj = cellIndex(p.y(), grid_origin_.y(), cell_size_, ny_);
    const double ox = p.x() - (grid_origin_.x() + ci * cell_size_);
    const double oy = p.y() - (grid_origin_.y() + cj * cell_size_);
    const double margin = std::max(0.0, std::min({ox, cell_size_ - ox, oy, cell_size_ - oy}));
    const int k_max = std::max({ci, nx_ - 1 - ci, cj, ny_ - 1 - cj});
    visitRow(cj, ci, ci);
    for (int k = 1; k <= k_max; ++k) {
      if ((k - 1) * cell_size_ + margin - max_radius_ >= best) break;
      const int i0 = std::max(ci - k, 0);
      const int i1 = std::min(ci + k, nx_ - 1);
      if (cj - k >= 0) visitRow(cj - k, i0, i1);
      if (cj + k < ny_) visitRow(cj + k, i0, i1);
      for (int j = std::max(cj - k + 1, 0); j <= std::min(cj + k - 1, ny_ - 1); ++j) {
        if (ci - k >= 0) visitRow(j, ci - k, ci - k);
        if (ci + k < nx_) visitRow(j, ci + k, ci + k);
      }
    }
  }

  if (gradient) {
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    if (best_cylinder) {
      const Eigen::Vector3d radial(p.x() - best_cylinder->x, p.y() - best_cylinder->y, 0.0);
      const double rho = radial.norm();
      // On the axis every horizontal direction is steepest; pick +x.
      const Eigen::Vector3d outward =
          rho > 0 ? Eigen::Vector3d(radial / rho) : Eigen::Vector3d::UnitX();
      *gradient =
          cornerGradient(rho - best_cylinder->radius, p.z() - best_cylinder->height, outward, up);
    } else if (wall_nearer) {
      static const std::array<Eigen::Vector3d, 4> kInward = {
          Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
          -Eigen::Vector3d::UnitY()};
      *gradient = cornerGradient(wall_offsets[wall], p.z() - hi.z(), kInward[wall], up);
    } else {
      *gradient = up;
    }
  }
  return best;
}

double cylinderDistance(const Cylinder& cylinder, const Eigen::Vector3d& p) {
  // As GroundTruth::distance computes it, to the bit.
  const double dx = p.x() - cylinder.x;
  const double dy = p.y() - cylinder.y;
  return corner(std::sqrt(dx * dx + dy * dy) - cylinder.radius, p.z() - cylinder.height);
}

double GroundTruth::pathClearance(const std::vector<Eigen::Vector3d>& points,
                                  size_t* argmin) const {
  double best = kInfinity;
  for (size_t i = 0; i < points.size(); ++i) {
    const double d = distance(points[i]);
    if (d < best) {
      best = d;
      if (argmin) *argmin = i;
    }
  }
  return best;
}

}  // namespace thicket::sim

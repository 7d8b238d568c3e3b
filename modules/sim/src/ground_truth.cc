#include "thicket/sim/ground_truth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace thicket::sim {
namespace {

// Edge of the cylinder buckets [m], a few tree diameters. Query time barely changes between 0.5 and
// 2 m on the benchmark forests.
constexpr double kCellSize = 1.0;
// Cylinders spread over kilometres get coarser cells rather than a huge grid.
constexpr double kMaxCellsPerSide = 1024;
// checkSolvable refuses grids larger than this (1e8 cells take about 0.6 GB of search state).
constexpr double kMaxOracleCells = 1e8;

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

// Index of the grid cell holding coordinate x, clamped to [0, cells - 1] (NaN gives 0).
int cellIndex(double x, double origin, double cell_size, int cells) {
  const double f = (x - origin) / cell_size;
  return f > 0 ? (f < cells ? static_cast<int>(f) : cells - 1) : 0;
}

OracleResult unsolvable(std::string reason) {
  OracleResult result;
  result.reason = std::move(reason);
  return result;
}

std::string format(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
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

OracleResult checkSolvable(const GroundTruth& ground_truth, const OracleOptions& options) {
  const World& world = ground_truth.world();
  const double res = options.resolution;
  if (!(res > 0) || !std::isfinite(res)) {
    throw std::invalid_argument("checkSolvable: resolution must be positive and finite");
  }
  const double r = world.robot_radius;
  const double bottom = world.bounds_min.z() + r;  // lowest and highest centre altitudes
  const double top = world.bounds_max.z() - r;
  if (top < bottom) return unsolvable("the world is lower than the robot's diameter");
  for (const auto& [name, p] : {std::pair{"start", world.start}, std::pair{"goal", world.goal}}) {
    if (!(p.z() >= bottom && p.z() <= top)) {
      return unsolvable(std::string(name) + " altitude " + format(p.z()) + " m is outside [" +
                        format(bottom) + ", " + format(top) + "] m");
    }
    const double clearance = ground_truth.distance(p);
    if (!(clearance >= r)) {
      return unsolvable(std::string(name) + " is in collision: clearance " + format(clearance) +
                        " m < robot radius " + format(r) + " m");
    }
  }

  const Eigen::Vector2d origin = world.bounds_min.head<2>();
  const Eigen::Vector2d extent = (world.bounds_max - world.bounds_min).head<2>();
  const double cells_x = std::ceil(extent.x() / res);
  const double cells_y = std::ceil(extent.y() / res);
  if (cells_x * cells_y > kMaxOracleCells) {
    throw std::invalid_argument("checkSolvable: resolution " + format(res) + " m gives " +
                                format(cells_x * cells_y) + " cells, more than " +
                                format(kMaxOracleCells));
  }
  const int nx = static_cast<int>(cells_x);
  const int ny = static_cast<int>(cells_y);
  const size_t cells = static_cast<size_t>(nx) * ny;
  const auto centre = [&](ptrdiff_t cell) {
    return Eigen::Vector2d(origin.x() + (static_cast<double>(cell % nx) + 0.5) * res,
                           origin.y() + (static_cast<double>(cell / nx) + 0.5) * res);
  };
  // A cell is free when every point of it is at least r from the obstacles: its centre's clearance
  // minus the half diagonal, the farthest any point of the cell is from its centre.
  const double half_diagonal = res * std::sqrt(0.5);
  const double reach = r + half_diagonal;
  std::vector<uint8_t> blocked(cells, 0);
  for (int i = 0; i < nx; ++i) {
    const double x = origin.x() + (i + 0.5) * res;
    if (std::min(x - origin.x(), origin.x() + extent.x() - x) < reach) {
      for (int j = 0; j < ny; ++j) blocked[static_cast<size_t>(j) * nx + i] = 1;
    }
  }
  for (int j = 0; j < ny; ++j) {
    const double y = origin.y() + (j + 0.5) * res;
    if (std::min(y - origin.y(), origin.y() + extent.y() - y) < reach) {
      std::fill_n(blocked.begin() + static_cast<ptrdiff_t>(j) * nx, nx, 1);
    }
  }
  // Over cylinders with height + r <= top the sphere flies; the others block within r.
  for (const Cylinder& c : world.cylinders) {
    if (c.height + r <= top) continue;
    const double block = c.radius + reach;
    const auto range = [&](double axis, double o, int n) {
      const double from = std::ceil((axis - block - o) / res - 0.5);
      const double to = std::floor((axis + block - o) / res - 0.5);
      return std::pair{static_cast<int>(std::clamp(from, 0.0, 1.0 * n)),
                       static_cast<int>(std::clamp(to, -1.0, n - 1.0))};
    };
    const auto [i0, i1] = range(c.x, origin.x(), nx);
    const auto [j0, j1] = range(c.y, origin.y(), ny);
    for (int j = j0; j <= j1; ++j) {
      const double dy = origin.y() + (j + 0.5) * res - c.y;
      for (int i = i0; i <= i1; ++i) {
        const double dx = origin.x() + (i + 0.5) * res - c.x;
        if (dx * dx + dy * dy < block * block) blocked[static_cast<size_t>(j) * nx + i] = 1;
      }
    }
  }

  const auto cellOf = [&](const Eigen::Vector3d& p) {
    return static_cast<ptrdiff_t>(cellIndex(p.y(), origin.y(), res, ny)) * nx +
           cellIndex(p.x(), origin.x(), res, nx);
  };
  const ptrdiff_t start = cellOf(world.start);
  const ptrdiff_t goal = cellOf(world.goal);
  for (const auto& [name, cell] : {std::pair{"start", start}, std::pair{"goal", goal}}) {
    if (blocked[cell]) {
      return unsolvable(std::string(name) +
                        "'s grid cell is blocked: it is within r + half a cell " +
                        "diagonal of an obstacle at resolution " + format(res) + " m");
    }
  }

  // A* over 8-connected cells with integer edge costs (12 straight, 17 diagonal: sqrt(2) to
  // 0.2 %) and the octile heuristic. Integer f values let a ring of buckets replace a heap: f never
  // decreases, and an expansion raises it by at most two diagonal steps. Within a bucket the newest
  // entry goes first, following the deepest branch, which keeps the search narrow in open space.
  constexpr int kStraight = 12;
  constexpr int kDiagonal = 17;
  constexpr uint8_t kNoParent = 8;
  // The outermost cells are always blocked (their centres are half a cell from a wall), so every
  // neighbour of a free cell is on the grid.
  constexpr std::array<int, 8> kDi = {1, -1, 0, 0, 1, -1, 1, -1};
  constexpr std::array<int, 8> kDj = {0, 0, 1, -1, 1, 1, -1, -1};
  std::array<ptrdiff_t, 8> step;
  for (int d = 0; d < 8; ++d) step[d] = kDj[d] * static_cast<ptrdiff_t>(nx) + kDi[d];
  const int gi = static_cast<int>(goal % nx);
  const int gj = static_cast<int>(goal / nx);
  const auto heuristic = [&](int i, int j) {
    const int di = std::abs(i - gi);
    const int dj = std::abs(j - gj);
    return kStraight * std::abs(di - dj) + kDiagonal * std::min(di, dj);
  };
  std::vector<int> cost(cells, std::numeric_limits<int>::max());
  std::vector<uint8_t> parent(cells, kNoParent);
  std::array<std::vector<ptrdiff_t>, 2 * kDiagonal + 1> open;  // by f modulo their count
  size_t queued = 1;
  int f = heuristic(static_cast<int>(start % nx), static_cast<int>(start / nx));
  cost[start] = 0;
  open[f % open.size()].push_back(start);
  while (queued > 0) {
    std::vector<ptrdiff_t>& bucket = open[f % open.size()];
    if (bucket.empty()) {
      ++f;
      continue;
    }
    const ptrdiff_t cell = bucket.back();
    bucket.pop_back();
    --queued;
    const int i = static_cast<int>(cell % nx);
    const int j = static_cast<int>(cell / nx);
    if (cost[cell] + heuristic(i, j) != f) continue;  // superseded by a cheaper entry
    if (cell == goal) break;
    for (int d = 0; d < 8; ++d) {
      const ptrdiff_t next = cell + step[d];
      const int g = cost[cell] + (d < 4 ? kStraight : kDiagonal);
      if (blocked[next] || g >= cost[next]) continue;
      cost[next] = g;
      parent[next] = static_cast<uint8_t>(d);
      open[(g + heuristic(i + kDi[d], j + kDj[d])) % open.size()].push_back(next);
      ++queued;
    }
  }
  if (cost[goal] == std::numeric_limits<int>::max()) {
    return unsolvable("the goal cannot be reached from the start at resolution " + format(res) +
                      " m (passages narrower than about 2 r + 3 cells may be missed)");
  }

  std::vector<ptrdiff_t> route = {goal};  // cells from the goal back to the start
  while (route.back() != start) route.push_back(route.back() - step[parent[route.back()]]);
  std::reverse(route.begin(), route.end());

  // Fly at one altitude, the lowest that clears everything near the route (a cylinder within
  // reach of a route cell raises it to the cylinder's height + r), but not below the start and
  // goal. Route cells are free, so no cylinder near them is too tall for that.
  double altitude = std::max(bottom, std::min(world.start.z(), world.goal.z()));
  for (const ptrdiff_t cell : route) {
    const Eigen::Vector2d c = centre(cell);
    for (const Cylinder& cylinder : world.cylinders) {
      const double limit = cylinder.radius + reach;
      if ((c - Eigen::Vector2d(cylinder.x, cylinder.y)).squaredNorm() < limit * limit) {
        altitude = std::max(altitude, cylinder.height + r);
      }
    }
  }

  OracleResult result;
  result.solvable = true;
  const auto add = [&result](const Eigen::Vector3d& p) {
    if (!result.path.empty()) {
      const double length = (p - result.path.back()).norm();
      if (length == 0) return;
      result.path_length += length;
    }
    result.path.push_back(p);
  };
  add(world.start);
  add(Eigen::Vector3d(world.start.x(), world.start.y(), altitude));
  for (size_t k = 0; k < route.size(); ++k) {
    // Straight runs of cells need only their ends.
    const bool turn = k == 0 || k + 1 == route.size() || parent[route[k]] != parent[route[k + 1]];
    if (turn) add(Eigen::Vector3d(centre(route[k]).x(), centre(route[k]).y(), altitude));
  }
  add(Eigen::Vector3d(world.goal.x(), world.goal.y(), altitude));
  add(world.goal);
  return result;
}

}  // namespace thicket::sim

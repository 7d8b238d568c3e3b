#include "thicket/sim/oracle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "grid_cell.h"

namespace thicket::sim {
namespace {

// checkSolvable refuses grids larger than this (1e8 cells take about 0.6 GB of search state).
constexpr double kMaxOracleCells = 1e8;

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

// The grid search of checkSolvable for a sphere of radius r (oracle.h).
OracleResult searchPath(const GroundTruth& ground_truth, double res, double r) {
  const World& world = ground_truth.world();
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
                        " m < radius " + format(r) + " m");
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

// ---- the bottleneck ----

// Two obstacles (cylinders or walls) whose dilations by more than gap / 2 overlap, and the winding
// weight (turns()) of a polyline from one to the other inside the union of both.
struct Link {
  double gap;
  int a, b;
  double turns;
};

// (The signed angle segment a→b subtends at s minus the one it subtends at t) / 2π. Summed over
// a closed polyline that passes through neither, it is the polyline's winding number around s
// minus that around t: not 0 exactly when the polyline separates s from t.
double turns(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& s,
             const Eigen::Vector2d& t) {
  const auto angle = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector2d u = a - p;
    const Eigen::Vector2d v = b - p;
    return std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));
  };
  return (angle(s) - angle(t)) / (2 * std::numbers::pi);
}

// Union-find over obstacles whose nodes know their potential relative to their root: the turns
// along the links that joined them. A link between two nodes already joined closes a ring; the
// ring separates s from t when the link's turns differ from the path's.
class WindingForest {
 public:
  explicit WindingForest(size_t nodes) : parent_(nodes), size_(nodes, 1), offset_(nodes, 0.0) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }

  // Joins a and b by a link of `turns` (b's potential minus a's); true when it closes a ring
  // that separates s from t.
  bool join(int a, int b, double turns) {
    const auto [root_a, offset_a] = find(a);
    const auto [root_b, offset_b] = find(b);
    if (root_a == root_b) return std::abs(offset_a + turns - offset_b) > 0.5;
    if (size_[root_a] < size_[root_b]) {
      parent_[root_a] = root_b;
      offset_[root_a] = offset_b - turns - offset_a;
      size_[root_b] += size_[root_a];
    } else {
      parent_[root_b] = root_a;
      offset_[root_b] = offset_a + turns - offset_b;
      size_[root_a] += size_[root_b];
    }
    return false;
  }

 private:
  // x's root and x's potential minus the root's; compresses the path.
  std::pair<int, double> find(int x) {
    if (parent_[x] == x) return {x, 0.0};
    const auto [root, parent_offset] = find(parent_[x]);
    offset_[x] += parent_offset;
    parent_[x] = root;
    return {root, offset_[x]};
  }

  std::vector<int> parent_;
  std::vector<int> size_;
  std::vector<double> offset_;  // potential minus the parent's
};

}  // namespace

double bottleneckClearance(const World& world) {
  const Eigen::Vector2d lo = world.bounds_min.head<2>();
  const Eigen::Vector2d hi = world.bounds_max.head<2>();
  const Eigen::Vector2d s = world.start.head<2>();
  const Eigen::Vector2d t = world.goal.head<2>();
  const std::vector<Cylinder>& cylinders = world.cylinders;
  const auto centre = [&](int i) { return Eigen::Vector2d(cylinders[i].x, cylinders[i].y); };
  const int n = static_cast<int>(cylinders.size());
  const auto clearance = [&](const Eigen::Vector2d& p) {
    double d = std::min({p.x() - lo.x(), hi.x() - p.x(), p.y() - lo.y(), hi.y() - p.y()});
    for (int i = 0; i < n; ++i) d = std::min(d, (p - centre(i)).norm() - cylinders[i].radius);
    return d;
  };
  const double endpoints = std::min(clearance(s), clearance(t));
  if (!(endpoints > 0)) return 0.0;
  // Only gaps narrower than twice the endpoints' clearance can make c* smaller.
  const double widest = 2 * endpoints;

  // Obstacle graph nodes: the cylinders, then the walls n .. n + 3 (bottom, right, top, left),
  // wall w from corner w to corner w + 1 counter-clockwise. A link to a wall runs to its foot on
  // the wall, then along the wall to its middle. Everything outside the walls is obstacle, so
  // neighbouring walls always touch at their corner.
  const std::array<Eigen::Vector2d, 4> corners = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi,
                                                  Eigen::Vector2d(lo.x(), hi.y())};
  std::array<Eigen::Vector2d, 4> middles;
  for (int w = 0; w < 4; ++w) middles[w] = (corners[w] + corners[(w + 1) % 4]) / 2;
  std::vector<Link> links;
  for (int w = 0; w < 4; ++w) {
    const int next = (w + 1) % 4;
    links.push_back(
        {-std::numeric_limits<double>::infinity(), n + w, n + next,
         turns(middles[w], corners[next], s, t) + turns(corners[next], middles[next], s, t)});
  }
  double max_radius = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d c = centre(i);
    max_radius = std::max(max_radius, cylinders[i].radius);
    // The distances from the centre to the walls' lines, positive inside.
    const std::array<double, 4> inside = {c.y() - lo.y(), hi.x() - c.x(), hi.y() - c.y(),
                                          c.x() - lo.x()};
    for (int w = 0; w < 4; ++w) {
      const double gap = inside[w] - cylinders[i].radius;
      if (gap >= widest) continue;
      // Perpendicular to the wall when the centre is between its ends; otherwise the centre is
      // outside the walls and so is the whole way to the clamped foot.
      Eigen::Vector2d foot = c.cwiseMax(lo).cwiseMin(hi);
      foot[w % 2 == 0 ? 1 : 0] = corners[w][w % 2 == 0 ? 1 : 0];
      links.push_back({gap, i, n + w, turns(c, foot, s, t) + turns(foot, middles[w], s, t)});
    }
  }
  // Cylinder pairs, swept in x: centres further apart in x than `widest` plus both radii cannot
  // link.
  std::vector<int> by_x(static_cast<size_t>(n));
  std::iota(by_x.begin(), by_x.end(), 0);
  std::sort(by_x.begin(), by_x.end(),
            [&](int a, int b) { return cylinders[a].x < cylinders[b].x; });
  for (size_t k = 0; k < by_x.size(); ++k) {
    const int i = by_x[k];
    const double reach = widest + cylinders[i].radius + max_radius;
    for (size_t m = k + 1; m < by_x.size() && cylinders[by_x[m]].x - cylinders[i].x < reach; ++m) {
      const int j = by_x[m];
      const double gap = (centre(i) - centre(j)).norm() - cylinders[i].radius - cylinders[j].radius;
      if (gap < widest) links.push_back({gap, i, j, turns(centre(i), centre(j), s, t)});
    }
  }

  // Dilating every obstacle by ρ joins the links with gap < 2ρ; the disc of radius ρ gets through
  // until a ring of them separates start from goal.
  std::sort(links.begin(), links.end(), [](const Link& a, const Link& b) { return a.gap < b.gap; });
  WindingForest forest(static_cast<size_t>(n) + 4);
  for (const Link& link : links) {
    if (forest.join(link.a, link.b, link.turns)) return std::clamp(link.gap / 2, 0.0, endpoints);
  }
  return endpoints;
}

OracleResult checkSolvable(const GroundTruth& ground_truth, const OracleOptions& options) {
  if (!(options.resolution > 0) || !std::isfinite(options.resolution)) {
    throw std::invalid_argument("checkSolvable: resolution must be positive and finite");
  }
  if (!(options.radius >= 0) || !std::isfinite(options.radius)) {
    throw std::invalid_argument("checkSolvable: radius must be finite and >= 0");
  }
  const World& world = ground_truth.world();
  const double r = options.radius > 0 ? options.radius : world.robot_radius;
  OracleResult result = searchPath(ground_truth, options.resolution, r);
  result.bottleneck_m = bottleneckClearance(world);
  result.needs_overflight = result.solvable && result.bottleneck_m < r;
  return result;
}

}  // namespace thicket::sim

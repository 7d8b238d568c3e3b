// frontier_memory: frontier viewpoints reached along verified paths, with a memory of what failed
// and of the places the vehicle has been (beyond the paper; issue "a vehicle that never stalls").
//
// Each request:
// 1. Frontiers. Observed free TSDF voxels (weight >= gain.min_weight, distance > 0) with an
//    unobserved 6-neighbour, in a box of half-width `radius` around the start and inside the
//    altitude band, binned into cells of `cluster_size`: a cell holding at least `min_frontier`
//    of them is a frontier cluster, at their centroid.
// 2. Reachability. Dijkstra from the start over a grid of `grid` cells in the same box, a cell
//    being free when its ESDF voxel is observed with at least min_clearance (near the start: the
//    start's own clearance, so a vehicle inside the margin can leave), 26-connected, a step
//    costing its length (up to 1 + w_comfort times it into a cell with less than min_clearance +
//    comfort) plus w_climb per metre climbed. The altitude band is the flight volume up
//    to `climb` above the start (without `layers`: the start's grid layer only), so the search
//    climbs over a bottleneck only when going around costs more.
// 3. The answer, in order: the goal itself when it is in the box and reachable (a verified path
//    to it); else the reached cell nearest the goal when it is `progress` nearer than the start
//    (a verified path toward it); else, with layers, a climb to look toward the goal: of the
//    reached cells 0.8 m or more above the start within 3 m (the highest of each column, the 12
//    highest), the one whose view toward the goal holds the most unknown space, if at least
//    `climb_look` (over a wall of trees the space stays unknown until the camera is high enough,
//    and the clusters seen so far have their viewpoints below); else the best viewpoint: for each
//    cluster, cells on rings around it (1.5 and 2.5 m, 8 bearings, at the cluster's height) that
//    are reached and see the cluster (the segment to it crosses no surface), facing it; scored by
//    path cost + w_goal * (the cluster's distance to the goal - the start's) + w_altitude *
//    |height - the goal's| - w_size * (the cluster's share of min(size, 50) / 50); else the way
//    home: the most recent remembered place, at least 2 m away, that had reachable clusters, along
//    the places flown since. Never the global goal by itself. A path is the Dijkstra path
//    shortened by straight free segments, each segment checked at the planner's clearance and bent
//    around the margin of a tree it would cut; each waypoint faces along its segment, the
//    viewpoint faces its cluster, the climb faces the goal.
//
// Memory (off without `memory`: every request is answered as if it were the first): the places
// requests came from and whether they had clusters (the road home); the targets proposed and how
// often the vehicle asked again from about where it asked before (a target tried `tabu_attempts`
// times is not proposed again within tabu_radius; targets within 1 m are one); the committed
// target, kept while it is still among the candidates unless another scores hysteresis better. As
// with nbvp, the memory a request writes is read only by requests of later cycles, so the answers
// are deterministic given the sequence of requests and maps.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <queue>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "strategies.h"
#include "thicket/common/esdf_query.h"

namespace thicket::explorer::detail {
namespace {

struct Cluster {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int size = 0;
};

// Viewpoints closer than this are one target: a cluster's viewpoint drifts by millimetres to
// centimetres from one request to the next as the map around it grows [m].
constexpr double kSameTarget = 1.0;

struct Target {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  int attempts = 0;
};

struct Place {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool frontiers = false;  // reachable clusters were seen from here
};

// What a request remembers for later ones.
struct Memory {
  std::vector<Place> places;    // request starts, oldest first
  std::vector<Target> targets;  // proposed targets and their attempts
  std::optional<Eigen::Vector3d> committed;
  std::optional<Eigen::Vector3d> last_start;
};

// The search grid: a box of cells around the start.
class Grid {
 public:
  Grid(const Eigen::Vector3d& origin, double cell, const Eigen::Vector3i& size)
      : origin_(origin), cell_(cell), size_(size) {}
  int count() const { return size_.prod(); }
  bool inside(const Eigen::Vector3i& c) const {
    return (c.array() >= 0).all() && (c.array() < size_.array()).all();
  }
  int index(const Eigen::Vector3i& c) const {
    return c.x() + size_.x() * (c.y() + size_.y() * c.z());
  }
  Eigen::Vector3i cellOf(int i) const {
    return {i % size_.x(), (i / size_.x()) % size_.y(), i / (size_.x() * size_.y())};
  }
  Eigen::Vector3i cellAt(const Eigen::Vector3d& p) const {
    return ((p - origin_) / cell_).array().round().cast<int>();
  }
  Eigen::Vector3d center(const Eigen::Vector3i& c) const {
    return origin_ + cell_ * c.cast<double>();
  }
  Eigen::Vector3d center(int i) const { return center(cellOf(i)); }

 private:
  Eigen::Vector3d origin_;
  double cell_;
  Eigen::Vector3i size_;
};

class FrontierMemorySelector final : public GoalSelector {
 public:
  explicit FrontierMemorySelector(const ExplorerOptions& options)
      : options_(options), gains_(options.gain) {}
  const char* name() const override { return "frontier_memory"; }

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    // The memory of earlier cycles only (see the header).
    if (request.cycle != written_cycle_) {
      memory_ = written_;
    }
    Memory next = memory_;
    Proposal proposal;
    if (maps.tsdf == nullptr || maps.esdf == nullptr) {
      proposal.reason = "no map";
      proposal.map_missing = true;
      return proposal;
    }
    const FrontierMemoryOptions& o = options_.frontier_memory;
    if (o.memory) noteAttempt(next, request.start);

    const std::optional<double> start_clearance =
        treeClearance(options_, *maps.esdf, request.start);
    const Grid grid = makeGrid(request.start);
    const Reach reached = start_clearance
                              ? reach(grid, *maps.esdf, request.start, *start_clearance)
                              : Reach{std::vector<double>(static_cast<size_t>(grid.count()),
                                                          std::numeric_limits<double>::infinity()),
                                      {}};
    const std::vector<double>& cost = reached.cost;
    const auto costAt = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector3i c = grid.cellAt(p);
      return grid.inside(c) ? cost[static_cast<size_t>(grid.index(c))]
                            : std::numeric_limits<double>::infinity();
    };

    // The answer along the path to `target`, keeping the count of the gain evaluations so far.
    const auto pathTo = [&](const Eigen::Vector3d& target, std::optional<double> final_yaw) {
      Proposal path = pathProposal(grid, reached, *maps.esdf, request.start, target, final_yaw,
                                   *start_clearance);
      path.gain_evaluations = proposal.gain_evaluations;
      return path;
    };

    // A verified path to the goal, unless it failed from here.
    if (std::isfinite(costAt(request.goal)) && !(o.memory && tabu(next, request.goal)) &&
        esdfFree(options_, *maps.esdf, request.goal, options_.min_clearance)) {
      proposal = pathTo(request.goal, std::nullopt);
      proposal.reason = "a verified path to the goal";
      remember(request, next, proposal, true);
      return proposal;
    }
    // Else a verified path toward it: to the reached cell nearest it, when that is `progress`
    // nearer than the start and has not failed from here.
    const double start_to_goal = (request.goal - request.start).norm();
    int nearest = -1;
    double nearest_to_goal = start_to_goal - o.progress;
    for (int i = 0; i < grid.count(); ++i) {
      if (!std::isfinite(cost[static_cast<size_t>(i)])) continue;
      const double d = (grid.center(i) - request.goal).norm();
      if (d < nearest_to_goal && !(o.memory && tabu(next, grid.center(i)))) {
        nearest_to_goal = d;
        nearest = i;
      }
    }
    if (nearest >= 0) {
      const Eigen::Vector3d target = grid.center(nearest);
      const Eigen::Vector3d ahead = request.goal - target;
      proposal = pathTo(target, std::atan2(ahead.y(), ahead.x()));
      char text[160];
      std::snprintf(text, sizeof(text),
                    "a verified path toward the goal, to (%.1f, %.1f, %.1f), %.1f m nearer it",
                    target.x(), target.y(), target.z(), start_to_goal - nearest_to_goal);
      proposal.reason = text;
      remember(request, next, proposal, true);
      return proposal;
    }

    // Else climb to look toward the goal: over a wall of trees the space is unknown until the
    // camera is high enough to see it, and the viewpoints of the clusters seen so far lie below.
    if (o.layers && o.climb_look > 0) {
      const Eigen::Vector3d to_goal = request.goal - request.start;
      const double yaw = std::atan2(to_goal.y(), to_goal.x());
      const ExplorationGain& gain = gains_.forVoxelSize(maps.tsdf->voxelSize());
      // The highest reached cell of each column within 3 m, 0.8 m or more above the start.
      std::map<std::pair<int, int>, int> top;
      for (int i = 0; i < grid.count(); ++i) {
        if (!std::isfinite(cost[static_cast<size_t>(i)])) continue;
        const Eigen::Vector3d c = grid.center(i);
        if (c.z() < request.start.z() + 0.8 || (c - request.start).head<2>().norm() > 3.0) continue;
        const Eigen::Vector3i cell = grid.cellOf(i);
        auto [it, fresh] = top.try_emplace({cell.x(), cell.y()}, i);
        if (!fresh && grid.center(it->second).z() < c.z()) it->second = i;
      }
      std::vector<int> candidates;
      for (const auto& [xy, i] : top) candidates.push_back(i);
      std::sort(candidates.begin(), candidates.end(), [&](int x, int y) {
        return grid.center(x).z() > grid.center(y).z() ||
               (grid.center(x).z() == grid.center(y).z() && x < y);
      });
      if (candidates.size() > 12) candidates.resize(12);
      std::optional<std::pair<double, Eigen::Vector3d>> best_up;
      for (const int i : candidates) {
        const Eigen::Vector3d up = grid.center(i);
        if (o.memory && tabu(next, up)) continue;
        // At least climb_look and more than the best so far, or the view is not worth finishing.
        const std::optional<Gain> g = gain.visibleUnknownFractionIfAbove(
            *maps.tsdf, ExplorationGain::cameraAt(up, yaw), options_.look_around.subsample,
            o.climb_look, best_up ? best_up->first : -1.0);
        ++proposal.gain_evaluations;
        if (g) best_up = {g->unknown_fraction, up};
      }
      if (best_up) {
        const Eigen::Vector3d up = best_up->second;
        proposal = pathTo(up, yaw);
        char text[160];
        std::snprintf(text, sizeof(text),
                      "climb to (%.1f, %.1f, %.1f) to look toward the goal (%.0f %% unknown)",
                      up.x(), up.y(), up.z(), 100 * best_up->first);
        proposal.reason = text;
        remember(request, next, proposal, true);
        return proposal;
      }
    }

    const std::vector<Cluster> clusters = frontierClusters(*maps.tsdf, request.start);
    struct Candidate {
      Eigen::Vector3d viewpoint, centroid;
      double score;
    };
    std::optional<Candidate> best, kept;
    int reachable = 0;
    // A cluster's score is at least its bound (the path at least as long as the straight line to
    // its farthest ring): clusters are scored in the order of their bounds, until no other can
    // beat the best (or stand as the committed one).
    const auto terms = [&](const Cluster& c, const Eigen::Vector3d& v) {
      return o.w_goal * ((request.goal - c.centroid).norm() - start_to_goal) +
             o.w_altitude * std::abs(v.z() - request.goal.z()) -
             o.w_size * std::min(c.size, 50) / 50.0;
    };
    std::vector<std::pair<double, size_t>> order;
    for (size_t i = 0; i < clusters.size(); ++i) {
      const double straight = (clusters[i].centroid - request.start).norm() - 2.5 - o.grid;
      order.push_back({std::max(0.0, straight) + terms(clusters[i], clusters[i].centroid), i});
    }
    std::sort(order.begin(), order.end());
    for (const auto& [bound, index] : order) {
      if (best && bound > best->score + o.hysteresis) break;
      const Cluster& cluster = clusters[index];
      std::optional<Candidate> mine;
      for (const double d : {1.5, 2.5}) {
        for (int k = 0; k < 8; ++k) {
          const double bearing = M_PI / 4 * k;
          const Eigen::Vector3d v =
              cluster.centroid + d * Eigen::Vector3d(std::cos(bearing), std::sin(bearing), 0);
          if ((v - request.start).norm() < 1.0) continue;  // a look, not a flight
          const double path = costAt(v);
          if (!std::isfinite(path) || !observedFree(options_, maps, v)) continue;
          if (!seesCluster(*maps.tsdf, v, cluster.centroid)) continue;
          if (o.memory && tabu(next, v)) continue;
          const double score = path + terms(cluster, v);
          if (!mine || score < mine->score) mine = Candidate{v, cluster.centroid, score};
        }
      }
      if (!mine) continue;
      ++reachable;
      if (!best || mine->score < best->score) best = mine;
      if (o.memory && next.committed && (mine->viewpoint - *next.committed).norm() < kSameTarget) {
        kept = mine;
      }
    }
    if (best) {
      // Hysteresis: the committed target stands unless another is clearly better.
      const Candidate chosen = kept && kept->score <= best->score + o.hysteresis ? *kept : *best;
      const Eigen::Vector3d look = chosen.centroid - chosen.viewpoint;
      proposal = pathTo(chosen.viewpoint, std::atan2(look.y(), look.x()));
      proposal.score = chosen.score;
      char text[200];
      std::snprintf(text, sizeof(text),
                    "viewpoint (%.1f, %.1f, %.1f) of the best of %d reachable frontier clusters "
                    "scored (%zu seen), score %.2f%s",
                    chosen.viewpoint.x(), chosen.viewpoint.y(), chosen.viewpoint.z(), reachable,
                    clusters.size(), chosen.score,
                    kept && chosen.viewpoint == kept->viewpoint ? ", kept" : "");
      proposal.reason = text;
      remember(request, next, proposal, true);
      return proposal;
    }

    // The way home: back along the places flown since the last one with frontiers.
    if (o.memory) {
      for (size_t i = memory_.places.size(); i-- > 0;) {
        const Place& place = memory_.places[i];
        if (!place.frontiers || (place.position - request.start).norm() < 2.0 ||
            tabu(next, place.position)) {
          continue;
        }
        proposal.found = true;
        Eigen::Vector3d from = request.start;
        for (size_t j = memory_.places.size(); j-- > i;) {
          const Eigen::Vector3d& p = memory_.places[j].position;
          if ((p - from).norm() < 0.5) continue;
          proposal.waypoints.push_back(p);
          proposal.yaws.push_back(std::atan2(p.y() - from.y(), p.x() - from.x()));
          from = p;
        }
        char text[160];
        std::snprintf(text, sizeof(text),
                      "no reachable frontier here (%zu clusters seen): home to (%.1f, %.1f, %.1f) "
                      "over %zu remembered places",
                      clusters.size(), place.position.x(), place.position.y(), place.position.z(),
                      proposal.waypoints.size());
        proposal.reason = text;
        remember(request, next, proposal, false);
        return proposal;
      }
    }
    char text[160];
    std::snprintf(text, sizeof(text),
                  "no reachable frontier cluster (%zu seen) and no place to go back to%s",
                  clusters.size(), start_clearance ? "" : " (the start has too little clearance)");
    proposal.reason = text;
    remember(request, next, proposal, false);
    return proposal;
  }

 private:
  // The request came from about where the previous one did: its target was not reached.
  void noteAttempt(Memory& next, const Eigen::Vector3d& start) const {
    if (!next.last_start || !next.committed) return;
    if ((start - *next.last_start).norm() > options_.frontier_memory.tabu_radius) return;
    for (Target& t : next.targets) {
      if ((t.position - *next.committed).norm() < kSameTarget) ++t.attempts;
    }
  }

  bool tabu(const Memory& memory, const Eigen::Vector3d& p) const {
    const FrontierMemoryOptions& o = options_.frontier_memory;
    for (const Target& t : memory.targets) {
      if (t.attempts >= o.tabu_attempts && (t.position - p).norm() < o.tabu_radius) return true;
    }
    return false;
  }

  void remember(const ExplorationRequest& request, Memory& next, const Proposal& proposal,
                bool frontiers) {
    if (options_.frontier_memory.memory) {
      next.places.push_back(Place{request.start, frontiers});
      next.last_start = request.start;
      next.committed.reset();
      if (proposal.found) {
        const Eigen::Vector3d& target = proposal.waypoints.back();
        next.committed = target;
        const bool known = std::any_of(
            next.targets.begin(), next.targets.end(),
            [&](const Target& t) { return (t.position - target).norm() < kSameTarget; });
        if (!known) next.targets.push_back(Target{target, 0});
      }
    }
    written_ = next;
    written_cycle_ = request.cycle;
  }

  // The heights searched: `climb` above and below the start inside the flight volume; without
  // layers the start's height (+- `flat`).
  std::pair<double, double> band(const Eigen::Vector3d& start, double flat) const {
    const FrontierMemoryOptions& o = options_.frontier_memory;
    if (!o.layers) return {start.z() - flat, start.z() + flat};
    return {std::max(options_.flight_volume_min.z(), start.z() - o.climb),
            std::min(options_.flight_volume_max.z(), start.z() + o.climb)};
  }

  Grid makeGrid(const Eigen::Vector3d& start) const {
    const FrontierMemoryOptions& o = options_.frontier_memory;
    const auto [low, high] = band(start, 0.0);
    // Cells are aligned on the start, so the start is a cell centre.
    const int below = static_cast<int>(std::floor((start.z() - low) / o.grid + 1e-9));
    const int above = static_cast<int>(std::floor((high - start.z()) / o.grid + 1e-9));
    const int half = static_cast<int>(std::ceil(o.radius / o.grid));
    const Eigen::Vector3d origin = start - o.grid * Eigen::Vector3d(half, half, below);
    return Grid(origin, o.grid, Eigen::Vector3i(2 * half + 1, 2 * half + 1, below + above + 1));
  }

  // Path costs from the start to every grid cell (infinity where unreached), and the ESDF
  // distance of every free cell tested.
  struct Reach {
    std::vector<double> cost;
    std::vector<float> clearance;
  };
  Reach reach(const Grid& grid, const EsdfLayer& esdf, const Eigen::Vector3d& start,
              double start_clearance) const {
    const FrontierMemoryOptions& o = options_.frontier_memory;
    const double inf = std::numeric_limits<double>::infinity();
    Reach r{std::vector<double>(static_cast<size_t>(grid.count()), inf),
            std::vector<float>(static_cast<size_t>(grid.count()), 0.0f)};
    std::vector<signed char> free(static_cast<size_t>(grid.count()), -1);  // -1: not yet tested
    const auto isFree = [&](int i) {
      signed char& f = free[static_cast<size_t>(i)];
      if (f < 0) {
        const Eigen::Vector3d p = grid.center(i);
        const double needed = (p - start).norm() < 1.0 ? start_clearance : options_.min_clearance;
        const EsdfVoxel* v = esdf.voxel(esdf.voxelIndex(p));
        f = inFlightVolume(options_, p) && v != nullptr && v->observed && v->distance >= needed;
        if (f > 0) r.clearance[static_cast<size_t>(i)] = v->distance;
      }
      return f > 0;
    };
    // A step into a cell with less than the comfortable clearance costs up to 1 + w_comfort
    // times its length: paths keep to the middle of gaps and pass narrow ones only when the way
    // around costs more.
    const double comfortable = options_.min_clearance + o.comfort;
    const auto penalty = [&](int j) {
      if (o.comfort <= 0) return 1.0;
      const double short_by = comfortable - r.clearance[static_cast<size_t>(j)];
      return 1.0 + o.w_comfort * std::clamp(short_by / o.comfort, 0.0, 1.0);
    };
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
    const int s = grid.index(grid.cellAt(start));
    r.cost[static_cast<size_t>(s)] = 0;
    free[static_cast<size_t>(s)] = 1;
    r.clearance[static_cast<size_t>(s)] = static_cast<float>(start_clearance);
    open.push({0, s});
    while (!open.empty()) {
      const auto [c, i] = open.top();
      open.pop();
      if (c > r.cost[static_cast<size_t>(i)]) continue;
      const Eigen::Vector3i cell = grid.cellOf(i);
      for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            if (dx == 0 && dy == 0 && dz == 0) continue;
            const Eigen::Vector3i n = cell + Eigen::Vector3i(dx, dy, dz);
            if (!grid.inside(n)) continue;
            const int j = grid.index(n);
            if (!isFree(j)) continue;
            const double step =
                o.grid * std::sqrt(static_cast<double>(dx * dx + dy * dy + dz * dz)) * penalty(j);
            const double next = c + step + o.w_climb * o.grid * std::max(0, dz);
            if (next < r.cost[static_cast<size_t>(j)]) {
              r.cost[static_cast<size_t>(j)] = next;
              open.push({next, j});
            }
          }
        }
      }
    }
    return r;
  }

  // The path to `target` down the cost field, shortened by straight free segments: a shortcut
  // keeps the clearance of the cells it replaces, up to the comfortable one, and at least
  // `clearance`.
  Proposal pathProposal(const Grid& grid, const Reach& reach, const EsdfLayer& esdf,
                        const Eigen::Vector3d& start, const Eigen::Vector3d& target,
                        std::optional<double> final_yaw, double clearance) const {
    const auto costOf = [&](const Eigen::Vector3i& c) {
      return reach.cost[static_cast<size_t>(grid.index(c))];
    };
    Eigen::Vector3i cell = grid.cellAt(target);
    std::vector<Eigen::Vector3d> cells = {target};
    std::vector<double> clear = {reach.clearance[static_cast<size_t>(grid.index(cell))]};
    const Eigen::Vector3i s = grid.cellAt(start);
    for (int guard = 0; cell != s && guard < grid.count(); ++guard) {
      Eigen::Vector3i down = cell;
      double lowest = costOf(cell);
      for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const Eigen::Vector3i n = cell + Eigen::Vector3i(dx, dy, dz);
            if (grid.inside(n) && costOf(n) < lowest) {
              lowest = costOf(n);
              down = n;
            }
          }
        }
      }
      if (down == cell) break;
      cell = down;
      cells.push_back(grid.center(cell));
      clear.push_back(reach.clearance[static_cast<size_t>(grid.index(cell))]);
    }
    std::reverse(cells.begin(), cells.end());
    std::reverse(clear.begin(), clear.end());
    // The path runs from the start itself (in place of its cell's centre) to the target, also
    // when the target lies in the start's cell.
    if (cells.size() == 1) {
      cells.insert(cells.begin(), start);
      clear.insert(clear.begin(), clear.front());
    }
    cells.front() = start;
    // Shortcut: from each kept point, the farthest later one a straight segment reaches with the
    // clearance of the cells between them (capped at the comfortable one). Every segment is
    // flown straight and must keep `clearance`, the one to the next point too, unchecked by the
    // shortcut: two points at the edge of a tree's margin see each other across it, and the chord
    // between them dips in. Such a segment is bent around.
    const double step = 0.5 * esdf.voxelSize();
    const double comfortable = options_.min_clearance + options_.frontier_memory.comfort;
    Proposal proposal;
    proposal.found = true;
    const auto fly = [&](const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
      proposal.waypoints.push_back(to);
      proposal.yaws.push_back(std::atan2(to.y() - from.y(), to.x() - from.x()));
    };
    size_t i = 0;
    while (i + 1 < cells.size()) {
      size_t j = cells.size() - 1;
      const auto needed = [&](size_t last) {
        const double least = *std::min_element(clear.begin() + static_cast<long>(i) + 1,
                                               clear.begin() + static_cast<long>(last) + 1);
        return std::max(clearance, std::min(comfortable, least));
      };
      while (j > i + 1 && !esdfSegmentFree(options_, esdf, cells[i], cells[j], needed(j), step))
        --j;
      Eigen::Vector3d from = cells[i];
      if (j == i + 1 && !esdfSegmentFree(options_, esdf, from, cells[j], clearance, step)) {
        if (const auto bend = bendPoint(esdf, from, cells[j], clearance, step)) {
          fly(from, *bend);
          from = *bend;
        }
      }
      fly(from, cells[j]);
      i = j;
    }
    if (final_yaw) proposal.yaws.back() = *final_yaw;
    return proposal;
  }

  // The point that bends a segment a-b which dips below `clearance` around the obstacle: its
  // lowest sample pushed up the ESDF gradient to `clearance` + kBendMargin, when both halves then
  // keep `clearance`. Nothing when the push fails (the segment stays: the planner refuses it and
  // the target's attempts count toward its tabu).
  std::optional<Eigen::Vector3d> bendPoint(const EsdfLayer& esdf, const Eigen::Vector3d& a,
                                           const Eigen::Vector3d& b, double clearance,
                                           double step) const {
    constexpr double kBendMargin = 0.05;  // [m]
    const int n = std::max(2, static_cast<int>(std::ceil((b - a).norm() / step)));
    Eigen::Vector3d m = a;
    double least = std::numeric_limits<double>::infinity();
    for (int k = 1; k < n; ++k) {
      const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(k) / n);
      const EsdfSample s = sampleEsdf(esdf, p);
      if (!s.known) return std::nullopt;
      if (s.distance < least) {
        least = s.distance;
        m = p;
      }
    }
    const double wanted = clearance + kBendMargin;
    for (int push = 0; push < 8; ++push) {
      const EsdfSample s = sampleEsdf(esdf, m);
      if (!s.known || s.gradient.norm() < 1e-6) return std::nullopt;
      if (s.distance >= wanted) break;
      m += (wanted - s.distance) * s.gradient.normalized();
    }
    if (!esdfFree(options_, esdf, m, wanted) ||
        !esdfSegmentFree(options_, esdf, a, m, clearance, step) ||
        !esdfSegmentFree(options_, esdf, m, b, clearance, step)) {
      return std::nullopt;
    }
    return m;
  }

  // Frontier clusters in the box around the start and the altitude band.
  std::vector<Cluster> frontierClusters(const TsdfLayer& tsdf, const Eigen::Vector3d& start) const {
    const FrontierMemoryOptions& o = options_.frontier_memory;
    const double min_weight = options_.gain.min_weight;
    // Without layers: the frontiers a camera at the start's height sees ahead.
    const auto [low, high] = band(start, o.cluster_size);
    const Eigen::Vector3d lo(start.x() - o.radius, start.y() - o.radius, low);
    const Eigen::Vector3d hi(start.x() + o.radius, start.y() + o.radius, high);
    const auto observed = [&](const VoxelIndex& v) {
      const TsdfVoxel* voxel = tsdf.voxel(v);
      return voxel != nullptr && voxel->weight >= min_weight;
    };
    std::map<std::tuple<int, int, int>, Cluster> cells;  // ordered: deterministic
    // The frontier voxels of one block, into their cells.
    const auto scan = [&](const BlockIndex& b, const TsdfLayer::BlockType& block) {
      for (int k = 0; k < kVoxelsPerBlock; ++k) {
        const TsdfVoxel& voxel = block.voxels[static_cast<size_t>(k)];
        if (!(voxel.weight >= min_weight) || voxel.distance <= 0) continue;
        const VoxelIndex v = voxelOfBlock(b, k);
        const Eigen::Vector3d p = tsdf.voxelCenter(v);
        if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
        // A neighbour inside the block is read from its array, the others looked up.
        bool frontier = false;
        const int local[3] = {k & 15, (k >> 4) & 15, k >> 8};
        const int stride[3] = {1, 16, 256};
        for (int axis = 0; axis < 3 && !frontier; ++axis) {
          for (const int sign : {-1, 1}) {
            const int l = local[axis] + sign;
            const bool seen =
                l >= 0 && l < 16
                    ? block.voxels[static_cast<size_t>(k + sign * stride[axis])].weight >=
                          min_weight
                    : observed(v + sign * VoxelIndex::Unit(axis));
            if (!seen) {
              frontier = true;
              break;
            }
          }
        }
        if (!frontier) continue;
        const Eigen::Vector3i c = (p / o.cluster_size).array().floor().cast<int>();
        Cluster& cluster = cells[{c.x(), c.y(), c.z()}];
        cluster.centroid += p;
        ++cluster.size;
      }
    };
    const BlockIndex blo = tsdf.blockIndex(lo), bhi = tsdf.blockIndex(hi);
    for (BlockIndex b = blo; b.z() <= bhi.z(); ++b.z()) {
      for (b.y() = blo.y(); b.y() <= bhi.y(); ++b.y()) {
        for (b.x() = blo.x(); b.x() <= bhi.x(); ++b.x()) {
          if (const auto* block = tsdf.block(b)) scan(b, *block);
        }
      }
    }
    std::vector<Cluster> clusters;
    for (auto& [key, cluster] : cells) {
      if (cluster.size < o.min_frontier) continue;
      cluster.centroid /= cluster.size;
      clusters.push_back(cluster);
    }
    return clusters;
  }

  // The segment from the viewpoint to the cluster crosses no surface the TSDF saw.
  static bool seesCluster(const TsdfLayer& tsdf, const Eigen::Vector3d& from,
                          const Eigen::Vector3d& to) {
    const double step = 0.5 * tsdf.voxelSize();
    const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / step)));
    for (int k = 0; k < n; ++k) {
      const TsdfVoxel* v = tsdf.voxel(tsdf.voxelIndex(from + (to - from) * (double(k) / n)));
      if (v != nullptr && v->weight > 0 && v->distance <= 0) return false;
    }
    return true;
  }

  ExplorerOptions options_;
  GainCache gains_;
  Memory memory_, written_;
  int64_t written_cycle_ = std::numeric_limits<int64_t>::min();
};

}  // namespace

std::unique_ptr<GoalSelector> makeFrontierMemory(const ExplorerOptions& options) {
  return std::make_unique<FrontierMemorySelector>(options);
}

}  // namespace thicket::explorer::detail

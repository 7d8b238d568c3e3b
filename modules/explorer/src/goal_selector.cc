#include "thicket/explorer/goal_selector.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "strategies.h"
#include "thicket/common/esdf_query.h"
#include "thicket/common/random.h"

namespace thicket::explorer {

void ExplorerOptions::declare(Params& p) {
  p.choice("strategy", strategy, strategyNames(), "the goal-selection strategy");
  p("seed", seed, "random draws are seeded from this and the planner cycle");
  p("radius", radius, "r: candidates lie within this of the start [m]", Range::positive());
  p("candidates", candidates, "N: candidates scored per request", Range::between(1, 10000));
  p("subsample", subsample, "s: the gain checks every s-th frustum voxel",
    Range::between(1, 100000));
  p("w_e", w_e, "weight of the exploration gain", Range::atLeast(0));
  p("w_g", w_g, "weight of the progress toward the goal", Range::atLeast(0));
  p("p_goal", p_goal, "P_g: probability of proposing the global goal", Range::between(0, 1));
  p("min_clearance", min_clearance, "candidates need at least this ESDF distance [m]",
    Range::positive());
  p("reachable", reachable,
    "local_exploration: candidates need a straight line from the start that keeps the trees' "
    "clearance");
  p("fixed_yaw", fixed_yaw,
    "send the proposals' yaws: the vehicle faces them on the way and turns at each waypoint; "
    "false: it faces along its velocity (the paper)");
  p("max_draws", max_draws, "random draws per request", Range::between(1, 10000000));
  p("flight_volume_min", flight_volume_min, "candidates lie in this box: its low corner [m]");
  p("flight_volume_max", flight_volume_max, "... and its high corner [m]");
  p.group("gain", gain, "the camera whose frustum the exploration gain counts");
  p.group("look_around", look_around,
          "answer the first stuck request at each place with a turn in place (needs fixed_yaw)");
  p.group("rrt_star", rrt_star, "the RRT* baselines (rrt_star_optimistic, rrt_star_conservative)");
  p.group("nbvp", nbvp, "the next-best-view baseline");
  p.group("frontier_memory", frontier_memory,
          "frontier viewpoints along verified paths, with a memory of places and failed targets");
}

void FrontierMemoryOptions::declare(Params& p) {
  p("radius", radius, "frontiers and paths in a box of this half-width [m]", Range::positive());
  p("grid", grid, "the path search's cell [m]", Range::between(0.05, 5));
  p("cluster_size", cluster_size, "frontier voxels are clustered in cells of this [m]",
    Range::positive());
  p("min_frontier", min_frontier, "a cluster has at least this many frontier voxels",
    Range::between(1, 100000));
  p("layers", layers, "search and look up to `climb` above and below the start; false: its height");
  p("climb", climb, "... that far [m]", Range::atLeast(0));
  p("memory", memory, "remember places, failed targets and the committed target");
  p("progress", progress,
    "a verified path toward a goal out of reach must end this much nearer it [m]",
    Range::positive());
  p("w_goal", w_goal, "weight of the cluster's distance to the goal", Range::atLeast(0));
  p("w_climb", w_climb, "extra path cost per metre climbed", Range::atLeast(0));
  p("comfort", comfort,
    "paths prefer this much clearance above min_clearance [m]; shortcuts keep what they replace",
    Range::atLeast(0));
  p("w_comfort", w_comfort, "a step into a cell short of it costs up to 1 + this times its length",
    Range::atLeast(0));
  p("w_altitude", w_altitude, "weight of the viewpoint's height difference to the goal",
    Range::atLeast(0));
  p("w_size", w_size, "weight of the cluster's size", Range::atLeast(0));
  p("hysteresis", hysteresis, "the committed target stands unless another scores this better",
    Range::atLeast(0));
  p("climb_look", climb_look,
    "with layers, when no verified path makes progress: first climb to the reached cell 0.8 m or "
    "more above the start, within 3 m, whose view toward the goal is the most unknown, if at "
    "least this fraction; 0: never",
    Range::between(0, 1));
  p("tabu_attempts", tabu_attempts, "a target asked again from its request's place this often ...",
    Range::between(1, 1000));
  p("tabu_radius", tabu_radius, "... is not proposed again within this [m]", Range::positive());
}

void LookAroundOptions::declare(Params& p) {
  p("enabled", enabled, "look around before the strategy is asked");
  p("radius", radius, "a place is where a look was answered, within this [m]", Range::positive());
  p("headings", headings, "headings compared, evenly spaced", Range::between(1, 360));
  p("min_gain", min_gain, "a view with less visible unknown fraction is not worth a look",
    Range::between(0, 1));
  p("subsample", subsample, "the look's gains check every subsample-th frustum voxel",
    Range::between(1, 100000));
}

void RrtStarOptions::declare(Params& p) {
  p("iterations", iterations, "RRT* iterations per request", Range::between(1, 1000000));
  p("range", range, "longest tree edge [m]", Range::positive());
  p("goal_bias", goal_bias, "probability of sampling the goal", Range::between(0, 1));
  p("goal_tolerance", goal_tolerance, "a node this close to the goal reaches it [m]",
    Range::positive());
  p("check_step", check_step, "edges are checked for collisions every this [m]", Range::positive());
  p("box_margin", box_margin,
    "the tree grows in the bounding box of start and goal grown by this [m]", Range::atLeast(0));
  p("delay_collision_checks", delay_collision_checks,
    "OMPL's delayCC: check a new node's edges to its neighbours in order of cost rather than "
    "each cheaper one in neighbour order (the same tree, slower here)");
}

void NbvpOptions::declare(Params& p) {
  p("initial_nodes", initial_nodes, "N_T: the tree grows at least this many nodes",
    Range::between(1, 100000));
  p("max_nodes", max_nodes, "... and at most this many, until a branch beats zero_gain",
    Range::between(1, 100000));
  p("range", range, "longest tree edge [m]", Range::positive());
  p("lambda", lambda, "the gain decays as exp(-lambda * branch length) [1/m]", Range::atLeast(0));
  p("zero_gain", zero_gain, "a best branch worth no more than this: nothing to explore",
    Range::atLeast(0));
  p("check_step", check_step, "edges are checked for collisions every this [m]", Range::positive());
}

namespace {

using detail::drawInBall;
using detail::Rng;

class NoneSelector final : public GoalSelector {
 public:
  const char* name() const override { return "none"; }
  Proposal select(const ExplorationRequest&, const MapView&) override {
    Proposal proposal;
    proposal.reason = "strategy none proposes no intermediate goals";
    return proposal;
  }
};

class RandomSelector final : public GoalSelector {
 public:
  explicit RandomSelector(const ExplorerOptions& options) : options_(options) {}
  const char* name() const override { return "random"; }
  Proposal select(const ExplorationRequest& request, const MapView&) override {
    Rng rng(mixSeed(options_.seed, request.cycle));
    Proposal proposal;
    const auto point =
        drawInBall(rng, request.start, options_.radius, options_, options_.max_draws);
    if (!point) {
      proposal.reason = "no point of the flight volume within r of the start";
      return proposal;
    }
    proposal.found = true;
    proposal.waypoints = {*point};
    proposal.reason = "a random point within r of the start";
    return proposal;
  }

 private:
  ExplorerOptions options_;
};

}  // namespace

namespace detail {

bool inFlightVolume(const ExplorerOptions& o, const Eigen::Vector3d& p) {
  return (p.array() >= o.flight_volume_min.array()).all() &&
         (p.array() <= o.flight_volume_max.array()).all();
}

std::optional<Eigen::Vector3d> drawInBall(Rng& rng, const Eigen::Vector3d& center, double radius,
                                          const ExplorerOptions& o, int max_draws) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (int draw = 0; draw < max_draws; ++draw) {
    const Eigen::Vector3d offset(u(rng), u(rng), u(rng));
    if (offset.squaredNorm() > 1) continue;
    const Eigen::Vector3d p = center + radius * offset;
    if (inFlightVolume(o, p)) return p;
  }
  return std::nullopt;
}

bool esdfFree(const ExplorerOptions& o, const EsdfLayer& esdf, const Eigen::Vector3d& p,
              double clearance) {
  if (!inFlightVolume(o, p)) return false;
  const EsdfSample sample = sampleEsdf(esdf, p);
  return sample.known && sample.distance >= clearance;
}

bool esdfSegmentFree(const ExplorerOptions& o, const EsdfLayer& esdf, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, double clearance, double step) {
  const int steps = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step)));
  for (int i = 0; i <= steps; ++i) {
    if (!esdfFree(o, esdf, a + (b - a) * (static_cast<double>(i) / steps), clearance)) return false;
  }
  return true;
}

std::optional<double> treeClearance(const ExplorerOptions& o, const EsdfLayer& esdf,
                                    const Eigen::Vector3d& start) {
  const EsdfSample sample = sampleEsdf(esdf, start);
  if (!sample.known || !inFlightVolume(o, start) || sample.distance < 0.5 * o.min_clearance) {
    return std::nullopt;
  }
  return std::min(o.min_clearance, sample.distance);
}

bool observedFree(const ExplorerOptions& o, const MapView& maps, const Eigen::Vector3d& p) {
  const TsdfVoxel* voxel = maps.tsdf->voxel(maps.tsdf->voxelIndex(p));
  if (voxel == nullptr || !(voxel->weight >= o.gain.min_weight) || voxel->distance <= 0) {
    return false;
  }
  return esdfFree(o, *maps.esdf, p, o.min_clearance);
}

}  // namespace detail

namespace {

std::unique_ptr<GoalSelector> makeStrategy(const ExplorerOptions& o) {
  if (o.strategy == "none") return std::make_unique<NoneSelector>();
  if (o.strategy == "random") return std::make_unique<RandomSelector>(o);
  if (o.strategy == "local_exploration") return detail::makeLocalExploration(o);
  if (o.strategy == "rrt_star_optimistic") return detail::makeRrtStar(o, /*optimistic=*/true);
  if (o.strategy == "rrt_star_conservative") return detail::makeRrtStar(o, /*optimistic=*/false);
  if (o.strategy == "nbvp") return detail::makeNbvp(o);
  if (o.strategy == "frontier_memory") return detail::makeFrontierMemory(o);
  throw std::invalid_argument("explorer: unknown strategy '" + o.strategy + "'");
}

}  // namespace

const std::vector<std::string>& strategyNames() {
  static const std::vector<std::string> names = {"none",
                                                 "random",
                                                 "rrt_star_optimistic",
                                                 "rrt_star_conservative",
                                                 "nbvp",
                                                 "local_exploration",
                                                 "frontier_memory"};
  return names;
}

std::unique_ptr<GoalSelector> makeGoalSelector(const ExplorerOptions& o) {
  // The rules of ExplorerOptions::declare, and those between fields it cannot state.
  if (const std::string error = paramsError(o); !error.empty()) {
    throw std::invalid_argument("explorer: " + error);
  }
  if (!(o.flight_volume_min.array() < o.flight_volume_max.array()).all()) {
    throw std::invalid_argument("explorer: the flight volume's corners are not in order");
  }
  if (o.nbvp.max_nodes < o.nbvp.initial_nodes) {
    throw std::invalid_argument("explorer: nbvp.max_nodes is below nbvp.initial_nodes");
  }
  if (o.frontier_memory.radius / o.frontier_memory.grid > 200) {
    throw std::invalid_argument(
        "explorer: frontier_memory.radius spans more than 200 cells of frontier_memory.grid");
  }
  if (o.look_around.enabled && !o.fixed_yaw) {
    throw std::invalid_argument("explorer: look_around needs fixed_yaw (a look is a yaw)");
  }
  std::unique_ptr<GoalSelector> strategy = makeStrategy(o);
  return o.look_around.enabled ? detail::lookAround(o, std::move(strategy)) : std::move(strategy);
}

}  // namespace thicket::explorer

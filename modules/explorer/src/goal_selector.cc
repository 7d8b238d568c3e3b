#include "thicket/explorer/goal_selector.h"

#include <cmath>
#include <cstdio>
#include <limits>
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

class LocalExplorationSelector final : public GoalSelector {
 public:
  explicit LocalExplorationSelector(const ExplorerOptions& options) : options_(options) {}
  const char* name() const override { return "local_exploration"; }
  void prepare(double voxel_size) override { gains_.forVoxelSize(voxel_size); }

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    Rng rng(mixSeed(options_.seed, request.cycle));
    Proposal proposal;
    if (std::bernoulli_distribution(options_.p_goal)(rng)) {
      proposal.found = true;
      proposal.waypoints = {request.goal};
      proposal.reason = "the global goal (drawn with probability P_g)";
      return proposal;
    }
    if (maps.tsdf == nullptr || maps.esdf == nullptr) {
      proposal.reason = "no map";
      proposal.map_missing = true;
      return proposal;
    }
    const ExplorationGain& gain = gains_.forVoxelSize(maps.tsdf->voxelSize());
    const double d_g = (request.goal - request.start).norm() + options_.radius;
    const std::optional<double> line_clearance =
        options_.reachable ? detail::treeClearance(options_, *maps.esdf, request.start)
                           : std::nullopt;
    double best = -std::numeric_limits<double>::infinity();
    int candidates = 0;
    for (int draw = 0; draw < options_.max_draws && candidates < options_.candidates; ++draw) {
      const auto x = drawInBall(rng, request.start, options_.radius, options_, 1);
      if (!x || !detail::observedFree(options_, maps, *x)) continue;
      if (line_clearance &&
          !detail::esdfSegmentFree(options_, *maps.esdf, request.start, *x, *line_clearance,
                                   0.5 * maps.esdf->voxelSize())) {
        continue;
      }
      ++candidates;
      // Face away from the start, then look: the gain is that of the view the vehicle will have.
      const Eigen::Vector3d away = *x - request.start;
      const double yaw = std::atan2(away.y(), away.x());
      const Gain g =
          gain.unknownFraction(*maps.tsdf, ExplorationGain::cameraAt(*x, yaw), options_.subsample);
      ++proposal.gain_evaluations;
      const double score = options_.w_e * g.unknown_fraction +
                           options_.w_g * (d_g - (request.goal - *x).norm()) / d_g;
      if (score > best) {
        best = score;
        proposal.found = true;
        proposal.waypoints = {*x};
        proposal.yaws = {yaw};
        proposal.score = score;
      }
    }
    char text[160];
    if (proposal.found) {
      std::snprintf(text, sizeof(text), "best of %d observed free candidates, score %.3f",
                    candidates, best);
    } else {
      std::snprintf(text, sizeof(text),
                    "no observed free point%s within %.1f m of the start in %d draws",
                    line_clearance ? " reachable in a straight line" : "", options_.radius,
                    options_.max_draws);
    }
    proposal.reason = text;
    return proposal;
  }

 private:
  ExplorerOptions options_;
  detail::GainCache gains_{options_.gain};
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

bool frontierMemoryOptionsValid(const FrontierMemoryOptions& f) {
  const auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  const auto nonNegative = [](double x) { return std::isfinite(x) && x >= 0; };
  return positive(f.radius) && f.grid >= 0.05 && f.grid <= 5 && positive(f.cluster_size) &&
         f.min_frontier >= 1 && nonNegative(f.climb) && nonNegative(f.w_goal) &&
         nonNegative(f.w_climb) && nonNegative(f.comfort) && nonNegative(f.w_comfort) &&
         nonNegative(f.w_altitude) && nonNegative(f.w_size) && nonNegative(f.hysteresis) &&
         f.climb_look >= 0 && f.climb_look <= 1 && positive(f.progress) && f.tabu_attempts >= 1 &&
         positive(f.tabu_radius) && f.radius / f.grid <= 200;
}

std::unique_ptr<GoalSelector> makeStrategy(const ExplorerOptions& o) {
  if (o.strategy == "none") return std::make_unique<NoneSelector>();
  if (o.strategy == "random") return std::make_unique<RandomSelector>(o);
  if (o.strategy == "local_exploration") return std::make_unique<LocalExplorationSelector>(o);
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
  const auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  if (!positive(o.radius) || o.candidates < 1 || o.subsample < 1 || !(o.w_e >= 0) ||
      !(o.w_g >= 0) || !(o.p_goal >= 0 && o.p_goal <= 1) || !positive(o.min_clearance) ||
      o.max_draws < 1 || !o.flight_volume_min.allFinite() || !o.flight_volume_max.allFinite() ||
      !(o.flight_volume_min.array() < o.flight_volume_max.array()).all() ||
      o.rrt_star.iterations < 1 || !positive(o.rrt_star.range) ||
      !(o.rrt_star.goal_bias >= 0 && o.rrt_star.goal_bias <= 1) ||
      !positive(o.rrt_star.goal_tolerance) || !positive(o.rrt_star.check_step) ||
      !(o.rrt_star.box_margin >= 0) || !std::isfinite(o.rrt_star.box_margin) ||
      o.nbvp.initial_nodes < 1 || o.nbvp.max_nodes < o.nbvp.initial_nodes ||
      !positive(o.nbvp.range) || !(o.nbvp.lambda >= 0) || !std::isfinite(o.nbvp.lambda) ||
      !(o.nbvp.zero_gain >= 0) || !std::isfinite(o.nbvp.zero_gain) ||
      !positive(o.nbvp.check_step) || !positive(o.look_around.radius) ||
      o.look_around.headings < 1 || o.look_around.subsample < 1 ||
      !(o.look_around.min_gain >= 0 && o.look_around.min_gain <= 1) ||
      !frontierMemoryOptionsValid(o.frontier_memory)) {
    throw std::invalid_argument("explorer: an option is out of range (see ExplorerOptions)");
  }
  if (o.look_around.enabled && !o.fixed_yaw) {
    throw std::invalid_argument("explorer: look_around needs fixed_yaw (a look is a yaw)");
  }
  std::unique_ptr<GoalSelector> strategy = makeStrategy(o);
  return o.look_around.enabled ? detail::lookAround(o, std::move(strategy)) : std::move(strategy);
}

}  // namespace thicket::explorer

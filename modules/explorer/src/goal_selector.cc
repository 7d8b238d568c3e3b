#include "thicket/explorer/goal_selector.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>

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
  p("max_draws", max_draws, "random draws per request", Range::between(1, 10000000));
  p("flight_volume_min", flight_volume_min, "candidates lie in this box: its low corner [m]");
  p("flight_volume_max", flight_volume_max, "... and its high corner [m]");
  p.group("gain", gain, "the camera whose frustum the exploration gain counts");
}

namespace {

using Rng = std::mt19937_64;

// A uniform point in the ball of `radius` around `center`, inside the flight volume; nothing
// after `max_draws` draws outside it.
std::optional<Eigen::Vector3d> drawInBall(Rng& rng, const Eigen::Vector3d& center, double radius,
                                          const ExplorerOptions& o, int max_draws) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (int draw = 0; draw < max_draws; ++draw) {
    const Eigen::Vector3d offset(u(rng), u(rng), u(rng));
    if (offset.squaredNorm() > 1) continue;
    const Eigen::Vector3d p = center + radius * offset;
    if ((p.array() >= o.flight_volume_min.array()).all() &&
        (p.array() <= o.flight_volume_max.array()).all()) {
      return p;
    }
  }
  return std::nullopt;
}

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
    const ExplorationGain& gain = gainFor(maps.tsdf->voxelSize());
    const double d_g = (request.goal - request.start).norm() + options_.radius;
    double best = -std::numeric_limits<double>::infinity();
    int candidates = 0;
    for (int draw = 0; draw < options_.max_draws && candidates < options_.candidates; ++draw) {
      const auto x = drawInBall(rng, request.start, options_.radius, options_, 1);
      if (!x || !observedFree(*x, maps)) continue;
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
                    "no observed free point within %.1f m of the start in %d draws",
                    options_.radius, options_.max_draws);
    }
    proposal.reason = text;
    return proposal;
  }

 private:
  // Observed in the TSDF, and clear of obstacles (and of unknown space) in the ESDF.
  bool observedFree(const Eigen::Vector3d& x, const MapView& maps) const {
    const TsdfVoxel* voxel = maps.tsdf->voxel(maps.tsdf->voxelIndex(x));
    if (voxel == nullptr || !(voxel->weight >= options_.gain.min_weight) || voxel->distance <= 0) {
      return false;
    }
    const EsdfSample sample = sampleEsdf(*maps.esdf, x);
    return sample.known && sample.distance >= options_.min_clearance;
  }

  const ExplorationGain& gainFor(double voxel_size) {
    if (!gain_ || gain_voxel_size_ != voxel_size) {
      gain_.emplace(options_.gain, voxel_size);
      gain_voxel_size_ = voxel_size;
    }
    return *gain_;
  }

  ExplorerOptions options_;
  std::optional<ExplorationGain> gain_;
  double gain_voxel_size_ = 0;
};

}  // namespace

const std::vector<std::string>& strategyNames() {
  static const std::vector<std::string> names = {"none", "random", "local_exploration"};
  return names;
}

std::unique_ptr<GoalSelector> makeGoalSelector(const ExplorerOptions& o) {
  const auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  if (!positive(o.radius) || o.candidates < 1 || o.subsample < 1 || !(o.w_e >= 0) ||
      !(o.w_g >= 0) || !(o.p_goal >= 0 && o.p_goal <= 1) || !positive(o.min_clearance) ||
      o.max_draws < 1 || !o.flight_volume_min.allFinite() || !o.flight_volume_max.allFinite() ||
      !(o.flight_volume_min.array() < o.flight_volume_max.array()).all()) {
    throw std::invalid_argument("explorer: an option is out of range (see ExplorerOptions)");
  }
  if (o.strategy == "none") return std::make_unique<NoneSelector>();
  if (o.strategy == "random") return std::make_unique<RandomSelector>(o);
  if (o.strategy == "local_exploration") return std::make_unique<LocalExplorationSelector>(o);
  throw std::invalid_argument("explorer: unknown strategy '" + o.strategy + "'");
}

}  // namespace thicket::explorer

// The paper's strategy, local exploration: with probability P_g the global goal; else, of up to
// `candidates` random points within r of the start that the map has observed free (and, with
// `reachable`, that a straight line from the start reaches with clearance), the one that
// maximizes w_e * (unknown fraction of the view facing away from the start) + w_g * (progress
// toward the goal, normalized by the distance to it plus r).
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "strategies.h"
#include "thicket/common/random.h"

namespace thicket::explorer::detail {
namespace {

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
        options_.reachable ? treeClearance(options_, *maps.esdf, request.start) : std::nullopt;
    double best = -std::numeric_limits<double>::infinity();
    int candidates = 0;
    for (int draw = 0; draw < options_.max_draws && candidates < options_.candidates; ++draw) {
      const auto x = drawInBall(rng, request.start, options_.radius, options_, 1);
      if (!x || !observedFree(options_, maps, *x)) continue;
      if (line_clearance && !esdfSegmentFree(options_, *maps.esdf, request.start, *x,
                                             *line_clearance, 0.5 * maps.esdf->voxelSize())) {
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
  GainCache gains_{options_.gain};
};

}  // namespace

std::unique_ptr<GoalSelector> makeLocalExploration(const ExplorerOptions& options) {
  return std::make_unique<LocalExplorationSelector>(options);
}

}  // namespace thicket::explorer::detail

// Look-around: before a strategy answers a stuck request, the vehicle turns in place once per
// place toward the heading whose view holds the most visible unknown space; when the strategy then
// finds nothing there, it looks toward the best heading not looked at yet. A stuck planner
// otherwise hovers with its yaw held, so its next frame, map and optimization repeat the last.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "strategies.h"

namespace thicket::explorer::detail {
namespace {

class LookAroundSelector final : public GoalSelector {
 public:
  LookAroundSelector(const ExplorerOptions& options, std::unique_ptr<GoalSelector> strategy)
      : options_(options), strategy_(std::move(strategy)) {}
  const char* name() const override { return strategy_->name(); }
  void prepare(double voxel_size) override {
    gains_.forVoxelSize(voxel_size);
    strategy_->prepare(voxel_size);
  }

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    // Only looks of earlier cycles count: the same cycle asked again is answered the same.
    std::erase_if(looks_, [&](const Look& l) { return l.cycle >= request.cycle; });
    if (maps.tsdf == nullptr || maps.esdf == nullptr) return strategy_->select(request, maps);
    const bool here = std::any_of(looks_.begin(), looks_.end(), [&](const Look& l) {
      return (l.place - request.start).norm() <= options_.look_around.radius;
    });
    if (!here) {
      std::optional<Proposal> look = bestLook(request, *maps.tsdf);
      looks_.push_back(
          {request.start, look ? std::optional(look->yaws[0]) : std::nullopt, request.cycle});
      if (look) return *look;
    }
    Proposal proposal = strategy_->select(request, maps);
    if (proposal.found || proposal.map_missing || !here) return proposal;
    // The strategy has nothing: rather than hover, look where this place has not looked yet.
    std::optional<Proposal> look = bestLook(request, *maps.tsdf);
    if (!look) return proposal;
    looks_.push_back({request.start, look->yaws[0], request.cycle});
    look->reason += "; " + proposal.reason;
    look->gain_evaluations += proposal.gain_evaluations;
    return *look;
  }

 private:
  struct Look {
    Eigen::Vector3d place;
    std::optional<double> yaw;  // none: no heading was worth a look
    int64_t cycle;
  };

  // The heading, not yet looked at from this place, whose view holds the most visible unknown
  // space, weighted toward the goal (a third for the heading away from it); nothing when no view
  // reaches min_gain.
  std::optional<Proposal> bestLook(const ExplorationRequest& request, const TsdfLayer& tsdf) {
    const ExplorationGain& gain = gains_.forVoxelSize(tsdf.voxelSize());
    const int headings = options_.look_around.headings;
    const auto lookedAt = [&](double yaw) {
      return std::any_of(looks_.begin(), looks_.end(), [&](const Look& l) {
        return l.yaw && (l.place - request.start).norm() <= options_.look_around.radius &&
               std::abs(std::remainder(*l.yaw - yaw, 2 * M_PI)) < M_PI / headings;
      });
    };
    const Eigen::Vector3d to_goal = request.goal - request.start;
    Proposal look;
    double best = -1, best_yaw = 0, best_unknown = 0;
    for (int k = 0; k < headings; ++k) {
      const double yaw = std::remainder(2 * M_PI * k / headings, 2 * M_PI);
      if (lookedAt(yaw)) continue;
      const Gain g = gain.visibleUnknownFraction(
          tsdf, ExplorationGain::cameraAt(request.start, yaw), options_.look_around.subsample);
      ++look.gain_evaluations;
      if (g.unknown_fraction < options_.look_around.min_gain) continue;
      // Toward the goal counts fully, away from it a third.
      const double value =
          g.unknown_fraction * (2 + std::cos(yaw - std::atan2(to_goal.y(), to_goal.x()))) / 3;
      if (value > best) best = value, best_yaw = yaw, best_unknown = g.unknown_fraction;
    }
    if (best < 0) return std::nullopt;
    look.found = true;
    look.waypoints = {request.start};
    look.yaws = {best_yaw};
    look.score = best;
    char text[120];
    std::snprintf(text, sizeof(text),
                  "look around: heading %.2f rad sees %.0f %% unknown (best of %d)", best_yaw,
                  100 * best_unknown, static_cast<int>(look.gain_evaluations));
    look.reason = text;
    return look;
  }

  ExplorerOptions options_;
  std::unique_ptr<GoalSelector> strategy_;
  GainCache gains_{options_.gain};
  std::vector<Look> looks_;  // places answered with a look (or found not worth one)
};

}  // namespace

std::unique_ptr<GoalSelector> lookAround(const ExplorerOptions& options,
                                         std::unique_ptr<GoalSelector> strategy) {
  return std::make_unique<LookAroundSelector>(options, std::move(strategy));
}

}  // namespace thicket::explorer::detail

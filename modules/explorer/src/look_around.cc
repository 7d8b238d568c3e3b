// Look-around: before a strategy answers a stuck request, the vehicle turns in place once per
// place toward the heading whose view holds the most visible unknown space. A stuck planner
// otherwise hovers with its yaw held, so its next frame, map and optimization repeat the last.
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

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    if (maps.tsdf != nullptr && maps.esdf != nullptr && !lookedAt(request.start)) {
      looked_.push_back(request.start);
      if (std::optional<Proposal> look = bestLook(request.start, *maps.tsdf)) return *look;
    }
    return strategy_->select(request, maps);
  }

 private:
  bool lookedAt(const Eigen::Vector3d& place) const {
    for (const Eigen::Vector3d& p : looked_) {
      if ((p - place).norm() <= options_.look_around.radius) return true;
    }
    return false;
  }

  std::optional<Proposal> bestLook(const Eigen::Vector3d& start, const TsdfLayer& tsdf) {
    const ExplorationGain& gain = gains_.forVoxelSize(tsdf.voxelSize());
    const int headings = options_.look_around.headings;
    Proposal look;
    double best = -1, best_yaw = 0;
    for (int k = 0; k < headings; ++k) {
      const double yaw = std::remainder(2 * M_PI * k / headings, 2 * M_PI);
      const Gain g = gain.visibleUnknownFraction(tsdf, ExplorationGain::cameraAt(start, yaw),
                                                 options_.subsample);
      ++look.gain_evaluations;
      if (g.unknown_fraction > best) best = g.unknown_fraction, best_yaw = yaw;
    }
    if (best < options_.look_around.min_gain) return std::nullopt;
    look.found = true;
    look.waypoints = {start};
    look.yaws = {best_yaw};
    look.score = best;
    char text[120];
    std::snprintf(text, sizeof(text),
                  "look around: heading %.2f rad sees %.0f %% unknown (best of %d)", best_yaw,
                  100 * best, headings);
    look.reason = text;
    return look;
  }

  ExplorerOptions options_;
  std::unique_ptr<GoalSelector> strategy_;
  GainCache gains_{options_.gain};
  std::vector<Eigen::Vector3d> looked_;  // places answered with a look (or found not worth one)
};

}  // namespace

std::unique_ptr<GoalSelector> lookAround(const ExplorerOptions& options,
                                         std::unique_ptr<GoalSelector> strategy) {
  return std::make_unique<LookAroundSelector>(options, std::move(strategy));
}

}  // namespace thicket::explorer::detail

#include "thicket/local_planner/stop.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "thicket/local_planner/spline.h"

namespace thicket::local_planner {
namespace {

// The minimum-jerk stop from `start` taking `duration` seconds.
PolynomialTrajectory stopOf(int64_t utime, const TrajectoryState& start, double duration) {
  const JerkSpline spline({duration}, /*free_end_position=*/true);
  SplineEnds ends;
  ends.start_position = start.position;
  ends.start_velocity = start.velocity;
  ends.start_acceleration = start.acceleration;
  const Derivatives fixed = spline.fixedDerivatives(ends);
  auto trajectory =
      PolynomialTrajectory::create(utime, spline.segments(fixed, spline.minimumJerkStop(fixed)));
  if (!trajectory) throw std::logic_error("planStop: " + trajectory.error());
  return *trajectory;
}

// The minimum-jerk flight from `start` to rest at `end` taking `duration` seconds.
PolynomialTrajectory flightOf(int64_t utime, const TrajectoryState& start,
                              const Eigen::Vector3d& end, double duration) {
  const JerkSpline spline({duration}, /*free_end_position=*/false);
  SplineEnds ends;
  ends.start_position = start.position;
  ends.start_velocity = start.velocity;
  ends.start_acceleration = start.acceleration;
  ends.end_position = end;
  const Derivatives fixed = spline.fixedDerivatives(ends);
  auto trajectory = PolynomialTrajectory::create(
      utime, spline.segments(fixed, spline.minimumJerkFree(fixed, end)));
  if (!trajectory) throw std::logic_error("planRetreat: " + trajectory.error());
  return *trajectory;
}

bool withinLimits(const PolynomialTrajectory& trajectory, const LocoOptions& options) {
  constexpr double kLimitDt = 0.01;
  return trajectory.maxSpeed(kLimitDt) <= options.v_max + 1e-6 &&
         trajectory.maxAcceleration(kLimitDt) <= options.a_max + 1e-6;
}

// Stops are tried at durations growing by this factor, from kShortest up to kLongest [s].
constexpr double kGrowth = 1.15;
constexpr double kShortest = 0.1;
constexpr double kLongest = 8.0;
// How many durations from the shortest within the limits may be tried for a certified one.
constexpr int kCandidates = 8;

}  // namespace

Stop planStop(int64_t utime, const TrajectoryState& start, const DistanceField& field,
              const LocoOptions& options) {
  if (!start.position.allFinite() || !start.velocity.allFinite() ||
      !start.acceleration.allFinite()) {
    throw std::invalid_argument("planStop: the start state must be finite");
  }
  // The shortest duration within the limits (a start above them never gets there: the longest).
  double duration = kShortest;
  while (duration < kLongest && !withinLimits(stopOf(utime, start, duration), options)) {
    duration *= kGrowth;
  }
  const double required = options.requiredClearance();
  std::optional<Stop> hardest;
  for (int i = 0; i < kCandidates; ++i, duration *= kGrowth) {
    Stop stop{stopOf(utime, start, duration), false, 0};
    stop.distance = (stop.trajectory.evaluate(duration) - start.position).norm();
    stop.certified = checkClearance(stop.trajectory, 0, field, required).clear;
    if (stop.certified) return stop;
    if (!hardest) hardest = stop;
  }
  return *hardest;
}

std::optional<Retreat> planRetreat(int64_t utime, const TrajectoryState& start,
                                   const DistanceField& field, const LocoOptions& options,
                                   double beyond) {
  if (!start.position.allFinite() || !start.velocity.allFinite() ||
      !start.acceleration.allFinite()) {
    throw std::invalid_argument("planRetreat: the start state must be finite");
  }
  if (!(std::isfinite(beyond) && beyond > 0)) {
    throw std::invalid_argument("planRetreat: beyond must be finite and positive");
  }
  constexpr double kStep = 0.05;     // [m]
  constexpr int kSteps = 20;         // at most 1 m
  constexpr double kMinGain = 0.02;  // a partial way out gains at least this clearance [m]
  const double required = options.requiredClearance();
  const EsdfSample at = field(start.position);
  if (!at.known || at.distance >= required + beyond) return std::nullopt;
  // What every point of the way out must keep: the acceptance's threshold for this start.
  const double keep = std::min(required, at.distance - options.escape_slack);
  // The way out along each of the 26 directions to the neighbours of a cube, over the points
  // every 5 cm that are known and keep `keep`: the first `beyond` outside the margin; else
  // (a pinch wider than 1 m, where no way reaches it) the one farthest from obstacles.
  struct Exit {
    int steps;
    double distance;
    Eigen::Vector3d end;
  };
  std::vector<Exit> exits, partial;
  for (int i = 0; i < 27; ++i) {
    const Eigen::Vector3d direction(i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1);
    if (direction.isZero()) continue;
    std::optional<Exit> best;
    for (int k = 1; k <= kSteps; ++k) {
      const Eigen::Vector3d p = start.position + k * kStep * direction.normalized();
      const EsdfSample here = field(p);
      if (!here.known || here.distance < keep) break;
      if (!best || here.distance > best->distance) best = Exit{k, here.distance, p};
      if (here.distance >= required + beyond) {
        exits.push_back(*best);
        best.reset();
        break;
      }
    }
    if (best && best->distance >= at.distance + kMinGain) partial.push_back(*best);
  }
  // The shortest first, the farthest from obstacles among equals (then in the order of the
  // directions); without any, the partial ways farthest from obstacles first. The first whose
  // minimum-jerk flight to rest keeps the limits and passes the acceptance is flown.
  std::stable_sort(exits.begin(), exits.end(), [](const Exit& a, const Exit& b) {
    return a.steps < b.steps || (a.steps == b.steps && a.distance > b.distance);
  });
  std::stable_sort(partial.begin(), partial.end(),
                   [](const Exit& a, const Exit& b) { return a.distance > b.distance; });
  if (exits.empty()) exits = std::move(partial);
  for (const auto& [steps, distance, end] : exits) {
    double duration =
        std::max(kShortest, velocityRampTime(steps * kStep, options.v_max, options.a_max));
    while (duration < kLongest && !withinLimits(flightOf(utime, start, end, duration), options)) {
      duration *= kGrowth;
    }
    PolynomialTrajectory flight = flightOf(utime, start, end, duration);
    if (!withinLimits(flight, options) ||
        !checkClearance(flight, 0, field, required, options.escape_slack).clear) {
      continue;
    }
    return Retreat{std::move(flight), at.distance, distance};
  }
  return std::nullopt;
}

}  // namespace thicket::local_planner

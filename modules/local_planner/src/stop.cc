#include "thicket/local_planner/stop.h"

#include <optional>
#include <stdexcept>
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

}  // namespace thicket::local_planner

// A piecewise-polynomial 3D position trajectory: what the local planner commits and the simulator
// executes. Segments follow each other in time, each a polynomial in its own local time, so that
// evaluation stays well conditioned however long the trajectory is.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <thicket/polynomial_trajectory_t.hpp>

#include "thicket/common/expected.h"

namespace thicket {

/// One polynomial piece. Row a holds axis a (x, y, z); column k is the coefficient of tau^k, with
/// tau the local time in [0, duration] seconds.
struct PolynomialSegment {
  double duration = 0;
  Eigen::Matrix<double, 3, Eigen::Dynamic> coefficients;
};

/// Position and its first three derivatives at one instant.
struct TrajectoryState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  Eigen::Vector3d jerk = Eigen::Vector3d::Zero();
};

/// A validated piecewise-polynomial trajectory starting at an absolute time. Times `t` are seconds
/// since the start. Continuity between segments is the producer's business (the planner guarantees
/// it); maxDiscontinuity() lets callers check it.
class PolynomialTrajectory {
 public:
  /// Refuses an empty segment list, non-finite or non-positive durations, non-finite coefficients,
  /// and segments that do not all have the same (non-zero) number of coefficients.
  static Expected<PolynomialTrajectory> create(int64_t start_utime,
                                               std::vector<PolynomialSegment> segments);

  /// Holds `position` for `duration` seconds. Throws std::invalid_argument on a non-finite position
  /// or a duration that is not finite and positive.
  static PolynomialTrajectory hover(int64_t start_utime, const Eigen::Vector3d& position,
                                    double duration);

  /// Validates everything a received (or hand-built) message can get wrong, including the yaw
  /// metadata that the trajectory itself does not keep.
  static Expected<PolynomialTrajectory> fromLcm(const polynomial_trajectory_t& msg);

  /// The message for this trajectory; cycle, goal id and yaw are message metadata. Throws
  /// std::invalid_argument on an unknown yaw policy or a non-finite yaw.
  polynomial_trajectory_t toLcm(int64_t cycle, int64_t goal_id,
                                int8_t yaw_policy = polynomial_trajectory_t::YAW_ALONG_VELOCITY,
                                double yaw = 0) const;

  int64_t startUtime() const { return start_utime_; }
  /// Sum of the segment durations [s].
  double duration() const { return segment_starts_.back(); }
  int numSegments() const { return static_cast<int>(segments_.size()); }
  int numCoefficients() const { return static_cast<int>(segments_.front().coefficients.cols()); }
  const std::vector<PolynomialSegment>& segments() const { return segments_; }

  /// The `derivative`-th time derivative (0 = position) at t. At a segment boundary the later
  /// segment is used. Before the start: the state at t = 0. After the end the vehicle holds the
  /// final position at rest, so every derivative >= 1 is zero. Throws std::invalid_argument on a
  /// negative derivative or a NaN t.
  Eigen::Vector3d evaluate(double t, int derivative = 0) const;

  TrajectoryState state(double t) const;
  TrajectoryState stateAtUtime(int64_t utime) const;

  /// States at t0, t0 + dt, t0 + 2 dt, ... and always at exactly t1 last (not repeated when t1 is
  /// on the grid within 1e-9 s). Throws std::invalid_argument unless dt > 0 and t0 <= t1, all
  /// finite.
  std::vector<std::pair<double, TrajectoryState>> sample(double dt, double t0, double t1) const;
  /// Samples the whole trajectory, [0, duration()].
  std::vector<std::pair<double, TrajectoryState>> sample(double dt) const;

  /// Largest speed and acceleration norm over samples every dt (for v_max / a_max checks).
  double maxSpeed(double dt) const;
  double maxAcceleration(double dt) const;

  /// Largest jump of the given derivative between the end of one segment and the start of the
  /// next (0 for a single segment).
  double maxDiscontinuity(int derivative) const;

 private:
  PolynomialTrajectory(int64_t start_utime, std::vector<PolynomialSegment> segments);

  int64_t start_utime_;
  std::vector<PolynomialSegment> segments_;
  /// segment_starts_[i] is when segment i starts; the last entry is the total duration.
  std::vector<double> segment_starts_;
};

}  // namespace thicket

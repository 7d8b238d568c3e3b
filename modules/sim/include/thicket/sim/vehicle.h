// The simulated vehicle: executes the committed trajectory perfectly, one replan period per
// cycle, and checks every executed sample against the ground truth. It also keeps the mission's
// books (path length, clearance, limits, outcome) for the benchmark's per-trial metrics.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <thicket/polynomial_trajectory_t.hpp>

#include "thicket/common/params.h"
#include "thicket/common/polynomial_trajectory.h"
#include "thicket/sim/ground_truth.h"

namespace thicket::sim {

struct VehicleOptions {
  double replan_period = 1.0;    // simulated seconds executed per cycle [s]
  double sample_period = 0.01;   // executed path sampling, for checks and metrics [s]
  int replan_limit = 120;        // cycles before the mission ends unfinished
  double goal_tolerance = 0.2;   // the goal is reached within this distance [m]
  double max_start_lag = 2.0;    // a trajectory may start at most this long before now [s]
  double max_start_lead = 0.05;  // ... and at most this long after now [s]
  double v_max = 1.0;            // limits checked on the executed path (+0.01 slack) [m/s]
  double a_max = 2.0;            // [m/s^2]
  double max_yaw_rate = 3.0;     // the attitude controller turns no faster than this [rad/s]

  void declare(Params& p);
};

/// One executed sample.
struct PathSample {
  int64_t utime = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  double yaw = 0;
  double clearance = 0;  // ground-truth distance to the nearest obstacle surface [m]
};

enum class Outcome { kRunning, kGoalReached, kReplanLimit, kCollision };
const char* outcomeName(Outcome outcome);

/// What happened during one step.
struct StepReport {
  std::vector<PathSample> samples;      // from just after the previous step's end to now
  std::optional<PathSample> collision;  // the first sample below the robot radius, if any
  Outcome outcome = Outcome::kRunning;
};

class Vehicle {
 public:
  /// Keeps a reference to `truth`, which may be reassigned (SimNode adds an obstacle that way):
  /// samples after that see the new world. Starts at rest at the world's start, yaw facing the
  /// goal, at utime `start_utime`.
  Vehicle(const GroundTruth& truth, VehicleOptions options, int64_t start_utime = 0);

  /// Commits a trajectory received at the current time. Refuses malformed ones (see
  /// PolynomialTrajectory::fromLcm) and start times outside [now - max_start_lag,
  /// now + max_start_lead]; on refusal the previous trajectory stays committed.
  std::optional<std::string> commit(const polynomial_trajectory_t& msg);

  /// Executes one replan period of the committed trajectory (holding position when there is
  /// none, and at rest at its end after it ends) and advances the cycle count. Yaw turns toward
  /// the trajectory's yaw (YAW_CONSTANT) or its velocity (YAW_ALONG_VELOCITY, held when nearly at
  /// rest), no faster than max_yaw_rate, as a real attitude controller would.
  StepReport step();

  int64_t utime() const { return utime_; }
  int cycle() const { return cycle_; }
  const PathSample& state() const { return state_; }
  Outcome outcome() const { return outcome_; }
  bool hasTrajectory() const { return trajectory_.has_value(); }
  /// The committed trajectory, nullptr before the first one.
  const PolynomialTrajectory* trajectory() const { return trajectory_ ? &*trajectory_ : nullptr; }

  // Mission metrics (docs/benchmark.md).
  double pathLength() const { return path_length_; }
  double minClearance() const { return min_clearance_; }
  double maxSpeed() const { return max_speed_; }
  double maxAcceleration() const { return max_acceleration_; }
  bool feasible() const;
  double distanceToGoal() const;
  const std::vector<PathSample>& path() const { return path_; }

 private:
  PathSample sampleAt(int64_t utime, const PathSample& previous) const;

  const GroundTruth& truth_;
  VehicleOptions options_;
  std::optional<PolynomialTrajectory> trajectory_;
  int8_t yaw_policy_ = polynomial_trajectory_t::YAW_ALONG_VELOCITY;
  double trajectory_yaw_ = 0;  ///< with YAW_CONSTANT
  Eigen::Vector3d hold_position_;
  int64_t utime_;
  int cycle_ = 0;
  PathSample state_;
  Outcome outcome_ = Outcome::kRunning;
  std::vector<PathSample> path_;
  double path_length_ = 0;
  double min_clearance_;
  double max_speed_ = 0;
  double max_acceleration_ = 0;
};

}  // namespace thicket::sim

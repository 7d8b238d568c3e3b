// Odometry from the simulated vehicle: the ground truth (SIM_TRUTH) and a VIO-like estimate
// (VIO_ODOMETRY) with an optional seeded drift and noise model, off by default.
#pragma once

#include <cstdint>
#include <random>

#include <Eigen/Core>
#include <thicket/odometry_t.hpp>

#include "thicket/common/params.h"
#include "thicket/sim/vehicle.h"

namespace thicket::sim {

struct OdometryNoiseOptions {
  double position_noise = 0;  // white noise on each position axis, per message [m]
  double position_drift = 0;  // random-walk drift of the position per axis [m/sqrt(s)]
  double yaw_drift = 0;       // random-walk drift of the yaw [rad/sqrt(s)]
  int64_t seed = 1;           // the same seed and path give the same estimates
  bool enabled() const { return position_noise > 0 || position_drift > 0 || yaw_drift > 0; }
  void declare(Params& p);
};

class OdometrySimulator {
 public:
  explicit OdometrySimulator(OdometryNoiseOptions options = {});

  /// The true state as an odometry message. Roll and pitch are zero (the vehicle model tracks
  /// position and yaw); the yaw rate is the finite difference to the previous sample given.
  static odometry_t truth(const PathSample& sample, const PathSample& previous, int64_t sequence);

  /// A VIO-like estimate of the same state: the drift advances with the time since the previous
  /// call (samples must come in increasing utime), then white noise is added. Without noise the
  /// estimate equals the truth. The drift is applied in the world frame around the start, like a
  /// VIO whose frame slowly rotates and shifts.
  odometry_t estimate(const PathSample& sample, const PathSample& previous, int64_t sequence);

 private:
  double gaussian();

  OdometryNoiseOptions options_;
  std::mt19937_64 rng_;
  Eigen::Vector3d position_drift_ = Eigen::Vector3d::Zero();
  double yaw_drift_ = 0;
  int64_t last_utime_ = INT64_MIN;
};

}  // namespace thicket::sim

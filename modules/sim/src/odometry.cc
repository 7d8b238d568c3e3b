#include "thicket/sim/odometry.h"

#include <cmath>
#include <stdexcept>

#include "thicket/common/geometry.h"
#include "thicket/common/time.h"

namespace thicket::sim {

void OdometryNoiseOptions::declare(Params& p) {
  p("position_noise", position_noise, "white noise per position axis [m]", Range::atLeast(0));
  p("position_drift", position_drift, "position random walk per axis [m/sqrt(s)]",
    Range::atLeast(0));
  p("yaw_drift", yaw_drift, "yaw random walk [rad/sqrt(s)]", Range::atLeast(0));
  p("seed", seed, "seed of the noise generator");
}

OdometrySimulator::OdometrySimulator(OdometryNoiseOptions options)
    : options_(options), rng_(static_cast<uint64_t>(options.seed)) {
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("odometry noise: " + error);
  }
}

// Box-Muller on uniforms made from raw 64-bit outputs: std::normal_distribution is not the same
// on every standard library, this is.
double OdometrySimulator::gaussian() {
  const double u1 = (static_cast<double>(rng_() >> 11) + 1.0) * 0x1.0p-53;  // (0, 1]
  const double u2 = static_cast<double>(rng_() >> 11) * 0x1.0p-53;          // [0, 1)
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

odometry_t OdometrySimulator::truth(const PathSample& sample, const PathSample& previous,
                                    int64_t sequence) {
  odometry_t msg{};
  msg.utime = sample.utime;
  msg.sequence = sequence;
  poseToArrays(Pose::fromYaw(sample.position, sample.yaw), msg.position, msg.orientation);
  for (int i = 0; i < 3; ++i) msg.linear_velocity[i] = sample.velocity[i];
  const double dt = toSeconds(sample.utime - previous.utime);
  msg.angular_velocity[2] = dt > 0 ? wrapAngle(sample.yaw - previous.yaw) / dt : 0.0;
  msg.quality = odometry_t::QUALITY_GOOD;
  msg.flags = odometry_t::FLAG_NONE;
  return msg;
}

odometry_t OdometrySimulator::estimate(const PathSample& sample, const PathSample& previous,
                                       int64_t sequence) {
  odometry_t msg = truth(sample, previous, sequence);
  if (!options_.enabled()) return msg;
  if (last_utime_ != INT64_MIN) {
    if (sample.utime <= last_utime_) {
      throw std::invalid_argument("odometry samples must come in increasing utime");
    }
    const double root_dt = std::sqrt(toSeconds(sample.utime - last_utime_));
    for (int i = 0; i < 3; ++i)
      position_drift_[i] += options_.position_drift * root_dt * gaussian();
    yaw_drift_ += options_.yaw_drift * root_dt * gaussian();
  }
  last_utime_ = sample.utime;
  // The estimate lives in a drifted frame: rotated by the yaw drift about the start of the
  // mission (the origin here) and shifted by the position drift.
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(yaw_drift_, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Vector3d position = rotation * sample.position + position_drift_;
  for (int i = 0; i < 3; ++i) position[i] += options_.position_noise * gaussian();
  poseToArrays(Pose::fromYaw(position, sample.yaw + yaw_drift_), msg.position, msg.orientation);
  const Eigen::Vector3d velocity = rotation * sample.velocity;
  for (int i = 0; i < 3; ++i) msg.linear_velocity[i] = velocity[i];
  return msg;
}

}  // namespace thicket::sim

// Simulated odometry: the truth is exact, the VIO-like estimate equals it without noise and
// drifts like a random walk of the configured size with it, reproducibly per seed.
#include <gtest/gtest.h>

#include <cmath>

#include "thicket/common/geometry.h"
#include "thicket/sim/odometry.h"

namespace thicket::sim {
namespace {

PathSample sampleAt(double t) {
  PathSample sample;
  sample.utime = static_cast<int64_t>(std::llround(t * 1e6));
  sample.position = Eigen::Vector3d(1 + 0.5 * t, 2, 1.5);
  sample.velocity = Eigen::Vector3d(0.5, 0, 0);
  sample.yaw = 0.1 * t;
  return sample;
}

TEST(Odometry, TruthCarriesTheExactState) {
  const odometry_t msg = OdometrySimulator::truth(sampleAt(2.0), sampleAt(1.9), 7);
  EXPECT_EQ(msg.utime, 2'000'000);
  EXPECT_EQ(msg.sequence, 7);
  EXPECT_DOUBLE_EQ(msg.position[0], 2.0);
  auto pose = poseFromArrays(msg.position, msg.orientation);
  ASSERT_TRUE(pose) << pose.error();
  EXPECT_NEAR(pose->yaw(), 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(msg.linear_velocity[0], 0.5);
  EXPECT_NEAR(msg.angular_velocity[2], 0.1, 1e-9);  // yaw rate by finite difference
  EXPECT_EQ(msg.quality, +odometry_t::QUALITY_GOOD);
}

TEST(Odometry, EstimateWithoutNoiseIsTheTruth) {
  OdometrySimulator simulator;
  for (int i = 1; i < 10; ++i) {
    const odometry_t truth = OdometrySimulator::truth(sampleAt(i), sampleAt(i - 1), i);
    const odometry_t estimate = simulator.estimate(sampleAt(i), sampleAt(i - 1), i);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(estimate.position[k], truth.position[k]);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(estimate.orientation[k], truth.orientation[k]);
  }
}

// Drift after T seconds is a sum of independent steps: its spread over many runs is
// position_drift * sqrt(T) per axis.
TEST(Odometry, DriftGrowsLikeARandomWalkAndIsReproducible) {
  OdometryNoiseOptions options;
  options.position_drift = 0.05;
  constexpr int kRuns = 400;
  constexpr double kDuration = 25.0;
  double sum_squares = 0;
  std::vector<double> first_run;
  for (int run = 0; run < kRuns; ++run) {
    options.seed = 1000 + run;
    OdometrySimulator simulator(options);
    odometry_t last{};
    for (int i = 0; i <= 50; ++i) {
      const double t = kDuration * i / 50.0;
      last = simulator.estimate(sampleAt(t), sampleAt(std::max(0.0, t - 0.5)), i);
      if (run == 0) first_run.push_back(last.position[1]);
    }
    const double error = last.position[1] - 2.0;
    sum_squares += error * error;
  }
  const double spread = std::sqrt(sum_squares / kRuns);
  EXPECT_NEAR(spread, 0.05 * std::sqrt(kDuration), 0.25 * 0.05 * std::sqrt(kDuration));

  options.seed = 1000;
  OdometrySimulator again(options);
  for (int i = 0; i <= 50; ++i) {
    const double t = kDuration * i / 50.0;
    EXPECT_EQ(again.estimate(sampleAt(t), sampleAt(std::max(0.0, t - 0.5)), i).position[1],
              first_run[static_cast<size_t>(i)]);
  }
}

TEST(Odometry, YawDriftRotatesTheEstimate) {
  OdometryNoiseOptions options;
  options.yaw_drift = 0.02;
  options.seed = 5;
  OdometrySimulator simulator(options);
  double max_yaw_error = 0;
  for (int i = 0; i <= 100; ++i) {
    const odometry_t msg = simulator.estimate(sampleAt(i), sampleAt(std::max(0, i - 1)), i);
    auto pose = poseFromArrays(msg.position, msg.orientation);
    ASSERT_TRUE(pose);
    max_yaw_error = std::max(max_yaw_error, std::abs(wrapAngle(pose->yaw() - 0.1 * i)));
  }
  EXPECT_GT(max_yaw_error, 0.01);
  EXPECT_LT(max_yaw_error, 0.5);
}

TEST(Odometry, RefusesBadOptionsAndTimeGoingBackwards) {
  OdometryNoiseOptions bad;
  bad.position_noise = -1;
  EXPECT_THROW(OdometrySimulator{bad}, std::invalid_argument);
  OdometryNoiseOptions options;
  options.position_noise = 0.01;
  OdometrySimulator simulator(options);
  simulator.estimate(sampleAt(2), sampleAt(1), 0);
  EXPECT_THROW(simulator.estimate(sampleAt(2), sampleAt(1), 1), std::invalid_argument);
}

}  // namespace
}  // namespace thicket::sim

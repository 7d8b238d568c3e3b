#include "thicket/common/geometry.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace thicket {
namespace {

using std::numbers::pi;
using Status = PoseLookup::Status;

Pose randomPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> position(-10.0, 10.0);
  std::normal_distribution<double> gaussian;
  // A normalized 4D Gaussian is a uniformly distributed rotation.
  const Eigen::Quaterniond q(gaussian(rng), gaussian(rng), gaussian(rng), gaussian(rng));
  return Pose{Eigen::Vector3d(position(rng), position(rng), position(rng)), q.normalized()};
}

void expectPoseNear(const Pose& actual, const Pose& expected, double tolerance = 1e-9) {
  EXPECT_LT((actual.position - expected.position).norm(), tolerance)
      << actual.position.transpose() << " vs " << expected.position.transpose();
  EXPECT_LT(actual.orientation.angularDistance(expected.orientation), tolerance)
      << actual.orientation.coeffs().transpose() << " vs "
      << expected.orientation.coeffs().transpose();
}

TEST(Pose, CompositionAndInverseIdentities) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> coordinate(-5.0, 5.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Pose a = randomPose(rng), b = randomPose(rng), c = randomPose(rng);
    const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
    expectPoseNear(a * a.inverse(), Pose{});
    expectPoseNear(a.inverse() * a, Pose{});
    expectPoseNear((a * b) * c, a * (b * c));
    expectPoseNear((a * b).inverse(), b.inverse() * a.inverse());
    EXPECT_LT(((a * b).transform(p) - a.transform(b.transform(p))).norm(), 1e-9);
    EXPECT_LT((a.inverse().transform(a.transform(p)) - p).norm(), 1e-9);
    EXPECT_LT((a.isometry() * p - a.transform(p)).norm(), 1e-9);
  }
}

TEST(Pose, TransformRotatesThenTranslates) {
  const Pose pose = Pose::fromYaw(Eigen::Vector3d(1.0, 2.0, 3.0), pi / 2);
  // Facing world +y, the body's forward axis is world +y and its left axis world -x.
  EXPECT_LT((pose.transform(Eigen::Vector3d::UnitX()) - Eigen::Vector3d(1.0, 3.0, 3.0)).norm(),
            1e-12);
  EXPECT_LT((pose.transform(Eigen::Vector3d::UnitY()) - Eigen::Vector3d(0.0, 2.0, 3.0)).norm(),
            1e-12);
}

TEST(Pose, YawRoundTripsThroughFromYaw) {
  for (double yaw = -pi; yaw <= pi; yaw += pi / 16) {
    const double recovered = Pose::fromYaw(Eigen::Vector3d::Zero(), yaw).yaw();
    EXPECT_GT(recovered, -pi);
    EXPECT_LE(recovered, pi);
    EXPECT_NEAR(wrapAngle(recovered - yaw), 0.0, 1e-12) << "yaw " << yaw;
  }
  // Both ends of the range name the same heading and come back as +pi.
  EXPECT_DOUBLE_EQ(Pose::fromYaw(Eigen::Vector3d::Zero(), pi).yaw(), pi);
  EXPECT_DOUBLE_EQ(Pose::fromYaw(Eigen::Vector3d::Zero(), -pi).yaw(), pi);
}

TEST(Pose, YawIgnoresRollAndModeratePitch) {
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitX()));
  const Pose pose{Eigen::Vector3d::Zero(),
                  Pose::fromYaw(Eigen::Vector3d::Zero(), 2.0).orientation * tilt};
  EXPECT_NEAR(pose.yaw(), 2.0, 1e-12);
}

TEST(WrapAngle, MapsIntoHalfOpenRange) {
  EXPECT_DOUBLE_EQ(wrapAngle(0.0), 0.0);
  EXPECT_DOUBLE_EQ(wrapAngle(pi), pi);
  EXPECT_DOUBLE_EQ(wrapAngle(-pi), pi);
  EXPECT_NEAR(wrapAngle(3 * pi), pi, 1e-12);
  EXPECT_NEAR(wrapAngle(2 * pi + 0.1), 0.1, 1e-12);
  EXPECT_NEAR(wrapAngle(-0.1), -0.1, 1e-15);
  EXPECT_NEAR(wrapAngle(-1.5 * pi), 0.5 * pi, 1e-12);
  EXPECT_NEAR(wrapAngle(-pi + 1e-9), -pi + 1e-9, 1e-15);
}

TEST(Interpolate, HalfwayBetweenYawsIsMidpointAndHalfAngle) {
  const Pose a = Pose::fromYaw(Eigen::Vector3d(0.0, 0.0, 1.0), 0.0);
  const Pose b = Pose::fromYaw(Eigen::Vector3d(2.0, 4.0, 1.0), pi / 2);
  const Pose half = interpolate(a, b, 0.5);
  EXPECT_LT((half.position - Eigen::Vector3d(1.0, 2.0, 1.0)).norm(), 1e-12);
  EXPECT_NEAR(half.yaw(), pi / 4, 1e-12);
  expectPoseNear(interpolate(a, b, 0.0), a);
  expectPoseNear(interpolate(a, b, 1.0), b);
}

TEST(Interpolate, SlerpTakesTheShorterArc) {
  const Pose a = Pose::fromYaw(Eigen::Vector3d::Zero(), 0.0);
  const Pose b = Pose::fromYaw(Eigen::Vector3d::Zero(), pi / 2);
  // -q is the same rotation as q; interpolating toward it must not go the long way round (-135°).
  const Pose b_negated{b.position, Eigen::Quaterniond(-b.orientation.coeffs())};
  EXPECT_NEAR(interpolate(a, b_negated, 0.5).yaw(), pi / 4, 1e-12);
  EXPECT_NEAR(interpolate(a, b_negated, 0.25).yaw(), pi / 8, 1e-12);
}

TEST(Interpolate, RefusesAlphaOutsideUnitInterval) {
  const Pose a, b;
  EXPECT_THROW(interpolate(a, b, -0.01), std::invalid_argument);
  EXPECT_THROW(interpolate(a, b, 1.01), std::invalid_argument);
  EXPECT_THROW(interpolate(a, b, std::nan("")), std::invalid_argument);
}

TEST(PoseArrays, RefuseNonFiniteValues) {
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  const double good_position[3] = {1.0, 2.0, 3.0};
  const double good_orientation[4] = {1.0, 0.0, 0.0, 0.0};
  const double nan_position[3] = {1.0, nan, 3.0};
  const double inf_orientation[4] = {1.0, 0.0, inf, 0.0};
  const auto nan_result = poseFromArrays(nan_position, good_orientation);
  ASSERT_FALSE(nan_result.ok());
  EXPECT_NE(nan_result.error().find("position"), std::string::npos) << nan_result.error();
  const auto inf_result = poseFromArrays(good_position, inf_orientation);
  ASSERT_FALSE(inf_result.ok());
  EXPECT_NE(inf_result.error().find("quaternion"), std::string::npos) << inf_result.error();
}

TEST(PoseArrays, RefuseNonUnitQuaternionAndSayTheNorm) {
  const double position[3] = {0.0, 0.0, 0.0};
  const double short_quaternion[4] = {0.9, 0.0, 0.0, 0.0};
  const auto result = poseFromArrays(position, short_quaternion);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().find("norm 0.9 "), std::string::npos) << result.error();
  EXPECT_TRUE(poseFromArrays(position, short_quaternion, 0.2).ok());
}

TEST(PoseArrays, RenormalizeNearlyUnitQuaternion) {
  const double position[3] = {1.0, 2.0, 3.0};
  const double s = 1.0005 / std::sqrt(2.0);
  const double nearly_unit[4] = {s, 0.0, 0.0, s};  // norm 1.0005, yaw 90°
  const auto result = poseFromArrays(position, nearly_unit);
  ASSERT_TRUE(result.ok()) << result.error();
  EXPECT_NEAR(result->orientation.norm(), 1.0, 1e-15);
  EXPECT_NEAR(result->yaw(), pi / 2, 1e-12);
  EXPECT_EQ(result->position, Eigen::Vector3d(1.0, 2.0, 3.0));
}

TEST(PoseArrays, RoundTripInWxyzOrder) {
  const Pose pose = Pose::fromYaw(Eigen::Vector3d(4.0, 5.0, 6.0), pi / 2);
  double position[3], orientation[4];
  poseToArrays(pose, position, orientation);
  EXPECT_EQ(position[0], 4.0);
  EXPECT_EQ(position[2], 6.0);
  EXPECT_NEAR(orientation[0], std::cos(pi / 4), 1e-15);  // w first
  EXPECT_NEAR(orientation[3], std::sin(pi / 4), 1e-15);  // z last
  const auto back = poseFromArrays(position, orientation);
  ASSERT_TRUE(back.ok()) << back.error();
  expectPoseNear(*back, pose, 1e-15);
}

// Poses at 1.0 s and 1.1 s, 100 ms apart: within the default interpolation gap.
PoseHistory twoPoseHistory(PoseHistoryOptions options = {}) {
  PoseHistory history(options);
  EXPECT_EQ(history.add(1'000'000, Pose::fromYaw(Eigen::Vector3d(0.0, 0.0, 0.0), 0.0)).verdict,
            Timeline::Verdict::kAccepted);
  EXPECT_EQ(history.add(1'100'000, Pose::fromYaw(Eigen::Vector3d(1.0, 2.0, 3.0), pi / 2)).verdict,
            Timeline::Verdict::kAccepted);
  return history;
}

TEST(PoseHistory, EmptyHistoryAnswersEmpty) {
  PoseHistory history;
  EXPECT_TRUE(history.empty());
  EXPECT_FALSE(history.newestUtime().has_value());
  EXPECT_FALSE(history.oldestUtime().has_value());
  const PoseLookup lookup = history.lookup(1'000'000);
  EXPECT_EQ(lookup.status, Status::kEmpty);
  EXPECT_FALSE(lookup.reason.empty());
}

TEST(PoseHistory, ExactHitReturnsStoredPose) {
  const PoseHistory history = twoPoseHistory();
  const PoseLookup lookup = history.lookup(1'100'000);
  ASSERT_TRUE(lookup.ok()) << lookup.reason;
  EXPECT_TRUE(lookup.reason.empty());
  expectPoseNear(lookup.pose, Pose::fromYaw(Eigen::Vector3d(1.0, 2.0, 3.0), pi / 2), 1e-15);
}

TEST(PoseHistory, InterpolatesBetweenBracketingPoses) {
  const PoseHistory history = twoPoseHistory();
  const PoseLookup lookup = history.lookup(1'025'000);  // a quarter of the way
  ASSERT_TRUE(lookup.ok()) << lookup.reason;
  EXPECT_LT((lookup.pose.position - Eigen::Vector3d(0.25, 0.5, 0.75)).norm(), 1e-12);
  EXPECT_NEAR(lookup.pose.yaw(), pi / 8, 1e-12);
}

TEST(PoseHistory, NewerThanNewestIsNotYet) {
  const PoseLookup lookup = twoPoseHistory().lookup(1'100'001);
  EXPECT_EQ(lookup.status, Status::kNotYet);
  EXPECT_NE(lookup.reason.find("1.100000 s"), std::string::npos) << lookup.reason;
}

TEST(PoseHistory, OlderThanOldestIsTooOld) {
  const PoseLookup lookup = twoPoseHistory().lookup(999'999);
  EXPECT_EQ(lookup.status, Status::kTooOld);
  EXPECT_NE(lookup.reason.find("1.000000 s"), std::string::npos) << lookup.reason;
}

TEST(PoseHistory, WideGapIsRefusedAndGapAtTheLimitInterpolates) {
  const PoseHistory too_wide = twoPoseHistory({.max_interpolation_gap_us = 99'999});
  const PoseLookup refused = too_wide.lookup(1'050'000);
  EXPECT_EQ(refused.status, Status::kGap);
  EXPECT_FALSE(refused.reason.empty());
  EXPECT_TRUE(too_wide.lookup(1'000'000).ok());  // the stored poses themselves remain answerable
  EXPECT_TRUE(twoPoseHistory({.max_interpolation_gap_us = 100'000}).lookup(1'050'000).ok());
}

TEST(PoseHistory, ToleranceAnswersNearEndsWithTheNearestPose) {
  const PoseHistory history = twoPoseHistory({.tolerance_us = 5'000});
  const Pose oldest = Pose::fromYaw(Eigen::Vector3d::Zero(), 0.0);
  const Pose newest = Pose::fromYaw(Eigen::Vector3d(1.0, 2.0, 3.0), pi / 2);
  const PoseLookup after_newest = history.lookup(1'105'000);
  ASSERT_TRUE(after_newest.ok()) << after_newest.reason;
  expectPoseNear(after_newest.pose, newest, 1e-15);
  const PoseLookup before_oldest = history.lookup(995'000);
  ASSERT_TRUE(before_oldest.ok()) << before_oldest.reason;
  expectPoseNear(before_oldest.pose, oldest, 1e-15);
  EXPECT_EQ(history.lookup(1'105'001).status, Status::kNotYet);
  EXPECT_EQ(history.lookup(994'999).status, Status::kTooOld);
}

TEST(PoseHistory, ToleranceAnswersInsideGapWithTheNearestPose) {
  const PoseHistory history =
      twoPoseHistory({.max_interpolation_gap_us = 50'000, .tolerance_us = 5'000});
  const PoseLookup near_oldest = history.lookup(1'004'000);
  ASSERT_TRUE(near_oldest.ok()) << near_oldest.reason;
  expectPoseNear(near_oldest.pose, Pose::fromYaw(Eigen::Vector3d::Zero(), 0.0), 1e-15);
  EXPECT_EQ(history.lookup(1'050'000).status, Status::kGap);
}

TEST(PoseHistory, RefusesTimeGoingBackwardsAndDuplicatesWithoutChange) {
  PoseHistory history = twoPoseHistory();
  const auto backwards = history.add(1'050'000, Pose{});
  ASSERT_FALSE(backwards.accepted());
  EXPECT_EQ(
      backwards.reason,
      "pose at 1.050000 s refused: utime 1.050000 s is before the previous pose's 1.100000 s");
  const auto duplicate = history.add(1'100'000, Pose{});
  ASSERT_FALSE(duplicate.accepted());
  EXPECT_NE(duplicate.reason.find("repeats"), std::string::npos) << duplicate.reason;

  EXPECT_EQ(history.size(), 2u);
  EXPECT_EQ(history.newestUtime(), 1'100'000);
  expectPoseNear(history.lookup(1'100'000).pose,
                 Pose::fromYaw(Eigen::Vector3d(1.0, 2.0, 3.0), pi / 2), 1e-15);
  EXPECT_NEAR(history.lookup(1'050'000).pose.yaw(), pi / 4, 1e-12);
}

TEST(PoseHistory, RefusesNonFiniteAndNonUnitPoses) {
  PoseHistory history = twoPoseHistory();
  Pose nan_pose;
  nan_pose.position.y() = std::nan("");
  const auto nan_error = history.add(1'200'000, nan_pose);
  ASSERT_FALSE(nan_error.accepted());
  EXPECT_NE(nan_error.reason.find("not finite"), std::string::npos) << nan_error.reason;
  const Pose scaled{Eigen::Vector3d::Zero(), Eigen::Quaterniond(1.1, 0.0, 0.0, 0.0)};
  EXPECT_FALSE(history.add(1'200'000, scaled).accepted());
  // Finite but absurd: 1e18 m would overflow voxel indices in the mapper.
  const auto far = history.add(1'200'000, Pose::fromYaw(Eigen::Vector3d(1e18, 0.0, 0.0), 0.0));
  ASSERT_FALSE(far.accepted());
  EXPECT_NE(far.reason.find("is beyond +-1000"), std::string::npos) << far.reason;
  EXPECT_EQ(history.size(), 2u);
  EXPECT_EQ(history.newestUtime(), 1'100'000);
}

TEST(PoseHistory, DropsPosesOlderThanMaxAge) {
  PoseHistory history({.max_age_us = 1'000'000});
  for (int64_t utime = 0; utime <= 3'000'000; utime += 100'000) {
    ASSERT_TRUE(history.add(utime, Pose::fromYaw(Eigen::Vector3d::Zero(), 0.0)).accepted());
  }
  EXPECT_EQ(history.size(), 11u);  // 2.0 s through 3.0 s
  EXPECT_EQ(history.oldestUtime(), 2'000'000);
  EXPECT_EQ(history.newestUtime(), 3'000'000);
  EXPECT_EQ(history.lookup(1'950'000).status, Status::kTooOld);
  EXPECT_TRUE(history.lookup(2'050'000).ok());
}

// One pose stamped 11 days ahead (a corrupt estimate) made every later pose "not after the
// newest", for good. Now ten consecutive earlier poses start a new timeline.
TEST(PoseHistory, AFarFuturePoseCostsAtMostTenRefusalsThenTheHistoryReanchors) {
  PoseHistory history;
  const auto at = [](int64_t utime) {
    return Pose::fromYaw(Eigen::Vector3d(toSeconds(utime), 0.0, 0.0), 0.0);
  };
  for (int64_t t = 0; t <= 1'000'000; t += 50'000) ASSERT_TRUE(history.add(t, at(t)).accepted());
  ASSERT_TRUE(history.add(1'000'000'000'000, at(0)).accepted());
  int refused = 0;
  for (int64_t t = 1'050'000;; t += 50'000) {
    const Timeline::Result result = history.add(t, at(t));
    if (result.verdict == Timeline::Verdict::kReanchored) {
      EXPECT_NE(result.reason.find("clock reset: 10 consecutive poses before the previous "
                                   "timeline's 1000000.000000 s; re-anchored at 1.500000 s"),
                std::string::npos)
          << result.reason;
      break;
    }
    ASSERT_FALSE(result.accepted()) << t;
    ASSERT_LT(++refused, 10);
  }
  EXPECT_EQ(refused, 9);
  EXPECT_EQ(history.size(), 1u);  // the old timeline is gone
  EXPECT_EQ(history.newestUtime(), 1'500'000);
  EXPECT_EQ(history.lookup(1'000'000).status, Status::kTooOld);
  ASSERT_TRUE(history.add(1'550'000, at(1'550'000)).accepted());
  ASSERT_TRUE(history.lookup(1'525'000).ok());
  EXPECT_NEAR(history.lookup(1'525'000).pose.position.x(), 1.525, 1e-12);
}

TEST(PoseHistory, StampsThatAreNoTimeAreRefusedWithoutArithmetic) {
  PoseHistory history = twoPoseHistory();
  for (const int64_t utime : {INT64_MIN, int64_t{-1}, kMaxUtime + 1, INT64_MAX}) {
    const auto result = history.add(utime, Pose{});
    ASSERT_FALSE(result.accepted());
    EXPECT_NE(result.reason.find("not a time"), std::string::npos) << result.reason;
    EXPECT_EQ(history.lookup(utime).status, Status::kTooOld);
  }
  EXPECT_EQ(history.size(), 2u);
}

}  // namespace
}  // namespace thicket

// The VIO bridge's gate: each check with the quality, flags and reason it produces, the estimates
// it drops, how it re-anchors after a jump, and that good data after a bad estimate is accepted
// again. Identity frames throughout, so the outputs can be compared with the inputs directly.
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include <thicket/odometry_t.hpp>

#include "thicket/vio_bridge/vio_bridge.h"

namespace thicket::vio_bridge {
namespace {

constexpr int64_t kStep = 50'000;  // 20 Hz, as the simulator publishes [µs]

// The vehicle flying along x at 1 m/s, level, facing +x; sample k at k · 50 ms.
odometry_t estimate(int64_t k, double x_offset = 0) {
  odometry_t m{};
  m.utime = 1'000'000 + k * kStep;
  m.sequence = k;
  m.position[0] = 0.05 * static_cast<double>(k) + x_offset;
  m.position[2] = 1.5;
  m.orientation[0] = 1;
  m.linear_velocity[0] = 1;
  return m;
}

odometry_t withYaw(odometry_t m, double yaw) {
  m.orientation[0] = std::cos(yaw / 2);
  m.orientation[3] = std::sin(yaw / 2);
  return m;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

int bitOf(int32_t flag) {
  int bit = 0;
  while ((1 << bit) != flag) ++bit;
  return bit;
}

void expectGood(const GateResult& r) {
  EXPECT_TRUE(r.publish) << r.reason;
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_GOOD) << r.reason;
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_NONE) << r.reason;
  EXPECT_EQ(r.estimate.reason, "");
  EXPECT_EQ(r.reason, "good");
}

TEST(Gate, PassesAGoodStreamThroughUnchanged) {
  VioBridge bridge{VioBridgeOptions{}};
  for (int64_t k = 0; k < 20; ++k) {
    const GateResult r = bridge.process(estimate(k));
    expectGood(r);
    EXPECT_EQ(r.estimate.utime, estimate(k).utime);
    EXPECT_EQ(r.estimate.position[0], estimate(k).position[0]);
  }
  EXPECT_EQ(bridge.health().received, 20);
  EXPECT_EQ(bridge.health().published, 20);
  EXPECT_EQ(bridge.health().published_by_quality[0], 20);
  EXPECT_EQ(bridge.health().dropped, 0);
  EXPECT_EQ(bridge.health().last_reason, "");
}

TEST(Gate, DropsNonFiniteValuesAnywhereAndAcceptsGoodDataAfter) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  odometry_t nan_position = estimate(1);
  nan_position.position[1] = std::numeric_limits<double>::quiet_NaN();
  GateResult r = bridge.process(nan_position);
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_NOT_FINITE);
  EXPECT_TRUE(contains(r.reason, "position[1]")) << r.reason;
  EXPECT_TRUE(contains(r.reason, "dropped")) << r.reason;
  // A far-future stamp on a non-finite estimate must not become the reference.
  odometry_t inf_covariance = estimate(400);
  inf_covariance.twist_covariance[20] = std::numeric_limits<double>::infinity();
  r = bridge.process(inf_covariance);
  EXPECT_FALSE(r.publish);
  EXPECT_TRUE(contains(r.reason, "twist_covariance[20]")) << r.reason;
  expectGood(bridge.process(estimate(2)));
  EXPECT_EQ(bridge.health().dropped, 2);
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_NOT_FINITE)], 2);
  EXPECT_EQ(bridge.health().published, 2);
  EXPECT_TRUE(contains(bridge.health().last_reason, "twist_covariance"));
}

TEST(Gate, RenormalizesASlightlyOffQuaternionAndFlagsIt) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  // Within the tolerance (1e-3): renormalized silently.
  odometry_t close = estimate(1);
  close.orientation[0] = 1.0005;
  GateResult r = bridge.process(close);
  expectGood(r);
  EXPECT_DOUBLE_EQ(r.estimate.orientation[0], 1.0);
  // Beyond it: renormalized and degraded.
  odometry_t off = withYaw(estimate(2), 0.1);
  for (double& q : off.orientation) q *= 1.02;
  r = bridge.process(off);
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_DEGRADED);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_QUATERNION_NOT_UNIT);
  EXPECT_TRUE(contains(r.estimate.reason, "renormalized")) << r.estimate.reason;
  EXPECT_EQ(r.reason, r.estimate.reason);
  EXPECT_NEAR(r.estimate.orientation[0], std::cos(0.05), 1e-12);
  EXPECT_NEAR(r.estimate.orientation[3], std::sin(0.05), 1e-12);
  expectGood(bridge.process(withYaw(estimate(3), 0.1)));
  EXPECT_EQ(bridge.health().flagged[bitOf(odometry_t::FLAG_QUATERNION_NOT_UNIT)], 1);
}

TEST(Gate, DropsAQuaternionFarFromUnit) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  odometry_t far = estimate(1);
  far.orientation[0] = 1.2;
  GateResult r = bridge.process(far);
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_QUATERNION_NOT_UNIT);
  EXPECT_TRUE(contains(r.reason, "too far from 1")) << r.reason;
  odometry_t zero = estimate(2);
  zero.orientation[0] = 0;
  EXPECT_FALSE(bridge.process(zero).publish);
  expectGood(bridge.process(estimate(3)));
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_QUATERNION_NOT_UNIT)], 2);
}

TEST(Gate, DropsEstimatesWhoseTimeDoesNotAdvance) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  expectGood(bridge.process(estimate(5)));
  GateResult r = bridge.process(estimate(5));
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_TIME_BACKWARDS);
  EXPECT_TRUE(contains(r.reason, "repeats")) << r.reason;
  r = bridge.process(estimate(3));
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_TIME_BACKWARDS);
  EXPECT_TRUE(contains(r.reason, "before")) << r.reason;
  EXPECT_TRUE(contains(r.reason, "1.250000 s")) << r.reason;  // the previous estimate's utime
  expectGood(bridge.process(estimate(6)));
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_TIME_BACKWARDS)], 2);
}

TEST(Gate, ReAnchorsOnAClockResetAfterEnoughConsecutiveEarlierEstimates) {
  VioBridgeOptions options;
  options.clock_reset_after = 3;
  VioBridge bridge{options};
  for (int64_t k = 100; k < 110; ++k) expectGood(bridge.process(estimate(k)));
  // The VIO restarts: a new timeline from k = 0, far from where the old one ended.
  EXPECT_FALSE(bridge.process(estimate(0)).publish);
  EXPECT_FALSE(bridge.process(estimate(1)).publish);
  GateResult r = bridge.process(estimate(2));
  ASSERT_TRUE(r.publish) << r.reason;
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_TIME_BACKWARDS);  // no jump against the old one
  EXPECT_TRUE(contains(r.reason, "clock reset: 3 consecutive estimates")) << r.reason;
  EXPECT_TRUE(contains(r.reason, "re-anchored at 1.100000 s")) << r.reason;
  expectGood(bridge.process(estimate(3)));
  EXPECT_EQ(bridge.health().clock_resets, 1);
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_TIME_BACKWARDS)], 2);
  EXPECT_TRUE(contains(bridge.health().summary(), "clock resets 1")) << bridge.health().summary();
}

TEST(Gate, OutOfOrderEstimatesAreNotAClockReset) {
  VioBridgeOptions options;
  options.clock_reset_after = 3;
  VioBridge bridge{options};
  expectGood(bridge.process(estimate(10)));
  // Late, shuffled or repeated estimates: never three earlier ones in increasing order.
  for (int64_t k : {5, 4, 6, 3, 10, 2, 1, 10, 7, 5}) {
    EXPECT_FALSE(bridge.process(estimate(k)).publish) << k;
  }
  // A run broken by an accepted estimate starts again from zero.
  EXPECT_FALSE(bridge.process(estimate(0)).publish);
  EXPECT_FALSE(bridge.process(estimate(1)).publish);
  expectGood(bridge.process(estimate(11)));
  EXPECT_FALSE(bridge.process(estimate(2)).publish);
  EXPECT_FALSE(bridge.process(estimate(3)).publish);
  EXPECT_EQ(bridge.health().clock_resets, 0);

  options.clock_reset_after = 0;  // never re-anchor
  VioBridge strict{options};
  expectGood(strict.process(estimate(100)));
  for (int64_t k = 0; k < 50; ++k) EXPECT_FALSE(strict.process(estimate(k)).publish);
  EXPECT_EQ(strict.health().clock_resets, 0);
}

TEST(Gate, FlagsAPositionJumpLostAndReAnchorsOnIt) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  expectGood(bridge.process(estimate(1)));
  // 0.6 m in 50 ms: under max_position_step (1 m) but beyond 10 m/s · 0.05 s + 0.05 m = 0.55 m.
  GateResult r = bridge.process(estimate(2, 0.55));
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_POSITION_JUMP);
  EXPECT_TRUE(contains(r.estimate.reason, "position jumped 0.600 m")) << r.estimate.reason;
  // The next estimate continues from the jumped one: the VIO reset once, and is trusted again.
  expectGood(bridge.process(estimate(3, 0.55)));
  // A just-allowed step: 0.5 m + 0.05 m slack in 50 ms.
  expectGood(bridge.process(estimate(4, 1.0)));
  // The absolute bound: 1.2 m over 0.4 s is slower than max_speed but longer than 1 m.
  r = bridge.process(estimate(12, 1.0 + 0.8));
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_POSITION_JUMP);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  expectGood(bridge.process(estimate(13, 1.8)));
  EXPECT_EQ(bridge.health().flagged[bitOf(odometry_t::FLAG_POSITION_JUMP)], 2);
  EXPECT_EQ(bridge.health().published_by_quality[odometry_t::QUALITY_LOST], 2);
}

TEST(Gate, FlagsAnOrientationJumpButNotAFastTurn) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  // 0.3 rad in 50 ms (6 rad/s + slack allows 0.32 rad): a fast turn.
  expectGood(bridge.process(withYaw(estimate(1), 0.3)));
  // A quarter turn in 50 ms.
  GateResult r = bridge.process(withYaw(estimate(2), 0.3 + M_PI / 2));
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_ORIENTATION_JUMP);
  EXPECT_TRUE(contains(r.estimate.reason, "orientation jumped 1.571 rad")) << r.estimate.reason;
  expectGood(bridge.process(withYaw(estimate(3), 0.3 + M_PI / 2)));
  EXPECT_EQ(bridge.health().flagged[bitOf(odometry_t::FLAG_ORIENTATION_JUMP)], 1);
}

TEST(Gate, FlagsTheFirstEstimateAfterAGapStale) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  expectGood(bridge.process(estimate(10)));  // 0.5 s: exactly the max gap, not stale
  GateResult r = bridge.process(estimate(30));
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_DEGRADED);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_STALE);
  EXPECT_TRUE(contains(r.estimate.reason, "resumed after 1.000 s")) << r.estimate.reason;
  expectGood(bridge.process(estimate(31)));
  EXPECT_EQ(bridge.health().flagged[bitOf(odometry_t::FLAG_STALE)], 1);
}

TEST(Gate, DroppedEstimatesCountTowardsTheGap) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  for (int64_t k = 1; k < 20; ++k) {
    odometry_t bad = estimate(k);
    bad.linear_velocity[0] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(bridge.process(bad).publish);
  }
  const GateResult r = bridge.process(estimate(20));
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_STALE);
  EXPECT_TRUE(contains(r.estimate.reason, "resumed after 1.000 s")) << r.estimate.reason;
}

TEST(Gate, KeepsWhatTheEstimatorReportsAndRaisesItsQualityOnly) {
  VioBridge bridge{VioBridgeOptions{}};
  expectGood(bridge.process(estimate(0)));
  odometry_t degraded = estimate(1);
  degraded.quality = odometry_t::QUALITY_DEGRADED;
  degraded.flags = odometry_t::FLAG_STALE;
  degraded.reason = "few features tracked";
  GateResult r = bridge.process(degraded);
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_DEGRADED);
  EXPECT_EQ(r.estimate.flags, int32_t{odometry_t::FLAG_SOURCE_REPORTED} | odometry_t::FLAG_STALE);
  EXPECT_TRUE(contains(r.estimate.reason, "few features tracked")) << r.estimate.reason;
  // The bridge's own verdict wins when it is worse: a jump on a degraded estimate is lost.
  degraded = estimate(2, 3.0);
  degraded.quality = odometry_t::QUALITY_DEGRADED;
  degraded.reason = "few features tracked";
  r = bridge.process(degraded);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(r.estimate.flags,
            int32_t{odometry_t::FLAG_SOURCE_REPORTED} | odometry_t::FLAG_POSITION_JUMP);
  // The estimator's worse verdict wins too.
  odometry_t lost = estimate(3, 3.0);
  lost.quality = odometry_t::QUALITY_LOST;
  r = bridge.process(lost);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_TRUE(contains(r.estimate.reason, "lost")) << r.estimate.reason;
  // A quality outside QUALITY_* counts as lost.
  odometry_t unknown = estimate(4, 3.0);
  unknown.quality = 7;
  r = bridge.process(unknown);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_TRUE(contains(r.estimate.reason, "unknown quality 7")) << r.estimate.reason;
  // Flags and a reason on a GOOD estimate explain nothing and are not passed on.
  odometry_t good = estimate(5, 3.0);
  good.flags = odometry_t::FLAG_STALE;
  good.reason = "stale reason";
  expectGood(bridge.process(good));
  EXPECT_EQ(bridge.health().flagged[bitOf(odometry_t::FLAG_SOURCE_REPORTED)], 4);
}

TEST(Gate, DropModesDropAndAnnounceTheDiscontinuityOnTheNextEstimate) {
  VioBridgeOptions options;
  options.on_position_jump = "drop";
  options.on_source_not_good = "drop";
  VioBridge bridge{options};
  expectGood(bridge.process(estimate(0)));
  GateResult r = bridge.process(estimate(1, 2.0));
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_POSITION_JUMP);
  EXPECT_TRUE(contains(r.reason, "dropped: position jumped")) << r.reason;
  // Re-anchored on the dropped jump; the next estimate tells the consumers what happened.
  r = bridge.process(estimate(2, 2.0));
  EXPECT_TRUE(r.publish);
  EXPECT_EQ(r.estimate.quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(r.estimate.flags, +odometry_t::FLAG_POSITION_JUMP);
  EXPECT_TRUE(contains(r.estimate.reason, "after an estimate dropped at 1.050000 s"))
      << r.estimate.reason;
  expectGood(bridge.process(estimate(3, 2.0)));
  odometry_t lost = estimate(4, 2.0);
  lost.quality = odometry_t::QUALITY_LOST;
  r = bridge.process(lost);
  EXPECT_FALSE(r.publish);
  EXPECT_EQ(r.flags, +odometry_t::FLAG_SOURCE_REPORTED);
  // Not a discontinuity: nothing carried.
  expectGood(bridge.process(estimate(5, 2.0)));
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_POSITION_JUMP)], 1);
  EXPECT_EQ(bridge.health().dropped_by_flag[bitOf(odometry_t::FLAG_SOURCE_REPORTED)], 1);
  EXPECT_EQ(bridge.health().dropped, 2);
}

TEST(Gate, HealthSummaryCountsEveryKind) {
  VioBridge bridge{VioBridgeOptions{}};
  bridge.process(estimate(0));
  odometry_t nan = estimate(1);
  nan.position[0] = std::numeric_limits<double>::quiet_NaN();
  bridge.process(nan);
  bridge.process(estimate(2, 5.0));
  bridge.process(estimate(13, 5.0));  // 0.55 s later, 0.55 m on: stale only
  const std::string summary = bridge.health().summary();
  EXPECT_EQ(summary,
            "4 estimates in, 3 published (1 good, 1 degraded, 1 lost), 1 dropped (not_finite 1); "
            "flagged: position_jump 1, stale 1; last problem at 1.650000 s: resumed after 0.550 s "
            "without an estimate (max gap 0.5 s)");
  EXPECT_EQ(describeFlags(int32_t{odometry_t::FLAG_STALE} | odometry_t::FLAG_NOT_FINITE),
            "not_finite+stale");
  EXPECT_EQ(describeFlags(0), "none");
}

TEST(Gate, RefusesInconsistentOptions) {
  VioBridgeOptions options;
  options.quaternion_max_error = 1e-4;  // below the tolerance
  EXPECT_THROW(VioBridge{options}, std::invalid_argument);
  options = {};
  options.max_gap = 0;
  EXPECT_THROW(VioBridge{options}, std::invalid_argument);
  options = {};
  options.on_stale = "ignore";
  EXPECT_THROW(VioBridge{options}, std::invalid_argument);
  options = {};
  options.clock_reset_after = -1;
  EXPECT_THROW(VioBridge{options}, std::invalid_argument);
}

}  // namespace
}  // namespace thicket::vio_bridge

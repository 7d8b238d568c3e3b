#include "thicket/common/time.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <gtest/gtest.h>

namespace thicket {
namespace {

TEST(Time, ToSecondsIsConstexpr) {
  static_assert(toSeconds(kMicrosPerSecond) == 1.0);
  EXPECT_DOUBLE_EQ(toSeconds(250), 250e-6);
  EXPECT_DOUBLE_EQ(toSeconds(-1'500'000), -1.5);
}

TEST(Time, SecondsToUtimeRoundsToNearestMicrosecond) {
  EXPECT_EQ(secondsToUtime(1.5), 1'500'000);
  EXPECT_EQ(secondsToUtime(0.0000004), 0);
  EXPECT_EQ(secondsToUtime(0.0000006), 1);
  EXPECT_EQ(secondsToUtime(-0.0000006), -1);
  EXPECT_EQ(secondsToUtime(0.1), 100'000);  // 0.1 is not exact in binary; rounding hides that
  EXPECT_EQ(secondsToUtime(1.7e9), 1'700'000'000'000'000);
}

TEST(Time, SecondsToUtimeRefusesUnrepresentableInput) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(secondsToUtime(std::nan("")), std::invalid_argument);
  EXPECT_THROW(secondsToUtime(inf), std::invalid_argument);
  EXPECT_THROW(secondsToUtime(-inf), std::invalid_argument);
  EXPECT_THROW(secondsToUtime(1e13), std::invalid_argument);  // 1e19 µs > INT64_MAX
  EXPECT_THROW(secondsToUtime(-1e13), std::invalid_argument);
  EXPECT_NO_THROW(secondsToUtime(9e12));
}

TEST(Time, FormatUtimePrintsSecondsWithSixDecimals) {
  EXPECT_EQ(formatUtime(12'000'250), "12.000250 s");
  EXPECT_EQ(formatUtime(0), "0.000000 s");
  EXPECT_EQ(formatUtime(-250), "-0.000250 s");
  EXPECT_EQ(formatUtime(-3'000'001), "-3.000001 s");
  EXPECT_EQ(formatUtime(std::numeric_limits<int64_t>::max()), "9223372036854.775807 s");
  EXPECT_EQ(formatUtime(std::numeric_limits<int64_t>::min()), "-9223372036854.775808 s");
}

TEST(Timeline, AcceptsIncreasingStampsAndRefusesRepeatsAndEarlierOnes) {
  Timeline timeline("frame");
  EXPECT_FALSE(timeline.last().has_value());
  EXPECT_EQ(timeline.offer(0).verdict, Timeline::Verdict::kAccepted);
  EXPECT_EQ(timeline.offer(100).verdict, Timeline::Verdict::kAccepted);
  EXPECT_EQ(timeline.offer(100).reason, "utime 0.000100 s repeats the previous frame's 0.000100 s");
  EXPECT_EQ(timeline.offer(50).reason,
            "utime 0.000050 s is before the previous frame's 0.000100 s");
  EXPECT_EQ(timeline.last(), 100);
  EXPECT_EQ(timeline.offer(-1).reason, "frame utime -1 us is outside [0, 2^62] us: not a time");
  EXPECT_FALSE(timeline.offer(kMaxUtime + 1).accepted());
  EXPECT_EQ(timeline.last(), 100);
}

TEST(Timeline, ARunOfIncreasingEarlierStampsReanchorsAndOthersRestartTheCount) {
  Timeline timeline("pose", 3);
  ASSERT_TRUE(timeline.offer(1'000).accepted());
  EXPECT_FALSE(timeline.offer(10).accepted());             // run 1
  EXPECT_FALSE(timeline.offer(20).accepted());             // run 2
  EXPECT_FALSE(timeline.offer(15).accepted());             // not after the run's last: run 1 again
  EXPECT_FALSE(timeline.offer(1'000).accepted());          // a repeat ends the run
  EXPECT_FALSE(timeline.offer(30).accepted());             // run 1
  EXPECT_FALSE(timeline.offer(40).accepted());             // run 2
  const Timeline::Result reanchored = timeline.offer(50);  // run 3
  EXPECT_EQ(reanchored.verdict, Timeline::Verdict::kReanchored);
  EXPECT_EQ(reanchored.reason,
            "clock reset: 3 consecutive poses before the previous timeline's 0.001000 s; "
            "re-anchored at 0.000050 s");
  EXPECT_EQ(timeline.last(), 50);
  EXPECT_EQ(timeline.reanchors(), 1);
  EXPECT_EQ(timeline.offer(60).verdict, Timeline::Verdict::kAccepted);

  Timeline never("pose", 0);
  ASSERT_TRUE(never.offer(1'000).accepted());
  for (int64_t t = 1; t < 100; ++t) ASSERT_FALSE(never.offer(t).accepted());
  EXPECT_THROW(Timeline("pose", -1), std::invalid_argument);
}

}  // namespace
}  // namespace thicket

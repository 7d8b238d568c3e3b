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

}  // namespace
}  // namespace thicket

// Time in thicket is `int64_t utime`, microseconds, as in every LCM message. Stamps stay integers
// so that they compare and sort exactly; doubles are only for arithmetic on durations.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace thicket {

inline constexpr int64_t kMicrosPerSecond = 1'000'000;

/// A utime difference in seconds.
constexpr double toSeconds(int64_t utime_delta) {
  return static_cast<double>(utime_delta) / static_cast<double>(kMicrosPerSecond);
}

/// Seconds to microseconds, rounded to the nearest microsecond. Throws std::invalid_argument for
/// NaN, infinities and values outside the int64 range.
inline int64_t secondsToUtime(double s) {
  const double micros = s * static_cast<double>(kMicrosPerSecond);
  const double two_to_63 = std::ldexp(1.0, 63);  // exactly representable, unlike INT64_MAX
  if (!(micros >= -two_to_63 && micros < two_to_63)) {
    throw std::invalid_argument("secondsToUtime: " + std::to_string(s) +
                                " s is not a finite time representable in int64 microseconds");
  }
  return std::llround(micros);
}

/// "12.000250 s", "-0.000250 s": seconds with all six microsecond digits.
inline std::string formatUtime(int64_t utime) {
  // Integer arithmetic, so that large stamps print exactly; unsigned so that INT64_MIN negates.
  const uint64_t magnitude =
      utime < 0 ? uint64_t{0} - static_cast<uint64_t>(utime) : static_cast<uint64_t>(utime);
  const auto per_second = static_cast<uint64_t>(kMicrosPerSecond);
  char text[32];
  std::snprintf(text, sizeof text, "%s%llu.%06llu s", utime < 0 ? "-" : "",
                static_cast<unsigned long long>(magnitude / per_second),
                static_cast<unsigned long long>(magnitude % per_second));
  return text;
}

}  // namespace thicket

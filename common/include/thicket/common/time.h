// Time in thicket is `int64_t utime`, microseconds, as in every LCM message. Stamps stay integers
// so that they compare and sort exactly; doubles are only for arithmetic on durations.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
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

/// The largest utime thicket accepts (2^62 us, some 146,000 years): differences of accepted
/// stamps cannot overflow int64.
inline constexpr int64_t kMaxUtime = int64_t{1} << 62;

/// Whether `utime` is a stamp thicket accepts: in [0, kMaxUtime].
inline bool isTime(int64_t utime) {
  return utime >= 0 && utime <= kMaxUtime;
}

/// The refusal of a stamp that is not one: "<what> utime <utime> us is outside [0, 2^62] us: not
/// a time".
std::string notATime(const std::string& what, int64_t utime);

/// The stamps of one input stream (poses, frames, estimates), which must increase, with a way
/// back from a bad one. A stamp not after the last accepted one is refused. But `reset_after`
/// consecutive refused stamps that increase among themselves mean that the stream's clock
/// restarted (a VIO restart, a looping log) or that the last accepted stamp was bad (one
/// far-future stamp would otherwise wedge the stream for good): the last of them is accepted and
/// starts a new timeline (kReanchored), and the caller drops what it holds of the old one. So a
/// single bad stamp costs at most `reset_after` refused inputs. Stamps outside [0, kMaxUtime] are
/// refused and do not count.
class Timeline {
 public:
  static constexpr int kDefaultResetAfter = 10;

  enum class Verdict { kAccepted, kRefused, kReanchored };
  struct Result {
    Verdict verdict = Verdict::kAccepted;
    std::string reason;  ///< why it was refused, or how it re-anchored; empty when accepted
    bool accepted() const { return verdict != Verdict::kRefused; }
  };

  /// `what` names one input in messages ("pose", "frame", "estimate"); `reset_after` 0 never
  /// re-anchors.
  explicit Timeline(std::string what, int reset_after = kDefaultResetAfter);

  Result offer(int64_t utime);
  /// The last accepted stamp.
  std::optional<int64_t> last() const { return last_; }
  int64_t reanchors() const { return reanchors_; }

 private:
  std::string what_;
  int reset_after_;
  std::optional<int64_t> last_;
  int run_ = 0;           // consecutive refused stamps before last_, each after the one before
  int64_t run_last_ = 0;  // the last of them
  int64_t reanchors_ = 0;
};

}  // namespace thicket

// `thicket-log summary`: what an LCM log holds, per channel (count, time span, rate, message
// sizes, the LCM type identified by its fingerprint) and in total.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::log {

/// "package.type" of the known LCM type (every thicket and procman_lcm type) whose fingerprint
/// this is, else "unknown 0x<16 hex digits>".
std::string typeNameOfFingerprint(uint64_t fingerprint);

struct TypeCount {
  std::string type;  ///< as typeNameOfFingerprint, or "unknown (no fingerprint)" under 8 bytes
  int64_t count = 0;
};

struct ChannelSummary {
  std::string channel;
  int64_t count = 0;
  int64_t first_utime = 0;  ///< log event timestamps (receive time) [µs]
  int64_t last_utime = 0;
  int64_t total_bytes = 0;  ///< message payloads
  int64_t max_bytes = 0;
  std::vector<TypeCount> types;  ///< most frequent first; more than one means a mixed channel
  int64_t decode_failures = 0;   ///< messages of a known type that did not decode as it
  std::string first_decode_error;

  double durationSeconds() const {
    return 1e-6 * (static_cast<double>(last_utime) - static_cast<double>(first_utime));
  }
  /// Messages per second over the channel's span, (count - 1) / duration; 0 when undefined
  /// (fewer than two messages or no time between them).
  double rateHz() const;
  double meanBytes() const;
  /// types joined by " + ".
  std::string typeText() const;
};

struct LogSummary {
  std::string path;
  int64_t file_bytes = 0;
  std::vector<ChannelSummary> channels;  ///< sorted by name
  int64_t events = 0;
  int64_t bytes = 0;  ///< message payloads
  int64_t first_utime = 0;
  int64_t last_utime = 0;
  /// Why reading stopped before the end of the file (a torn or corrupt log); empty when whole.
  std::string error;
  std::vector<std::string> warnings;  ///< e.g. timestamps going backwards

  double spanSeconds() const {
    return 1e-6 * (static_cast<double>(last_utime) - static_cast<double>(first_utime));
  }
};

/// Reads the whole log. The error is for a file that cannot be opened; a damaged log gives the
/// summary of what could be read, with `error` set.
Expected<LogSummary> summarizeLog(const std::string& path);

/// A table for people.
std::string summaryText(const LogSummary& summary);
/// The same as one JSON object (times in µs as integers, durations in s, rates in Hz).
std::string summaryJson(const LogSummary& summary);

}  // namespace thicket::log

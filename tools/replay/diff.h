// Comparing recorded and replayed messages field by field, decoded with the schema of
// lcmtypes/*.lcm, and the readable diff thicket-replay prints:
//
//   PLANNER_STATUS: recorded 45 messages, replayed 45, 1 differs
//   PLANNER_STATUS message 7 of 45 (utime 6000000): cost_total: recorded 12.5 replayed 12.75
//
// Everything is compared exactly (floating point bitwise) except the fields of excludedFields().
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "thicket/common/lcm_schema.h"

namespace thicket::replay {

/// A field that is never compared, with the reason.
struct ExcludedField {
  const char* type;   ///< "package.type"
  const char* field;  ///< a field of that type, wherever the type appears
  const char* why;
};
/// Wall-clock measurements: what a replay cannot reproduce, by design (docs/design.md §2).
const std::vector<ExcludedField>& excludedFields();

struct FieldDifference {
  std::string path;  ///< e.g. "segments[2].coefficients[5]"
  std::string recorded;
  std::string replayed;
};

/// The differences between two decoded messages of the same type, excluded fields skipped: the
/// first `keep` in `kept`; returns how many there are in all.
size_t diffMessages(const LcmValue& recorded, const LcmValue& replayed, size_t keep,
                    std::vector<FieldDifference>& kept);

/// One channel's encoded messages, in order.
using ChannelMessages = std::map<std::string, std::vector<std::vector<uint8_t>>>;

struct ChannelComparison {
  std::string channel;
  size_t recorded = 0;
  size_t replayed = 0;
  size_t differing = 0;  ///< pairs (same index) that differ
  bool equal() const { return recorded == replayed && differing == 0; }
};

struct Comparison {
  std::vector<ChannelComparison> channels;  ///< every channel of either side, by name
  /// The differences as printed, at most the limit given to compareChannels.
  std::vector<std::string> lines;
  size_t differences = 0;  ///< field differences in all (printed or not)
  bool equal() const;
  /// The count lines of the channels that differ, then `lines`, then how many were left out.
  std::string text() const;
};

/// Compares each channel's replayed messages with the recorded ones, pair by pair in order.
/// Messages that do not decode (a damaged log) are differences, never a crash.
Comparison compareChannels(const LcmTypeSet& types, const ChannelMessages& recorded,
                           const ChannelMessages& replayed, size_t max_lines);

}  // namespace thicket::replay

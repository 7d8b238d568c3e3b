// thicket-replay's commands: recording a simulated flight as a reference log, replaying a log
// into the real nodes and comparing their outputs with the recorded ones, and the table of the
// reference flights kept in logs/ (regenerated with `thicket-replay record-references`).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "diff.h"
#include "thicket/common/lcm_schema.h"
#include "replay.h"
#include "thicket/common/expected.h"
#include "thicket/common/lcm_log.h"

namespace thicket::replay {

/// One simulated flight flown like a trial of `thicket-bench run` (depth sensor, soft goal).
struct FlightSpec {
  std::string scenario = "paper";
  double density = 0;
  int64_t seed = 0;
  std::string method = "none";
  int replans = 60;
  bool dynamic_obstacle = false;  ///< the simulator's dynamic obstacle (benchmark E6)
};

/// A reference log: logs/<name>.lcmlog.ref, and what its flight exercises.
struct ReferenceFlight {
  std::string name;
  FlightSpec flight;
  std::string exercises;
};
const std::vector<ReferenceFlight>& referenceFlights();
/// The reference whose log `path` is (by file name), or nullptr.
const ReferenceFlight* findReference(const std::string& path);
/// logs/<name>.lcmlog.ref under `logs_dir`.
std::string referencePath(const std::string& logs_dir, const ReferenceFlight& reference);

/// Size limits of the reference logs (logs/README.md).
inline constexpr int64_t kMaxReferenceBytes = 5'000'000;
inline constexpr int64_t kMaxReferencesBytes = 20'000'000;

/// The channels a recording keeps: every input and output of the replayed modules, the world
/// (for the replay's options) and the simulator's events (for `thicket-log mission`). The
/// simulator's ground truth is left out to keep the logs small.
std::string recordedChannelsRegex();

/// Why `flight` cannot be flown (an unknown scenario or method, a bad number), or nothing.
std::optional<std::string> validateFlight(const FlightSpec& flight);

struct RecordSummary {
  int64_t events = 0;
  int64_t bytes = 0;  ///< the file
  int num_replans = 0;
  std::string end_reason;
};

/// Flies `flight` with the real graph on memq:// (tools/bench/trials.h) and records it to `path`
/// (written beside it first, then renamed, so a failed recording leaves no log). The error says
/// why not: bad flight options, an unloadable scenario, a failed write.
Expected<RecordSummary> recordFlight(const FlightSpec& flight, const std::string& path);

struct CheckResult {
  bool equal = false;
  std::string text;  ///< what thicket-replay check prints
  double replay_seconds = 0;
  ReplayResult replay;
  Comparison comparison;
};

/// Replays `events` into the nodes built with `options` and compares the outputs; `damage` is
/// why reading the log stopped early (empty when whole), which makes the check fail.
CheckResult checkEvents(const std::vector<LogEvent>& events, const GraphOptions& options,
                        const LcmTypeSet& types, size_t max_diffs, const std::string& damage = {});

struct CheckOptions {
  std::string log;
  std::string method;  ///< empty: the method of the reference flight of that file name
  size_t max_diffs = 20;
  std::string lcmtypes_dir;  ///< the .lcm files the messages are decoded with
};

/// Reads the log and checks it. The error is for a log that cannot be checked at all (cannot be
/// opened, no SIM_WORLD, no method known for it, unreadable type definitions).
Expected<CheckResult> checkLog(const CheckOptions& options);

/// The source tree's lcmtypes/ and logs/.
std::string defaultLcmTypesDir();
std::string defaultLogsDir();

}  // namespace thicket::replay

// `thicket-log record`: records the LCM bus into a log in the lcm-logger format, like
// lcm-logger, but without losing bursts. lcm-logger (LCM 1.3.1) keeps LCM's default subscription
// queue of 30 messages, so a burst longer than that (the lockstep simulator publishes them) loses
// messages before they reach its writer; the recorder's queue holds thousands.
#pragma once

#include <cstdint>
#include <string>

#include "thicket/common/expected.h"

namespace thicket::log {

struct RecordOptions {
  std::string out;              ///< the log file, or its stem with `increment`
  bool increment = false;       ///< write out.00, out.01, ...: the first that does not exist
  bool force = false;           ///< overwrite an existing `out`
  std::string channels = ".*";  ///< regular expression of the channels to record
  std::string lcm_url;          ///< the bus
  int queue = 10000;            ///< messages the subscription may hold before LCM drops
  double drain_s = 0.2;         ///< after a stop, keep recording until the bus is quiet this long
};

/// Why the options cannot be used, or empty.
std::string validateRecordOptions(const RecordOptions& options);

/// The file to write: `out` itself (an error when it exists, unless `force`), or with `increment`
/// the first of out.00 .. out.99 that does not exist (lcm-logger's -i naming). Unless forced, the
/// file is claimed by creating it empty (O_EXCL), so that recorders started at once never share
/// one.
Expected<std::string> chooseRecordPath(const std::string& out, bool increment, bool force);

/// Records until SIGINT or SIGTERM, then until the bus has been quiet for `drain_s` (at most 2 s
/// more), so the last messages published before the stop are kept. Prints "recording ..." on
/// stderr once subscribed, and a summary at the end. Returns 0, 1 when writing failed (the log
/// then holds everything before the failure) or 2 when recording could not start.
int record(const RecordOptions& options);

}  // namespace thicket::log

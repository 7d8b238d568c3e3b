// Reading a whole LCM log for the log tools through LogReader (lcm_log.h), which does not trust
// it: a torn tail, a corrupt header or an impossible length ends the reading with a message
// saying where, instead of a crash.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "thicket/common/lcm_log.h"

namespace thicket::log {

/// How far reading a log got.
struct LogReadResult {
  int64_t events = 0;      ///< events passed to the callback
  int64_t file_bytes = 0;  ///< size of the file
  std::string error;       ///< why reading stopped before the end of the file; empty otherwise
};

/// Calls `on_event` with every event of the log at `path`, in file order, up to the first damaged
/// one. Throws std::runtime_error naming the file when it cannot be opened.
LogReadResult readLog(const std::string& path,
                      const std::function<void(const LogEvent&)>& on_event);

}  // namespace thicket::log

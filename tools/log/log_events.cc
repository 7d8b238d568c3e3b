#include "log_events.h"

namespace thicket::log {

LogReadResult readLog(const std::string& path,
                      const std::function<void(const LogEvent&)>& on_event) {
  LogReader reader(path);
  LogReadResult result;
  result.file_bytes = reader.fileBytes();
  while (auto event = reader.next()) {
    on_event(*event);
    ++result.events;
  }
  result.error = reader.error();
  return result;
}

}  // namespace thicket::log

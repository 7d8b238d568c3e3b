// LCM logs (the lcm-logger format): reading events in order with their timestamps without
// trusting the file (a torn tail, a corrupt header or an impossible length ends the reading with
// a message saying where; LCM 1.3.1's reader crashes on some of them), writing them, recording live
// traffic, and replaying a log into nodes without wall-clock pacing — how replay regression tests
// drive modules (docs/design.md §4).
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "thicket/common/node.h"

namespace thicket {

class Loop;

struct LogEvent {
  int64_t eventnum = 0;
  int64_t timestamp = 0;  // when the logger received it [us]; message utime is inside data
  std::string channel;
  std::vector<uint8_t> data;

  /// Decodes the payload as Msg; returns an error text (empty on success), as decodeMessage.
  template <class Msg>
  std::string decode(Msg& msg) const {
    return decodeMessage(data.data(), data.size(), msg);
  }
};

/// Reads a log from start to end.
class LogReader {
 public:
  /// Throws std::runtime_error naming the file when it cannot be opened.
  explicit LogReader(const std::string& path);
  ~LogReader();

  /// The next event, or nullopt at the end. A log that ends in a torn or corrupt event (a
  /// logger killed mid-write) ends there; error() then says where and why. No event allocates
  /// more than the bytes left in the file.
  std::optional<LogEvent> next();

  /// Every remaining event.
  std::vector<LogEvent> readAll();

  /// Why reading stopped early, or empty when the log ended cleanly (so far).
  const std::string& error() const { return error_; }
  const std::string& path() const { return path_; }
  /// The size of the file when it was opened: what is read.
  int64_t fileBytes() const { return file_size_; }

 private:
  struct FileCloser {
    void operator()(FILE* file) const;
  };
  std::string path_;
  std::unique_ptr<FILE, FileCloser> file_;
  int64_t file_size_ = 0;
  int64_t good_end_ = 0;  // bytes the events read so far take in the file
  int64_t events_read_ = 0;
  std::string error_;
};

/// Writes a log. Event numbers are assigned in order; timestamps must not decrease.
class LogWriter {
 public:
  /// Throws std::runtime_error naming the file when it cannot be created.
  explicit LogWriter(const std::string& path);
  ~LogWriter();

  /// Throws std::invalid_argument when the timestamp goes backwards, std::runtime_error when
  /// the write fails.
  void write(int64_t timestamp, const std::string& channel, const void* data, size_t size);

  template <class Msg>
  void write(int64_t timestamp, const std::string& channel, const Msg& msg) {
    std::vector<uint8_t> buffer(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    write(timestamp, channel, buffer.data(), buffer.size());
  }

  /// Hands everything written to the operating system; throws std::runtime_error when it fails.
  void flush();
  int64_t eventsWritten() const { return events_written_; }

 private:
  std::string path_;
  std::unique_ptr<lcm::LogFile> file_;
  int64_t events_written_ = 0;
  int64_t last_timestamp_ = INT64_MIN;
};

/// Records every message on channels matching `channel_regex` into a log, stamped with its
/// receive time — what lcm-logger does, for `thicket-log record`, in-process composites and
/// tests. Its subscription queue holds `queue_capacity` messages, so bursts longer than LCM's
/// default 30 (the lockstep simulator publishes such bursts) are kept, not dropped.
class LogRecorder : public Node {
 public:
  LogRecorder(lcm::LCM& lcm, const std::string& path, const std::string& channel_regex = ".*",
              int queue_capacity = 1000);
  int64_t eventsWritten() const { return writer_.eventsWritten(); }
  int64_t bytesWritten() const { return bytes_written_; }
  /// Flushes to disk; a failure is kept in writeError() like a failed write.
  void flush();
  /// Why writing failed (the disk is full, the file was removed...), or empty. After a failure
  /// nothing more is written: the log holds everything up to it.
  const std::string& writeError() const { return write_error_; }

 private:
  LogWriter writer_;
  int64_t last_stamp_ = 0;
  int64_t bytes_written_ = 0;
  std::string write_error_;
};

/// Replays a log onto `lcm` as fast as it can: publishes each event (those `filter` accepts)
/// and lets `loop` drain everything it causes before the next, so the nodes on a memq:// LCM
/// see exactly the logged order. Returns the number of events published.
int64_t replayLog(LogReader& reader, lcm::LCM& lcm, Loop& loop,
                  const std::function<bool(const LogEvent&)>& filter = {});

}  // namespace thicket

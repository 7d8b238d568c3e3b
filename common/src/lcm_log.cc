#include "thicket/common/lcm_log.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "thicket/common/loop.h"

namespace thicket {

namespace {

constexpr uint32_t kSyncWord = 0xEDA1DA01;
constexpr int64_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;  // sync, eventnum, timestamp, lengths
constexpr int32_t kMaxChannelBytes = 1000;                // what LCM's reader accepts (exclusive)

uint64_t bigEndian(const uint8_t* bytes, int n) {
  uint64_t value = 0;
  for (int i = 0; i < n; ++i) value = (value << 8) | bytes[i];
  return value;
}

}  // namespace

void LogReader::FileCloser::operator()(FILE* file) const {
  std::fclose(file);
}

LogReader::LogReader(const std::string& path) : path_(path), file_(std::fopen(path.c_str(), "rb")) {
  struct stat info {};
  if (!file_ || ::fstat(fileno(file_.get()), &info) != 0) {
    throw std::runtime_error("cannot open log '" + path + "': " + std::strerror(errno));
  }
  // Every length is checked against the file's size, which a pipe or a device does not have.
  if (!S_ISREG(info.st_mode)) {
    throw std::runtime_error("cannot read log '" + path +
                             "': not a regular file (a pipe or a device has no size to check "
                             "event lengths against; write it to a file first)");
  }
  file_size_ = info.st_size;
}

LogReader::~LogReader() = default;

std::optional<LogEvent> LogReader::next() {
  if (!error_.empty() || good_end_ >= file_size_) return std::nullopt;
  // Every length is checked against the bytes left in the file before anything is allocated or
  // read: a corrupt header ends the reading with a message saying where, never a crash.
  const auto fail = [&](const std::string& what) -> std::optional<LogEvent> {
    error_ = path_ + ": event " + std::to_string(events_read_) + " at byte " +
             std::to_string(good_end_) + ": " + what + "; " +
             std::to_string(file_size_ - good_end_) + " bytes are not part of the " +
             std::to_string(events_read_) + " events read: torn or corrupt log";
    return std::nullopt;
  };
  const int64_t remaining = file_size_ - good_end_;
  uint8_t header[kEventHeaderBytes];
  if (remaining < kEventHeaderBytes) {
    return fail("torn header (" + std::to_string(remaining) + " of " +
                std::to_string(kEventHeaderBytes) + " bytes): the log ends mid-event");
  }
  if (std::fread(header, 1, sizeof(header), file_.get()) != sizeof(header)) {
    return fail("read error: " + std::string(std::strerror(errno)));
  }
  if (bigEndian(header, 4) != kSyncWord) return fail("no sync word: corrupt data");
  const auto channel_bytes = static_cast<int32_t>(bigEndian(header + 20, 4));
  const auto data_bytes = static_cast<int32_t>(bigEndian(header + 24, 4));
  if (channel_bytes <= 0 || channel_bytes >= kMaxChannelBytes) {
    return fail("impossible channel name length " + std::to_string(channel_bytes) +
                ": corrupt header");
  }
  if (data_bytes < 0) {
    return fail("negative data length " + std::to_string(data_bytes) + ": corrupt header");
  }
  const int64_t body = int64_t{channel_bytes} + data_bytes;
  if (body > remaining - kEventHeaderBytes) {
    return fail("torn or corrupt event: its header claims " +
                std::to_string(kEventHeaderBytes + body) + " bytes, " + std::to_string(remaining) +
                " are left in the file");
  }
  LogEvent event;
  event.eventnum = static_cast<int64_t>(bigEndian(header + 4, 8));
  event.timestamp = static_cast<int64_t>(bigEndian(header + 12, 8));
  event.channel.resize(static_cast<size_t>(channel_bytes));
  event.data.resize(static_cast<size_t>(data_bytes));
  if (std::fread(event.channel.data(), 1, event.channel.size(), file_.get()) !=
          event.channel.size() ||
      std::fread(event.data.data(), 1, event.data.size(), file_.get()) != event.data.size()) {
    return fail("read error: " + std::string(std::strerror(errno)));
  }
  good_end_ += kEventHeaderBytes + body;
  ++events_read_;
  return event;
}

std::vector<LogEvent> LogReader::readAll() {
  std::vector<LogEvent> events;
  while (auto event = next()) events.push_back(std::move(*event));
  return events;
}

LogWriter::LogWriter(const std::string& path)
    : path_(path), file_(std::make_unique<lcm::LogFile>(path, "w")) {
  if (!file_->good()) {
    throw std::runtime_error("cannot create log '" + path + "': " + std::strerror(errno));
  }
}

LogWriter::~LogWriter() {
  flush();
}

void LogWriter::write(int64_t timestamp, const std::string& channel, const void* data,
                      size_t size) {
  if (timestamp < last_timestamp_) {
    throw std::invalid_argument(path_ + ": timestamp " + std::to_string(timestamp) +
                                " is before the previous event's " +
                                std::to_string(last_timestamp_));
  }
  lcm::LogEvent event;
  event.eventnum = events_written_;
  event.timestamp = timestamp;
  event.channel = channel;
  event.datalen = static_cast<int32_t>(size);
  event.data = const_cast<void*>(data);  // LogFile::writeEvent only reads it
  if (file_->writeEvent(&event) != 0) {
    throw std::runtime_error(path_ + ": cannot write event on " + channel);
  }
  last_timestamp_ = timestamp;
  ++events_written_;
}

void LogWriter::flush() {
  if (std::fflush(file_->getFilePtr()) != 0) {
    throw std::runtime_error(path_ + ": cannot write: " + std::strerror(errno));
  }
}

LogRecorder::LogRecorder(lcm::LCM& lcm, const std::string& path, const std::string& channel_regex,
                         int queue_capacity)
    : Node("recorder", lcm), writer_(path) {
  subscribeRaw(
      channel_regex,
      [this](const void* data, size_t size, const MessageInfo& info) {
        if (!write_error_.empty()) return;
        // Receive times of different transports can step back by a few microseconds; the log
        // keeps arrival order, so clamp instead of refusing.
        last_stamp_ = std::max(info.recv_utime, last_stamp_);
        try {
          writer_.write(last_stamp_, std::string(info.channel), data, size);
          bytes_written_ += static_cast<int64_t>(size);
        } catch (const std::exception& e) {
          write_error_ = e.what();
        }
      },
      queue_capacity);
}

void LogRecorder::flush() {
  if (!write_error_.empty()) return;
  try {
    writer_.flush();
  } catch (const std::exception& e) {
    write_error_ = e.what();
  }
}

int64_t replayLog(LogReader& reader, lcm::LCM& lcm, Loop& loop,
                  const std::function<bool(const LogEvent&)>& filter) {
  int64_t published = 0;
  while (auto event = reader.next()) {
    if (filter && !filter(*event)) continue;
    if (lcm.publish(event->channel, event->data.data(),
                    static_cast<unsigned int>(event->data.size())) != 0) {
      throw std::runtime_error("replay: cannot publish event " + std::to_string(event->eventnum) +
                               " on " + event->channel);
    }
    ++published;
    loop.drain();
  }
  return published;
}

}  // namespace thicket

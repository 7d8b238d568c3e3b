#include "thicket/common/lcm_log.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "thicket/common/loop.h"

namespace thicket {

LogReader::LogReader(const std::string& path)
    : path_(path), file_(std::make_unique<lcm::LogFile>(path, "r")) {
  if (!file_->good()) {
    throw std::runtime_error("cannot open log '" + path + "': " + std::strerror(errno));
  }
  struct stat info {};
  if (::stat(path.c_str(), &info) == 0) file_size_ = info.st_size;
}

LogReader::~LogReader() = default;

std::optional<LogEvent> LogReader::next() {
  const lcm::LogEvent* event = file_->readNextEvent();
  if (event == nullptr) {
    // LCM skips what it cannot parse while hunting for the next sync word, and reports a torn
    // tail and a clean end alike: whatever bytes the events read do not account for are damage.
    if (error_.empty() && good_end_ < file_size_) {
      error_ = path_ + ": " + std::to_string(file_size_ - good_end_) +
               " bytes are not part of the " + std::to_string(events_read_) +
               " events read: torn or corrupt log";
    }
    return std::nullopt;
  }
  ++events_read_;
  // The bytes this event takes in the file (sync word, event number, timestamp, the two lengths,
  // channel, data), summed rather than taken from ftell: LCM 1.3.1 consumes a tail too short for
  // the next sync word together with the last event, so ftell would hide that damage.
  constexpr int64_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;
  good_end_ += kEventHeaderBytes + static_cast<int64_t>(event->channel.size()) + event->datalen;
  const auto* bytes = static_cast<const uint8_t*>(event->data);
  return LogEvent{event->eventnum, event->timestamp, event->channel,
                  std::vector<uint8_t>(bytes, bytes + event->datalen)};
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

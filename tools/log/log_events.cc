#include "log_events.h"

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace thicket::log {
namespace {

constexpr uint32_t kSyncWord = 0xEDA1DA01;
constexpr int64_t kHeaderBytes = 4 + 8 + 8 + 4 + 4;  // sync, eventnum, timestamp, lengths
constexpr int32_t kMaxChannelBytes = 1000;           // what LCM's reader accepts (exclusive)

uint64_t bigEndian(const uint8_t* bytes, int n) {
  uint64_t value = 0;
  for (int i = 0; i < n; ++i) value = (value << 8) | bytes[i];
  return value;
}

struct FileCloser {
  void operator()(FILE* f) const { std::fclose(f); }
};

}  // namespace

LogReadResult readLog(const std::string& path,
                      const std::function<void(const LogEvent&)>& on_event) {
  std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "rb"));
  if (!file) throw std::runtime_error("cannot open log '" + path + "': " + std::strerror(errno));
  LogReadResult result;
  std::fseek(file.get(), 0, SEEK_END);
  result.file_bytes = std::ftell(file.get());
  std::fseek(file.get(), 0, SEEK_SET);

  int64_t offset = 0;
  const auto fail = [&](const std::string& what) {
    result.error = path + ": event " + std::to_string(result.events) + " at byte " +
                   std::to_string(offset) + ": " + what;
    return result;
  };
  LogEvent event;
  while (offset < result.file_bytes) {
    uint8_t header[kHeaderBytes];
    const int64_t remaining = result.file_bytes - offset;
    if (remaining < kHeaderBytes) {
      return fail("torn header (" + std::to_string(remaining) + " of " +
                  std::to_string(kHeaderBytes) + " bytes): the log ends mid-event");
    }
    if (std::fread(header, 1, sizeof(header), file.get()) != sizeof(header)) {
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
    if (body > remaining - kHeaderBytes) {
      return fail("torn or corrupt event: its header claims " +
                  std::to_string(kHeaderBytes + body) + " bytes, " + std::to_string(remaining) +
                  " are left in the file");
    }
    event.eventnum = static_cast<int64_t>(bigEndian(header + 4, 8));
    event.timestamp = static_cast<int64_t>(bigEndian(header + 12, 8));
    event.channel.resize(static_cast<size_t>(channel_bytes));
    event.data.resize(static_cast<size_t>(data_bytes));
    if (std::fread(event.channel.data(), 1, event.channel.size(), file.get()) !=
            event.channel.size() ||
        std::fread(event.data.data(), 1, event.data.size(), file.get()) != event.data.size()) {
      return fail("read error: " + std::string(std::strerror(errno)));
    }
    on_event(event);
    offset += kHeaderBytes + body;
    ++result.events;
  }
  return result;
}

}  // namespace thicket::log

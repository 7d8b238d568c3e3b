#include "record.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <regex>

#include <lcm/lcm-cpp.hpp>

#include "thicket/common/lcm_log.h"
#include "thicket/common/loop.h"

namespace thicket::log {

namespace {

constexpr int64_t kFlushPeriodUs = 1'000'000;
constexpr double kMaxDrainS = 2.0;

std::string megabytes(int64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return text;
}

}  // namespace

std::string validateRecordOptions(const RecordOptions& options) {
  if (options.out.empty()) return "no output file given";
  if (options.increment && options.force) return "--increment and --force exclude each other";
  if (options.queue < 1 || options.queue > 1'000'000) return "--queue must be 1 .. 1000000";
  if (!(options.drain_s >= 0.0 && options.drain_s <= kMaxDrainS)) {
    return "--drain must be 0 .. 2 seconds";
  }
  if (options.channels.empty()) return "--channels needs a regular expression";
  try {
    std::regex check(options.channels);
  } catch (const std::regex_error& e) {
    return "--channels '" + options.channels + "' is not a regular expression: " + e.what();
  }
  return {};
}

Expected<std::string> chooseRecordPath(const std::string& out, bool increment, bool force) {
  namespace fs = std::filesystem;
  std::error_code error;
  const fs::path parent = fs::path(out).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, error)) {
    return unexpected("the directory '" + parent.string() + "' does not exist");
  }
  if (fs::is_directory(out, error) && !increment) return unexpected("'" + out + "' is a directory");
  if (force && !increment) return out;
  // Claimed by creating it: two recorders started together never pick the same file.
  const auto claim = [](const std::string& path) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) return errno;
    ::close(fd);
    return 0;
  };
  if (!increment) {
    const int failed = claim(out);
    if (failed == EEXIST) {
      return unexpected("'" + out + "' exists (--force overwrites it, --increment numbers logs)");
    }
    if (failed != 0) return unexpected("cannot create '" + out + "': " + std::strerror(failed));
    return out;
  }
  for (int n = 0; n < 100; ++n) {
    char suffix[8];
    std::snprintf(suffix, sizeof suffix, ".%02d", n);
    const std::string candidate = out + suffix;
    const int failed = claim(candidate);
    if (failed == 0) return candidate;
    if (failed != EEXIST) {
      return unexpected("cannot create '" + candidate + "': " + std::strerror(failed));
    }
  }
  return unexpected("'" + out + ".00' .. '" + out + ".99' all exist");
}

int record(const RecordOptions& options) {
  if (const std::string error = validateRecordOptions(options); !error.empty()) {
    std::fprintf(stderr, "thicket-log: %s\n", error.c_str());
    return 2;
  }
  const auto path = chooseRecordPath(options.out, options.increment, options.force);
  if (!path) {
    std::fprintf(stderr, "thicket-log: %s\n", path.error().c_str());
    return 2;
  }
  // What cannot start leaves no empty log behind (a forced OUT was not created here; --force and
  // --increment exclude each other).
  const auto unclaim = [&] {
    if (!options.force) std::remove(path->c_str());
  };
  lcm::LCM lcm(options.lcm_url);
  if (!lcm.good()) {
    std::fprintf(stderr, "thicket-log: cannot open LCM at %s\n", options.lcm_url.c_str());
    unclaim();
    return 2;
  }
  Loop::installSignalHandlers();
  std::unique_ptr<LogRecorder> recorder;
  try {
    recorder = std::make_unique<LogRecorder>(lcm, *path, options.channels, options.queue);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "thicket-log: %s\n", e.what());
    unclaim();
    return 2;
  }
  std::fprintf(stderr, "thicket-log: recording '%s' from %s to %s\n", options.channels.c_str(),
               options.lcm_url.c_str(), path->c_str());

  Loop loop(lcm);
  // Flushed every second: a recorder that is killed loses at most the last second.
  loop.addTimer(kFlushPeriodUs, [&] {
    recorder->flush();
    if (!recorder->writeError().empty()) loop.stop();
  });
  const auto started = std::chrono::steady_clock::now();
  loop.run();
  // What was published before the stop may still be on its way: keep recording until the bus is
  // quiet, but not forever on a busy bus.
  const auto drain_end =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(kMaxDrainS);
  const int quiet_ms = static_cast<int>(options.drain_s * 1000.0);
  while (recorder->writeError().empty() && quiet_ms > 0 &&
         std::chrono::steady_clock::now() < drain_end) {
    const int status = lcm.handleTimeout(quiet_ms);
    if (status <= 0) break;
  }
  recorder->flush();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::fprintf(stderr, "thicket-log: recorded %lld events (%s) in %.1f s to %s\n",
               static_cast<long long>(recorder->eventsWritten()),
               megabytes(recorder->bytesWritten()).c_str(), seconds, path->c_str());
  if (!recorder->writeError().empty()) {
    std::fprintf(stderr, "thicket-log: recording stopped: %s; the log holds the events before\n",
                 recorder->writeError().c_str());
    return 1;
  }
  return 0;
}

}  // namespace thicket::log

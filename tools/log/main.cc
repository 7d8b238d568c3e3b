// thicket-log: LCM log utilities.
//
//   thicket-log summary LOG [--json]          what a log holds, per channel and in total
//   thicket-log plot LOG --out FILE.png [...]  a top-down picture of a simulated mission
//   thicket-log mission LOG                    how a simulated mission went
//   thicket-log record OUT [...]               records the bus, like lcm-logger but lossless
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "mission.h"
#include "plot.h"
#include "record.h"
#include "summary.h"
#include "thicket/common/node_main.h"

namespace {

constexpr const char* kUsage =
    "usage: thicket-log summary LOG [--json]\n"
    "       thicket-log plot LOG --out FILE.png [--size PIXELS] [--layer esdf|tsdf|auto]\n"
    "                            [--z-band MIN,MAX]\n"
    "       thicket-log mission LOG\n"
    "       thicket-log record OUT [--increment | --force] [--channels REGEX] [--lcm-url URL]\n"
    "                          [--queue N] [--drain SECONDS]\n"
    "\n"
    "summary  per channel (sorted by name): message count, first and last time, duration, mean\n"
    "         rate ((count - 1) / duration), mean and maximum message size, and the LCM type\n"
    "         identified by the message fingerprint (\"unknown 0x...\" when no thicket or\n"
    "         procman_lcm type has it); then totals. Times are the log's event timestamps.\n"
    "         --json prints one JSON object instead of the table.\n"
    "plot     a top-down PNG of a simulated mission: SIM_WORLD obstacles and flight volume, the\n"
    "         map (MAP_ESDF, else MAP_TSDF: the last state, every update applied in revision\n"
    "         order) as a max-projection over a z band, the SIM_TRUTH path (else STATE_ESTIMATE),\n"
    "         start, goal (MISSION_GOAL, else SIM_WORLD), EXPLORER_GOAL goals and SIM_EVENT\n"
    "         collisions, with a legend and a scale bar. What the log lacks is named on stderr.\n"
    "         --size      width and height of the image [px], 400 .. 10000 (default 1000)\n"
    "         --layer     the map layer to draw (default auto: ESDF if logged, else TSDF)\n"
    "         --z-band    the projected band [m] (default: median flown height +- 0.5 m)\n"
    "mission  how a simulated mission went, from the simulator's SIM_EVENT (the trial end's\n"
    "         summary, collisions, refused trajectories) and the EXPLORER_GOAL goals; exit\n"
    "         status 0 only when it reached the goal without a collision, 1 otherwise.\n"
    "record   records the bus into the log OUT (the lcm-logger format; event timestamps are\n"
    "         receive times) until SIGINT or SIGTERM, then until the bus has been quiet for "
    "--drain\n"
    "         seconds (default 0.2, at most 2 s more). Unlike lcm-logger (LCM 1.3.1), whose\n"
    "         subscription queue holds 30 messages, it keeps bursts of up to --queue messages\n"
    "         (default 10000). An existing OUT is refused unless --force; --increment writes "
    "OUT.00,\n"
    "         OUT.01, ... (the first free one, as lcm-logger -i). Flushed every second. It prints\n"
    "         \"recording ...\" on stderr once subscribed and what it wrote when it stops.\n"
    "         --channels  regular expression of the channels to record (default .*)\n"
    "         --lcm-url   the bus (default: $LCM_DEFAULT_URL, else "
    "udpm://239.255.76.67:7667?ttl=0)\n"
    "\n"
    "exit status: 0 done (damage found in the log is reported on stderr); 1 nothing could be\n"
    "read, nothing to draw, the PNG could not be written, or a recording could not be\n"
    "written; 2 bad arguments, a log that cannot be opened, or a recording that cannot start.\n";

int usageError(const std::string& message) {
  std::fprintf(stderr, "thicket-log: %s\n%s", message.c_str(), kUsage);
  return 2;
}

int fail(int status, const std::string& message) {
  std::fprintf(stderr, "thicket-log: %s\n", message.c_str());
  return status;
}

// The log argument and "--flag value" / "--flag=value" options; `booleans` take no value.
struct Arguments {
  std::string log;
  std::map<std::string, std::string> flags;
  std::string error;
};

Arguments parseArguments(const std::vector<std::string>& args,
                         const std::vector<std::string>& with_value,
                         const std::vector<std::string>& booleans) {
  Arguments parsed;
  const auto known = [](const std::vector<std::string>& names, const std::string& name) {
    for (const std::string& n : names) {
      if (n == name) return true;
    }
    return false;
  };
  for (size_t i = 0; i < args.size() && parsed.error.empty(); ++i) {
    const std::string& arg = args[i];
    if (arg.rfind("--", 0) != 0) {
      if (!parsed.log.empty()) parsed.error = "unexpected argument '" + arg + "'";
      parsed.log = arg;
      continue;
    }
    const size_t equals = arg.find('=');
    const std::string name = arg.substr(0, equals);
    if (known(booleans, name) && equals == std::string::npos) {
      parsed.flags[name] = "true";
    } else if (!known(with_value, name)) {
      parsed.error = "unknown option '" + arg + "'";
    } else if (equals != std::string::npos) {
      parsed.flags[name] = arg.substr(equals + 1);
    } else if (i + 1 < args.size()) {
      parsed.flags[name] = args[++i];
    } else {
      parsed.error = name + " needs a value";
    }
    if (parsed.error.empty() && parsed.flags[name].empty()) {
      parsed.error = name + " needs a value";
    }
  }
  if (parsed.error.empty() && parsed.log.empty()) parsed.error = "no LOG given";
  return parsed;
}

// A readable regular file, else the reason (exit status 2).
std::string checkReadable(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) return "'" + path + "' is a directory";
  FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return "cannot open log '" + path + "': " + std::strerror(errno);
  std::fclose(file);
  return {};
}

bool parseNumber(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && std::isfinite(value);
}

int summary(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {}, {"--json"});
  if (!parsed.error.empty()) return usageError(parsed.error);
  if (const std::string error = checkReadable(parsed.log); !error.empty()) return fail(2, error);
  const auto summary = thicket::log::summarizeLog(parsed.log);
  if (!summary) return fail(2, summary.error());
  const bool json = parsed.flags.count("--json") > 0;
  std::fputs((json ? summaryJson(*summary) : summaryText(*summary)).c_str(), stdout);
  for (const std::string& warning : summary->warnings) {
    std::fprintf(stderr, "thicket-log: warning: %s\n", warning.c_str());
  }
  if (summary->error.empty()) return 0;
  // A damaged log is still worth its summary: only an unreadable one is a failure.
  std::fprintf(stderr, "thicket-log: read %lld events, then stopped: %s\n",
               static_cast<long long>(summary->events), summary->error.c_str());
  return summary->events > 0 ? 0 : 1;
}

int plot(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {"--out", "--size", "--layer", "--z-band"}, {});
  if (!parsed.error.empty()) return usageError(parsed.error);
  thicket::log::PlotOptions options;
  if (!parsed.flags.count("--out")) return usageError("plot needs --out FILE.png");
  options.out = parsed.flags.at("--out");
  if (parsed.flags.count("--size")) {
    double size = 0;
    if (!parseNumber(parsed.flags.at("--size"), size) || size != std::floor(size)) {
      return usageError("--size must be a whole number of pixels");
    }
    options.size = static_cast<int>(std::clamp(size, -1.0, 1e6));
  }
  if (parsed.flags.count("--layer")) options.layer = parsed.flags.at("--layer");
  if (parsed.flags.count("--z-band")) {
    const std::string& band = parsed.flags.at("--z-band");
    const size_t comma = band.find(',');
    double z_min = 0, z_max = 0;
    if (comma == std::string::npos || !parseNumber(band.substr(0, comma), z_min) ||
        !parseNumber(band.substr(comma + 1), z_max)) {
      return usageError("--z-band must be MIN,MAX in metres");
    }
    options.z_min = z_min;
    options.z_max = z_max;
  }
  if (const std::string error = validatePlotOptions(options); !error.empty()) {
    return usageError(error);
  }
  if (const std::string error = checkReadable(parsed.log); !error.empty()) return fail(2, error);

  const auto result = thicket::log::plotLog(parsed.log, options);
  if (!result) return fail(1, result.error());
  for (const std::string& note : result->notes) {
    std::fprintf(stderr, "thicket-log: %s\n", note.c_str());
  }
  std::printf("wrote %s (%dx%d px, %.1f px/m)\n", options.out.c_str(), options.size, options.size,
              result->frame.pixels_per_metre);
  return 0;
}

int mission(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {}, {});
  if (!parsed.error.empty()) return usageError(parsed.error);
  if (const std::string error = checkReadable(parsed.log); !error.empty()) return fail(2, error);
  const auto report = thicket::log::missionReport(parsed.log);
  if (!report) return fail(2, report.error());
  if (!report->read_error.empty()) {
    std::fprintf(stderr, "thicket-log: the log is damaged: %s\n", report->read_error.c_str());
  }
  std::printf("mission: %s\n", report->text().c_str());
  return report->success() ? 0 : 1;
}

int record(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {"--channels", "--lcm-url", "--queue", "--drain"},
                                          {"--increment", "--force"});
  if (!parsed.error.empty())
    return usageError(parsed.error == "no LOG given" ? "no OUT given" : parsed.error);
  thicket::log::RecordOptions options;
  options.out = parsed.log;
  options.increment = parsed.flags.count("--increment") > 0;
  options.force = parsed.flags.count("--force") > 0;
  if (parsed.flags.count("--channels")) options.channels = parsed.flags.at("--channels");
  options.lcm_url =
      parsed.flags.count("--lcm-url") ? parsed.flags.at("--lcm-url") : thicket::defaultLcmUrl();
  if (parsed.flags.count("--queue")) {
    double queue = 0;
    if (!parseNumber(parsed.flags.at("--queue"), queue) || queue != std::floor(queue)) {
      return usageError("--queue must be a whole number of messages");
    }
    options.queue = static_cast<int>(std::clamp(queue, -1.0, 1e7));
  }
  if (parsed.flags.count("--drain") && !parseNumber(parsed.flags.at("--drain"), options.drain_s)) {
    return usageError("--drain must be a number of seconds");
  }
  if (const std::string error = thicket::log::validateRecordOptions(options); !error.empty()) {
    return usageError(error);
  }
  return thicket::log::record(options);
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + std::min(argc, 2), argv + argc);
  const std::string command = argc >= 2 ? argv[1] : "";
  const bool help = std::any_of(argv + 1, argv + argc, [](const char* arg) {
    return std::strcmp(arg, "-h") == 0 || std::strcmp(arg, "--help") == 0;
  });
  if (help || command == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (command == "summary") return summary(args);
  if (command == "plot") return plot(args);
  if (command == "mission") return mission(args);
  if (command == "record") return record(args);
  return usageError(command.empty() ? "no command given" : "unknown command '" + command + "'");
}

// thicket-log: LCM log utilities.
//
//   thicket-log summary LOG [--json]          what a log holds, per channel and in total
//   thicket-log plot LOG --out FILE.png [...]  a top-down picture of a simulated mission
//   thicket-log mission LOG                    how a simulated mission went
//   thicket-log record OUT [...]               records the bus, like lcm-logger but lossless
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "mission.h"
#include "plot.h"
#include "record.h"
#include "summary.h"
#include "thicket/common/cli.h"

namespace {

constexpr const char* kSummaryHelp =
    "Per channel (sorted by name): message count, first and last time, duration, mean rate\n"
    "((count - 1) / duration), mean and maximum message size, and the LCM type identified by\n"
    "the message fingerprint (\"unknown 0x...\" when no thicket or procman_lcm type has it);\n"
    "then totals. Times are the log's event timestamps.";
constexpr const char* kPlotHelp =
    "A top-down PNG of a simulated mission: SIM_WORLD obstacles and flight volume, the map\n"
    "(MAP_ESDF, else MAP_TSDF: the last state, every update applied in revision order) as a\n"
    "max-projection over a z band, the SIM_TRUTH path (else STATE_ESTIMATE), start, goal\n"
    "(MISSION_GOAL, else SIM_WORLD), EXPLORER_GOAL goals and SIM_EVENT collisions, with a legend\n"
    "and a scale bar. What the log lacks is named on stderr.";
constexpr const char* kMissionHelp =
    "How a simulated mission went, from the simulator's SIM_EVENT (the trial end's summary,\n"
    "collisions, refused trajectories) and the EXPLORER_GOAL goals; exit status 0 only when it\n"
    "reached the goal without a collision, 1 otherwise.";
constexpr const char* kRecordHelp =
    "Records the bus into the log OUT (the lcm-logger format; event timestamps are receive\n"
    "times) until SIGINT or SIGTERM, then until the bus has been quiet for --drain seconds (at\n"
    "most 2 s more). Unlike lcm-logger (LCM 1.3.1), whose subscription queue holds 30\n"
    "messages, it keeps bursts of up to --queue messages. An existing OUT is refused unless\n"
    "--force; --increment writes OUT.00, OUT.01, ... (the first free one, as lcm-logger -i).\n"
    "Flushed every second. It prints \"recording ...\" on stderr once subscribed and what it\n"
    "wrote when it stops.";
constexpr const char* kExitStatus =
    "Exit status: 0 done (damage found in the log is reported on stderr); 1 nothing could be\n"
    "read, nothing to draw, the PNG could not be written, or a recording could not be written;\n"
    "2 bad arguments, a log that cannot be opened, or a recording that cannot start.";

int usageError(const std::string& message) {
  return thicket::cli::usageError("thicket-log", message);
}

int fail(int status, const std::string& message) {
  std::fprintf(stderr, "thicket-log: %s\n", message.c_str());
  return status;
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

int summary(const std::string& log, bool json) {
  if (const std::string error = checkReadable(log); !error.empty()) return fail(2, error);
  const auto summary = thicket::log::summarizeLog(log);
  if (!summary) return fail(2, summary.error());
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

int plot(const std::string& log, const thicket::log::PlotOptions& options) {
  if (const std::string error = validatePlotOptions(options); !error.empty()) {
    return usageError(error);
  }
  if (const std::string error = checkReadable(log); !error.empty()) return fail(2, error);

  const auto scene = thicket::log::plotLog(log, options);
  if (!scene) return fail(1, scene.error());
  for (const std::string& note : scene->notes) {
    std::fprintf(stderr, "thicket-log: %s\n", note.c_str());
  }
  std::printf("wrote %s (%dx%d px)\n", options.out.c_str(), options.size, options.size);
  return 0;
}

int mission(const std::string& log) {
  if (const std::string error = checkReadable(log); !error.empty()) return fail(2, error);
  const auto report = thicket::log::missionReport(log);
  if (!report) return fail(2, report.error());
  if (!report->read_error.empty()) {
    std::fprintf(stderr, "thicket-log: the log is damaged: %s\n", report->read_error.c_str());
  }
  std::printf("mission: %s\n", report->text().c_str());
  return report->success() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  using thicket::cli::nonEmpty;
  CLI::App app("thicket-log: LCM log utilities.", "thicket-log");
  app.footer(kExitStatus);
  app.require_subcommand(1);
  std::string log;
  const auto addLog = [&](CLI::App& command) {
    command.add_option("LOG", log, "the log")->required()->check(nonEmpty());
  };

  CLI::App* summary_command =
      app.add_subcommand("summary", "what a log holds, per channel and in total");
  summary_command->footer(kSummaryHelp);
  addLog(*summary_command);
  bool json = false;
  summary_command->add_flag("--json", json, "one JSON object instead of the table");

  CLI::App* plot_command = app.add_subcommand("plot", "a top-down picture of a simulated mission");
  plot_command->footer(kPlotHelp);
  addLog(*plot_command);
  thicket::log::PlotOptions plot_options;
  std::vector<double> z_band;
  plot_command->add_option("--out", plot_options.out, "the PNG to write")
      ->required()
      ->check(nonEmpty());
  plot_command->add_option("--size", plot_options.size, "width and height [px], 400 .. 10000")
      ->check(
          thicket::cli::integer(std::numeric_limits<int>::min(), std::numeric_limits<int>::max()))
      ->capture_default_str();
  plot_command
      ->add_option("--layer", plot_options.layer,
                   "the map layer to draw: esdf, tsdf or auto (ESDF if logged, else TSDF)")
      ->capture_default_str();
  plot_command
      ->add_option("--z-band", z_band,
                   "MIN,MAX: the projected band [m] (default: median flown height +- 0.5 m)")
      ->delimiter(',')
      ->expected(2)
      ->check(thicket::cli::number());

  CLI::App* mission_command = app.add_subcommand("mission", "how a simulated mission went");
  mission_command->footer(kMissionHelp);
  addLog(*mission_command);

  CLI::App* record_command =
      app.add_subcommand("record", "record the bus, like lcm-logger but lossless");
  record_command->footer(kRecordHelp);
  thicket::log::RecordOptions record_options;
  record_command->add_option("OUT", record_options.out, "the log to write")
      ->required()
      ->check(nonEmpty());
  CLI::Option* increment = record_command->add_flag("--increment", record_options.increment,
                                                    "write OUT.00, OUT.01, ...");
  record_command->add_flag("--force", record_options.force, "overwrite an existing OUT")
      ->excludes(increment);
  record_command
      ->add_option("--channels", record_options.channels,
                   "regular expression of the channels to record")
      ->capture_default_str();
  thicket::cli::addLcmUrl(*record_command, record_options.lcm_url);
  record_command
      ->add_option("--queue", record_options.queue,
                   "messages the subscription may hold, 1 .. 1000000")
      ->check(
          thicket::cli::integer(std::numeric_limits<int>::min(), std::numeric_limits<int>::max()))
      ->capture_default_str();
  record_command
      ->add_option("--drain", record_options.drain_s,
                   "after a stop, record until the bus is quiet this long [s], 0 .. 2")
      ->check(thicket::cli::number())
      ->capture_default_str();

  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  if (*summary_command) return summary(log, json);
  if (*plot_command) {
    if (z_band.size() == 2) {
      plot_options.z_min = z_band[0];
      plot_options.z_max = z_band[1];
    }
    return plot(log, plot_options);
  }
  if (*mission_command) return mission(log);
  if (const std::string error = thicket::log::validateRecordOptions(record_options);
      !error.empty()) {
    return usageError(error);
  }
  return thicket::log::record(record_options);
}

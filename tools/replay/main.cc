// thicket-replay: replay regression of the mapper, the planner, the explorer and the VIO bridge
// against reference logs (docs/design.md §4). `thicket-replay --help` says more.
//
//   thicket-replay check LOG                  replays LOG into the real nodes, prints the diff
//   thicket-replay record --out LOG ...       flies one simulated trial and records it
//   thicket-replay record-references          regenerates the reference logs in logs/
#include <cstdio>
#include <string>
#include <vector>

#include "commands.h"
#include "thicket/common/cli.h"
#include "thicket/common/node_main.h"

namespace {

using thicket::replay::CheckOptions;
using thicket::replay::FlightSpec;

constexpr const char* kCheckHelp =
    "Replays LOG into the real VIO bridge, mapper, explorer (unless the method is none) and local\n"
    "planner, built as the benchmark builds a trial on the log's SIM_WORLD, feeding each its\n"
    "inputs from the log in the recorded order, and compares every message they publish with\n"
    "the recorded one, field by field, exactly (wall-clock durations excepted). Prints the\n"
    "differences as CHANNEL message I of N (utime U): FIELD: recorded A replayed B.";
constexpr const char* kRecordHelp =
    "Flies one trial as `thicket-bench run` does (depth sensor, soft goal) with the real graph\n"
    "in this process and records it to LOG (the inputs and outputs of the replayed modules,\n"
    "SIM_WORLD and SIM_EVENT), then checks that it replays exactly.";
constexpr const char* kRecordReferencesHelp =
    "Regenerates every reference log, logs/<name>.lcmlog.ref, and checks each replays exactly\n"
    "and stays under 5 MB (20 MB in all). Run it when behaviour changes on purpose, and commit\n"
    "the logs with the change.";
constexpr const char* kExitStatus =
    "Exit status: 0 the replay equals the recording (check), the logs were written and replay\n"
    "exactly (record, record-references); 1 a difference, a damaged log, a failed recording or\n"
    "an oversized reference; 2 bad arguments or a log that cannot be replayed at all.";

std::string megabytes(int64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f MB", static_cast<double>(bytes) * 1e-6);
  return text;
}

// Records one flight and checks it replays; prints a line about each. Returns the log's size, or
// -1 when either failed.
int64_t recordAndCheck(const FlightSpec& flight, const std::string& path) {
  const auto recorded = thicket::replay::recordFlight(flight, path);
  if (!recorded) {
    std::fprintf(stderr, "thicket-replay: %s: %s\n", path.c_str(), recorded.error().c_str());
    return -1;
  }
  std::printf("wrote %s: %lld events, %s; %d replans, %s\n", path.c_str(),
              static_cast<long long>(recorded->events), megabytes(recorded->bytes).c_str(),
              recorded->num_replans, recorded->end_reason.c_str());
  CheckOptions check;
  check.log = path;
  check.method = flight.method;
  check.lcmtypes_dir = thicket::replay::defaultLcmTypesDir();
  const auto result = thicket::replay::checkLog(check);
  if (!result) {
    std::fprintf(stderr, "thicket-replay: %s\n", result.error().c_str());
    return -1;
  }
  if (!result->equal) {
    std::printf("%s", result->text.c_str());
    std::fprintf(stderr, "thicket-replay: %s does not replay as recorded\n", path.c_str());
    return -1;
  }
  std::printf("  replays exactly in %.2f s\n", result->replay_seconds);
  return recorded->bytes;
}

int check(const CheckOptions& options) {
  const auto result = thicket::replay::checkLog(options);
  if (!result) {
    std::fprintf(stderr, "thicket-replay: %s\n", result.error().c_str());
    return 2;
  }
  std::printf("%s: %s", options.log.c_str(), result->text.c_str());
  return result->equal ? 0 : 1;
}

int record(const FlightSpec& flight, const std::string& out) {
  if (const auto invalid = thicket::replay::validateFlight(flight)) {
    return thicket::failNode("thicket-replay", *invalid);
  }
  return recordAndCheck(flight, out) < 0 ? 1 : 0;
}

int recordReferences(const std::string& dir) {
  bool ok = true;
  int64_t total = 0;
  for (const auto& reference : thicket::replay::referenceFlights()) {
    const std::string path = thicket::replay::referencePath(dir, reference);
    const int64_t bytes = recordAndCheck(reference.flight, path);
    if (bytes < 0) {
      ok = false;
      continue;
    }
    total += bytes;
    if (bytes > thicket::replay::kMaxReferenceBytes) {
      std::fprintf(stderr, "thicket-replay: %s is %s, over the 5 MB a reference may take\n",
                   path.c_str(), megabytes(bytes).c_str());
      ok = false;
    }
  }
  std::printf("%zu reference logs, %s in all\n", thicket::replay::referenceFlights().size(),
              megabytes(total).c_str());
  if (total > thicket::replay::kMaxReferencesBytes) {
    std::fprintf(stderr, "thicket-replay: the reference logs take %s, over the 20 MB allowed\n",
                 megabytes(total).c_str());
    ok = false;
  }
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  using thicket::cli::nonEmpty;
  CLI::App app(
      "thicket-replay: replay regression of the mapper, the planner, the explorer and the VIO\n"
      "bridge against reference logs (docs/design.md, Replay).",
      "thicket-replay");
  app.footer(kExitStatus);
  app.require_subcommand(1);

  CheckOptions check_options;
  check_options.lcmtypes_dir = thicket::replay::defaultLcmTypesDir();
  CLI::App* check_command = app.add_subcommand("check", "replay LOG and print the differences");
  check_command->footer(kCheckHelp);
  check_command->add_option("LOG", check_options.log, "the log")->required()->check(nonEmpty());
  check_command
      ->add_option("--method", check_options.method,
                   "the goal-selection method the log was flown with (default: that of the "
                   "reference log of the same file name)")
      ->check(nonEmpty());
  check_command->add_option("--max-diffs", check_options.max_diffs, "differences printed at most")
      ->check(thicket::cli::integer(0))
      ->capture_default_str();
  check_command
      ->add_option("--lcmtypes", check_options.lcmtypes_dir,
                   "the .lcm type definitions (default: the source tree's lcmtypes/)")
      ->check(nonEmpty());

  FlightSpec flight;
  std::string out;
  CLI::App* record_command =
      app.add_subcommand("record", "fly one simulated trial, record it and check it replays");
  record_command->footer(kRecordHelp);
  record_command->add_option("--out", out, "the log to write")->required()->check(nonEmpty());
  record_command->add_option("--scenario", flight.scenario, "paper, eth, forest50 or a .yaml")
      ->required()
      ->check(nonEmpty());
  record_command->add_option("--density", flight.density, "trees per m^2 of the obstacle region")
      ->required()
      ->check(thicket::cli::number(0));
  thicket::cli::addSeed(*record_command, flight.seed)->required();
  record_command->add_option("--method", flight.method, "none or an explorer strategy")
      ->required()
      ->check(nonEmpty());
  record_command->add_option("--replans", flight.replans, "the replan limit [cycles]")
      ->check(thicket::cli::integer(1, 100000))
      ->capture_default_str();
  thicket::cli::addSwitch(*record_command, "--dynamic-obstacle", flight.dynamic_obstacle,
                          "the simulator's tree that appears on the committed path, as in E6");

  std::string logs_dir = thicket::replay::defaultLogsDir();
  CLI::App* references_command =
      app.add_subcommand("record-references", "regenerate the reference logs in logs/");
  references_command->footer(kRecordReferencesHelp);
  references_command
      ->add_option("--logs", logs_dir, "where to write them (default: the source tree's logs/)")
      ->check(nonEmpty());

  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  if (*check_command) return check(check_options);
  if (*record_command) return record(flight, out);
  return recordReferences(logs_dir);
}

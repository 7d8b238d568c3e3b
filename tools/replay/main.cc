// thicket-replay: replay regression of the mapper, the planner, the explorer and the VIO bridge
// against reference logs (docs/design.md §4).
//
//   thicket-replay check LOG                  replays LOG into the real nodes, prints the diff
//   thicket-replay record --out LOG ...       flies one simulated trial and records it
//   thicket-replay record-references          regenerates the reference logs in logs/
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "commands.h"

namespace {

using thicket::replay::CheckOptions;
using thicket::replay::FlightSpec;

constexpr const char* kUsage =
    "usage: thicket-replay check LOG [--method M] [--max-diffs N] [--lcmtypes DIR]\n"
    "       thicket-replay record --out LOG --scenario S --density D --seed N --method M\n"
    "                             [--replans R] [--dynamic-obstacle on|off]\n"
    "       thicket-replay record-references [--logs DIR]\n"
    "\n"
    "check    replays LOG into the real VIO bridge, mapper, explorer (unless the method is\n"
    "         none) and local planner, built as the benchmark builds a trial on the log's\n"
    "         SIM_WORLD, feeding each its inputs from the log in the recorded order, and compares\n"
    "         every message they publish with the recorded one, field by field, exactly (wall-\n"
    "         clock durations excepted). Prints the differences as CHANNEL message I of N (utime\n"
    "         U): FIELD: recorded A replayed B.\n"
    "         --method     the goal-selection method the log was flown with (default: that of\n"
    "                      the reference log of the same file name)\n"
    "         --max-diffs  differences printed at most (default 20)\n"
    "         --lcmtypes   the .lcm type definitions (default: the source tree's lcmtypes/)\n"
    "record   flies one trial as `thicket-bench run` does (depth sensor, soft goal) with the\n"
    "         real graph in this process and records it to LOG (the inputs and outputs of the\n"
    "         replayed modules, SIM_WORLD and SIM_EVENT), then checks that it replays exactly.\n"
    "         --scenario S (paper, eth, forest50 or a .yaml), --density D, --seed N (the world's\n"
    "         seed), --method M (none or an explorer strategy), --replans R (default 60),\n"
    "         --dynamic-obstacle on|off (the simulator's tree that appears on the committed\n"
    "         path, as in E6; default off)\n"
    "record-references\n"
    "         regenerates every reference log, logs/<name>.lcmlog.ref, and checks each replays\n"
    "         exactly and stays under 5 MB (20 MB in all). Run it when behaviour changes on\n"
    "         purpose, and commit the logs with the change.\n"
    "         --logs  where to write them (default: the source tree's logs/)\n"
    "\n"
    "exit status: 0 the replay equals the recording (check), the logs were written and replay\n"
    "exactly (record, record-references); 1 a difference, a damaged log, a failed recording or\n"
    "an oversized reference; 2 bad arguments or a log that cannot be replayed at all.\n";

int usageError(const std::string& message) {
  std::fprintf(stderr, "thicket-replay: %s\n(thicket-replay --help for usage)\n", message.c_str());
  return 2;
}

struct Arguments {
  std::vector<std::string> positional;
  std::map<std::string, std::string> flags;
  std::string error;
};

// "--flag value" or "--flag=value"; every flag takes a value.
Arguments parseArguments(const std::vector<std::string>& args, const std::set<std::string>& known) {
  Arguments parsed;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg.rfind("--", 0) != 0) {
      parsed.positional.push_back(arg);
      continue;
    }
    const size_t equals = arg.find('=');
    const std::string flag = arg.substr(0, equals);
    if (!known.count(flag)) {
      parsed.error = "unknown option " + flag;
      return parsed;
    }
    std::string value;
    if (equals != std::string::npos) {
      value = arg.substr(equals + 1);
    } else if (i + 1 < args.size()) {
      value = args[++i];
    }
    if (value.empty()) {
      parsed.error = flag + " needs a value";
      return parsed;
    }
    parsed.flags[flag] = value;
  }
  return parsed;
}

bool parseInteger(const std::string& text, long long min, long long& value) {
  try {
    size_t used = 0;
    value = std::stoll(text, &used);
    return used == text.size() && value >= min;
  } catch (const std::exception&) {
    return false;
  }
}

bool parseDensity(const std::string& text, double& value) {
  try {
    size_t used = 0;
    value = std::stod(text, &used);
    return used == text.size() && std::isfinite(value) && value >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

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

int check(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {"--method", "--max-diffs", "--lcmtypes"});
  if (!parsed.error.empty()) return usageError(parsed.error);
  if (parsed.positional.size() != 1) return usageError("check needs exactly one LOG");
  CheckOptions options;
  options.log = parsed.positional[0];
  options.lcmtypes_dir = thicket::replay::defaultLcmTypesDir();
  if (parsed.flags.count("--method")) options.method = parsed.flags.at("--method");
  if (parsed.flags.count("--lcmtypes")) options.lcmtypes_dir = parsed.flags.at("--lcmtypes");
  if (parsed.flags.count("--max-diffs")) {
    long long n = 0;
    if (!parseInteger(parsed.flags.at("--max-diffs"), 0, n)) {
      return usageError("--max-diffs must be an integer >= 0, not '" +
                        parsed.flags.at("--max-diffs") + "'");
    }
    options.max_diffs = static_cast<size_t>(n);
  }
  const auto result = thicket::replay::checkLog(options);
  if (!result) {
    std::fprintf(stderr, "thicket-replay: %s\n", result.error().c_str());
    return 2;
  }
  std::printf("%s: %s", options.log.c_str(), result->text.c_str());
  return result->equal ? 0 : 1;
}

int record(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {"--out", "--scenario", "--density", "--seed",
                                                 "--method", "--replans", "--dynamic-obstacle"});
  if (!parsed.error.empty()) return usageError(parsed.error);
  if (!parsed.positional.empty()) {
    return usageError("unexpected argument '" + parsed.positional[0] + "'");
  }
  for (const char* required : {"--out", "--scenario", "--density", "--seed", "--method"}) {
    if (!parsed.flags.count(required)) return usageError(std::string("record needs ") + required);
  }
  FlightSpec flight;
  flight.scenario = parsed.flags.at("--scenario");
  flight.method = parsed.flags.at("--method");
  if (!parseDensity(parsed.flags.at("--density"), flight.density)) {
    return usageError("--density '" + parsed.flags.at("--density") +
                      "' is not a non-negative number");
  }
  long long value = 0;
  if (!parseInteger(parsed.flags.at("--seed"), 0, value)) {
    return usageError("--seed must be an integer >= 0, not '" + parsed.flags.at("--seed") + "'");
  }
  flight.seed = value;
  if (parsed.flags.count("--replans")) {
    if (!parseInteger(parsed.flags.at("--replans"), 1, value) || value > 100000) {
      return usageError("--replans must be an integer from 1 to 100000, not '" +
                        parsed.flags.at("--replans") + "'");
    }
    flight.replans = static_cast<int>(value);
  }
  if (parsed.flags.count("--dynamic-obstacle")) {
    const std::string& on = parsed.flags.at("--dynamic-obstacle");
    if (on != "on" && on != "off") {
      return usageError("--dynamic-obstacle must be on or off, not '" + on + "'");
    }
    flight.dynamic_obstacle = on == "on";
  }
  if (const auto invalid = thicket::replay::validateFlight(flight)) return usageError(*invalid);
  return recordAndCheck(flight, parsed.flags.at("--out")) < 0 ? 1 : 0;
}

int recordReferences(const std::vector<std::string>& args) {
  const Arguments parsed = parseArguments(args, {"--logs"});
  if (!parsed.error.empty()) return usageError(parsed.error);
  if (!parsed.positional.empty()) {
    return usageError("unexpected argument '" + parsed.positional[0] + "'");
  }
  const std::string dir =
      parsed.flags.count("--logs") ? parsed.flags.at("--logs") : thicket::replay::defaultLogsDir();
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
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) return usageError("no command given");
  const std::string& command = args[0];
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "check") return check(rest);
  if (command == "record") return record(rest);
  if (command == "record-references") return recordReferences(rest);
  return usageError("unknown command '" + command + "'");
}

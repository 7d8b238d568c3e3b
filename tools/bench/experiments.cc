#include "experiments.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <tuple>

#include "csv.h"
#include "flags.h"
#include "report.h"
#include "subsampling.h"
#include "thicket/common/lcm_log.h"
#include "thicket/common/number_text.h"
#include "thicket/sim/world.h"
#include "trials.h"

namespace thicket::bench {

namespace fs = std::filesystem;

std::string TrialSpec::key() const {
  return experiment + "/" + scenario + "/d" + formatNumber("%g", density) + "/" + method + "/" +
         goal_finding + "/" + sensor + "/s" + std::to_string(seed);
}

std::string keyFileName(const std::string& key) {
  std::string name = key;
  std::replace(name.begin(), name.end(), '/', '-');
  return name;
}

std::string trialPathFile(const std::string& key) {
  return "paths/" + keyFileName(key) + ".csv";
}

std::string trialLogFile(const std::string& key) {
  return "logs/" + keyFileName(key) + ".lcm";
}

namespace {

// ---- the experiments (docs/benchmark.md) ----

// An experiment that flies trials: the cross product of its lists, `trials` worlds each.
struct Plan {
  const char* id;
  std::vector<std::string> scenarios;
  std::vector<double> densities;
  std::vector<std::string> methods;
  std::vector<std::string> goal_findings;
  int trials;
  int replans;
  bool dynamic_obstacle = false;  // the simulator's dynamic obstacle, with its default options
};

const std::vector<Plan>& plans() {
  static const std::vector<Plan> table = [] {
    // 0.05 ... 0.50: k / 20 is the double nearest each decimal, as "0.15" parses.
    std::vector<double> paper;
    for (int k = 1; k <= 10; ++k) paper.push_back(k / 20.0);
    return std::vector<Plan>{
        {"E1", {"paper"}, paper, {"none"}, goalFindingNames(), 100, 60},
        {"E2", {"paper", "eth"}, paper, methodNames(), {"soft"}, 50, 120},
        {"E4", {"forest50"}, {0.1, 0.2}, methodNames(false), {"soft"}, 20, 500},
        // A path blocked in flight: a cylinder appears on the committed trajectory.
        {"E6", {"paper"}, {0.2}, methodNames(false), {"soft"}, 20, 60, true},
    };
  }();
  return table;
}

// What each --experiment name selects: the plan whose trials it needs (E3 is computed from E2's
// rows, T1 from E4's), or none for E5, which is its own program.
struct ExperimentName {
  const char* name;
  const char* plan;  // nullptr: E5
};
const ExperimentName kExperimentNames[] = {{"E1", "E1"}, {"E2", "E2"},    {"E3", "E2"},
                                           {"E4", "E4"}, {"E5", nullptr}, {"E6", "E6"},
                                           {"T1", "E4"}};

bool sameDensity(double a, double b) {
  return std::abs(a - b) < 1e-9;
}

std::string joined(const std::vector<std::string>& items, const char* separator = ", ") {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : separator) + item;
  return text;
}

std::string densityList(const std::vector<double>& densities) {
  std::vector<std::string> items;
  for (double d : densities) items.push_back(formatNumber("%g", d));
  return joined(items);
}

int onlineCpus() {
  const long cpus = ::sysconf(_SC_NPROCESSORS_ONLN);
  return cpus > 0 ? static_cast<int>(cpus) : 1;
}

std::vector<std::string> experimentNames() {
  std::vector<std::string> names;
  for (const ExperimentName& e : kExperimentNames) names.emplace_back(e.name);
  return names;
}

// "a,b," -> {"a", "b", ""}; "" -> {}.
std::vector<std::string> split(const std::string& text, char separator = ',') {
  std::vector<std::string> items;
  std::stringstream stream(text);
  for (std::string item; std::getline(stream, item, separator);) items.push_back(item);
  if (!text.empty() && text.back() == separator) items.emplace_back();
  return items;
}

// "i/N" with 0 <= i < N into the shard's index and count.
bool parseShard(const std::string& text, int& index, int& count) {
  const size_t slash = text.find('/');
  if (slash == std::string::npos) return false;
  const std::optional<int> i = integerNumber<int>(text.substr(0, slash));
  const std::optional<int> n = integerNumber<int>(text.substr(slash + 1));
  if (!i || !n || *n < 1 || *i < 0 || *i >= *n) return false;
  index = *i;
  count = *n;
  return true;
}

bool selects(const std::vector<std::string>& filter, const std::string& item) {
  return filter.empty() || std::find(filter.begin(), filter.end(), item) != filter.end();
}

bool selectsDensity(const std::vector<double>& filter, double density) {
  return filter.empty() || std::any_of(filter.begin(), filter.end(),
                                       [&](double d) { return sameDensity(d, density); });
}

// The plans the experiments select, in the plans' order.
std::vector<const Plan*> selectedPlans(const ExperimentOptions& options) {
  std::vector<const Plan*> selected;
  for (const Plan& plan : plans()) {
    for (const ExperimentName& e : kExperimentNames) {
      if (e.plan != nullptr && e.plan == std::string(plan.id) &&
          selects(options.experiments, e.name)) {
        selected.push_back(&plan);
        break;
      }
    }
  }
  return selected;
}

// A filter value that matches no configuration of the selected experiments is a mistake (a
// typo, or a density an experiment does not fly), not a reason to run nothing quietly.
std::optional<std::string> checkFilters(const ExperimentOptions& options) {
  const std::vector<const Plan*> selected = selectedPlans(options);
  if (selected.empty() && !(options.scenarios.empty() && options.densities.empty() &&
                            options.methods.empty() && options.goal_findings.empty())) {
    return std::string(
        "--scenario, --density, --method and --goal-finding select trials; the "
        "selected experiments fly none");
  }
  const auto refuse = [&](const std::string& flag, const std::string& value,
                          const std::string& what,
                          const std::function<std::string(const Plan&)>& list) -> std::string {
    std::string known;
    for (const Plan* plan : selected) {
      known += (known.empty() ? "" : "; ") + std::string(plan->id) + ": " + list(*plan);
    }
    return flag + " " + value + " is not a " + what + " of the selected experiments (" + known +
           ")";
  };
  for (const std::string& scenario : options.scenarios) {
    if (std::none_of(selected.begin(), selected.end(),
                     [&](const Plan* p) { return selects(p->scenarios, scenario); })) {
      return refuse("--scenario", scenario, "scenario",
                    [](const Plan& p) { return joined(p.scenarios); });
    }
  }
  for (double density : options.densities) {
    if (std::none_of(selected.begin(), selected.end(),
                     [&](const Plan* p) { return selectsDensity(p->densities, density); })) {
      return refuse("--density", formatNumber("%g", density), "density",
                    [](const Plan& p) { return densityList(p.densities); });
    }
  }
  struct NameFilter {
    const char* flag;
    const std::vector<std::string>& values;
    std::vector<std::string> Plan::*names;
    const char* what;
  };
  for (const NameFilter& filter :
       {NameFilter{"--method", options.methods, &Plan::methods, "method"},
        NameFilter{"--goal-finding", options.goal_findings, &Plan::goal_findings,
                   "goal-finding variant"}}) {
    const auto names = filter.names;
    for (const std::string& value : filter.values) {
      if (std::none_of(selected.begin(), selected.end(),
                       [&](const Plan* p) { return selects(p->*names, value); })) {
        return refuse(filter.flag, value, filter.what,
                      [names](const Plan& p) { return joined(p.*names); });
      }
    }
  }
  return {};
}

void addExperimentFlags(CLI::App& app, ExperimentOptions& o) {
  using cli::nonEmpty;
  const auto defaults = [](int Plan::*member) {
    std::string text;
    for (const Plan& plan : plans()) {
      text +=
          (text.empty() ? "" : ", ") + std::string(plan.id) + " " + std::to_string(plan.*member);
    }
    return text;
  };
  app.add_option("--out", o.out, "the output folder")->required()->check(nonEmpty());
  app.add_option("--experiment", o.experiments,
                 "comma list of E1, E2, E3 (E2's trials), E4, T1 (E4's trials), E5, E6 "
                 "(default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(experimentNames()));
  app.add_option("--scenario", o.scenarios,
                 "only these scenarios (E1, E6: paper; E2: paper, eth; E4: forest50)")
      ->delimiter(',')
      ->check(nonEmpty());
  app.add_option("--density", o.densities,
                 "only these densities (E1, E2: 0.05 ... 0.5; E4: 0.1, 0.2; E6: 0.2)")
      ->delimiter(',')
      ->check(cli::number(0));
  app.add_option("--method", o.methods, "only these methods: " + joined(methodNames()))
      ->delimiter(',')
      ->check(CLI::IsMember(methodNames()));
  app.add_option(
         "--goal-finding", o.goal_findings,
         "only these goal-finding variants: " + joined(goalFindingNames()) + " (E2, E4, E6: soft)")
      ->delimiter(',')
      ->check(CLI::IsMember(goalFindingNames()));
  app.add_option("--trials", o.trials,
                 "trials per configuration (default " + defaults(&Plan::trials) + ")")
      ->check(cli::integer(1, std::numeric_limits<int>::max()));
  app.add_option("--replans", o.replans,
                 "replan limit of every trial (default " + defaults(&Plan::replans) + ")")
      ->check(cli::integer(1, std::numeric_limits<int>::max()));
  app.add_option("--seed-base", o.seed_base, "trial t flies the world of seed B+t")
      ->check(cli::integer(0))
      ->capture_default_str();
  app.add_option("--jobs", o.jobs,
                 "trials run on J threads (default: the online CPUs, " +
                     std::to_string(onlineCpus()) + " here)")
      ->check(cli::integer(1, 1024));
  app.add_option("--shard", o.shard,
                 "i/N: run only the trials at positions i, i+N, i+2N ... of the trial list (0 <= "
                 "i < N); give every shard the same selection flags, then thicket-bench merge "
                 "the output folders")
      ->check(CLI::Validator(
          [](const std::string& text) -> std::string {
            int index = 0, count = 0;
            return parseShard(text, index, count)
                       ? ""
                       : "must be i/N with 0 <= i < N (e.g. 0/4 ... 3/4), not '" + text + "'";
          },
          "i/N"));
  app.add_option("--record", o.record,
                 "keep the LCM log of the trials run whose key contains a match of this regular "
                 "expression: DIR/logs/<key>.lcm")
      ->check(CLI::Validator(
          [](const std::string& text) -> std::string {
            try {
              std::regex check(text);
            } catch (const std::regex_error& e) {
              return "'" + text + "' is not a regular expression: " + e.what();
            }
            return {};
          },
          "REGEX"));
  app.add_option("--worlds-dir", o.worlds_dir, "where scenario names are looked up")
      ->check(nonEmpty())
      ->capture_default_str();
}

constexpr const char* kExperimentHelp =
    "thicket-bench experiment: flies the trials of the benchmark's experiments\n"
    "(docs/benchmark.md) with the real nodes on memq://, on parallel threads, and writes\n"
    "DIR/trials.csv (one row per trial), DIR/paths/<key>.csv, DIR/run_log.csv and the report.\n"
    "Every finished trial is kept at once in DIR/rows/, so running the same command again\n"
    "resumes: trials already there are skipped, trials that could not run are tried again.\n"
    "A trial's key is experiment/scenario/d<density>/method/goal_finding/sensor/s<seed>, e.g.\n"
    "E2/paper/d0.2/random/soft/depth/s7; its files are named by the key with '-'.";

constexpr const char* kMergeHelp =
    "thicket-bench merge: gathers the trials of output folders of thicket-bench experiment\n"
    "(shards run on other machines) into DIR: their rows (each trial once; one that ran is\n"
    "preferred to one that could not) in DIR/rows/merged.csv with the trials' paths and logs,\n"
    "their run log lines, then writes DIR/trials.csv, a DIR/run_log.csv line and the report.\n"
    "Refuses rows files written with other columns (also those of an older thicket-bench\n"
    "without the oracle columns solvable_collision_radius, bottleneck_m, needs_overflight or\n"
    "the dynamic obstacle's obstacle_clearance_m, blocked_cycles).";

}  // namespace

Expected<ExperimentOptions> parseExperimentOptions(const std::vector<std::string>& args) {
  ExperimentOptions options;
  options.worlds_dir = std::string(THICKET_SOURCE_DIR) + "/config/worlds";
  options.jobs = onlineCpus();
  auto parsed = parseCommand<ExperimentOptions>("experiment", kExperimentHelp, args,
                                                addExperimentFlags, options);
  if (!parsed || !parsed->help.empty()) return parsed;
  if (!parsed->shard.empty()) parseShard(parsed->shard, parsed->shard_index, parsed->shard_count);
  for (auto* list : {&parsed->experiments, &parsed->scenarios, &parsed->methods,
                     &parsed->goal_findings}) {  // duplicates are dropped, the order kept
    std::vector<std::string> unique;
    for (const std::string& item : *list) {
      if (std::find(unique.begin(), unique.end(), item) == unique.end()) unique.push_back(item);
    }
    *list = unique;
  }
  if (auto error = checkFilters(*parsed)) return unexpected(*error);
  return parsed;
}

std::vector<TrialSpec> trialList(const ExperimentOptions& options) {
  std::vector<TrialSpec> list;
  for (const Plan* plan : selectedPlans(options)) {
    TrialSpec spec;
    spec.experiment = plan->id;
    spec.dynamic_obstacle = plan->dynamic_obstacle;
    spec.replans = options.replans.value_or(plan->replans);
    const int trials = options.trials.value_or(plan->trials);
    for (int t = 0; t < trials; ++t) {
      spec.trial = t;
      spec.seed = static_cast<uint64_t>(options.seed_base) + static_cast<uint64_t>(t);
      for (const std::string& scenario : plan->scenarios) {
        if (!selects(options.scenarios, scenario)) continue;
        spec.scenario = scenario;
        for (double density : plan->densities) {
          if (!selectsDensity(options.densities, density)) continue;
          spec.density = density;
          for (const std::string& method : plan->methods) {
            if (!selects(options.methods, method)) continue;
            spec.method = method;
            for (const std::string& goal_finding : plan->goal_findings) {
              if (!selects(options.goal_findings, goal_finding)) continue;
              spec.goal_finding = goal_finding;
              list.push_back(spec);
            }
          }
        }
      }
    }
  }
  return list;
}

namespace {

// ---- rows: the trials finished so far ----

// The columns of a rows file: trials.csv's fixed columns, then the timings of every stage in one
// cell ("<stage>=<median>/<p95>/<max>;...", ms).
const std::vector<std::string>& idColumns() {
  static const std::vector<std::string> columns = {"experiment",   "trial",   "seed",
                                                   "scenario",     "density", "method",
                                                   "goal_finding", "sensor",  "replan_limit"};
  return columns;
}

const std::vector<std::string>& rowColumns() {
  static const std::vector<std::string> columns = [] {
    std::vector<std::string> all = idColumns();
    all.insert(all.end(), outcomeColumns().begin(), outcomeColumns().end());
    all.emplace_back("timings");
    return all;
  }();
  return columns;
}

size_t column(const std::string& name) {
  const auto& columns = rowColumns();
  return static_cast<size_t>(std::find(columns.begin(), columns.end(), name) - columns.begin());
}

// One finished trial, as stored.
struct Row {
  std::vector<std::string> cells;  // under rowColumns()
  TrialSpec spec;                  // what the cells say, for keys and sorting
  std::map<std::string, StageTiming> timings;
  std::string source;  // the output folder the row was read from (merge copies its files)

  const std::string& cell(const std::string& name) const { return cells[column(name)]; }
  bool failed() const { return failedToRun(cell("end_reason")); }
};

std::string timingsText(const std::map<std::string, StageTiming>& timings) {
  std::string text;
  for (const auto& [stage, t] : timings) {
    text += (text.empty() ? "" : ";") + stage + "=" + formatNumber("%.3f", t.median_ms) + "/" +
            formatNumber("%.3f", t.p95_ms) + "/" + formatNumber("%.3f", t.max_ms);
  }
  return text;
}

bool parseDouble(const std::string& text, double& value) {
  const std::optional<double> parsed = finiteNumber(text);
  if (parsed) value = *parsed;
  return parsed.has_value();
}

template <class Int>
bool parseInt(const std::string& text, Int& value) {
  const std::optional<Int> parsed = integerNumber<Int>(text);
  if (parsed) value = *parsed;
  return parsed.has_value();
}

std::optional<std::map<std::string, StageTiming>> parseTimings(const std::string& text) {
  std::map<std::string, StageTiming> timings;
  if (text.empty()) return timings;
  for (const std::string& item : split(text, ';')) {
    const size_t equals = item.find('=');
    if (equals == 0 || equals == std::string::npos) return std::nullopt;
    const std::vector<std::string> numbers = split(item.substr(equals + 1), '/');
    StageTiming t;
    if (numbers.size() != 3 || !parseDouble(numbers[0], t.median_ms) ||
        !parseDouble(numbers[1], t.p95_ms) || !parseDouble(numbers[2], t.max_ms)) {
      return std::nullopt;
    }
    timings[item.substr(0, equals)] = t;
  }
  return timings;
}

// The row a stored line holds, or why it is not one.
Expected<Row> rowFromCells(std::vector<std::string> cells) {
  if (cells.size() != rowColumns().size()) {
    return unexpected(std::to_string(cells.size()) + " cells instead of " +
                      std::to_string(rowColumns().size()));
  }
  Row row;
  row.cells = std::move(cells);
  TrialSpec& s = row.spec;
  s.experiment = row.cell("experiment");
  s.scenario = row.cell("scenario");
  s.method = row.cell("method");
  s.goal_finding = row.cell("goal_finding");
  s.sensor = row.cell("sensor");
  const auto plan = std::find_if(plans().begin(), plans().end(),
                                 [&](const Plan& p) { return s.experiment == p.id; });
  if (plan == plans().end()) return unexpected("unknown experiment '" + s.experiment + "'");
  s.dynamic_obstacle = plan->dynamic_obstacle;
  if (!parseInt(row.cell("trial"), s.trial) || !parseInt(row.cell("seed"), s.seed) ||
      !parseDouble(row.cell("density"), s.density) ||
      !parseInt(row.cell("replan_limit"), s.replans)) {
    return unexpected("trial, seed, density or replan_limit is not a number");
  }
  for (const char* flag : {"success", "collision", "feasible", "solvable",
                           "solvable_collision_radius", "needs_overflight"}) {
    if (row.cell(flag) != "0" && row.cell(flag) != "1") {
      return unexpected(std::string(flag) + " is neither 0 nor 1");
    }
  }
  double clearance = 0;
  int blocked = 0;
  if (!row.cell("obstacle_clearance_m").empty() &&
      !parseDouble(row.cell("obstacle_clearance_m"), clearance)) {
    return unexpected("obstacle_clearance_m is neither empty nor a number");
  }
  if (!parseInt(row.cell("blocked_cycles"), blocked) || blocked < 0) {
    return unexpected("blocked_cycles is not a count");
  }
  auto timings = parseTimings(row.cell("timings"));
  if (!timings) return unexpected("timings is not stage=median/p95/max;...");
  row.timings = std::move(*timings);
  return row;
}

Row rowFromResult(const TrialSpec& spec, const TrialResult& result) {
  Row row;
  row.spec = spec;
  row.cells = {spec.experiment,
               std::to_string(spec.trial),
               std::to_string(spec.seed),
               spec.scenario,
               formatNumber("%g", spec.density),
               spec.method,
               spec.goal_finding,
               spec.sensor,
               std::to_string(spec.replans)};
  const std::vector<std::string> outcome = outcomeCells(result);
  row.cells.insert(row.cells.end(), outcome.begin(), outcome.end());
  row.cells.push_back(timingsText(result.timings));
  row.timings = result.timings;
  return row;
}

std::string readWholeFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error("cannot read " + path);
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (file.bad()) throw std::runtime_error("cannot read " + path);
  return text;
}

void warn(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "thicket-bench %s: %s\n", command.c_str(), message.c_str());
}

// Throws unless `csv` is empty or starts with the rows header. Rows of an older thicket-bench
// are refused with what they lack, not read with the new columns empty: those written before the
// oracle had two radii have `solvable` at the collision radius, where new rows have it at the
// planning radius; those written before the dynamic obstacle have no obstacle_clearance_m and
// blocked_cycles, which an E6 row must have.
void checkRowsHeader(const std::string& path, const CsvText& csv) {
  if (csv.records.empty() || csv.records[0].cells == rowColumns()) return;
  const std::vector<std::string>& header = csv.records[0].cells;
  const auto has = [&](const char* column) {
    return std::find(header.begin(), header.end(), column) != header.end();
  };
  const auto older = [&](const std::string& what) {
    return std::runtime_error(path + ": rows of an older thicket-bench, " + what +
                              "; they cannot be resumed or merged with new rows (use another "
                              "--out; the report still reads that folder's trials.csv)");
  };
  if (has("solvable") && !has("solvable_collision_radius")) {
    throw older(
        "whose solvable is the oracle at the collision radius and which lack "
        "solvable_collision_radius, bottleneck_m and needs_overflight");
  }
  if (has("end_reason") && !has("obstacle_clearance_m") && !has("blocked_cycles")) {
    throw older(
        "written before the dynamic obstacle (E6), which lack obstacle_clearance_m and "
        "blocked_cycles");
  }
  throw std::runtime_error(path + ": not a rows file of this thicket-bench (its header is '" +
                           joined(header, ",") + "', expected '" + joined(rowColumns(), ",") +
                           "')");
}

// The rows of `text` (the file `path`); a torn last line is ignored (a run killed mid-write), a
// line that is not a row is reported and ignored (its trial runs again). Throws when the header
// is not rowColumns(): that is another program's file, or another version's.
std::vector<Row> parseRows(const std::string& command, const std::string& path,
                           const std::string& text, const std::string& source) {
  const CsvText csv = parseCsv(text);
  std::vector<Row> rows;
  checkRowsHeader(path, csv);
  if (csv.records.empty()) return rows;  // empty, or a header torn while being written
  if (csv.torn_tail) warn(command, "ignoring the torn last line of " + path + " (a killed run)");
  for (size_t i = 1; i < csv.records.size(); ++i) {
    Expected<Row> row = rowFromCells(csv.records[i].cells);
    if (!row) {
      warn(command, path + " line " + std::to_string(csv.records[i].line) + ": " + row.error() +
                        "; ignored");
      continue;
    }
    row->source = source;
    rows.push_back(std::move(*row));
  }
  return rows;
}

// Every row of DIR/rows/*.csv, in file name order. Throws as parseRows, or when a file cannot be
// read.
std::vector<Row> readRows(const std::string& command, const std::string& dir) {
  std::vector<std::string> files;
  if (fs::is_directory(dir + "/rows")) {
    for (const fs::directory_entry& entry : fs::directory_iterator(dir + "/rows")) {
      if (entry.is_regular_file() && entry.path().extension() == ".csv") {
        files.push_back(entry.path().string());
      }
    }
  }
  std::sort(files.begin(), files.end());
  std::vector<Row> rows;
  for (const std::string& file : files) {
    std::vector<Row> more = parseRows(command, file, readWholeFile(file), dir);
    std::move(more.begin(), more.end(), std::back_inserter(rows));
  }
  return rows;
}

// Each trial once: a later row replaces an earlier one, unless the later could not run and the
// earlier did. Sorted by experiment, scenario, density, method, goal finding, sensor, seed.
// Throws when a trial was flown with two replan limits (runs with different --replans in one
// folder): the rows would not describe one experiment.
std::vector<Row> uniqueRows(std::vector<Row> rows) {
  std::map<std::string, Row> by_key;
  for (Row& row : rows) {
    const std::string key = row.spec.key();
    const auto existing = by_key.find(key);
    if (existing == by_key.end()) {
      by_key.emplace(key, std::move(row));
      continue;
    }
    const Row& kept = existing->second;
    if (!row.failed() && !kept.failed() && row.spec.replans != kept.spec.replans) {
      throw std::runtime_error(
          key + " was flown with replan limit " + std::to_string(kept.spec.replans) + " (in " +
          kept.source + ") and " + std::to_string(row.spec.replans) + " (in " + row.source + ")");
    }
    if (!row.failed() || kept.failed()) {
      existing->second = std::move(row);
    }
  }
  std::vector<Row> unique;
  for (auto& [key, row] : by_key) unique.push_back(std::move(row));
  const auto order = [](const Row& r) {
    const TrialSpec& s = r.spec;
    return std::tie(s.experiment, s.scenario, s.density, s.method, s.goal_finding, s.sensor,
                    s.seed);
  };
  std::sort(unique.begin(), unique.end(),
            [&](const Row& a, const Row& b) { return order(a) < order(b); });
  return unique;
}

// Written beside `path` and renamed over it, so a reader never sees half a file.
void replaceFile(const std::string& path, const std::string& text) {
  const std::string temporary = path + ".tmp";
  writeTextFile(temporary, text);
  std::error_code error;
  fs::rename(temporary, path, error);
  if (error) throw std::runtime_error("cannot write " + path + ": " + error.message());
}

std::string rowsText(const std::vector<Row>& rows) {
  std::string text = csvLine(rowColumns());
  for (const Row& row : rows) text += csvLine(row.cells);
  return text;
}

// trials.csv: the rows with their timings spread into three columns per stage seen in any row.
void writeTrialsCsv(const std::string& dir, const std::vector<Row>& rows) {
  std::set<std::string> stages;
  for (const Row& row : rows) {
    for (const auto& [stage, timing] : row.timings) stages.insert(stage);
  }
  std::vector<std::string> header(rowColumns().begin(), rowColumns().end() - 1);
  const std::vector<std::string> stage_columns = stageColumns(stages);
  header.insert(header.end(), stage_columns.begin(), stage_columns.end());
  std::string text = csvLine(header);
  for (const Row& row : rows) {
    std::vector<std::string> cells(row.cells.begin(), row.cells.end() - 1);
    const std::vector<std::string> timing_cells = stageCells(stages, row.timings);
    cells.insert(cells.end(), timing_cells.begin(), timing_cells.end());
    text += csvLine(cells);
  }
  replaceFile(dir + "/trials.csv", text);
}

// The rows file this shard appends to, locked against a second run of the same shard.
class RowsAppender {
 public:
  // Opens (creates) `path`; cuts a torn last line, so the next row starts on a line of its own;
  // writes the header into an empty file. Throws std::runtime_error saying what failed.
  RowsAppender(const std::string& command, const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd_);
      throw std::runtime_error("another thicket-bench experiment is writing " + path +
                               " (same --out and --shard)");
    }
    try {
      const std::string text = readWholeFile(path);
      const CsvText csv = parseCsv(text);
      checkRowsHeader(path, csv);
      if (csv.torn_tail || csv.records.empty()) {
        if (csv.torn_tail) {
          warn(command, "cutting the torn last line of " + path + " (a killed run)");
        }
        if (::ftruncate(fd_, csv.records.empty() ? 0 : static_cast<off_t>(csv.complete_bytes)) !=
            0) {
          throw std::runtime_error("cannot cut " + path + ": " + std::strerror(errno));
        }
      }
      if (csv.records.empty()) append(csvLine(rowColumns()));
    } catch (...) {
      ::close(fd_);
      throw;
    }
  }
  ~RowsAppender() { ::close(fd_); }
  RowsAppender(const RowsAppender&) = delete;
  RowsAppender& operator=(const RowsAppender&) = delete;

  // Appends a whole line; the kernel has it when this returns, so a killed run keeps it.
  void append(const std::string& line) {
    size_t written = 0;
    while (written < line.size()) {
      const ssize_t n = ::write(fd_, line.data() + written, line.size() - written);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) throw std::runtime_error("cannot write " + path_ + ": " + std::strerror(errno));
      written += static_cast<size_t>(n);
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
};

// ---- flying the trials ----

// The recorder of a trial's log; what went wrong writing it is known once the trial's graph is
// gone.
class TrialLog : public LogRecorder {
 public:
  TrialLog(lcm::LCM& lcm, const std::string& path, std::string& error)
      : LogRecorder(lcm, path), error_(error) {}
  ~TrialLog() override {
    flush();
    error_ = writeError();
  }

 private:
  std::string& error_;
};

struct FlyContext {
  const ExperimentOptions& options;
  std::optional<std::regex> record;
};

// Flies `spec`, writes its path (and log); a trial that could not run, or whose files could not
// be written, gets an "error: " row, so a resumed run tries it again.
Row flyTrial(const TrialSpec& spec, const FlyContext& context) {
  RunOptions run;
  run.scenario = spec.scenario;
  run.density = spec.density;
  run.method = spec.method;
  run.goal_finding = spec.goal_finding;
  run.sensor = spec.sensor;
  run.trials = 1;
  run.seed_base = static_cast<int64_t>(spec.seed) - spec.trial;
  run.replans = spec.replans;
  run.dynamic_obstacle = spec.dynamic_obstacle;
  run.worlds_dir = context.options.worlds_dir;
  run.out = context.options.out;
  const std::string key = spec.key();
  try {
    std::string log_error;
    TrialObserver observer;
    if (context.record && std::regex_search(key, *context.record)) {
      const std::string log = context.options.out + "/" + trialLogFile(key);
      observer = [log, &log_error](lcm::LCM& lcm) {
        return std::make_unique<TrialLog>(lcm, log, log_error);
      };
    }
    TrialResult result = runTrial(run, trialWorld(run, spec.trial), spec.trial, observer);
    if (!log_error.empty()) throw std::runtime_error("log: " + log_error);
    writePathFile(context.options.out + "/" + trialPathFile(key), result.path);
    return rowFromResult(spec, result);
  } catch (const std::exception& e) {
    TrialResult failed;
    failed.trial = spec.trial;
    failed.seed = spec.seed;
    failed.end_reason = failedEndReason(e.what());
    return rowFromResult(spec, failed);
  }
}

std::string formatDuration(double seconds) {
  const long s = std::lround(seconds);
  char text[32];
  if (s < 60) {
    std::snprintf(text, sizeof(text), "%lds", s);
  } else if (s < 3600) {
    std::snprintf(text, sizeof(text), "%ldm%02lds", s / 60, s % 60);
  } else {
    std::snprintf(text, sizeof(text), "%ldh%02ldm", s / 3600, s % 3600 / 60);
  }
  return text;
}

// One stderr line at most every 2 s and one at the end:
// "[E2] 1234/3000 done (12 resumed), 2.1 trials/s, ETA 14m10s, last: paper d0.2 random s7 goal
// reached". The counts are those of the last trial's experiment in this shard; the rate is that
// of the last kRateWindow trials this invocation finished (E4's trials take several times as
// long as E2's), the ETA the trials left in the whole run at that rate.
class Progress {
 public:
  Progress(const std::vector<const TrialSpec*>& shard, const std::set<std::string>& done,
           size_t to_run)
      : to_run_(to_run) {
    for (const TrialSpec* spec : shard) {
      Count& count = counts_[spec->experiment];
      ++count.total;
      if (done.count(spec->key())) {
        ++count.done;
        ++count.resumed;
      }
    }
    if (!shard.empty()) experiment_ = shard.front()->experiment;
  }

  void finished(const TrialSpec& spec, const Row& row) {
    const std::lock_guard lock(mutex_);
    ++run_;
    const auto now = std::chrono::steady_clock::now();
    finish_times_.push_back(now);
    if (finish_times_.size() > kRateWindow) finish_times_.pop_front();
    ++counts_[spec.experiment].done;
    experiment_ = spec.experiment;
    last_ = spec.scenario + " d" + formatNumber("%g", spec.density) + " " + spec.method +
            (spec.goal_finding == "soft" ? "" : " " + spec.goal_finding) + " s" +
            std::to_string(spec.seed) + " " + row.cell("end_reason");
    unprinted_ = true;
    if (now - printed_ >= std::chrono::seconds(2)) {
      printed_ = now;
      unprinted_ = false;
      print(now);
    }
  }

  // The last line, unless the last trial's line was it.
  void end() {
    const std::lock_guard lock(mutex_);
    if (!counts_.empty() && (unprinted_ || run_ == 0)) print(std::chrono::steady_clock::now());
  }

 private:
  void print(std::chrono::steady_clock::time_point now) const {
    const Count& count = counts_.at(experiment_);
    // Trials per second: over the window once it is full, before that since the start.
    const bool full = finish_times_.size() == kRateWindow;
    const double elapsed =
        std::chrono::duration<double>(now - (full ? finish_times_.front() : started_)).count();
    const double trials = full ? static_cast<double>(kRateWindow - 1) : static_cast<double>(run_);
    const double rate = elapsed > 0 ? trials / elapsed : 0;
    const size_t left = to_run_ - run_;
    const std::string eta = left == 0  ? "0s"
                            : rate > 0 ? formatDuration(static_cast<double>(left) / rate)
                                       : "?";
    std::fprintf(stderr, "[%s] %d/%d done (%d resumed), %s trials/s, ETA %s%s\n",
                 experiment_.c_str(), count.done, count.total, count.resumed,
                 formatNumber("%.3g", rate).c_str(), eta.c_str(),
                 last_.empty() ? "" : (", last: " + last_).c_str());
  }

  struct Count {
    int total = 0, done = 0, resumed = 0;
  };
  static constexpr size_t kRateWindow = 50;
  std::mutex mutex_;
  std::deque<std::chrono::steady_clock::time_point> finish_times_;
  std::map<std::string, Count> counts_;
  std::string experiment_;
  std::string last_;
  size_t to_run_ = 0;
  size_t run_ = 0;
  bool unprinted_ = false;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point printed_ = started_;
};

// ---- run log ----

std::string cpuModel() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) break;
    const size_t first = line.find_first_not_of(" \t", colon + 1);
    return first == std::string::npos ? "unknown" : line.substr(first);
  }
  return "unknown";
}

std::string utcNow(std::time_t when) {
  std::tm utc{};
  ::gmtime_r(&when, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

const std::vector<std::string>& runLogColumns() {
  static const std::vector<std::string> columns = {"started_utc",    "wall_s", "command",
                                                   "jobs",           "shard",  "trials_run",
                                                   "trials_skipped", "cpu",    "cores"};
  return columns;
}

// Appends `lines` (complete CSV lines) to DIR/run_log.csv, with the header when it is new.
void appendRunLog(const std::string& dir, const std::string& lines) {
  const std::string path = dir + "/run_log.csv";
  std::string text;
  if (fs::exists(path)) {
    const CsvText csv = parseCsv(readWholeFile(path));
    if (!csv.records.empty() && csv.records[0].cells != runLogColumns()) {
      throw std::runtime_error(path + " is not a run log of this thicket-bench (header '" +
                               joined(csv.records[0].cells, ",") + "')");
    }
    if (csv.records.empty()) text = csvLine(runLogColumns());
  } else {
    text = csvLine(runLogColumns());
  }
  std::ofstream file(path, std::ios::binary | std::ios::app);
  file << text << lines;
  file.close();
  if (!file) throw std::runtime_error("cannot write " + path);
}

std::string runLogLine(std::time_t started, double wall_s, const std::string& command, int jobs,
                       const std::string& shard, size_t run, size_t skipped) {
  return csvLine({utcNow(started), formatNumber("%.1f", wall_s), command, std::to_string(jobs),
                  shard, std::to_string(run), std::to_string(skipped), cpuModel(),
                  std::to_string(onlineCpus())});
}

std::string commandLine(const std::string& subcommand, const std::vector<std::string>& args) {
  std::string text = "thicket-bench " + subcommand;
  for (const std::string& arg : args) text += " " + arg;
  return text;
}

// ---- the end of a run or merge ----

// trials.csv from every row in DIR/rows, a stdout summary, and the report. Returns false when
// something could not be written.
// Experiment E5 (subsampling.h) into out/e5_subsampling.csv, on shard 0 only, and not again
// when a resumed run finds its table there. False when it failed (said on stderr).
bool runE5(const ExperimentOptions& options) {
  const std::string table = options.out + "/e5_subsampling.csv";
  if (options.shard_index != 0) return true;
  if (std::filesystem::exists(table)) {
    std::fprintf(stderr, "[E5] %s exists: not run again\n", table.c_str());
    return true;
  }
  SubsamplingOptions e5;
  e5.seed_base = options.seed_base;
  e5.jobs = options.jobs;
  e5.worlds_dir = options.worlds_dir;
  e5.out_dir = options.out;
  const auto rows = runSubsampling(e5);
  if (!rows) {
    std::fprintf(stderr, "[E5] failed: %s\n", rows.error().c_str());
    return false;
  }
  return true;
}

bool finish(const std::string& command, const std::string& dir) {
  try {
    const std::vector<Row> rows = uniqueRows(readRows(command, dir));
    writeTrialsCsv(dir, rows);
    std::vector<std::string> collisions;
    size_t conservative_rows = 0, failed = 0;
    for (const Row& row : rows) {
      failed += row.failed();
      if (!conservativeMethod(row.spec.method) || row.failed()) continue;
      ++conservative_rows;
      if (row.cell("collision") == "1") collisions.push_back(row.spec.key());
    }
    std::printf(
        "%s/trials.csv: %zu trials, %zu could not run; collisions of conservative "
        "methods: %zu of %zu trials\n",
        dir.c_str(), rows.size(), failed, collisions.size(), conservative_rows);
    for (size_t i = 0; i < collisions.size() && i < 10; ++i) {
      std::printf("  collision: %s\n", collisions[i].c_str());
    }
    if (collisions.size() > 10) std::printf("  ... and %zu more\n", collisions.size() - 10);
    const std::string report = writeReport(dir);
    if (!report.empty()) std::printf("%s\n", report.c_str());
    return true;
  } catch (const std::exception& e) {
    warn(command, e.what());
    return false;
  }
}

}  // namespace

int experimentCommand(const std::vector<std::string>& args) {
  const std::string command = "experiment";
  auto parsed = parseExperimentOptions(args);
  if (!parsed) return usageError(command, parsed.error());
  const ExperimentOptions& options = *parsed;
  if (!options.help.empty()) {
    std::fputs(options.help.c_str(), stdout);
    return 0;
  }
  const std::time_t started_utc = std::time(nullptr);
  const auto started = std::chrono::steady_clock::now();

  const std::vector<TrialSpec> list = trialList(options);
  std::set<std::string> scenarios;
  for (const TrialSpec& spec : list) scenarios.insert(spec.scenario);
  for (const std::string& scenario : scenarios) {
    if (auto spec = sim::loadScenario(scenario, options.worlds_dir); !spec) {
      return usageError(command, spec.error() + " (--worlds-dir " + options.worlds_dir + ")");
    }
  }
  std::optional<std::regex> record;
  if (!options.record.empty()) record.emplace(options.record);

  const std::string shard =
      std::to_string(options.shard_index) + "/" + std::to_string(options.shard_count);
  const std::string shard_file = options.out + "/rows/shard-" +
                                 std::to_string(options.shard_index) + "-of-" +
                                 std::to_string(options.shard_count) + ".csv";
  std::unique_ptr<RowsAppender> appender;
  std::set<std::string> done;
  std::map<std::string, int> done_replans;
  try {
    fs::create_directories(options.out + "/rows");
    fs::create_directories(options.out + "/paths");
    if (record) fs::create_directories(options.out + "/logs");
    appender = std::make_unique<RowsAppender>(command, shard_file);
    for (const Row& row : readRows(command, options.out)) {
      if (row.failed()) continue;
      done.insert(row.spec.key());
      done_replans[row.spec.key()] = row.spec.replans;
    }
  } catch (const std::exception& e) {
    warn(command, e.what());
    return 1;
  }

  std::vector<const TrialSpec*> in_shard, to_run;
  for (size_t i = 0; i < list.size(); ++i) {
    if (!inShard(i, options.shard_index, options.shard_count)) continue;
    const TrialSpec& spec = list[i];
    in_shard.push_back(&spec);
    const auto kept = done_replans.find(spec.key());
    if (kept == done_replans.end()) {
      to_run.push_back(&spec);
    } else if (kept->second != spec.replans) {
      return usageError(command, "--replans: " + options.out + "/rows holds " + spec.key() +
                                     " flown with replan limit " + std::to_string(kept->second) +
                                     ", this run asks for " + std::to_string(spec.replans) +
                                     "; use another --out");
    }
  }
  const size_t skipped = in_shard.size() - to_run.size();
  if (record) {
    const auto logs = std::count_if(to_run.begin(), to_run.end(), [&](const TrialSpec* spec) {
      return std::regex_search(spec->key(), *record);
    });
    warn(command, logs == 0 ? "--record '" + options.record + "' matches none of the " +
                                  std::to_string(to_run.size()) + " trials to run"
                            : "keeping the logs of " + std::to_string(logs) + " trials in " +
                                  options.out + "/logs");
  }

  // A pool of threads pulling trials in list order; each trial has its own LCM and nodes, the
  // threads share the rows file and the progress (under locks).
  const FlyContext context{options, record};
  Progress progress(in_shard, done, to_run.size());
  std::atomic<size_t> next{0};
  std::atomic<size_t> failed{0};
  std::mutex rows_mutex;
  std::string write_error;
  auto worker = [&] {
    for (size_t i = next++; i < to_run.size(); i = next++) {
      const Row row = flyTrial(*to_run[i], context);
      failed += row.failed();
      {
        const std::lock_guard lock(rows_mutex);
        try {
          appender->append(csvLine(row.cells));
        } catch (const std::exception& e) {
          if (write_error.empty()) write_error = e.what();
        }
      }
      progress.finished(*to_run[i], row);
    }
  };
  const size_t threads_wanted = std::min(static_cast<size_t>(options.jobs), to_run.size());
  std::vector<std::thread> threads;
  for (size_t j = 0; j < threads_wanted; ++j) threads.emplace_back(worker);
  for (std::thread& thread : threads) thread.join();
  progress.end();
  appender.reset();

  int status = 0;
  if (!write_error.empty()) {
    warn(command, write_error);
    status = 1;
  }
  if (selects(options.experiments, "E5") && !runE5(options)) status = 1;

  std::printf(
      "shard %s: %zu trials, %zu run, %zu skipped (already in %s/rows), %zu could not "
      "run\n",
      shard.c_str(), in_shard.size(), to_run.size(), skipped, options.out.c_str(), failed.load());
  if (failed > 0) status = 1;
  // The run log first, so the report lists this invocation too.
  try {
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    appendRunLog(options.out, runLogLine(started_utc, wall_s, commandLine(command, args),
                                         options.jobs, shard, to_run.size(), skipped));
  } catch (const std::exception& e) {
    warn(command, e.what());
    status = 1;
  }
  if (!finish(command, options.out)) status = 1;
  return status;
}

namespace {

struct MergeOptions {
  std::string out;
  std::vector<std::string> inputs;
  std::string help;
};

void addMergeFlags(CLI::App& app, MergeOptions& o) {
  app.add_option("--out", o.out, "the output folder")->required()->check(cli::nonEmpty());
  app.add_option("IN_DIR", o.inputs, "output folders of thicket-bench experiment")
      ->required()
      ->check(cli::nonEmpty());
}

// Copies `from` over `to` unless they are the same file.
void copyOver(const fs::path& from, const fs::path& to) {
  std::error_code error;
  if (fs::exists(to) && fs::equivalent(from, to, error)) return;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, error);
  if (error) {
    throw std::runtime_error("cannot copy " + from.string() + " to " + to.string() + ": " +
                             error.message());
  }
}

}  // namespace

int mergeCommand(const std::vector<std::string>& args) {
  const std::string command = "merge";
  const auto parsed = parseCommand<MergeOptions>("merge", kMergeHelp, args, addMergeFlags);
  if (!parsed) return usageError(command, parsed.error());
  const MergeOptions& options = *parsed;
  if (!options.help.empty()) {
    std::fputs(options.help.c_str(), stdout);
    return 0;
  }
  const std::vector<std::string>& inputs = options.inputs;
  for (const std::string& input : inputs) {
    if (!fs::is_directory(input + "/rows")) {
      return usageError(command, "IN_DIR " + input +
                                     " has no rows/ folder: not an output folder of "
                                     "thicket-bench experiment");
    }
  }
  const std::time_t started_utc = std::time(nullptr);
  const auto started = std::chrono::steady_clock::now();
  try {
    // Everything is read and checked before anything is written.
    std::vector<Row> rows = readRows(command, options.out);
    std::string run_log_lines;
    std::set<std::string> run_log_seen;
    if (fs::exists(options.out + "/run_log.csv")) {
      const CsvText own = parseCsv(readWholeFile(options.out + "/run_log.csv"));
      for (size_t i = 1; i < own.records.size(); ++i) {
        run_log_seen.insert(csvLine(own.records[i].cells));
      }
    }
    for (const std::string& input : inputs) {
      std::vector<Row> more = readRows(command, input);
      std::move(more.begin(), more.end(), std::back_inserter(rows));
      // The shards' own run log lines, so the merged folder tells how every part was run.
      if (!fs::exists(input + "/run_log.csv")) continue;
      const CsvText log = parseCsv(readWholeFile(input + "/run_log.csv"));
      if (log.records.empty() || log.records[0].cells != runLogColumns()) {
        warn(command, input + "/run_log.csv is not a run log; its lines are not merged");
        continue;
      }
      for (size_t i = 1; i < log.records.size(); ++i) {
        const std::string line = csvLine(log.records[i].cells);
        if (run_log_seen.insert(line).second) run_log_lines += line;
      }
    }
    const size_t gathered = rows.size();
    rows = uniqueRows(std::move(rows));

    for (const char* sub : {"/rows", "/paths", "/logs"}) fs::create_directories(options.out + sub);
    size_t missing_paths = 0;
    for (const Row& row : rows) {
      const std::string path = trialPathFile(row.spec.key());
      if (fs::exists(fs::path(row.source) / path)) {
        copyOver(fs::path(row.source) / path, fs::path(options.out) / path);
      } else if (!row.failed()) {
        ++missing_paths;
      }
      const std::string log = trialLogFile(row.spec.key());
      if (fs::exists(fs::path(row.source) / log)) {
        copyOver(fs::path(row.source) / log, fs::path(options.out) / log);
      }
    }
    if (missing_paths > 0) {
      warn(command, std::to_string(missing_paths) + " trials have no path file in their folder");
    }
    for (const std::string& input : inputs) {
      const fs::path e5 = fs::path(input) / "e5_subsampling.csv";
      if (fs::exists(e5) && !fs::exists(fs::path(options.out) / "e5_subsampling.csv")) {
        copyOver(e5, fs::path(options.out) / "e5_subsampling.csv");
      }
    }
    replaceFile(options.out + "/rows/merged.csv", rowsText(rows));
    std::printf("merged %zu rows of %zu folders into %zu trials\n", gathered, inputs.size(),
                rows.size());
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    appendRunLog(options.out,
                 run_log_lines + runLogLine(started_utc, wall_s, commandLine(command, args), 1,
                                            "0/1", 0, rows.size()));
    if (!finish(command, options.out)) return 1;
  } catch (const std::exception& e) {
    warn(command, e.what());
    return 1;
  }
  return 0;
}

}  // namespace thicket::bench

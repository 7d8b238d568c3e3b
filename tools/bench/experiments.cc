// `thicket-bench experiment` and `merge`: their flags, flying the trials of a shard on a pool of
// threads into the row store, E5, and the end of a run or merge (trials.csv and the report).
#include "experiments.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <regex>
#include <set>
#include <stdexcept>

#include "csv.h"
#include "flags.h"
#include "parallel.h"
#include "plans.h"
#include "progress.h"
#include "report.h"
#include "row_store.h"
#include "run_log.h"
#include "subsampling.h"
#include "thicket/common/lcm_log.h"
#include "thicket/common/number_text.h"
#include "thicket/sim/world.h"
#include "trials.h"

namespace thicket::bench {

namespace fs = std::filesystem;

namespace {

// ---- the flags ----

std::string densityList(const std::vector<double>& densities) {
  std::vector<std::string> items;
  for (double d : densities) items.push_back(formatNumber("%g", d));
  return joined(items);
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
  app.add_option(
         "--config", o.config_dir,
         "every trial's graph options, DIR/<module>.yaml as for thicket-bench run (default: "
         "config/sim; config/sim_coarse flies 0.2 m voxels); a folder's rows are one "
         "configuration's: give another --out")
      ->check(nonEmpty());
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
  options.config_dir = simConfigDir();
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

namespace {

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
  run.config_dir = context.options.config_dir;
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

// ---- the end of a run or merge ----

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

// trials.csv from every row in DIR/rows, a stdout summary, and the report. Returns false when
// something could not be written.
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
  // A configuration that does not load is the user's to fix, before any trial flies.
  if (!list.empty()) {
    try {
      const TrialSpec& first = list.front();
      const auto world = sim::loadScenario(first.scenario, options.worlds_dir);
      trialGraphOptions(first.method, first.goal_finding, 0, Eigen::Vector3d::Zero(), world->size,
                        world->robot_radius, options.config_dir);
    } catch (const std::exception& e) {
      return usageError(command, e.what());
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
  std::atomic<size_t> failed{0};
  std::mutex rows_mutex;
  std::string write_error;
  parallelFor(to_run.size(), options.jobs, [&](size_t i) {
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
  });
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

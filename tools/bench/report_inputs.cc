// Reading trials.csv, run_log.csv and e5_subsampling.csv into rows, refusing bad cells.
#include "report_inputs.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "csv.h"
#include "thicket/common/number_text.h"

namespace thicket::bench::report_internal {
namespace {

// Bad input found while reading a file; caught in writeReport and returned as its message.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The cells of one file's rows by column name, converted with messages naming line and column.
class Columns {
 public:
  Columns(std::string file, const CsvTable& table) : file_(std::move(file)), table_(table) {
    for (size_t i = 0; i < table.header.size(); ++i) index_.emplace(table.header[i], i);
  }

  bool has(const std::string& name) const { return index_.count(name) > 0; }

  size_t require(const std::string& name) const {
    const auto found = index_.find(name);
    if (found == index_.end()) throw InputError(file_ + ": the header has no column " + name);
    return found->second;
  }

  // A finite number; an empty cell reads as `empty` when one is given.
  double number(const CsvRecord& row, size_t column,
                std::optional<double> empty = std::nullopt) const {
    const std::string& text = row.cells[column];
    if (text.empty() && empty) return *empty;
    const std::optional<double> value = finiteNumber(text);
    if (!value) {
      throw InputError(csvWhere(file_, row.line, column) + " (" + table_.header[column] + "): '" +
                       text + "' is not a finite number");
    }
    return *value;
  }

  int64_t integer(const CsvRecord& row, size_t column,
                  std::optional<int64_t> empty = std::nullopt) const {
    const std::string& text = row.cells[column];
    if (text.empty() && empty) return *empty;
    const std::optional<int64_t> value = integerNumber<int64_t>(text);
    if (!value) {
      throw InputError(csvWhere(file_, row.line, column) + " (" + table_.header[column] + "): '" +
                       text + "' is not an integer");
    }
    return *value;
  }

  bool flag(const CsvRecord& row, size_t column, std::optional<bool> empty = {}) const {
    const std::string& text = row.cells[column];
    if (text.empty() && empty) return *empty;
    if (text != "0" && text != "1") {
      throw InputError(csvWhere(file_, row.line, column) + " (" + table_.header[column] + "): '" +
                       text + "' is not 0 or 1");
    }
    return text == "1";
  }

 private:
  std::string file_;
  const CsvTable& table_;
  std::map<std::string, size_t> index_;
};

CsvTable readTable(const std::string& path) {
  auto table = readCsv(path);
  if (!table) throw InputError(table.error());
  return std::move(*table);
}

}  // namespace

std::vector<Trial> readTrials(const std::string& path) {
  const CsvTable table = readTable(path);
  const Columns columns(path, table);
  const size_t experiment = columns.require("experiment"), trial = columns.require("trial"),
               seed = columns.require("seed"), scenario = columns.require("scenario"),
               density = columns.require("density"), method = columns.require("method"),
               goal_finding = columns.require("goal_finding"), sensor = columns.require("sensor"),
               replan_limit = columns.require("replan_limit"), success = columns.require("success"),
               collision = columns.require("collision"),
               min_clearance = columns.require("min_clearance_m"),
               feasible = columns.require("feasible"), num_replans = columns.require("num_replans"),
               distance_to_goal = columns.require("distance_to_goal_m"),
               path_length = columns.require("path_length_m"),
               straight_line = columns.require("straight_line_m"),
               path_time = columns.require("path_time_s"), solvable = columns.require("solvable"),
               wall_time = columns.require("wall_time_s"),
               end_reason = columns.require("end_reason");
  // The dynamic obstacle's columns come together; without them the file is older.
  struct ObstacleColumns {
    size_t clearance, blocked;
  };
  std::optional<ObstacleColumns> obstacle;
  if (columns.has("blocked_cycles")) {
    obstacle =
        ObstacleColumns{columns.require("obstacle_clearance_m"), columns.require("blocked_cycles")};
  }
  // The planning radius's oracle columns come together; without them the file is older.
  struct PlanningOracle {
    size_t collision_radius, bottleneck, overflight;
  };
  std::optional<PlanningOracle> planning;
  if (columns.has("solvable_collision_radius")) {
    planning = PlanningOracle{columns.require("solvable_collision_radius"),
                              columns.require("bottleneck_m"), columns.require("needs_overflight")};
  }

  // <stage>_ms_median, _ms_p95 and _ms_max: a stage has all three columns.
  struct StageColumns {
    size_t median, p95, max;
  };
  std::map<std::string, StageColumns> stages;
  const std::string median_suffix = "_ms_median";
  for (const std::string& name : table.header) {
    if (name.size() <= median_suffix.size() ||
        name.compare(name.size() - median_suffix.size(), median_suffix.size(), median_suffix)) {
      continue;
    }
    const std::string stage = name.substr(0, name.size() - median_suffix.size());
    stages[stage] = {columns.require(name), columns.require(stage + "_ms_p95"),
                     columns.require(stage + "_ms_max")};
  }

  std::vector<Trial> trials;
  std::map<std::string, int> line_of_key;
  for (const CsvRecord& row : table.rows) {
    Trial t;
    t.line = row.line;
    t.spec.experiment = row.cells[experiment];
    t.spec.scenario = row.cells[scenario];
    t.spec.method = row.cells[method];
    t.spec.goal_finding = row.cells[goal_finding];
    t.spec.sensor = row.cells[sensor];
    t.end_reason = row.cells[end_reason];
    if (t.spec.experiment.empty()) {
      throw InputError(csvWhere(path, row.line, experiment) + " (experiment): empty");
    }
    // A trial that could not run has no measurements; its cells may be empty.
    const bool ran = t.ran();
    const auto zero = ran ? std::nullopt : std::optional<double>(0);
    const auto zero_int = ran ? std::nullopt : std::optional<int64_t>(0);
    const auto no = ran ? std::nullopt : std::optional<bool>(false);
    t.spec.trial = static_cast<int>(columns.integer(row, trial));
    const int64_t seed_value = columns.integer(row, seed);
    if (seed_value < 0) throw InputError(csvWhere(path, row.line, seed) + " (seed): negative");
    t.spec.seed = static_cast<uint64_t>(seed_value);
    t.spec.density = columns.number(row, density);
    t.spec.replans = static_cast<int>(columns.integer(row, replan_limit, zero_int));
    t.success = columns.flag(row, success, no);
    t.collision = columns.flag(row, collision, no);
    t.min_clearance_m = columns.number(row, min_clearance, zero);
    t.feasible = columns.flag(row, feasible, no);
    t.num_replans = columns.integer(row, num_replans, zero_int);
    t.distance_to_goal_m = columns.number(row, distance_to_goal, zero);
    t.path_length_m = columns.number(row, path_length, zero);
    t.straight_line_m = columns.number(row, straight_line, zero);
    t.path_time_s = columns.number(row, path_time, zero);
    if (planning) {
      t.solvable = columns.flag(row, solvable, no);
      t.solvable_collision_radius = columns.flag(row, planning->collision_radius, no);
      t.bottleneck_m = columns.number(row, planning->bottleneck, zero);
      t.needs_overflight = columns.flag(row, planning->overflight, no);
    } else {
      t.solvable_collision_radius = columns.flag(row, solvable, no);
    }
    t.wall_time_s = columns.number(row, wall_time, zero);
    if (obstacle) {
      if (!row.cells[obstacle->clearance].empty()) {
        t.obstacle_clearance_m = columns.number(row, obstacle->clearance);
      }
      t.blocked_cycles = columns.integer(row, obstacle->blocked, zero_int);
    }
    for (const auto& [stage, c] : stages) {
      if (row.cells[c.median].empty()) continue;  // the trial did not run this stage
      t.timings[stage] = {columns.number(row, c.median), columns.number(row, c.p95),
                          columns.number(row, c.max)};
    }
    t.key = t.spec.key();
    const auto [previous, inserted] = line_of_key.emplace(t.key, row.line);
    if (!inserted) {
      throw InputError(path + " line " + std::to_string(row.line) + ": trial " + t.key +
                       " is already on line " + std::to_string(previous->second));
    }
    trials.push_back(std::move(t));
  }
  return trials;
}

std::vector<RunLogRow> readRunLog(const std::string& path) {
  const CsvTable table = readTable(path);
  const Columns columns(path, table);
  const size_t started = columns.require("started_utc"), wall = columns.require("wall_s"),
               command = columns.require("command"), jobs = columns.require("jobs"),
               shard = columns.require("shard"), run = columns.require("trials_run"),
               skipped = columns.require("trials_skipped"), cpu = columns.require("cpu"),
               cores = columns.require("cores");
  std::vector<RunLogRow> rows;
  for (const CsvRecord& row : table.rows) {
    RunLogRow r;
    r.started_utc = row.cells[started];
    r.command = row.cells[command];
    r.shard = row.cells[shard];
    r.cpu = row.cells[cpu];
    r.wall_s = columns.number(row, wall);
    r.jobs = columns.integer(row, jobs);
    r.trials_run = columns.integer(row, run);
    r.trials_skipped = columns.integer(row, skipped);
    r.cores = columns.integer(row, cores);
    rows.push_back(std::move(r));
  }
  return rows;
}

std::vector<E5Row> readE5(const std::string& path) {
  const CsvTable table = readTable(path);
  const Columns columns(path, table);
  const size_t fraction = columns.require("fraction"), stride = columns.require("stride"),
               poses = columns.require("poses"), mean = columns.require("mean_abs_error"),
               p95 = columns.require("p95_abs_error"), max = columns.require("max_abs_error"),
               median_us = columns.require("median_us"), speedup = columns.require("speedup");
  std::vector<E5Row> rows;
  for (const CsvRecord& row : table.rows) {
    E5Row r;
    r.fraction = columns.number(row, fraction);
    r.stride = columns.integer(row, stride);
    r.poses = columns.integer(row, poses);
    r.mean_abs_error = columns.number(row, mean);
    r.p95_abs_error = columns.number(row, p95);
    r.max_abs_error = columns.number(row, max);
    r.median_us = columns.number(row, median_us);
    r.speedup = columns.number(row, speedup);
    rows.push_back(r);
  }
  std::sort(rows.begin(), rows.end(),
            [](const E5Row& a, const E5Row& b) { return a.fraction < b.fraction; });
  return rows;
}

}  // namespace thicket::bench::report_internal

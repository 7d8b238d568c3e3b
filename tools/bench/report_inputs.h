// The report's inputs: the rows of trials.csv, run_log.csv and e5_subsampling.csv.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "plans.h"
#include "trials.h"

namespace thicket::bench::report_internal {

// One row of trials.csv (the contract of the benchmark's parts).
struct Trial {
  int line = 0;
  TrialSpec spec;   // what was flown
  std::string key;  // spec.key()
  std::string end_reason;
  bool success = false, collision = false, feasible = false;
  // The oracle at the collision radius (the world's robot radius) and at the planning radius.
  // A file written before the oracle had a planning radius has `solvable` at the collision
  // radius and none of the other columns: the planning radius's stay unknown.
  bool solvable_collision_radius = false;
  std::optional<bool> solvable, needs_overflight;
  std::optional<double> bottleneck_m;
  double min_clearance_m = 0, distance_to_goal_m = 0, path_length_m = 0, straight_line_m = 0,
         path_time_s = 0, wall_time_s = 0;
  int64_t num_replans = 0;
  // The dynamic obstacle's columns (E6): the clearance is absent when the trial had no obstacle
  // or it never appeared; both are absent in a file written before the columns existed.
  std::optional<double> obstacle_clearance_m;
  std::optional<int64_t> blocked_cycles;
  std::map<std::string, StageTiming> timings;

  bool ran() const { return !failedToRun(end_reason); }
};

struct RunLogRow {
  std::string started_utc, command, shard, cpu;
  double wall_s = 0;
  int64_t jobs = 0, trials_run = 0, trials_skipped = 0, cores = 0;
};

struct E5Row {
  double fraction = 0, mean_abs_error = 0, p95_abs_error = 0, max_abs_error = 0, median_us = 0,
         speedup = 0;
  int64_t stride = 0, poses = 0;
};

// Each reader throws a std::runtime_error that names the file when the input is bad.
std::vector<Trial> readTrials(const std::string& path);

std::vector<RunLogRow> readRunLog(const std::string& path);

std::vector<E5Row> readE5(const std::string& path);

}  // namespace thicket::bench::report_internal

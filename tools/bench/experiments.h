// thicket-bench experiment / merge: the benchmark's experiments (docs/benchmark.md: E1, E2, E4 fly
// trials; E3 and T1 are computed from E2's and E4's rows; E5 is its own program; E6 flies trials
// with the simulator's dynamic obstacle), run as one deterministic list of trials that can be
// resumed after a kill, split across machines (--shard i/N) and merged back.
//
// Output folder DIR:
//   rows/shard-<i>-of-<N>.csv  one line per finished trial, appended and flushed at once (the
//                              resume state). Columns: the fixed columns of trials.csv (up to
//                              blocked_cycles), then `timings`: "<stage>=<median>/<p95>/<max>;..."
//                              in milliseconds, sorted by stage, since the stages differ from
//                              trial to trial. merge writes rows/merged.csv.
//   trials.csv                 every trial of rows/*.csv once (a row that could not run is
//                              replaced by a later one that did), sorted; the timings spread
//                              into <stage>_ms_median, _ms_p95, _ms_max columns.
//   paths/<key, '/' -> '-'>.csv  the executed path of every trial (t, x, y, z, yaw).
//   logs/<key, '/' -> '-'>.lcm   the LCM log of the trials --record selects.
//   run_log.csv                one line per run or merge.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::bench {

/// One trial of an experiment.
struct TrialSpec {
  std::string experiment;  ///< "E1", "E2", "E4" or "E6"
  std::string scenario;
  double density = 0;
  std::string method;
  std::string goal_finding;
  std::string sensor = "depth";
  int replans = 0;  ///< the sim's replan limit
  /// The simulator's dynamic obstacle is on (E6; implied by the experiment, not in the key).
  bool dynamic_obstacle = false;
  int trial = 0;  ///< its number in its configuration
  uint64_t seed = 0;

  /// "<experiment>/<scenario>/d<density %g>/<method>/<goal_finding>/<sensor>/s<seed>".
  std::string key() const;
};

/// The key with '/' replaced by '-': the name of the trial's path and log files.
std::string keyFileName(const std::string& key);
/// The trial's path file and log file, relative to the output folder:
/// "paths/<keyFileName(key)>.csv" and "logs/<keyFileName(key)>.lcm".
std::string trialPathFile(const std::string& key);
std::string trialLogFile(const std::string& key);

/// What `thicket-bench experiment` was asked for. Empty selection lists select everything.
struct ExperimentOptions {
  std::vector<std::string> experiments;  ///< E1, E2, E3, E4, E5, E6, T1, in the order given
  std::vector<std::string> scenarios;
  std::vector<double> densities;
  std::vector<std::string> methods;
  std::vector<std::string> goal_findings;
  std::optional<int> trials;   ///< overrides every experiment's trial count
  std::optional<int> replans;  ///< overrides every experiment's replan limit
  int64_t seed_base = 0;
  int jobs = 1;
  std::string shard;  ///< "i/N" as given (--shard), or empty
  int shard_index = 0;
  int shard_count = 1;
  std::string record;  ///< regex searched in trial keys; empty records nothing
  std::string worlds_dir;
  std::string out;
  std::string help;  ///< the --help text, when it was asked
};

/// Parses the flags after "experiment"; the error is a message for the user naming the flag
/// (exit status 2).
Expected<ExperimentOptions> parseExperimentOptions(const std::vector<std::string>& args);

/// Every trial the selection asks for, in a fixed order that depends only on the selection:
/// E1, E2, E4, E6; within an experiment trial number first, then scenario (E2: paper, eth),
/// density, method and goal finding, so a run stopped early covers every configuration evenly.
/// Trial t uses seed seed_base + t.
std::vector<TrialSpec> trialList(const ExperimentOptions& options);

/// Whether shard `index`/`count` runs the trial at `position` of trialList().
inline bool inShard(size_t position, int index, int count) {
  return position % static_cast<size_t>(count) == static_cast<size_t>(index);
}

/// `thicket-bench experiment ARGS` and `thicket-bench merge ARGS`: exit status 0 when every
/// trial ran and the output was written, 1 when a trial could not run or output could not be
/// written (or read), 2 for bad flags.
int experimentCommand(const std::vector<std::string>& args);
int mergeCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

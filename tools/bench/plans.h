// The benchmark's experiments as plans of trials (E1, E2, E4, E6): the trials, what a selection
// asks for, and the list of trials it flies.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

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
  std::string config_dir;  ///< the graph's option files (trials.h: RunOptions::config_dir)
  std::string out;
  std::string help;  ///< the --help text, when it was asked
};

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

// The experiments that fly trials, in the order they run.
const std::vector<Plan>& plans();

// The names --experiment takes.
std::vector<std::string> experimentNames();

// Whether `filter` (a selection flag's list; empty selects everything) selects `item`.
bool selects(const std::vector<std::string>& filter, const std::string& item);
bool selectsDensity(const std::vector<double>& filter, double density);

// The plans the experiments select, in the plans' order.
std::vector<const Plan*> selectedPlans(const ExperimentOptions& options);

/// Every trial the selection asks for, in a fixed order that depends only on the selection:
/// E1, E2, E4, E6; within an experiment trial number first, then scenario (E2: paper, eth),
/// density, method and goal finding, so a run stopped early covers every configuration evenly.
/// Trial t uses seed seed_base + t.
std::vector<TrialSpec> trialList(const ExperimentOptions& options);

/// Whether shard `index`/`count` runs the trial at `position` of trialList().
inline bool inShard(size_t position, int index, int count) {
  return position % static_cast<size_t>(count) == static_cast<size_t>(index);
}

}  // namespace thicket::bench

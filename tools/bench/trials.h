// thicket-bench run: trials of one configuration, each with the real nodes (sim, mapper, local
// planner and the method's nodes) hosted on one memq:// LCM in this process, several trials on
// parallel threads (docs/benchmark.md). Trial i flies the world of seed base + i.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "explorer_node.h"
#include "local_planner_node.h"
#include "mapper_node.h"
#include "thicket/common/expected.h"
#include "thicket/common/node.h"
#include "thicket/sim/vehicle.h"
#include "thicket/sim/world.h"
#include "vio_bridge_node.h"

namespace thicket::bench {

/// Where the simulated graph's option files live: `<dir>/<module>.yaml` for vio_bridge, mapper,
/// local_planner and explorer. The process sheets (config/sim*.pmd) pass the same files to the
/// executables, so the benchmark flies what the sheets run: the source tree's config/sim.
std::string simConfigDir();

/// What `thicket-bench run` was asked for.
struct RunOptions {
  std::string scenario = "paper";
  double density = 0;
  std::string method = "none";        ///< the goal-selection strategy (docs/benchmark.md E2)
  std::string goal_finding = "soft";  ///< "line", "gradient" or "soft" (gradient + soft goal)
  std::string sensor = "depth";  ///< "depth" (rendered depth) or "stereo" (through stereo_depth)
  int trials = 0;
  int64_t seed_base = 0;
  int replans = 60;  ///< the sim's replan limit
  int jobs = 1;      ///< trials run on this many threads
  /// The simulator's dynamic obstacle (sim/dynamic_obstacle.h) with its default options: a
  /// cylinder that appears on the committed path during the flight (docs/benchmark.md E6).
  bool dynamic_obstacle = false;
  std::string worlds_dir;
  /// Where the graph's option files are read (trialGraphOptions).
  std::string config_dir = simConfigDir();
  std::string out;   ///< the output folder
  std::string help;  ///< the --help text, when it was asked
};

/// Parses the flags after "run"; the error is a message for the user (exit status 2).
Expected<RunOptions> parseRunOptions(const std::vector<std::string>& args);

/// Median, 95th percentile and maximum of one module stage's durations in a trial [ms].
struct StageTiming {
  double median_ms = 0;
  double p95_ms = 0;
  double max_ms = 0;
};

/// One row of trials.csv, and the executed path.
struct TrialResult {
  int trial = 0;
  uint64_t seed = 0;
  bool success = false;
  bool collision = false;
  double min_clearance_m = 0;
  bool feasible = false;
  int num_replans = 0;
  double distance_to_goal_m = 0;
  double path_length_m = 0;
  double straight_line_m = 0;
  double path_time_s = 0;
  /// The oracle (sim/oracle.h) at the planning radius: the robot radius plus the planner's
  /// acceptance margin, what the planner demands of every sample it accepts.
  bool solvable = false;
  /// The oracle at the world's robot radius, the radius collisions are judged by.
  bool solvable_collision_radius = false;
  double bottleneck_m = 0;        ///< the world's 2D bottleneck clearance
  bool needs_overflight = false;  ///< solvable at the planning radius only over a cylinder
  double wall_time_s = 0;         ///< building the graph and flying the mission
  std::string end_reason;         ///< the sim's, or "error: ..." when the trial could not run
  /// The vehicle's smallest clearance to the dynamic obstacle from its appearance on (the
  /// simulator's AppearedObstacle::min_clearance); absent when the trial had none or it never
  /// appeared.
  std::optional<double> obstacle_clearance_m;
  /// The planner cycles that found their committed trajectory blocked by a new map: every cycle
  /// one of whose PLANNER_STATUS messages (final or not) has a reason starting with
  /// local_planner::kBlockedTrajectoryReason, once.
  int blocked_cycles = 0;
  /// By "<module>_<stage>" as published on MODULE_TIMING.
  std::map<std::string, StageTiming> timings;
  std::vector<sim::PathSample> path;
};

/// Makes a node that watches a trial's graph (benchmarks record planning problems this way); it
/// lives as long as the trial.
using TrialObserver = std::function<std::unique_ptr<Node>(lcm::LCM&)>;

/// The end reason of a trial that could not run ("error: <why>"), and the test for one: such a
/// row is listed but left out of every statistic, and a resumed run tries the trial again.
std::string failedEndReason(const std::string& why);
bool failedToRun(const std::string& end_reason);

/// Flies `world` as trial `trial` of `options`, with `observer`'s node on the graph if given.
/// Throws what the nodes throw on bad options.
TrialResult runTrial(const RunOptions& options, const sim::World& world, int trial,
                     const TrialObserver& observer = {});

/// The world of trial `trial` (seed base + trial) of `options`; throws std::runtime_error when the
/// scenario cannot be loaded or the world not generated.
sim::World trialWorld(const RunOptions& options, int trial);

/// The methods (goal-selection strategies) and goal-finding variants trials accept, in their
/// fixed order; without the ablations (variants of a method that E2 flies to show what one
/// mechanism buys) when `with_ablations` is false.
std::vector<std::string> methodNames(bool with_ablations = true);
std::vector<std::string> goalFindingNames();
/// Whether `method` must never collide (docs/benchmark.md): every method but rrt_star_optimistic,
/// the one that plans through unknown space.
bool conservativeMethod(const std::string& method);

/// The options of a trial's nodes besides the simulator's: what a trial builds and what the
/// replay of a recorded trial (tools/replay) must build alike.
struct TrialGraphOptions {
  vio_bridge::VioBridgeNodeOptions bridge;
  mapper::MapperNodeOptions mapper;
  /// Absent for the method "none": no explorer in the graph.
  std::optional<explorer::ExplorerNodeOptions> explorer;
  local_planner::LocalPlannerNodeOptions planner;
};

/// The graph of a trial of `method` with `goal_finding` on the world of `seed` inside
/// [bounds_min, bounds_max] flown by a robot of `robot_radius`: every module's options are loaded
/// from `config_dir` (`thicket-bench run --config` flies another configuration), then the trial
/// sets what is its own: the explorer's strategy (none: no explorer, and the planner holds when
/// stuck), the goal finding, the seeds of the planner and the explorer (the world's), the map id
/// (seed + 1) and the flight volume of the planner and the explorer (the world's bounds shrunk by
/// the robot radius, where the oracle keeps the centre).
/// Throws std::invalid_argument naming an unknown method or goal finding, thicket::ParamError
/// when a file does not load.
TrialGraphOptions trialGraphOptions(const std::string& method, const std::string& goal_finding,
                                    uint64_t seed, const Eigen::Vector3d& bounds_min,
                                    const Eigen::Vector3d& bounds_max, double robot_radius,
                                    const std::string& config_dir = simConfigDir());

// ---- trials.csv, shared by `thicket-bench run` and `thicket-bench experiment` ----

/// The columns of a trial's outcome, success ... end_reason (docs/benchmark.md's metrics), then the
/// dynamic obstacle's obstacle_clearance_m (empty without one) and blocked_cycles.
const std::vector<std::string>& outcomeColumns();
/// A trial's cells under outcomeColumns(), unquoted; a line break in the end reason becomes a
/// space, so a row is one line.
std::vector<std::string> outcomeCells(const TrialResult& result);
/// "<stage>_ms_median", "<stage>_ms_p95", "<stage>_ms_max" for every stage, in `stages` order.
std::vector<std::string> stageColumns(const std::set<std::string>& stages);
/// The cells under stageColumns(stages) of a trial with `timings`: milliseconds with three
/// decimals, empty where the trial lacks the stage.
std::vector<std::string> stageCells(const std::set<std::string>& stages,
                                    const std::map<std::string, StageTiming>& timings);
/// `value` printed with printf's `spec` ("%g", "%.4f").
std::string formatNumber(const char* spec, double value);
/// Writes `text` to `path`; throws std::runtime_error naming the file when it cannot.
void writeTextFile(const std::string& path, const std::string& text);
/// The executed path as CSV: t (seconds from the first sample), x, y, z, yaw. Throws as
/// writeTextFile.
void writePathFile(const std::string& path, const std::vector<sim::PathSample>& samples);

/// `thicket-bench run ARGS`: runs the trials and writes DIR/trials.csv and DIR/paths/<trial>.csv.
/// Returns the exit status: 0 when every trial ran, 1 when one could not run or the output could
/// not be written, 2 for bad flags.
int runCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

#include "trials.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>

#include <lcm/lcm-cpp.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/module_timing_t.hpp>
#include <thicket/planner_status_t.hpp>

#include "csv.h"
#include "explorer_node.h"
#include "flags.h"
#include "local_planner_node.h"
#include "mapper_node.h"
#include "parallel.h"
#include "sim_node.h"
#include "stereo_depth_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node.h"
#include "thicket/common/statistics.h"
#include "thicket/common/time.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/oracle.h"
#include "vio_bridge_node.h"

namespace thicket::bench {
namespace {

// The goal-selection methods (docs/benchmark.md, E2): the explorer strategy a method runs, or none
// (no explorer in the graph; the planner holds when stuck), and the options it sets over the
// shipped configuration (YAML overlays, applied in order, over config/sim's explorer.yaml
// `explorer:` group and local_planner.yaml `planner:` group). Adding a method or an ablation is
// adding a row.
struct Method {
  const char* name;
  const char* strategy;               // explorer::ExplorerOptions::strategy, or nullptr
  std::vector<const char*> explorer;  // over explorer::ExplorerOptions
  std::vector<const char*> planner;   // over local_planner::LocalPlannerOptions
  bool ablation = false;              // flown in E2 only, to show what one mechanism buys
};
// The paper's semantics, whatever config/sim ships (frontier_memory's options): the vehicle faces
// along its velocity, no look around, waypoints one by one (no carrot), no stall watchdog, no
// escape slack, no retreat.
constexpr const char* kPaperExplorer = "{fixed_yaw: false, look_around: {enabled: false}}";
constexpr const char* kPaperPlanner =
    "{carrot: false, stall_cycles: 0, retreat: 0, loco: {escape_slack: 0}}";
// Proposals flown facing their yaws, and a look around at each new stuck place.
constexpr const char* kLookExplorer = "{fixed_yaw: true, look_around: {enabled: true}}";
// The stall watchdog.
constexpr const char* kWatchdog = "{stall_cycles: 4}";
// frontier_memory's planner: its paths followed by the carrot, and the stall watchdog.
const std::vector<const char*> kMemoryPlanner = {"{carrot: true}", kWatchdog};
const Method kMethods[] = {
    {"none", nullptr, {kPaperExplorer}, {kPaperPlanner}},
    {"random", "random", {kPaperExplorer}, {kPaperPlanner}},
    {"rrt_star_optimistic", "rrt_star_optimistic", {kPaperExplorer}, {kPaperPlanner}},
    {"rrt_star_conservative", "rrt_star_conservative", {kPaperExplorer}, {kPaperPlanner}},
    {"nbvp", "nbvp", {kPaperExplorer}, {kPaperPlanner}},
    {"local_exploration", "local_exploration", {kPaperExplorer}, {kPaperPlanner}},
    // Beyond the paper: frontier viewpoints along verified paths with a memory, flown facing
    // their yaws along the path (the carrot), a look around at each new stuck place, and the stall
    // watchdog.
    {"frontier_memory", "frontier_memory", {kLookExplorer}, kMemoryPlanner},
    // Ablation: the paper's method, its candidates flown facing their yaw, a look around at each
    // new stuck place, and the stall watchdog.
    {"local_exploration_look",
     "local_exploration",
     {kLookExplorer},
     {kPaperPlanner, kWatchdog},
     true},
    // Ablation: the paper's method, its candidates only where a straight line from the vehicle
    // keeps the clearance, and never the global goal as its answer.
    {"local_exploration_reachable",
     "local_exploration",
     {kPaperExplorer, "{reachable: true, p_goal: 0.0}"},
     {kPaperPlanner},
     true},
    // Ablations of frontier_memory: at the vehicle's height only; facing along the velocity (no
    // yaws, so no looks either); answering every request as if it were the first.
    {"frontier_memory_flat",
     "frontier_memory",
     {kLookExplorer, "{frontier_memory: {layers: false}}"},
     kMemoryPlanner,
     true},
    {"frontier_memory_no_yaw", "frontier_memory", {kPaperExplorer}, kMemoryPlanner, true},
    {"frontier_memory_no_memory",
     "frontier_memory",
     {kLookExplorer, "{frontier_memory: {memory: false}}"},
     kMemoryPlanner,
     true},
};

// The goal-finding variants of the optimization-only experiment (docs/benchmark.md, E1).
struct GoalFinding {
  const char* name;
  const char* finder_method;  // GoalFinderOptions::method
  bool soft_goal;
};
// The depth sensors: the simulator's depth camera, or its stereo pair through thicket-stereo-depth.
struct Sensor {
  const char* name;
};
const Sensor kSensors[] = {{"depth"}, {"stereo"}};

const GoalFinding kGoalFindings[] = {
    {"line", "line", false},
    {"gradient", "gradient", false},
    {"soft", "gradient", true},
};

template <class Row, size_t N>
std::string rowNames(const Row (&table)[N]) {
  std::string names;
  for (const Row& row : table) names += (names.empty() ? "" : ", ") + std::string(row.name);
  return names;
}

template <class Row, size_t N>
const Row& findRow(const Row (&table)[N], const std::string& name, const char* what) {
  for (const Row& row : table) {
    if (name == row.name) return row;
  }
  throw std::invalid_argument("unknown " + std::string(what) + " '" + name +
                              "' (known: " + rowNames(table) + ")");
}

template <class Row, size_t N>
std::vector<std::string> rowNameList(const Row (&table)[N]) {
  std::vector<std::string> names;
  for (const Row& row : table) names.emplace_back(row.name);
  return names;
}

void addRunFlags(CLI::App& app, RunOptions& o) {
  using cli::nonEmpty;
  app.footer("       thicket-bench [--benchmark_filter=REGEX ...]: the module micro-benchmarks");
  app.add_option("--scenario", o.scenario, "a scenario name in the worlds dir or a .yaml path")
      ->check(nonEmpty())
      ->capture_default_str();
  app.add_option("--density", o.density, "cylinders per m^2 of the obstacle region")
      ->required()
      ->check(cli::number(0));
  app.add_option("--method", o.method, "goal-selection strategy: " + rowNames(kMethods))
      ->check(CLI::IsMember(rowNameList(kMethods)))
      ->capture_default_str();
  app.add_option("--goal-finding", o.goal_finding,
                 rowNames(kGoalFindings) + " (soft: gradient + soft goal)")
      ->check(CLI::IsMember(rowNameList(kGoalFindings)))
      ->capture_default_str();
  app.add_option("--sensor", o.sensor,
                 rowNames(kSensors) + " (stereo: rendered pairs through thicket-stereo-depth)")
      ->check(CLI::IsMember(rowNameList(kSensors)))
      ->capture_default_str();
  cli::addSwitch(app, "--dynamic-obstacle", o.dynamic_obstacle,
                 "the simulator's dynamic obstacle with its default options: a cylinder that "
                 "appears on the committed path");
  app.add_option("--trials", o.trials, "number of trials")->required()->check(cli::integer(1));
  app.add_option("--seed-base", o.seed_base, "the seed of trial 0")
      ->check(cli::integer(0))
      ->capture_default_str();
  app.add_option("--replans", o.replans, "replan limit of a trial")
      ->check(cli::integer(1, std::numeric_limits<int>::max()))
      ->capture_default_str();
  app.add_option("--jobs", o.jobs, "trials run on J threads")
      ->check(cli::integer(1, 1024))
      ->capture_default_str();
  app.add_option("--worlds-dir", o.worlds_dir, "where scenario names are looked up")
      ->check(nonEmpty())
      ->capture_default_str();
  app.add_option("--config", o.config_dir,
                 "the graph's option files, DIR/<module>.yaml for vio_bridge, mapper, "
                 "local_planner, explorer and stereo_depth (default: config/sim, what the "
                 "simulation sheets run)")
      ->check(nonEmpty());
  app.add_option("--out", o.out, "the output folder")->required()->check(nonEmpty());
}

}  // namespace

Expected<RunOptions> parseRunOptions(const std::vector<std::string>& args) {
  RunOptions options;
  options.worlds_dir = std::string(THICKET_SOURCE_DIR) + "/config/worlds";
  return parseCommand<RunOptions>(
      "run",
      "thicket-bench run: runs N trials of one configuration, trial i on the world of seed B+i, "
      "with the real nodes on memq:// in this process. Writes DIR/trials.csv (one row per "
      "trial) and DIR/paths/<trial>.csv (the executed path at 0.01 s: t, x, y, z, yaw).",
      args, addRunFlags, options);
}

namespace {

// ---- one trial ----

// Wall-clock time for the nodes' stage durations (measured, never used to decide) [ms].

// The benchmark's own node in a trial's graph: the recorder of every module's stage durations
// and of the planner cycles that found their committed trajectory blocked.
class BenchNode : public Node {
 public:
  explicit BenchNode(lcm::LCM& lcm) : Node("bench", lcm) {
    // Each module publishes one message per frame or cycle, and the composite drains every
    // cycle; the capacity is only a margin.
    subscribe<module_timing_t>(
        "MODULE_TIMING",
        [this](const module_timing_t& msg, const MessageInfo&) {
          for (size_t i = 0; i < msg.stages.size(); ++i) {
            durations_ms_[msg.module + "_" + msg.stages[i]].push_back(msg.durations_ms[i]);
          }
        },
        1000);
    subscribe<planner_status_t>(
        "PLANNER_STATUS",
        [this](const planner_status_t& msg, const MessageInfo&) {
          if (msg.reason.rfind(local_planner::kBlockedTrajectoryReason, 0) == 0)
            blocked_cycles_.insert(msg.cycle);
        },
        1000);
  }

  int blockedCycles() const { return static_cast<int>(blocked_cycles_.size()); }

  std::map<std::string, StageTiming> timings() const {
    std::map<std::string, StageTiming> timings;
    for (const auto& [stage, ms] : durations_ms_) {
      timings[stage] = {median(ms), quantile(ms, 0.95), *std::max_element(ms.begin(), ms.end())};
    }
    return timings;
  }

 private:
  std::map<std::string, std::vector<double>> durations_ms_;
  std::set<int64_t> blocked_cycles_;
};

sim::SimOptions simOptions(const RunOptions& options, const sim::World& world) {
  sim::SimOptions sim;
  sim.scenario = world.scenario;
  sim.density = world.density;
  sim.seed = static_cast<int64_t>(world.seed);
  sim.worlds_dir = options.worlds_dir;
  sim.lockstep = true;
  sim.vehicle.replan_limit = options.replans;
  sim.sensor = options.sensor;
  sim.dynamic_obstacle.enabled = options.dynamic_obstacle;
  return sim;
}

// The depth node's options for the simulator's stereo pairs, what the stereo sheet gives it
// (config/sim/stereo_depth.yaml: the rendered pair's rectified camera).
stereo_depth::StereoDepthNodeOptions stereoDepthOptions(const RunOptions& options) {
  return loadParams<stereo_depth::StereoDepthNodeOptions>(options.config_dir +
                                                          "/stereo_depth.yaml");
}

// With the stereo sensor, the depth node for the simulator's pairs.
std::unique_ptr<Node> stereoDepthNode(lcm::LCM& lcm, const RunOptions& options) {
  if (options.sensor != "stereo") return nullptr;
  return std::make_unique<stereo_depth::StereoDepthNode>(lcm, stereoDepthOptions(options),
                                                         steadyClockMillis);
}

void checkOracle(const sim::World& world, const local_planner::LocalPlannerNodeOptions& planner,
                 TrialResult& result) {
  const sim::GroundTruth truth(world);
  sim::OracleOptions planning;
  planning.radius = planner.planner.loco.requiredClearance();
  const sim::OracleResult oracle = sim::checkSolvable(truth, planning);
  result.solvable = oracle.solvable;
  result.bottleneck_m = oracle.bottleneck_m;
  result.needs_overflight = oracle.needs_overflight;
  result.solvable_collision_radius = sim::checkSolvable(truth).solvable;
}

}  // namespace

std::string failedEndReason(const std::string& why) {
  return "error: " + why;
}

bool failedToRun(const std::string& end_reason) {
  return end_reason.rfind("error: ", 0) == 0;
}

sim::World trialWorld(const RunOptions& options, int trial) {
  const std::string worlds_dir = options.worlds_dir.empty()
                                     ? std::string(THICKET_SOURCE_DIR) + "/config/worlds"
                                     : options.worlds_dir;
  auto spec = sim::loadScenario(options.scenario, worlds_dir);
  if (!spec) throw std::runtime_error(spec.error());
  auto world =
      sim::generateWorld(*spec, options.density,
                         static_cast<uint64_t>(options.seed_base) + static_cast<uint64_t>(trial));
  if (!world) throw std::runtime_error(world.error());
  return *world;
}

TrialResult runTrial(const RunOptions& options, const sim::World& world, int trial,
                     const TrialObserver& observer) {
  TrialResult result;
  result.trial = trial;
  result.seed = world.seed;
  result.straight_line_m = (world.goal - world.start).norm();
  const TrialGraphOptions graph =
      trialGraphOptions(options.method, options.goal_finding, world.seed, world.bounds_min,
                        world.bounds_max, world.robot_radius, options.config_dir);
  checkOracle(world, graph.planner, result);

  const auto started = std::chrono::steady_clock::now();
  lcm::LCM lcm("memq://");
  if (!lcm.good()) throw std::runtime_error("cannot open an LCM on memq://");
  Loop loop(lcm);
  BenchNode bench(lcm);
  const sim::SimOptions sim_options = simOptions(options, world);
  sim::SimNode sim(lcm, sim_options, world);
  const std::unique_ptr<Node> stereo = stereoDepthNode(lcm, options);
  vio_bridge::VioBridgeNode bridge(lcm, graph.bridge, steadyClockMillis);
  // In one process the map's blocks travel raw (a quarter of a trial's time went into zstd),
  // unless an observer records the traffic: logs keep them compressed.
  mapper::MapperNodeOptions mapper_options = graph.mapper;
  mapper_options.compress_blocks = observer != nullptr;
  mapper::MapperNode mapper(lcm, mapper_options, mapper_options.map_id, steadyClockMillis);
  std::unique_ptr<Node> explorer;
  if (graph.explorer) {
    explorer = std::make_unique<explorer::ExplorerNode>(lcm, *graph.explorer, steadyClockMillis);
  }
  local_planner::LocalPlannerNode planner(lcm, graph.planner, steadyClockMillis);
  const std::unique_ptr<Node> observer_node = observer ? observer(lcm) : nullptr;

  sim.start();
  // In lockstep every frame is answered within the same drain; an idle graph with the mission
  // still open means the planner never closed the frame.
  while (!sim.finished()) {
    if (loop.drain() == 0) sim.abort("no final planner status for the frame");
  }
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  const sim::Vehicle& vehicle = sim.vehicle();
  result.min_clearance_m = vehicle.minClearance();
  result.collision = vehicle.minClearance() < world.robot_radius;
  result.success = vehicle.outcome() == sim::Outcome::kGoalReached && !result.collision;
  result.feasible = vehicle.feasible();
  result.num_replans = vehicle.cycle();
  result.distance_to_goal_m = vehicle.distanceToGoal();
  result.path_length_m = vehicle.pathLength();
  result.path = vehicle.path();
  result.path_time_s = toSeconds(result.path.back().utime - result.path.front().utime);
  result.end_reason = sim.endReason();
  result.timings = bench.timings();
  if (sim.dynamicObstacle()) result.obstacle_clearance_m = sim.dynamicObstacle()->min_clearance;
  result.blocked_cycles = bench.blockedCycles();
  return result;
}

std::vector<std::string> methodNames(bool with_ablations) {
  std::vector<std::string> names;
  for (const Method& method : kMethods)
    if (with_ablations || !method.ablation) names.emplace_back(method.name);
  return names;
}

std::vector<std::string> goalFindingNames() {
  std::vector<std::string> names;
  for (const GoalFinding& variant : kGoalFindings) names.emplace_back(variant.name);
  return names;
}

bool conservativeMethod(const std::string& method) {
  return method != "rrt_star_optimistic";
}

std::string simConfigDir() {
  return std::string(THICKET_SOURCE_DIR) + "/config/sim";
}

TrialGraphOptions trialGraphOptions(const std::string& method, const std::string& goal_finding,
                                    uint64_t seed, const Eigen::Vector3d& bounds_min,
                                    const Eigen::Vector3d& bounds_max, double robot_radius,
                                    const std::string& dir) {
  const Method& strategy = findRow(kMethods, method, "method");
  const GoalFinding& variant = findRow(kGoalFindings, goal_finding, "goal finding");
  TrialGraphOptions graph;
  graph.bridge = loadParams<vio_bridge::VioBridgeNodeOptions>(dir + "/vio_bridge.yaml");
  graph.mapper = loadParams<mapper::MapperNodeOptions>(dir + "/mapper.yaml");
  graph.mapper.map_id = static_cast<int64_t>(seed) + 1;
  // A trial's graph lives in one process, never respawned, and trials run side by side.
  graph.mapper.checkpoint.clear();
  const Eigen::Vector3d volume_min = (bounds_min.array() + robot_radius).matrix();
  const Eigen::Vector3d volume_max = (bounds_max.array() - robot_radius).matrix();
  if (strategy.strategy != nullptr) {
    explorer::ExplorerNodeOptions explorer =
        loadParams<explorer::ExplorerNodeOptions>(dir + "/explorer.yaml");
    explorer.explorer.strategy = strategy.strategy;
    for (const char* overlay : strategy.explorer) {
      overrideParams(explorer.explorer, overlay, "method " + method);
    }
    explorer.explorer.seed = static_cast<int64_t>(seed);
    explorer.explorer.flight_volume_min = volume_min;
    explorer.explorer.flight_volume_max = volume_max;
    graph.explorer = explorer;
  }
  local_planner::LocalPlannerNodeOptions& node = graph.planner;
  node = loadParams<local_planner::LocalPlannerNodeOptions>(dir + "/local_planner.yaml");
  if (graph.explorer) {
    // The explorer proposes, and its trees keep, the clearance the planner accepts.
    graph.explorer->explorer.min_clearance = node.planner.loco.requiredClearance();
  }
  for (const char* overlay : strategy.planner) {
    overrideParams(node.planner, overlay, "method " + method);
  }
  node.planner.goal_finder.method = variant.finder_method;
  node.planner.soft_goal = variant.soft_goal;
  node.planner.seed = static_cast<int64_t>(seed);
  node.planner.flight_volume_min = volume_min;
  node.planner.flight_volume_max = volume_max;
  node.planner.use_explorer = graph.explorer.has_value();
  return graph;
}

// ---- output ----

std::string formatNumber(const char* spec, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), spec, value);
  return text;
}

namespace {

std::string fixed(double value) {
  return formatNumber("%.4f", value);
}

std::string flag(bool value) {
  return value ? "1" : "0";
}

}  // namespace

void writeTextFile(const std::string& path, const std::string& text) {
  std::ofstream file(path, std::ios::binary);
  file << text;
  file.close();
  if (!file) throw std::runtime_error("cannot write " + path);
}

void writePathFile(const std::string& path, const std::vector<sim::PathSample>& samples) {
  std::string text = "t,x,y,z,yaw\n";
  char line[160];
  for (const sim::PathSample& s : samples) {
    std::snprintf(line, sizeof(line), "%.3f,%.6f,%.6f,%.6f,%.6f\n",
                  toSeconds(s.utime - samples.front().utime), s.position.x(), s.position.y(),
                  s.position.z(), s.yaw);
    text += line;
  }
  writeTextFile(path, text);
}

const std::vector<std::string>& outcomeColumns() {
  static const std::vector<std::string> columns = {"success",
                                                   "collision",
                                                   "min_clearance_m",
                                                   "feasible",
                                                   "num_replans",
                                                   "distance_to_goal_m",
                                                   "path_length_m",
                                                   "straight_line_m",
                                                   "path_time_s",
                                                   "solvable",
                                                   "solvable_collision_radius",
                                                   "bottleneck_m",
                                                   "needs_overflight",
                                                   "wall_time_s",
                                                   "end_reason",
                                                   "obstacle_clearance_m",
                                                   "blocked_cycles"};
  return columns;
}

std::vector<std::string> outcomeCells(const TrialResult& r) {
  std::string reason = r.end_reason;
  std::replace(reason.begin(), reason.end(), '\n', ' ');
  std::replace(reason.begin(), reason.end(), '\r', ' ');
  return {flag(r.success),
          flag(r.collision),
          fixed(r.min_clearance_m),
          flag(r.feasible),
          std::to_string(r.num_replans),
          fixed(r.distance_to_goal_m),
          fixed(r.path_length_m),
          fixed(r.straight_line_m),
          fixed(r.path_time_s),
          flag(r.solvable),
          flag(r.solvable_collision_radius),
          fixed(r.bottleneck_m),
          flag(r.needs_overflight),
          fixed(r.wall_time_s),
          reason,
          r.obstacle_clearance_m ? fixed(*r.obstacle_clearance_m) : "",
          std::to_string(r.blocked_cycles)};
}

std::vector<std::string> stageColumns(const std::set<std::string>& stages) {
  std::vector<std::string> columns;
  for (const std::string& stage : stages) {
    for (const char* summary : {"median", "p95", "max"})
      columns.push_back(stage + "_ms_" + summary);
  }
  return columns;
}

std::vector<std::string> stageCells(const std::set<std::string>& stages,
                                    const std::map<std::string, StageTiming>& timings) {
  std::vector<std::string> cells;
  for (const std::string& stage : stages) {
    const auto timing = timings.find(stage);
    for (double StageTiming::*summary :
         {&StageTiming::median_ms, &StageTiming::p95_ms, &StageTiming::max_ms}) {
      cells.push_back(timing == timings.end() ? "" : formatNumber("%.3f", timing->second.*summary));
    }
  }
  return cells;
}

namespace {

std::string pathFile(const RunOptions& options, int trial) {
  return options.out + "/paths/" + std::to_string(trial) + ".csv";
}

// trials.csv: the columns of docs/benchmark.md, then the median, p95 and max of every module stage
// seen in any trial (empty where a trial has none).
void writeTrials(const RunOptions& options, const std::string& scenario,
                 const std::vector<TrialResult>& results) {
  std::set<std::string> stages;
  for (const TrialResult& r : results) {
    for (const auto& [stage, timing] : r.timings) stages.insert(stage);
  }
  std::vector<std::string> header = {"trial",  "seed",         "scenario", "density",
                                     "method", "goal_finding", "sensor"};
  for (const std::vector<std::string>& more : {outcomeColumns(), stageColumns(stages)}) {
    header.insert(header.end(), more.begin(), more.end());
  }
  std::string text = csvLine(header);
  for (const TrialResult& r : results) {
    std::vector<std::string> cells = {std::to_string(r.trial),
                                      std::to_string(r.seed),
                                      scenario,
                                      formatNumber("%g", options.density),
                                      options.method,
                                      options.goal_finding,
                                      options.sensor};
    for (const std::vector<std::string>& more : {outcomeCells(r), stageCells(stages, r.timings)}) {
      cells.insert(cells.end(), more.begin(), more.end());
    }
    text += csvLine(cells);
  }
  writeTextFile(options.out + "/trials.csv", text);
}

// ---- the run ----

// Trial `trial` on its world, its path written; a trial that cannot run is reported in its row.
TrialResult attemptTrial(const RunOptions& options, int trial) {
  const uint64_t seed = static_cast<uint64_t>(options.seed_base) + static_cast<uint64_t>(trial);
  try {
    TrialResult result = runTrial(options, trialWorld(options, trial), trial);
    writePathFile(pathFile(options, trial), result.path);
    result.path = {};  // written; a long run should not hold every path
    return result;
  } catch (const std::exception& e) {
    TrialResult failed;
    failed.trial = trial;
    failed.seed = seed;
    failed.end_reason = failedEndReason(e.what());
    return failed;
  }
}

// "trial 3/20 seed 3: goal reached, 17.2 m, 23 replans, 4.1 s"; the error alone for a trial that
// could not run.
std::string progressLine(const TrialResult& r, int trials) {
  std::string line = "trial " + std::to_string(r.trial) + "/" + std::to_string(trials) + " seed " +
                     std::to_string(r.seed) + ": " + r.end_reason;
  if (!failedToRun(r.end_reason)) {
    char numbers[128];
    std::snprintf(numbers, sizeof(numbers), ", %.1f m, %d replans, %.1f s", r.path_length_m,
                  r.num_replans, r.wall_time_s);
    line += numbers;
  }
  return line + "\n";
}

// Every trial, on options.jobs threads, sorted by trial. Each trial has its own LCM and nodes;
// the threads share only the slots of the results (one each) and stderr.
std::vector<TrialResult> runAll(const RunOptions& options) {
  std::vector<TrialResult> results(static_cast<size_t>(options.trials));
  std::mutex progress;
  parallelFor(results.size(), options.jobs, [&](size_t slot) {
    const int trial = static_cast<int>(slot);
    results[slot] = attemptTrial(options, trial);
    const std::lock_guard lock(progress);
    std::fputs(progressLine(results[slot], options.trials).c_str(), stderr);
  });
  return results;
}

void printSummary(const RunOptions& options, const std::string& scenario,
                  const std::vector<TrialResult>& results) {
  int success = 0, collisions = 0, overflight = 0;
  // Solvable worlds and successes on them at the planning and at the collision radius.
  int solvable = 0, success_on_solvable = 0, solvable_collision = 0, success_on_collision = 0;
  std::vector<double> successful_lengths;
  for (const TrialResult& r : results) {
    success += r.success;
    collisions += r.collision;
    overflight += r.needs_overflight;
    solvable += r.solvable;
    success_on_solvable += r.success && r.solvable;
    solvable_collision += r.solvable_collision_radius;
    success_on_collision += r.success && r.solvable_collision_radius;
    if (r.success) successful_lengths.push_back(r.path_length_m);
  }
  const int n = static_cast<int>(results.size());
  std::printf(
      "%s, density %g, method %s, goal finding %s, sensor %s: %d trials, seeds %lld..%lld\n",
      scenario.c_str(), options.density, options.method.c_str(), options.goal_finding.c_str(),
      options.sensor.c_str(), n, static_cast<long long>(options.seed_base),
      static_cast<long long>(options.seed_base + n - 1));
  std::printf(
      "success %d/%d, collisions %d; solvable at the planning radius %d/%d (success on them "
      "%d/%d, %d need overflight), at the collision radius %d/%d (success on them %d/%d)\n",
      success, n, collisions, solvable, n, success_on_solvable, solvable, overflight,
      solvable_collision, n, success_on_collision, solvable_collision);
  if (options.dynamic_obstacle) {
    int appeared = 0, blocked = 0;
    std::vector<double> clearances;
    for (const TrialResult& r : results) {
      appeared += r.obstacle_clearance_m.has_value();
      blocked += r.blocked_cycles > 0;
      if (r.obstacle_clearance_m) clearances.push_back(*r.obstacle_clearance_m);
    }
    std::printf("dynamic obstacle: appeared in %d/%d trials", appeared, n);
    if (!clearances.empty()) {
      std::printf(", smallest clearance to it %.3f m",
                  *std::min_element(clearances.begin(), clearances.end()));
    }
    std::printf("; %d trials had a cycle whose committed trajectory was blocked\n", blocked);
  }
  if (successful_lengths.empty()) {
    std::printf("median path length of successful trials: none succeeded\n");
  } else {
    std::printf("median path length of successful trials: %.2f m\n", median(successful_lengths));
  }
  std::printf("wrote %s/trials.csv and %s/paths/\n", options.out.c_str(), options.out.c_str());
}

int failUsage(const std::string& message) {
  return usageError("run", message);
}

}  // namespace

int runCommand(const std::vector<std::string>& args) {
  auto options = parseRunOptions(args);
  if (!options) return failUsage(options.error());
  if (!options->help.empty()) {
    std::fputs(options->help.c_str(), stdout);
    return 0;
  }
  auto spec = sim::loadScenario(options->scenario, options->worlds_dir);
  if (!spec) return failUsage(spec.error());
  try {  // a configuration that does not load is the user's to fix, before any trial flies
    trialGraphOptions(options->method, options->goal_finding, 0, Eigen::Vector3d::Zero(),
                      spec->size, spec->robot_radius, options->config_dir);
    if (options->sensor == "stereo") stereoDepthOptions(*options);
  } catch (const std::exception& e) {
    return failUsage(e.what());
  }

  try {
    std::filesystem::create_directories(options->out + "/paths");
    const std::vector<TrialResult> results = runAll(*options);
    writeTrials(*options, spec->name, results);
    printSummary(*options, spec->name, results);
    const auto failed = std::count_if(results.begin(), results.end(), [](const TrialResult& r) {
      return failedToRun(r.end_reason);
    });
    if (failed > 0) {
      std::fprintf(stderr, "thicket-bench run: %lld of %d trials could not run\n",
                   static_cast<long long>(failed), options->trials);
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "thicket-bench run: %s\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace thicket::bench

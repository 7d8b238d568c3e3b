// `thicket-bench experiment` and `merge` as a user runs them: the trial list and its shards,
// resuming a killed run, shards merged back into one run's rows, trials whose rows do not depend
// on the thread count, kept logs, trials that could not run, and bad flags refused.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <thicket/sim_event_t.hpp>

#include "bench_tables.h"
#include "cli.h"
#include "config_copy.h"
#include "csv.h"
#include "experiments.h"
#include "parallel.h"
#include "thicket/common/lcm_log.h"
#include "trials.h"

namespace thicket::bench {
namespace {

namespace fs = std::filesystem;
using testing::cellsByColumn;
using testing::readTable;
using testing::Table;
using testing::withoutTimes;
using thicket::testing::CliResult;

CliResult bench(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_BENCH) + " " + args);
}

// Every folder of this test process, removed when the process ends.
std::string tempDir(const std::string& name) {
  return ::testing::TempDir() + "/bench_experiment_" + std::to_string(::getpid()) + "/" + name;
}

std::string readFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  EXPECT_TRUE(file.good()) << path;
  return std::string((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
}

void writeFile(const std::string& path, const std::string& text) {
  std::ofstream file(path, std::ios::binary);
  file << text;
}

std::vector<TrialSpec> list(std::vector<std::string> args) {
  args.insert(args.end(), {"--out", "unused"});
  const auto options = parseExperimentOptions(args);
  EXPECT_TRUE(options) << options.error();
  return options ? trialList(*options) : std::vector<TrialSpec>{};
}

TEST(BenchExperimentList, CoversTheExperimentsInAFixedOrder) {
  const std::vector<TrialSpec> all = list({});
  // E1: 10 densities x 3 goal findings x 100; E2: 2 scenarios x 10 x every method x 50; E4: 2 x
  // the methods but the ablations x 20; E6: 1 x those x 20.
  const size_t methods = methodNames().size();
  const size_t flown = methodNames(false).size();  // E4 and E6: no ablations
  ASSERT_GE(flown, 6u);
  ASSERT_GT(methods, flown);
  ASSERT_EQ(all.size(), 3000u + 1000u * methods + 40u * flown + 20u * flown);
  std::set<std::string> keys;
  for (const TrialSpec& spec : all) keys.insert(spec.key());
  EXPECT_EQ(keys.size(), all.size()) << "keys are not unique";

  // Trial number first, then scenario, density, method, goal finding.
  EXPECT_EQ(all[0].key(), "E1/paper/d0.05/none/line/depth/s0");
  EXPECT_EQ(all[1].key(), "E1/paper/d0.05/none/gradient/depth/s0");
  EXPECT_EQ(all[2].key(), "E1/paper/d0.05/none/soft/depth/s0");
  EXPECT_EQ(all[3].key(), "E1/paper/d0.1/none/line/depth/s0");
  EXPECT_EQ(all[29].key(), "E1/paper/d0.5/none/soft/depth/s0");
  EXPECT_EQ(all[30].key(), "E1/paper/d0.05/none/line/depth/s1");
  EXPECT_EQ(all[3000].key(), "E2/paper/d0.05/none/soft/depth/s0");
  EXPECT_EQ(all[3001].key(), "E2/paper/d0.05/random/soft/depth/s0");
  EXPECT_EQ(all[3000 + methods].key(), "E2/paper/d0.1/none/soft/depth/s0");
  EXPECT_EQ(all[3000 + 10 * methods].key(), "E2/eth/d0.05/none/soft/depth/s0");
  EXPECT_EQ(all[3000 + 20 * methods].key(), "E2/paper/d0.05/none/soft/depth/s1");
  const size_t e4 = 3000 + 1000 * methods, e6_start = e4 + 40 * flown;
  EXPECT_EQ(all[e4].key(), "E4/forest50/d0.1/none/soft/depth/s0");
  EXPECT_EQ(all[e4 + 5].key(), "E4/forest50/d0.1/local_exploration/soft/depth/s0");
  EXPECT_EQ(all[e4 + flown].key(), "E4/forest50/d0.2/none/soft/depth/s0");
  EXPECT_EQ(all[e6_start].key(), "E6/paper/d0.2/none/soft/depth/s0");
  EXPECT_EQ(all.back().key(), "E6/paper/d0.2/frontier_memory/soft/depth/s19");
  EXPECT_EQ(all[0].replans, 60);
  EXPECT_EQ(all[3000].replans, 120);
  EXPECT_EQ(all[3000 + 10 * methods].replans, 120);
  EXPECT_EQ(all[e4].replans, 500);
  EXPECT_EQ(all[e6_start].replans, 60);
  EXPECT_EQ(all[30].trial, 1);
  EXPECT_EQ(all[30].seed, 1u);
  // Only E6 flies the dynamic obstacle.
  for (const TrialSpec& spec : all) {
    EXPECT_EQ(spec.dynamic_obstacle, spec.experiment == "E6") << spec.key();
  }

  // E3 is E2's trials, T1 E4's; E5 flies none; --scenario picks E2's scenario.
  std::vector<TrialSpec> e2 = list({"--experiment", "E2"});
  ASSERT_EQ(e2.size(), 1000u * methods);
  EXPECT_EQ(e2.front().key(), all[3000].key());
  EXPECT_EQ(list({"--experiment", "E3"}).size(), 1000u * methods);
  EXPECT_EQ(list({"--experiment", "E3,E2"}).size(), 1000u * methods);
  const std::vector<TrialSpec> eth = list({"--experiment", "E2", "--scenario", "eth"});
  ASSERT_EQ(eth.size(), 500u * methods);
  EXPECT_EQ(eth.front().key(), "E2/eth/d0.05/none/soft/depth/s0");
  EXPECT_EQ(list({"--experiment", "E2", "--scenario", "paper"}).size(), 500u * methods);
  EXPECT_EQ(list({"--experiment", "T1"}).size(), 40u * flown);
  EXPECT_TRUE(list({"--experiment", "E5"}).empty());
  const std::vector<TrialSpec> e6 = list({"--experiment", "E6"});
  ASSERT_EQ(e6.size(), 20u * flown);
  EXPECT_EQ(e6.front().key(), "E6/paper/d0.2/none/soft/depth/s0");
  EXPECT_TRUE(e6.front().dynamic_obstacle);

  // The smoke run's selection: every experiment at density 0.2.
  EXPECT_EQ(list({"--density", "0.2"}).size(), 300u + 100u * methods + 20u * flown + 20u * flown);

  // The selection narrows the list; --trials, --seed-base and --replans change it.
  const std::vector<TrialSpec> small =
      list({"--experiment", "E2", "--scenario", "paper", "--method", "local_exploration,none",
            "--density", "0.3,0.1", "--trials", "2", "--seed-base", "10", "--replans", "7"});
  std::vector<std::string> small_keys;
  for (const TrialSpec& spec : small) {
    small_keys.push_back(spec.key());
    EXPECT_EQ(spec.replans, 7);
    EXPECT_EQ(spec.seed, 10u + static_cast<uint64_t>(spec.trial));
  }
  EXPECT_EQ(small_keys, (std::vector<std::string>{
                            "E2/paper/d0.1/none/soft/depth/s10",
                            "E2/paper/d0.1/local_exploration/soft/depth/s10",
                            "E2/paper/d0.3/none/soft/depth/s10",
                            "E2/paper/d0.3/local_exploration/soft/depth/s10",
                            "E2/paper/d0.1/none/soft/depth/s11",
                            "E2/paper/d0.1/local_exploration/soft/depth/s11",
                            "E2/paper/d0.3/none/soft/depth/s11",
                            "E2/paper/d0.3/local_exploration/soft/depth/s11",
                        }));
  EXPECT_EQ(list({"--experiment", "E1,E4", "--density", "0.2"}).size(), 300u + 20u * flown);
  EXPECT_EQ(list({"--scenario", "forest50"}).size(), 40u * flown);
  EXPECT_EQ(list({"--scenario", "paper"}).size(),
            3000u + 500u * methodNames().size() + 20u * flown);
}

TEST(BenchExperimentList, EveryTrialIsInExactlyOneShard) {
  const std::vector<TrialSpec> all = list({});
  for (int count : {1, 2, 3, 7, 10000}) {
    std::vector<int> shards_of(all.size(), 0);
    std::vector<size_t> sizes(static_cast<size_t>(count), 0);
    for (int index = 0; index < count; ++index) {
      for (size_t position = 0; position < all.size(); ++position) {
        if (inShard(position, index, count)) {
          ++shards_of[position];
          ++sizes[static_cast<size_t>(index)];
        }
      }
    }
    EXPECT_TRUE(std::all_of(shards_of.begin(), shards_of.end(), [](int n) { return n == 1; }))
        << count << " shards";
    // Balanced: the shards' trial counts differ by one at most.
    const auto [fewest, most] = std::minmax_element(sizes.begin(), sizes.end());
    EXPECT_LE(*most - *fewest, 1u) << count << " shards";
  }
}

TEST(BenchParallelFor, RunsEveryTaskOnceOnAnyNumberOfThreads) {
  for (const int jobs : {-1, 0, 1, 2, 7}) {
    for (const size_t count : {size_t{0}, size_t{1}, size_t{5}, size_t{100}}) {
      std::vector<std::atomic<int>> runs(count);
      parallelFor(count, jobs, [&](size_t i) { ++runs[i]; });
      for (size_t i = 0; i < count; ++i) {
        EXPECT_EQ(runs[i].load(), 1) << "task " << i << " of " << count << ", " << jobs << " jobs";
      }
    }
  }
}

TEST(BenchExperiment, BadFlagsFailWithAMessageNamingTheFlag) {
  const std::string out = tempDir("refused");
  const auto fails = [&](const std::string& args, const std::string& message) {
    const CliResult result = bench("experiment --out " + out + " " + args);
    EXPECT_EQ(result.status, 2) << args << ": " << result.output;
    EXPECT_NE(result.output.find(message), std::string::npos) << args << ": " << result.output;
  };
  for (const char* shard : {"2/2", "-1/2", "a/2", "0/0", "1", "0/2x", "/2"}) {
    fails(std::string("--shard ") + shard, "--shard: must be i/N with 0 <= i < N");
  }
  fails("--experiment E2,E9", "--experiment: E9 not in {E1,E2,E3,E4,E5,E6,T1}");
  fails("--method none,bogus", "--method: bogus not in {none,random,");
  fails("--goal-finding curve", "--goal-finding: curve not in {line,gradient,soft}");
  fails("--experiment E1 --method random", "--method random is not a method of the selected");
  fails("--experiment E4 --density 0.3", "--density 0.3 is not a density of the selected");
  fails("--experiment E1,E6 --scenario eth", "--scenario eth is not a scenario of the selected");
  fails("--scenario forest", "--scenario forest is not a scenario of the selected");
  fails("--experiment E6 --density 0.1", "--density 0.1 is not a density of the selected");
  fails("--experiment E5 --density 0.1", "the selected experiments fly none");
  fails("--density 0.1,x", "--density: must be a number >= 0, not 'x'");
  fails("--trials 0", "--trials: must be an integer >= 1, not '0'");
  fails("--jobs 0", "--jobs: must be an integer in [1, 1024], not '0'");
  fails("--replans -3", "--replans: must be an integer >= 1, not '-3'");
  fails("--record '('", "--record: '(' is not a regular expression");
  fails("--fast", "not expected: --fast");
  fails("--experiment E2 --scenario paper --worlds-dir " + tempDir("no_worlds"), "paper.yaml");
  EXPECT_EQ(bench("experiment --experiment E2").status, 2);
  EXPECT_FALSE(fs::exists(out));

  const auto merge_fails = [&](const std::string& args, const std::string& message) {
    const CliResult result = bench("merge " + args);
    EXPECT_EQ(result.status, 2) << args << ": " << result.output;
    EXPECT_NE(result.output.find(message), std::string::npos) << args << ": " << result.output;
  };
  merge_fails("--out " + out, "IN_DIR is required");
  merge_fails(tempDir("a"), "--out is required");
  merge_fails("--out " + out + " " + tempDir("nowhere"), "has no rows/ folder");
  EXPECT_FALSE(fs::exists(out));

  for (const char* command : {"experiment", "merge"}) {
    const CliResult help = bench(std::string(command) + " --help");
    EXPECT_EQ(help.status, 0) << help.output;
    EXPECT_NE(help.output.find(std::string("Usage: thicket-bench ") + command), std::string::npos)
        << help.output;
  }
}

// The trials of the end-to-end tests: two methods on a forest dense enough that they fly
// different paths, two worlds each, a short replan limit.
const std::string kSelection =
    "--experiment E2 --scenario paper --method none,local_exploration --density 0.3 --trials 2 "
    "--replans 20";
const std::vector<std::string> kKeys = {"E2/paper/d0.3/local_exploration/soft/depth/s0",
                                        "E2/paper/d0.3/local_exploration/soft/depth/s1",
                                        "E2/paper/d0.3/none/soft/depth/s0",
                                        "E2/paper/d0.3/none/soft/depth/s1"};

// One run of the selection on two threads, the reference of the others.
class BenchExperimentRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    reference_ = new CliResult(bench("experiment " + kSelection + " --jobs 2 --out " + dir()));
  }
  static void TearDownTestSuite() {
    delete reference_;
    fs::remove_all(tempDir(""));
  }
  static std::string dir() { return tempDir("reference"); }
  static const CliResult& reference() { return *reference_; }

 private:
  static CliResult* reference_;
};
CliResult* BenchExperimentRun::reference_ = nullptr;

TEST_F(BenchExperimentRun, WritesTheTrialsRowsPathsAndRunLog) {
  ASSERT_EQ(reference().status, 0) << reference().output;
  EXPECT_NE(reference().output.find("shard 0/1: 4 trials, 4 run, 0 skipped"), std::string::npos)
      << reference().output;
  EXPECT_NE(reference().output.find("collisions of conservative methods: 0 of 4 trials"),
            std::string::npos)
      << reference().output;
  EXPECT_NE(reference().output.find("[E2] 4/4 done (0 resumed), "), std::string::npos)
      << reference().output;
  EXPECT_NE(reference().output.find(", last: paper d0.3 "), std::string::npos)
      << reference().output;

  const Table trials = readTable(dir() + "/trials.csv");
  ASSERT_EQ(trials.size(), 5u);
  const std::vector<std::string> fixed = {"experiment",
                                          "trial",
                                          "seed",
                                          "scenario",
                                          "density",
                                          "method",
                                          "goal_finding",
                                          "sensor",
                                          "replan_limit",
                                          "success",
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
  const std::vector<std::string>& header = trials[0];
  ASSERT_GT(header.size(), fixed.size());
  EXPECT_EQ(std::vector<std::string>(header.begin(), header.begin() + 26), fixed);
  EXPECT_EQ((header.size() - fixed.size()) % 3, 0u);
  for (const char* column :
       {"mapper_tsdf_insert_ms_median", "mapper_esdf_update_ms_p95",
        "local_planner_trajectory_optimization_ms_max", "explorer_goal_selection_ms_median"}) {
    EXPECT_NE(std::find(header.begin(), header.end(), column), header.end()) << column;
  }
  // Sorted by method, then seed; the explorer's stage is empty where there is no explorer.
  const size_t goal_selection =
      std::find(header.begin(), header.end(), "explorer_goal_selection_ms_median") - header.begin();
  for (size_t i = 1; i < trials.size(); ++i) {
    SCOPED_TRACE(kKeys[i - 1]);
    const std::vector<std::string>& row = trials[i];
    ASSERT_EQ(row.size(), header.size());
    const std::string key = row[0] + "/" + row[3] + "/d" + row[4] + "/" + row[5] + "/" + row[6] +
                            "/" + row[7] + "/s" + row[2];
    EXPECT_EQ(key, kKeys[i - 1]);
    EXPECT_EQ(row[1], row[2]);  // trial t flies seed 0 + t
    EXPECT_EQ(row[8], "20");
    EXPECT_EQ(row[10], "0") << "collision";
    EXPECT_LE(std::stoi(row[13]), 20);
    EXPECT_EQ(row[goal_selection].empty(), row[5] == "none");
    // No dynamic obstacle in E2: no clearance to it; blocked cycles are counted all the same.
    EXPECT_EQ(row[24], "") << "obstacle_clearance_m";
    EXPECT_GE(std::stoi(row[25]), 0) << "blocked_cycles";
    EXPECT_TRUE(fs::exists(dir() + "/paths/" + keyFileName(key) + ".csv"));
  }
  // The two methods flew differently, or this selection would not tell their rows apart.
  EXPECT_NE(trials[1][15], trials[3][15]);

  const Table run_log = readTable(dir() + "/run_log.csv");
  ASSERT_EQ(run_log.size(), 2u);
  EXPECT_EQ(run_log[0],
            (std::vector<std::string>{"started_utc", "wall_s", "command", "jobs", "shard",
                                      "trials_run", "trials_skipped", "cpu", "cores"}));
  EXPECT_EQ(run_log[1][2].rfind("thicket-bench experiment --experiment E2", 0), 0u);
  EXPECT_EQ(run_log[1][3], "2");
  EXPECT_EQ(run_log[1][4], "0/1");
  EXPECT_EQ(run_log[1][5], "4");
  EXPECT_EQ(run_log[1][6], "0");
  EXPECT_EQ(std::to_string(::sysconf(_SC_NPROCESSORS_ONLN)), run_log[1][8]);
  // The report lists this invocation (the run log is written before it).
  const std::string summary = readFile(dir() + "/summary.md");
  EXPECT_NE(summary.find("### Invocations (run_log.csv)"), std::string::npos);
  EXPECT_NE(summary.find("thicket-bench experiment --experiment E2"), std::string::npos);
}

TEST_F(BenchExperimentRun, ResumesAKilledRunWithTheMissingTrialsOnly) {
  ASSERT_EQ(reference().status, 0) << reference().output;
  const std::string out = tempDir("resumed");
  fs::copy(dir(), out, fs::copy_options::recursive);
  fs::remove(out + "/trials.csv");
  // A killed run: a row that never came (the second) and a last row torn mid-write.
  const std::string rows_file = out + "/rows/shard-0-of-1.csv";
  std::vector<std::string> lines;
  {
    std::ifstream file(rows_file);
    for (std::string line; std::getline(file, line);) lines.push_back(line);
  }
  ASSERT_EQ(lines.size(), 5u);
  std::string killed =
      lines[0] + "\n" + lines[2] + "\n" + lines[3] + "\n" + lines[4].substr(0, lines[4].size() / 2);
  writeFile(rows_file, killed);

  const CliResult resumed = bench("experiment " + kSelection + " --jobs 1 --out " + out);
  ASSERT_EQ(resumed.status, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("shard 0/1: 4 trials, 2 run, 2 skipped"), std::string::npos)
      << resumed.output;
  EXPECT_NE(resumed.output.find("cutting the torn last line"), std::string::npos) << resumed.output;
  EXPECT_NE(resumed.output.find("[E2] 4/4 done (2 resumed)"), std::string::npos) << resumed.output;
  EXPECT_EQ(withoutTimes(readTable(out + "/trials.csv")),
            withoutTimes(readTable(dir() + "/trials.csv")));
  // The new rows start on lines of their own.
  const Table rows = readTable(rows_file);
  EXPECT_EQ(rows.size(), 5u);
  for (const auto& row : rows) EXPECT_EQ(row.size(), rows[0].size());
  EXPECT_EQ(readTable(out + "/run_log.csv").size(), 3u);

  // Run again: nothing is left to do.
  const CliResult again = bench("experiment " + kSelection + " --out " + out);
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_NE(again.output.find("shard 0/1: 4 trials, 0 run, 4 skipped"), std::string::npos)
      << again.output;
}

// Each shard flies its trials on one thread, the reference on two: the merged rows and the paths
// are the same.
TEST_F(BenchExperimentRun, ShardsOnOneThreadMergeIntoTheRowsOfOneRunOnTwo) {
  ASSERT_EQ(reference().status, 0) << reference().output;
  const std::string kept = "E2/paper/d0.3/local_exploration/soft/depth/s1";
  std::vector<std::string> shards;
  for (int i = 0; i < 2; ++i) {
    shards.push_back(tempDir("shard" + std::to_string(i)));
    const CliResult shard =
        bench("experiment " + kSelection + " --jobs 1 --shard " + std::to_string(i) +
              "/2 --record 'local_exploration.*s1$' " + "--out " + shards.back());
    ASSERT_EQ(shard.status, 0) << shard.output;
    EXPECT_NE(shard.output.find("shard " + std::to_string(i) + "/2: 2 trials, 2 run"),
              std::string::npos)
        << shard.output;
    EXPECT_EQ(readTable(shards.back() + "/trials.csv").size(), 3u);
  }
  const std::string merged = tempDir("merged");
  const CliResult merge = bench("merge --out " + merged + " " + shards[0] + " " + shards[1]);
  ASSERT_EQ(merge.status, 0) << merge.output;
  EXPECT_EQ(withoutTimes(readTable(merged + "/trials.csv")),
            withoutTimes(readTable(dir() + "/trials.csv")));
  for (const std::string& key : kKeys) {
    const std::string path = "/paths/" + keyFileName(key) + ".csv";
    EXPECT_EQ(readFile(merged + path), readFile(dir() + path)) << key;
  }
  EXPECT_TRUE(fs::exists(merged + "/logs/" + keyFileName(kept) + ".lcm"));
  // The shards' run log lines and the merge's.
  const Table run_log = readTable(merged + "/run_log.csv");
  ASSERT_EQ(run_log.size(), 4u);
  EXPECT_EQ(run_log[3][2].rfind("thicket-bench merge", 0), 0u);
  EXPECT_EQ(run_log[3][6], "4");
  EXPECT_NE(readFile(merged + "/summary.md").find("thicket-bench merge --out"), std::string::npos);

  // Merging again, with a shard twice, changes nothing.
  const CliResult twice =
      bench("merge --out " + merged + " " + shards[0] + " " + shards[1] + " " + shards[1]);
  ASSERT_EQ(twice.status, 0) << twice.output;
  EXPECT_EQ(withoutTimes(readTable(merged + "/trials.csv")),
            withoutTimes(readTable(dir() + "/trials.csv")));
}

// --record keeps the graph's traffic of the chosen trials: the log ends with the simulator's
// trial end, whose mission summary is the trial's row.
TEST_F(BenchExperimentRun, RecordKeepsTheLogOfTheChosenTrials) {
  ASSERT_EQ(reference().status, 0) << reference().output;
  const std::string out = tempDir("recorded");
  const CliResult run = bench(
      "experiment --experiment E2 --scenario paper --method local_exploration --density 0.3 "
      "--trials 2 --replans 20 --record 'local_exploration.*s1$' --out " +
      out);
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_NE(run.output.find("keeping the logs of 1 trials"), std::string::npos) << run.output;
  const std::string kept = "E2/paper/d0.3/local_exploration/soft/depth/s1";
  ASSERT_EQ(std::distance(fs::directory_iterator(out + "/logs"), fs::directory_iterator()), 1);

  LogReader reader(out + "/logs/" + keyFileName(kept) + ".lcm");
  std::map<std::string, int> channels;
  std::optional<sim_event_t> end;
  for (std::optional<LogEvent> event = reader.next(); event; event = reader.next()) {
    ++channels[event->channel];
    sim_event_t message;
    if (event->channel == "SIM_EVENT" && event->decode(message).empty() &&
        message.type == sim_event_t::TYPE_TRIAL_END) {
      end = message;
    }
  }
  EXPECT_EQ(reader.error(), "");
  EXPECT_GT(channels["CAMERA_DEPTH"], 0);
  EXPECT_GT(channels["EXPLORER_GOAL"] + channels["MODULE_TIMING"], 0);
  ASSERT_TRUE(end) << "no trial end in the log";

  const Table trials = readTable(out + "/trials.csv");
  ASSERT_EQ(trials.size(), 3u);
  const std::vector<std::string>& row = trials[2];  // seed 1
  ASSERT_EQ(row[2], "1");
  EXPECT_EQ(end->num_replans, std::stoi(row[13]));
  EXPECT_NEAR(end->path_length, std::stod(row[15]), 1e-4);
  EXPECT_NEAR(end->distance_to_goal, std::stod(row[14]), 1e-4);
}

// --config reaches every trial: a planner that demands 2 m of clearance (the start is 1.5 m above
// the ground) reaches no goal, where the shipped configuration does on the same world; one that
// does not load is refused before anything is written.
TEST(BenchExperiment, ConfigChangesTheOptionsEveryTrialFlies) {
  const std::string demanding =
      thicket::testing::configCopy(tempDir("demanding"), "clearance_margin: 1.5");
  const std::string selection =
      "experiment --experiment E1 --density 0.05 --goal-finding soft --trials 1 --seed-base 7 "
      "--replans 30 --jobs 1 --out ";
  const std::string shipped = tempDir("config_shipped"), changed = tempDir("config_changed");
  const CliResult first = bench(selection + shipped);
  ASSERT_EQ(first.status, 0) << first.output;
  const CliResult second = bench(selection + changed + " --config " + demanding);
  ASSERT_EQ(second.status, 0) << second.output;
  const auto success = [](const std::string& dir) {
    const Table table = readTable(dir + "/trials.csv");
    EXPECT_EQ(table.size(), 2u) << dir;
    return cellsByColumn(table)["success"];
  };
  EXPECT_EQ(success(shipped), "1");
  EXPECT_EQ(success(changed), "0");

  const std::string refused = tempDir("config_refused");
  const CliResult bad = bench(selection + refused + " --config " + tempDir("no_config"));
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_NE(bad.output.find("vio_bridge.yaml"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(refused));
}

TEST(BenchExperiment, ATrialThatCouldNotRunIsRecordedAndTriedAgain) {
  // A scenario whose trees cannot be placed clear of the start and goal: no world, no trial.
  const std::string worlds = tempDir("bad_worlds");
  fs::create_directories(worlds);
  std::string paper = readFile(std::string(THICKET_SOURCE_DIR) + "/config/worlds/paper.yaml");
  const size_t keep_clear = paper.find("keep_clear:");
  ASSERT_NE(keep_clear, std::string::npos);
  writeFile(worlds + "/paper.yaml", paper.substr(0, keep_clear) + "keep_clear: 50.0\n");

  const std::string out = tempDir("could_not_run");
  const std::string selection =
      "experiment --experiment E1 --goal-finding line --density 0.1 --trials 1 --replans 5 ";
  const CliResult failed = bench(selection + "--worlds-dir " + worlds + " --out " + out);
  EXPECT_EQ(failed.status, 1) << failed.output;
  EXPECT_NE(failed.output.find("1 run, 0 skipped"), std::string::npos) << failed.output;
  EXPECT_NE(failed.output.find("1 could not run"), std::string::npos) << failed.output;
  Table trials = readTable(out + "/trials.csv");
  ASSERT_EQ(trials.size(), 2u);
  EXPECT_EQ(trials[1][23].rfind("error: ", 0), 0u) << trials[1][23];
  EXPECT_NE(trials[1][23].find("keep_clear"), std::string::npos) << trials[1][23];

  const CliResult retried = bench(selection + "--out " + out);
  EXPECT_EQ(retried.status, 0) << retried.output;
  EXPECT_NE(retried.output.find("1 run, 0 skipped"), std::string::npos) << retried.output;
  trials = readTable(out + "/trials.csv");
  ASSERT_EQ(trials.size(), 2u);
  EXPECT_EQ(trials[1][23].rfind("error: ", 0), std::string::npos) << trials[1][23];
  EXPECT_EQ(trials[1][0] + trials[1][5] + trials[1][6], "E1noneline");
}

// Rows of another program, and of an older thicket-bench: before the planning radius's oracle
// (their solvable means the collision radius's) and before the dynamic obstacle's columns. Neither
// a merge nor a run (resuming) mixes them with new rows, nor appends to them.
TEST(BenchExperiment, RowsOfAnotherProgramOrAnOlderBenchAreRefused) {
  const std::string id =
      "experiment,trial,seed,scenario,density,method,goal_finding,sensor,replan_limit,success,"
      "collision,min_clearance_m,feasible,num_replans,distance_to_goal_m,path_length_m,"
      "straight_line_m,path_time_s,solvable,";
  const struct {
    const char* name;
    std::string rows;
    std::string message;
  } cases[] = {
      {"foreign", "experiment,trial,seed\nE2,0,0\n", "shard-0-of-1.csv: not a rows file"},
      {"before_planning_oracle",
       id + "wall_time_s,end_reason,timings\n"
            "E2,0,0,paper,0.1,none,soft,depth,120,1,0,0.9,1,12,0.1,14,13,15,1,2,goal reached,\n",
       "shard-0-of-1.csv: rows of an older thicket-bench, whose solvable is the oracle at the "
       "collision radius"},
      {"before_obstacle",
       id + "solvable_collision_radius,bottleneck_m,needs_overflight,wall_time_s,end_reason,"
            "timings\n"
            "E2,0,0,paper,0.1,none,soft,depth,120,1,0,0.9,1,12,0.1,14,13,15,1,1,0.8,0,2,goal "
            "reached,\n",
       "shard-0-of-1.csv: rows of an older thicket-bench, written before the dynamic obstacle "
       "(E6), which lack obstacle_clearance_m and blocked_cycles; they cannot be resumed or "
       "merged"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string input = tempDir(std::string("old_rows_") + c.name);
    const std::string merged = tempDir(std::string("old_merged_") + c.name);
    fs::create_directories(input + "/rows");
    writeFile(input + "/rows/shard-0-of-1.csv", c.rows);
    const CliResult merge = bench("merge --out " + merged + " " + input);
    EXPECT_EQ(merge.status, 1) << merge.output;
    EXPECT_NE(merge.output.find(c.message), std::string::npos) << merge.output;
    EXPECT_FALSE(fs::exists(merged + "/trials.csv"));

    const CliResult run = bench(
        "experiment --experiment E2 --scenario paper --method none --density 0.1 --trials 1 "
        "--out " +
        input);
    EXPECT_EQ(run.status, 1) << run.output;
    EXPECT_NE(run.output.find(c.message), std::string::npos) << run.output;
  }
}

}  // namespace
}  // namespace thicket::bench

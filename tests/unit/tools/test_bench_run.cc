// `thicket-bench run` as a user runs it: trials of the real graph write their rows and paths,
// and bad flags fail with a message.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bench_tables.h"
#include "cli.h"
#include "config_copy.h"
#include "thicket/sim/world.h"

namespace thicket::bench {
namespace {

using thicket::testing::CliResult;
using thicket::testing::configCopy;

CliResult bench(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_BENCH) + " " + args);
}

std::string tempDir(const std::string& name) {
  return ::testing::TempDir() + "/bench_run_" + std::to_string(::getpid()) + "_" + name;
}

using testing::cellsByColumn;
using testing::readTable;
using testing::Table;

sim::World paperWorld(uint64_t seed) {
  auto spec = sim::loadScenario("paper", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  EXPECT_TRUE(spec) << spec.error();
  return *sim::generateWorld(*spec, 0.05, seed);
}

// Checks a trial's path file against its row: 0.01 s samples inside the world, and the path
// length and time of the row.
void checkPath(const std::string& file, const sim::World& world, double path_length_m,
               double path_time_s) {
  SCOPED_TRACE(file);
  const Table path = readTable(file);
  ASSERT_GE(path.size(), 2u);
  EXPECT_EQ(path[0], (std::vector<std::string>{"t", "x", "y", "z", "yaw"}));
  double length = 0;
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (size_t i = 1; i < path.size(); ++i) {
    ASSERT_EQ(path[i].size(), 5u) << "row " << i;
    const double t = std::stod(path[i][0]);
    const Eigen::Vector3d p(std::stod(path[i][1]), std::stod(path[i][2]), std::stod(path[i][3]));
    EXPECT_NEAR(t, 0.01 * static_cast<double>(i - 1), 1e-6) << "row " << i;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(p[k], world.bounds_min[k]) << "row " << i;
      EXPECT_LE(p[k], world.bounds_max[k]) << "row " << i;
    }
    if (i > 1) length += (p - previous).norm();
    previous = p;
  }
  EXPECT_NEAR(length, path_length_m, 1e-3);
  EXPECT_NEAR(std::stod(path.back()[0]), path_time_s, 1e-3);
}

TEST(BenchRun, WritesARowAndAPathPerTrial) {
  const std::string out = tempDir("paper");
  const CliResult result = bench(
      "run --scenario paper --density 0.05 --trials 2 --seed-base 7 --replans 40 --jobs 2 --out " +
      out);
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("trial 0/2 seed 7: "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("trial 1/2 seed 8: "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("collisions 0"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("solvable at the planning radius 2/2 (success on them 2/2, 0 need "
                               "overflight), at the collision radius 2/2 (success on them 2/2)"),
            std::string::npos)
      << result.output;

  const Table rows = readTable(out + "/trials.csv");
  ASSERT_EQ(rows.size(), 3u);
  const std::vector<std::string> fixed_columns = {"trial",
                                                  "seed",
                                                  "scenario",
                                                  "density",
                                                  "method",
                                                  "goal_finding",
                                                  "sensor",
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
  const std::vector<std::string>& header = rows[0];
  ASSERT_GT(header.size(), fixed_columns.size());
  EXPECT_EQ(std::vector<std::string>(
                header.begin(), header.begin() + static_cast<std::ptrdiff_t>(fixed_columns.size())),
            fixed_columns);
  // Per-stage timing columns follow, three per stage; the mapper reports on every frame.
  EXPECT_EQ((header.size() - fixed_columns.size()) % 3, 0u);
  for (const char* column : {"mapper_tsdf_insert_ms_median", "mapper_tsdf_insert_ms_p95",
                             "mapper_tsdf_insert_ms_max", "mapper_esdf_update_ms_median"}) {
    EXPECT_NE(std::find(header.begin(), header.end(), column), header.end()) << column;
  }

  for (int trial = 0; trial < 2; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const std::vector<std::string>& row = rows[static_cast<size_t>(trial) + 1];
    ASSERT_EQ(row.size(), header.size());
    std::map<std::string, std::string> cell = cellsByColumn(rows, static_cast<size_t>(trial) + 1);
    EXPECT_EQ(cell["trial"], std::to_string(trial));
    EXPECT_EQ(cell["seed"], std::to_string(7 + trial));
    EXPECT_EQ(cell["scenario"], "paper");
    EXPECT_EQ(cell["density"], "0.05");
    EXPECT_EQ(cell["method"], "none");
    EXPECT_EQ(cell["goal_finding"], "soft");
    EXPECT_EQ(cell["sensor"], "depth");
    EXPECT_EQ(cell["collision"], "0");
    // At 0.05 trees per m^2 the planner alone flies both worlds (20 of 20 seeds when written).
    EXPECT_EQ(cell["success"], "1");
    EXPECT_EQ(cell["end_reason"], "goal reached");
    EXPECT_EQ(cell["solvable"], "1");
    EXPECT_EQ(cell["solvable_collision_radius"], "1");
    // Solvable at the planning radius without overflight: the bottleneck is at least 0.6 m.
    EXPECT_EQ(cell["needs_overflight"], "0");
    EXPECT_GE(std::stod(cell["bottleneck_m"]), 0.6);
    EXPECT_EQ(cell["feasible"], "1");
    EXPECT_GE(std::stod(cell["min_clearance_m"]), 0.5);
    EXPECT_LE(std::stoi(cell["num_replans"]), 40);
    EXPECT_NEAR(std::stod(cell["straight_line_m"]), 13.0, 1e-4);
    EXPECT_NE(cell["mapper_tsdf_insert_ms_median"], "");
    EXPECT_EQ(cell["obstacle_clearance_m"], "");  // no dynamic obstacle by default

    const sim::World world = paperWorld(static_cast<uint64_t>(7 + trial));
    checkPath(out + "/paths/" + std::to_string(trial) + ".csv", world,
              std::stod(cell["path_length_m"]), std::stod(cell["path_time_s"]));
  }
  std::filesystem::remove_all(out);
}

// --config flies another configuration: a planner that demands 2 m of clearance (the start is
// 1.5 m above the ground) accepts no trajectory, where the shipped configuration reaches the goal
// of the same world.
TEST(BenchRun, ConfigChangesTheOptionsTheGraphFlies) {
  const std::string demanding = configCopy(tempDir("demanding"), "clearance_margin: 1.5");
  const std::string shipped = tempDir("shipped"), changed = tempDir("changed");
  const std::string common = "run --density 0.05 --trials 1 --seed-base 7 --replans 30 --out ";
  const CliResult first = bench(common + shipped);
  ASSERT_EQ(first.status, 0) << first.output;
  const CliResult second = bench(common + changed + " --config " + demanding);
  ASSERT_EQ(second.status, 0) << second.output;
  const auto row = [](const std::string& dir) {
    const Table table = readTable(dir + "/trials.csv");
    EXPECT_EQ(table.size(), 2u);
    return cellsByColumn(table);
  };
  const auto reached = row(shipped), held = row(changed);
  EXPECT_EQ(reached.at("success"), "1");
  EXPECT_EQ(held.at("success"), "0");
  EXPECT_LT(std::stod(held.at("path_length_m")), 0.01);
  for (const std::string& dir : {demanding, shipped, changed}) std::filesystem::remove_all(dir);
}

TEST(BenchRun, BadFlagsFailWithAMessage) {
  const auto fails = [](const std::string& args, const std::string& message) {
    const CliResult result = bench("run " + args);
    EXPECT_EQ(result.status, 2) << args << ": " << result.output;
    EXPECT_NE(result.output.find(message), std::string::npos) << args << ": " << result.output;
  };
  const std::string out = " --out " + tempDir("refused");
  fails("--density 0.05 --trials 0" + out, "--trials: must be an integer >= 1, not '0'");
  fails("--density 0.05 --trials 2 --method bogus" + out, "--method: bogus not in {none,random,");
  fails("--density 0.05 --trials 2", "--out is required");
  fails("--density abc --trials 2" + out, "--density: must be a number >= 0, not 'abc'");
  fails("--density 0.05 --trials 2 --goal-finding curve" + out,
        "--goal-finding: curve not in {line,gradient,soft}");
  fails("--density 0.05 --trials 2 --fast 1" + out, "not expected: 1 --fast");
  fails("--density 0.05 --trials 2 --dynamic-obstacle yes" + out,
        "--dynamic-obstacle: must be on or off, not 'yes'");
  fails("--density 0.05 --trials 2 --scenario nowhere" + out, "nowhere");
  fails("--density 0.05 --trials 2 --config /nonexistent/sim" + out,
        "/nonexistent/sim/vio_bridge.yaml: cannot open");
  const std::string bad = configCopy(tempDir("bad_config"), "clearance_margin: -1");
  fails("--density 0.05 --trials 2 --config " + bad + out, "clearance_margin");
  std::filesystem::remove_all(bad);
  EXPECT_FALSE(std::filesystem::exists(tempDir("refused")));

  const CliResult help = bench("run --help");
  EXPECT_EQ(help.status, 0) << help.output;
  EXPECT_NE(help.output.find("Usage: thicket-bench run"), std::string::npos) << help.output;
}

}  // namespace
}  // namespace thicket::bench

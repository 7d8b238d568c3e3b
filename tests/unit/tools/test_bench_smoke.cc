// The benchmark's smoke run in CI: every experiment of docs/benchmark.md, a few trials each on
// short missions, run by `thicket-bench experiment` as a user runs it (the ctest bench_smoke_run,
// into BENCH_SMOKE_DIR: its exit status says every trial ran), and here the invariants that must
// hold whatever the numbers: every trial finished, no collision for a conservative strategy, a
// success really ends at the goal, a conservative strategy stops short of E6's dynamic obstacle,
// and every output (rows, paths, E5 table, summary, figures) well formed.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "csv.h"
#include "thicket/sim/world.h"
#include "trials.h"

namespace thicket::bench {
namespace {

namespace fs = std::filesystem;

constexpr int kTrials = 2;
constexpr int kReplans = 40;

std::string fileText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

double number(const std::string& cell) {
  size_t used = 0;
  const double value = std::stod(cell, &used);
  EXPECT_EQ(used, cell.size()) << "'" << cell << "' is not a number";
  return value;
}

const fs::path kDir = BENCH_SMOKE_DIR;

// trials.csv as rows keyed by column name.
std::vector<std::map<std::string, std::string>> trials() {
  const auto table = readCsv((kDir / "trials.csv").string());
  EXPECT_TRUE(table) << table.error();
  std::vector<std::map<std::string, std::string>> rows;
  if (!table) return rows;
  for (const auto& row : table->rows) {
    std::map<std::string, std::string> named;
    for (size_t c = 0; c < table->header.size(); ++c) named[table->header[c]] = row.cells[c];
    rows.push_back(named);
  }
  return rows;
}

TEST(BenchSmoke, EveryTrialOfEveryExperimentFinished) {
  const auto rows = trials();
  // E1: 3 goal findings; E2 (on paper and eth): every method; E4 and E6: every method but the
  // ablations; one density each, kTrials trials.
  const int methods = static_cast<int>(methodNames().size());
  const int flown = static_cast<int>(methodNames(false).size());
  std::map<std::string, int> per_experiment;
  std::set<std::string> keys;
  for (const auto& row : rows) {
    ++per_experiment[row.at("experiment") + "/" + row.at("scenario")];
    EXPECT_EQ(row.at("end_reason").rfind("error: ", 0), std::string::npos)
        << row.at("experiment") << " " << row.at("method") << " s" << row.at("seed") << ": "
        << row.at("end_reason");
    EXPECT_LE(number(row.at("num_replans")), kReplans);
    EXPECT_TRUE(keys.insert(row.at("experiment") + row.at("scenario") + row.at("method") +
                            row.at("goal_finding") + row.at("seed"))
                    .second);
  }
  EXPECT_EQ(per_experiment["E1/paper"], 3 * kTrials);
  EXPECT_EQ(per_experiment["E2/paper"], methods * kTrials);
  EXPECT_EQ(per_experiment["E2/eth"], methods * kTrials);
  EXPECT_EQ(per_experiment["E4/forest50"], flown * kTrials);
  EXPECT_EQ(per_experiment["E6/paper"], flown * kTrials);
  EXPECT_EQ(per_experiment.size(), 5u);
}

TEST(BenchSmoke, ConservativeStrategiesNeverCollideAndSuccessEndsAtTheGoal) {
  for (const auto& row : trials()) {
    const std::string what = row.at("experiment") + " " + row.at("method") + " " +
                             row.at("goal_finding") + " s" + row.at("seed");
    const double clearance = number(row.at("min_clearance_m"));
    EXPECT_TRUE(std::isfinite(clearance)) << what;
    if (row.at("method") != "rrt_star_optimistic") {
      EXPECT_EQ(row.at("collision"), "0") << what << ": min clearance " << clearance;
    }
    if (row.at("success") == "1") {
      EXPECT_LE(number(row.at("distance_to_goal_m")), 0.2) << what;
      EXPECT_EQ(row.at("collision"), "0") << what;
      EXPECT_GE(number(row.at("path_length_m")), number(row.at("straight_line_m")) - 0.2) << what;
    }
  }
}

// E6: where the dynamic obstacle appeared, a conservative strategy found its committed trajectory
// blocked and kept the robot radius from the obstacle; no other experiment has one.
TEST(BenchSmoke, ConservativeStrategiesStopShortOfTheDynamicObstacle) {
  const auto paper = sim::loadScenario("paper", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  ASSERT_TRUE(paper) << paper.error();
  int appeared = 0;
  for (const auto& row : trials()) {
    const std::string what = row.at("experiment") + " " + row.at("method") + " s" + row.at("seed");
    const std::string& clearance = row.at("obstacle_clearance_m");
    if (row.at("experiment") != "E6") {
      EXPECT_EQ(clearance, "") << what;
      continue;
    }
    if (clearance.empty() || !conservativeMethod(row.at("method"))) continue;
    ++appeared;
    EXPECT_GE(number(clearance), paper->robot_radius) << what;
    EXPECT_GE(number(row.at("blocked_cycles")), 1) << what;
  }
  EXPECT_GT(appeared, 0) << "the obstacle appeared in no conservative E6 trial";
}

// The oracle demands more at the planning radius than at the collision radius; overflight is
// needed only where the bottleneck is narrower than the planning radius.
TEST(BenchSmoke, TheOracleColumnsAgree) {
  const auto loco =
      trialGraphOptions("none", "soft", 0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(), 0.1)
          .planner.planner.loco;
  const double planning_radius = loco.robot_radius + loco.clearance_margin;
  for (const auto& row : trials()) {
    const std::string what = row.at("experiment") + " " + row.at("method") + " " +
                             row.at("goal_finding") + " s" + row.at("seed");
    const double bottleneck = number(row.at("bottleneck_m"));
    EXPECT_GE(bottleneck, 0.0) << what;
    if (row.at("solvable") == "1") {
      EXPECT_EQ(row.at("solvable_collision_radius"), "1") << what;
    }
    if (row.at("needs_overflight") == "1") {
      EXPECT_EQ(row.at("solvable"), "1") << what;
      EXPECT_LT(bottleneck, planning_radius) << what;
    } else if (row.at("solvable") == "1") {
      EXPECT_GE(bottleneck, planning_radius - 1e-4) << what;  // trials.csv has 4 decimals
    }
  }
}

TEST(BenchSmoke, EveryTrialHasItsPathFromStartToEnd) {
  int paths = 0;
  for (const auto& entry : fs::directory_iterator(kDir / "paths")) {
    const std::string text = fileText(entry.path());
    EXPECT_EQ(text.rfind("t,x,y,z,yaw\n", 0), 0u) << entry.path();
    EXPECT_GT(std::count(text.begin(), text.end(), '\n'), 10) << entry.path();
    ++paths;
  }
  EXPECT_EQ(paths, (3 + 2 * static_cast<int>(methodNames().size()) +
                    2 * static_cast<int>(methodNames(false).size())) *
                       kTrials);
}

TEST(BenchSmoke, TheSubsamplingTableHasTheExactGainAtFractionOne) {
  const auto table = readCsv((kDir / "e5_subsampling.csv").string());
  ASSERT_TRUE(table) << table.error();
  EXPECT_EQ(table->header,
            (std::vector<std::string>{"fraction", "stride", "poses", "mean_abs_error",
                                      "p95_abs_error", "max_abs_error", "median_us", "speedup"}));
  ASSERT_FALSE(table->rows.empty());
  for (const auto& row : table->rows) {
    for (size_t c = 3; c <= 5; ++c) {
      const double error = number(row.cells[c]);
      EXPECT_GE(error, 0.0);
      EXPECT_LE(error, 1.0);
    }
  }
  const auto& exact = table->rows.back();
  EXPECT_EQ(exact.cells[1], "1");
  EXPECT_EQ(number(exact.cells[5]), 0.0);
}

TEST(BenchSmoke, TheSummaryHasEveryExperimentAndTheFiguresArePngs) {
  const std::string summary = fileText(kDir / "summary.md");
  for (const char* heading :
       {"## Worlds:", "## E1:", "## E2: goal-selection strategies on paper,",
        "## E2: goal-selection strategies on eth,", "## E3:", "## E4:", "## T1:", "## E5:",
        "## E6: a path blocked in flight", "### E6 on paper, density 0.2",
        "### Success on worlds solvable at the planning radius (paper)",
        "### Success on worlds solvable at the collision radius (paper)",
        "### Success on worlds solvable at the planning radius (eth)",
        "### Success on worlds solvable at the collision radius (eth)"}) {
    EXPECT_NE(summary.find(heading), std::string::npos) << heading << " missing";
  }
  EXPECT_EQ(summary.find("## Problems"), std::string::npos) << summary;
  for (const char* figure : {"e1_success.png", "e2_success.png", "e2_success_eth.png",
                             "e4_success.png", "e4_forest.png", "e5_subsampling.png"}) {
    const std::string png = fileText(kDir / "figures" / figure);
    EXPECT_EQ(png.rfind("\x89PNG\r\n\x1a\n", 0), 0u) << figure;
  }
  const auto run_log = readCsv((kDir / "run_log.csv").string());
  ASSERT_TRUE(run_log) << run_log.error();
  EXPECT_EQ(run_log->rows.size(), 1u);
}

}  // namespace
}  // namespace thicket::bench

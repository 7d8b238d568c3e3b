// The real graph (sim, mapper, local planner, and the method's explorer) flying the paper's forest
// in-process, as `thicket-bench run` flies it: the planner reaches the goal on an easy world, never
// comes closer to an obstacle than the robot radius (ground truth) on dense ones with any
// goal-selection strategy, keeps the limits, flies the same path twice, and stops short of an
// obstacle that appears on its committed path (E6).
#include <gtest/gtest.h>

#include <string>

#include "thicket/explorer/goal_selector.h"
#include "trials.h"

namespace thicket::bench {
namespace {

RunOptions paper(double density, int replans) {
  RunOptions options;
  options.density = density;
  options.replans = replans;
  return options;
}

TrialResult fly(const RunOptions& options, int trial) {
  return runTrial(options, trialWorld(options, trial), trial);
}

TEST(TrialFlights, ReachTheGoalThroughASparseForest) {
  const RunOptions options = paper(0.1, 60);
  const TrialResult result = fly(options, 1);
  EXPECT_TRUE(result.success) << result.end_reason;
  EXPECT_FALSE(result.collision);
  EXPECT_TRUE(result.feasible);
  EXPECT_LT(result.distance_to_goal_m, 0.2);
  EXPECT_LT(result.path_length_m, 1.3 * result.straight_line_m);
}

TEST(TrialFlights, NeverComeCloserThanTheRobotRadiusInADenseForest) {
  for (const char* goal_finding : {"line", "soft"}) {
    RunOptions options = paper(0.3, 30);
    options.goal_finding = goal_finding;
    for (int trial = 0; trial < 3; ++trial) {
      const TrialResult result = fly(options, trial);
      SCOPED_TRACE(std::string(goal_finding) + ", trial " + std::to_string(trial) + ": " +
                   result.end_reason);
      EXPECT_FALSE(result.collision) << "clearance " << result.min_clearance_m;
      EXPECT_GE(result.min_clearance_m, 0.5);
      EXPECT_TRUE(result.feasible);
      // Every cycle closed with a final status: the simulator never gave up on the planner.
      EXPECT_EQ(result.end_reason.rfind("aborted", 0), std::string::npos);
    }
  }
}

TEST(TrialFlights, FlyTheSamePathTwice) {
  const RunOptions options = paper(0.2, 20);
  const TrialResult a = fly(options, 4);
  const TrialResult b = fly(options, 4);
  ASSERT_EQ(a.path.size(), b.path.size());
  for (size_t i = 0; i < a.path.size(); ++i) {
    ASSERT_EQ(a.path[i].utime, b.path[i].utime);
    ASSERT_EQ(a.path[i].position, b.path[i].position) << "sample " << i;
  }
  EXPECT_EQ(a.num_replans, b.num_replans);
}

// Every goal-selection strategy is a method of the benchmark, and flies safely and reproducibly
// where the forest blocks the optimizer.
TEST(TrialFlights, EveryStrategyFliesSafelyAndTheSamePathTwice) {
  for (const std::string& strategy : explorer::strategyNames()) {
    RunOptions options = paper(0.3, 30);
    options.method = strategy;
    ASSERT_TRUE(parseRunOptions(
        {"--density", "0.3", "--trials", "1", "--method", strategy, "--out", "unused"}))
        << strategy << " is not a method of thicket-bench run";
    const TrialResult a = fly(options, 3);
    const TrialResult b = fly(options, 3);
    SCOPED_TRACE(strategy + ": " + a.end_reason);
    EXPECT_FALSE(a.collision) << "clearance " << a.min_clearance_m;
    EXPECT_GE(a.min_clearance_m, 0.5);
    EXPECT_TRUE(a.feasible);
    EXPECT_EQ(a.end_reason.rfind("aborted", 0), std::string::npos);
    ASSERT_EQ(a.path.size(), b.path.size());
    for (size_t i = 0; i < a.path.size(); ++i) {
      ASSERT_EQ(a.path[i].position, b.path[i].position) << "sample " << i;
    }
  }
}

// E6: the simulator's dynamic obstacle appears on the committed trajectory 2-2.5 m ahead (at the
// first frame after 5 s with that much committed path left, not winding back toward the vehicle,
// so not in every trial: a vehicle that hovers or whose path runs short never gets one); the
// planner's re-check finds the trajectory blocked on a later map and stops or replans, and the
// vehicle never comes within the robot radius of it, nor of anything else.
TEST(TrialFlights, StopShortOfAnObstacleThatAppearsOnTheCommittedPath) {
  for (const char* method : {"local_exploration", "none"}) {
    RunOptions options = paper(0.2, 30);
    options.method = method;
    options.dynamic_obstacle = true;
    int appeared = 0;
    constexpr int kTrials = 8;
    for (int trial = 0; trial < kTrials; ++trial) {
      const sim::World world = trialWorld(options, trial);
      const TrialResult result = runTrial(options, world, trial);
      SCOPED_TRACE(std::string(method) + ", trial " + std::to_string(trial) + ": " +
                   result.end_reason);
      EXPECT_FALSE(result.collision) << "clearance " << result.min_clearance_m;
      EXPECT_EQ(result.end_reason.rfind("aborted", 0), std::string::npos);
      if (!result.obstacle_clearance_m) continue;
      ++appeared;
      EXPECT_GE(*result.obstacle_clearance_m, world.robot_radius);
      EXPECT_GE(result.blocked_cycles, 1);
    }
    // Most of those that never get one stall at the start, before 5 s.
    EXPECT_GE(appeared, 2) << method;
  }
  // Without it, nothing appears.
  const TrialResult plain = fly(paper(0.2, 10), 0);
  EXPECT_FALSE(plain.obstacle_clearance_m.has_value());
}

}  // namespace
}  // namespace thicket::bench

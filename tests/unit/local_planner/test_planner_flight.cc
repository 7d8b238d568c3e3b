// The real graph (sim, mapper, local planner) in a memq:// composite flying the paper's forest:
// the planner reaches the goal on an easy world, never comes closer to an obstacle than the robot
// radius (ground truth) on dense ones, keeps the limits, and flies the same way twice.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include <thicket/goal_t.hpp>
#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>

#include "local_planner_node.h"
#include "mapper_node.h"
#include "sim_node.h"
#include "thicket/common/loop.h"

namespace thicket::local_planner {
namespace {

struct Flight {
  sim::Outcome outcome = sim::Outcome::kRunning;
  std::string end_reason;
  double min_clearance = 0;
  double robot_radius = 0;
  bool feasible = false;
  int final_statuses = 0;
  std::vector<std::vector<uint8_t>> trajectories;  // encoded PLANNER_TRAJECTORY messages
};

Flight fly(double density, uint64_t seed, int replans) {
  auto spec = sim::loadScenario("paper", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  EXPECT_TRUE(spec) << spec.error();
  auto world = sim::generateWorld(*spec, density, seed);
  EXPECT_TRUE(world) << world.error();
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  sim::SimOptions sim_options;
  sim_options.lockstep = true;
  sim_options.seed = static_cast<int64_t>(seed);
  sim_options.vehicle.replan_limit = replans;
  mapper::MapperNodeOptions mapper_options;
  mapper_options.state_channel = "VIO_ODOMETRY";
  LocalPlannerNodeOptions planner_options;
  planner_options.state_channel = "VIO_ODOMETRY";
  planner_options.planner.seed = static_cast<int64_t>(seed);

  Flight flight;
  Node observer("observer", lcm);
  observer.subscribe<planner_status_t>("PLANNER_STATUS",
                                       [&](const planner_status_t& msg, const MessageInfo&) {
                                         flight.final_statuses += msg.is_final;
                                       });
  observer.subscribeRaw("PLANNER_TRAJECTORY",
                        [&](const void* data, size_t size, const MessageInfo&) {
                          const auto* bytes = static_cast<const uint8_t*>(data);
                          flight.trajectories.emplace_back(bytes, bytes + size);
                        });
  sim::SimNode sim(lcm, sim_options, *world);
  mapper::MapperNode mapper(lcm, mapper_options, static_cast<int64_t>(seed) + 1);
  LocalPlannerNode planner(lcm, planner_options);
  goal_t goal{};
  goal.goal_id = 1;
  goal.num_waypoints = 1;
  goal.waypoints = {{world->goal.x(), world->goal.y(), world->goal.z()}};
  goal.yaws = {0};
  observer.publish("MISSION_GOAL", goal);
  loop.drain();
  sim.start();
  while (!sim.finished()) {
    if (loop.drain() == 0) sim.abort("no final planner status");
  }
  flight.outcome = sim.vehicle().outcome();
  flight.end_reason = sim.endReason();
  flight.min_clearance = sim.vehicle().minClearance();
  flight.robot_radius = world->robot_radius;
  flight.feasible = sim.vehicle().feasible();
  return flight;
}

TEST(PlannerFlight, ReachesTheGoalThroughASparseForest) {
  const Flight flight = fly(0.1, 1, 60);
  EXPECT_EQ(flight.outcome, sim::Outcome::kGoalReached) << flight.end_reason;
  EXPECT_GE(flight.min_clearance, flight.robot_radius);
  EXPECT_TRUE(flight.feasible);
}

TEST(PlannerFlight, NeverComesCloserThanTheRobotRadiusInADenseForest) {
  for (uint64_t seed = 0; seed < 4; ++seed) {
    const Flight flight = fly(0.3, seed, 30);
    SCOPED_TRACE("seed " + std::to_string(seed) + ": " + flight.end_reason);
    EXPECT_NE(flight.outcome, sim::Outcome::kCollision);
    EXPECT_GE(flight.min_clearance, flight.robot_radius);
    EXPECT_TRUE(flight.feasible);
    // Every cycle closed with a final status: the simulator never had to give up on the planner.
    EXPECT_EQ(flight.end_reason.rfind("aborted", 0), std::string::npos);
  }
}

TEST(PlannerFlight, FliesTheSameTrajectoriesTwice) {
  const Flight a = fly(0.2, 4, 20);
  const Flight b = fly(0.2, 4, 20);
  ASSERT_FALSE(a.trajectories.empty());
  EXPECT_EQ(a.trajectories, b.trajectories);
  EXPECT_EQ(a.final_statuses, b.final_statuses);
}

}  // namespace
}  // namespace thicket::local_planner

// thicket-log mission: the outcome of a simulated mission from hand-made logs of the simulator's
// events, and the exit status the demo relies on.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include <thicket/goal_t.hpp>
#include <thicket/sim_event_t.hpp>

#include "cli.h"
#include "mission.h"
#include "temp_dir_test.h"
#include "thicket/common/lcm_log.h"

namespace thicket::log {
namespace {

class LogMission : public thicket::testing::TempDirTest {};

sim_event_t event(int8_t type, int8_t outcome = sim_event_t::OUTCOME_NONE) {
  sim_event_t e{};
  e.type = type;
  e.outcome = outcome;
  e.message = outcome == sim_event_t::OUTCOME_GOAL_REACHED ? "goal reached" : "replan limit";
  e.num_replans = 26;
  e.path_length = 13.69;
  e.path_time = 26.0;
  e.min_clearance = 0.71;
  e.distance_to_goal = 0.05;
  return e;
}

goal_t explorerGoal(int8_t status) {
  goal_t g{};
  g.source = goal_t::SOURCE_EXPLORER;
  g.status = status;
  return g;
}

// A mission with two explorer answers (one without a candidate) and the given events.
std::string writeMission(const std::string& path, const std::vector<sim_event_t>& events) {
  LogWriter writer(path);
  writer.write(1'000, "SIM_EVENT", event(sim_event_t::TYPE_TRIAL_START));
  writer.write(2'000, "EXPLORER_GOAL", explorerGoal(goal_t::STATUS_OK));
  writer.write(3'000, "EXPLORER_GOAL", explorerGoal(goal_t::STATUS_NO_CANDIDATE));
  int64_t t = 4'000;
  for (const sim_event_t& e : events) writer.write(t++, "SIM_EVENT", e);
  return path;
}

TEST_F(LogMission, AGoalReachedWithoutCollisionSucceeds) {
  const std::string path = writeMission(
      tempPath("ok.lcm"), {event(sim_event_t::TYPE_TRIAL_END, sim_event_t::OUTCOME_GOAL_REACHED)});
  const auto report = missionReport(path);
  ASSERT_TRUE(report) << report.error();
  EXPECT_TRUE(report->success());
  EXPECT_EQ(report->num_replans, 26);
  EXPECT_EQ(report->explorer_goals, 1);
  EXPECT_EQ(report->text(),
            "goal reached after 26 replans and 26.0 s: path 13.69 m, 0.05 m from the goal, min "
            "clearance 0.710 m, 0 collisions, 0 refused trajectories, 1 intermediate goals from "
            "the explorer");
  const auto cli = testing::runCommand(std::string(THICKET_LOG) + " mission " + path);
  EXPECT_EQ(cli.status, 0) << cli.output;
  EXPECT_NE(cli.output.find("mission: goal reached after 26 replans"), std::string::npos)
      << cli.output;
}

TEST_F(LogMission, ACollisionOrAnotherEndOrNoEndFails) {
  const std::string collided =
      writeMission(tempPath("collided.lcm"),
                   {event(sim_event_t::TYPE_COLLISION),
                    event(sim_event_t::TYPE_TRIAL_END, sim_event_t::OUTCOME_GOAL_REACHED)});
  const std::string limit =
      writeMission(tempPath("limit.lcm"),
                   {event(sim_event_t::TYPE_TRIAL_END, sim_event_t::OUTCOME_REPLAN_LIMIT)});
  const std::string unended = writeMission(tempPath("unended.lcm"), {});
  for (const std::string& path : {collided, limit, unended}) {
    const auto report = missionReport(path);
    ASSERT_TRUE(report) << report.error();
    EXPECT_FALSE(report->success()) << path;
    EXPECT_EQ(testing::runCommand(std::string(THICKET_LOG) + " mission " + path).status, 1) << path;
  }
  EXPECT_EQ(missionReport(collided)->collisions, 1);
  EXPECT_FALSE(missionReport(limit)->goal_reached);
  EXPECT_NE(missionReport(unended)->text().find("did not end"), std::string::npos);
  EXPECT_EQ(testing::runCommand(std::string(THICKET_LOG) + " mission /nonexistent.lcm").status, 2);
}

// A stray packet on the bus must not stop the demo from reporting: LCM's generated decoder threw
// std::length_error on a string length of 0 and aborted the tool.
TEST_F(LogMission, MalformedMessagesInTheLogAreSkipped) {
  goal_t strange = explorerGoal(goal_t::STATUS_OK);
  strange.strategy = "xyz";
  std::vector<uint8_t> bytes(static_cast<size_t>(strange.getEncodedSize()));
  strange.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const std::vector<uint8_t> length_and_text = {0, 0, 0, 4, 'x', 'y', 'z', 0};
  const auto at =
      std::search(bytes.begin(), bytes.end(), length_and_text.begin(), length_and_text.end());
  ASSERT_NE(at, bytes.end());
  at[3] = 0;  // a string of length 0: not even its NUL

  const std::string path = tempPath("stray.lcm");
  {
    LogWriter writer(path);
    writer.write(1'000, "SIM_EVENT", event(sim_event_t::TYPE_TRIAL_START));
    writer.write(2'000, "EXPLORER_GOAL", bytes.data(), bytes.size());
    writer.write(3'000, "EXPLORER_GOAL", explorerGoal(goal_t::STATUS_OK));
    writer.write(4'000, "SIM_EVENT", bytes.data(), bytes.size());  // another type's fingerprint
    writer.write(5'000, "SIM_EVENT",
                 event(sim_event_t::TYPE_TRIAL_END, sim_event_t::OUTCOME_GOAL_REACHED));
  }
  const auto report = missionReport(path);
  ASSERT_TRUE(report) << report.error();
  EXPECT_TRUE(report->success());
  EXPECT_EQ(report->explorer_goals, 1);
  EXPECT_EQ(testing::runCommand(std::string(THICKET_LOG) + " mission " + path).status, 0);
}

}  // namespace
}  // namespace thicket::log

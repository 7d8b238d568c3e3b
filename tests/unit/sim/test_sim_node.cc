// thicket-sim's node in a memq:// composite with a scripted planner: lockstep stepping, the
// messages of a mission, refusals, and byte-identical output from identical runs.
#include <gtest/gtest.h>

#include <thicket/depth_image_t.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/sim_world_t.hpp>

#include "sim_node.h"
#include "sim_test_support.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/loop.h"

namespace thicket::sim {
namespace {

using testing::restToRest;

World corridor() {
  return testing::corridor({{14.0, 5.0, 0.5, 4.0}, {6.0, 8.5, 0.3, 2.0}});
}

// Answers every depth frame: the first one with a trajectory to the goal, each with a final
// status planned from the frame's time.
class ScriptedPlanner : public Node {
 public:
  explicit ScriptedPlanner(lcm::LCM& lcm, const World& world) : Node("planner", lcm) {
    subscribe<depth_image_t>(
        "CAMERA_DEPTH", [this, world](const depth_image_t& msg, const MessageInfo&) {
          auto decoded = decodeDepthImage(msg);
          EXPECT_TRUE(decoded) << decoded.error();
          if (frames == 0)
            publish("PLANNER_TRAJECTORY", restToRest(msg.utime, world.start, world.goal, 15));
          planner_status_t status{};
          status.utime = msg.utime;
          status.cycle = frames++;
          status.is_final = true;
          publish("PLANNER_STATUS", status);
        });
  }
  int frames = 0;
};

struct Recorded {
  std::vector<std::string> channels;
  std::vector<std::vector<uint8_t>> payloads;
};

SimOptions lockstepOptions() {
  SimOptions options;
  options.lockstep = true;
  options.depth_camera.width = 64;
  options.depth_camera.height = 48;
  return options;
}

Recorded runMission(int* cycles = nullptr) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Recorded recorded;
  Node recorder("recorder", lcm);
  recorder.subscribeRaw(
      ".*",
      [&](const void* data, size_t size, const MessageInfo& info) {
        recorded.channels.emplace_back(info.channel);
        const auto* bytes = static_cast<const uint8_t*>(data);
        recorded.payloads.emplace_back(bytes, bytes + size);
      },
      100000);
  const World world = corridor();
  SimNode sim(lcm, lockstepOptions(), world);
  ScriptedPlanner planner(lcm, world);
  sim.start();
  while (loop.drain() > 0 && !sim.finished()) {
  }
  EXPECT_TRUE(sim.finished());
  EXPECT_EQ(sim.vehicle().outcome(), Outcome::kGoalReached);
  if (cycles) *cycles = sim.vehicle().cycle();
  return recorded;
}

TEST(SimNode, FliesAScriptedMissionInLockstep) {
  int cycles = 0;
  const Recorded recorded = runMission(&cycles);
  EXPECT_EQ(cycles, 14);
  auto count = [&](const std::string& channel) {
    return std::count(recorded.channels.begin(), recorded.channels.end(), channel);
  };
  EXPECT_EQ(count("SIM_WORLD"), 1);
  EXPECT_EQ(count("CAMERA_DEPTH"), 14);  // frames 0..13; the 14th step ends the mission
  EXPECT_EQ(count("PLANNER_STATUS"), 14);
  EXPECT_EQ(count("SIM_TRUTH"), count("VIO_ODOMETRY"));
  EXPECT_EQ(count("SIM_TRUTH"), 1 + 14 * 20);  // the start, then 20 Hz for 14 s

  std::vector<sim_event_t> events;
  for (size_t i = 0; i < recorded.channels.size(); ++i) {
    if (recorded.channels[i] != "SIM_EVENT") continue;
    sim_event_t event{};
    ASSERT_EQ(decodeMessage(recorded.payloads[i].data(), recorded.payloads[i].size(), event), "");
    events.push_back(event);
  }
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events.front().type, +sim_event_t::TYPE_TRIAL_START);
  EXPECT_EQ(events.back().type, +sim_event_t::TYPE_TRIAL_END);
  EXPECT_EQ(events.back().outcome, +sim_event_t::OUTCOME_GOAL_REACHED);
  EXPECT_EQ(events.back().num_replans, 14);
  EXPECT_LE(events.back().distance_to_goal, 0.2);
  EXPECT_NEAR(events.back().path_length, 9.0 - events.back().distance_to_goal, 1e-6);

  // Every depth frame was taken where the truth says the vehicle was, at that time.
  int64_t last_truth_utime = -1;
  for (size_t i = 0; i < recorded.channels.size(); ++i) {
    if (recorded.channels[i] == "SIM_TRUTH") {
      odometry_t truth{};
      ASSERT_EQ(decodeMessage(recorded.payloads[i].data(), recorded.payloads[i].size(), truth), "");
      last_truth_utime = truth.utime;
    } else if (recorded.channels[i] == "CAMERA_DEPTH") {
      depth_image_t depth{};
      ASSERT_EQ(decodeMessage(recorded.payloads[i].data(), recorded.payloads[i].size(), depth), "");
      EXPECT_EQ(depth.utime, last_truth_utime);
    }
  }
}

TEST(SimNode, IdenticalRunsPublishIdenticalBytes) {
  const Recorded a = runMission();
  const Recorded b = runMission();
  ASSERT_EQ(a.channels, b.channels);
  for (size_t i = 0; i < a.payloads.size(); ++i) {
    EXPECT_EQ(a.payloads[i], b.payloads[i]) << "message " << i << " on " << a.channels[i];
  }
}

TEST(SimNode, StepsOnlyOnAFinalStatusForTheAwaitedFrame) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  SimNode sim(lcm, lockstepOptions(), corridor());
  Node planner("planner", lcm);
  sim.start();
  loop.drain();
  ASSERT_EQ(sim.waitingFor(), std::optional<int64_t>(0));

  planner_status_t status{};
  status.utime = 0;
  status.is_final = false;
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  EXPECT_EQ(sim.vehicle().cycle(), 0);

  status.is_final = true;
  status.utime = -1;  // planned from an older state: not this frame
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  EXPECT_EQ(sim.vehicle().cycle(), 0);

  status.utime = 0;
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  EXPECT_EQ(sim.vehicle().cycle(), 1);
  EXPECT_EQ(sim.waitingFor(), std::optional<int64_t>(1'000'000));
}

// What a restarted planner needs: stepping on without a final status flies what was committed
// and sends a new estimate and frame (said in a SIM_EVENT); a planner that reports it has no goal
// gets the mission goal again, once per frame.
TEST(SimNode, StepsOnWithoutAnAnswerAndResendsTheGoalToAPlannerWithoutOne) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  const World world = corridor();
  SimNode sim(lcm, lockstepOptions(), world);
  Node planner("planner", lcm);
  std::vector<std::string> heard;
  std::vector<goal_t> goals;
  std::vector<sim_event_t> events;
  planner.subscribe<goal_t>("MISSION_GOAL", [&](const goal_t& goal, const MessageInfo&) {
    goals.push_back(goal);
    heard.push_back("goal");
  });
  planner.subscribe<depth_image_t>(
      "CAMERA_DEPTH", [&](const depth_image_t&, const MessageInfo&) { heard.push_back("frame"); });
  planner.subscribe<odometry_t>(
      "VIO_ODOMETRY", [&](const odometry_t&, const MessageInfo&) { heard.push_back("odometry"); });
  planner.subscribe<sim_event_t>(
      "SIM_EVENT", [&](const sim_event_t& event, const MessageInfo&) { events.push_back(event); });
  sim.start();
  loop.drain();
  planner.publish("PLANNER_TRAJECTORY", restToRest(0, world.start, world.goal, 15));
  loop.drain();
  ASSERT_EQ(goals.size(), 1u);
  heard.clear();

  sim.stepOn(3.2);  // the planner was gone
  loop.drain();
  EXPECT_EQ(sim.stepsOn(), 1);
  EXPECT_EQ(sim.vehicle().cycle(), 1);
  EXPECT_EQ(sim.waitingFor(), std::optional<int64_t>(1'000'000));
  EXPECT_GT(sim.vehicle().state().position.x(), world.start.x());  // it flew what it committed
  ASSERT_FALSE(heard.empty());
  EXPECT_EQ(heard.front(), "odometry");
  EXPECT_EQ(heard.back(), "frame");
  ASSERT_FALSE(events.empty());
  EXPECT_NE(events.back().message.find("stepping on"), std::string::npos) << events.back().message;

  // The respawned planner has no goal: the goal goes out again, once for this frame.
  planner_status_t status{};
  status.utime = 1'000'000;
  status.is_final = false;
  status.goal_id = -1;
  status.state = planner_status_t::STATE_HOLDING;
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  EXPECT_EQ(goals.size(), 1u);  // not a final status
  status.is_final = true;
  status.utime = 500'000;  // not the awaited frame: the goal, but no step
  planner.publish("PLANNER_STATUS", status);
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  ASSERT_EQ(goals.size(), 2u);
  EXPECT_EQ(goals[1].goal_id, goals[0].goal_id);
  EXPECT_EQ(goals[1].waypoints, goals[0].waypoints);
  EXPECT_EQ(sim.vehicle().cycle(), 1);
  status.utime = 1'000'000;
  status.goal_id = 1;
  planner.publish("PLANNER_STATUS", status);
  loop.drain();
  EXPECT_EQ(sim.vehicle().cycle(), 2);  // an answer steps as before
  EXPECT_EQ(sim.stepsOn(), 1);
  EXPECT_EQ(goals.size(), 2u);
}

// The executable turns rate into a timer period in whole microseconds: a rate whose period does
// not fit (1e6 / 1e-300) is refused when the options load, never cast.
TEST(SimOptions, ARateWhosePeriodCannotBeATimerIsRefused) {
  EXPECT_THROW(loadParamsFromString<SimOptions>("rate: 1e-300", "sim.yaml"), ParamError);
  EXPECT_THROW(loadParamsFromString<SimOptions>("rate: 1e9", "sim.yaml"), ParamError);
  EXPECT_EQ(loadParamsFromString<SimOptions>("rate: 4", "sim.yaml").rate, 4.0);
}

TEST(SimNode, RefusedTrajectoriesAreReportedAndTheVehicleHolds) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  const World world = corridor();
  SimNode sim(lcm, lockstepOptions(), world);
  Node planner("planner", lcm);
  std::vector<sim_event_t> events;
  planner.subscribe<sim_event_t>(
      "SIM_EVENT", [&](const sim_event_t& event, const MessageInfo&) { events.push_back(event); });
  sim.start();
  loop.drain();

  polynomial_trajectory_t bad = restToRest(0, world.start, world.goal, 15);
  bad.durations[0] = -1;
  planner.publish("PLANNER_TRAJECTORY", bad);
  planner.publish("PLANNER_TRAJECTORY", restToRest(5'000'000, world.start, world.goal, 15));
  loop.drain();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[1].type, +sim_event_t::TYPE_TRAJECTORY_REFUSED);
  EXPECT_NE(events[1].message.find("not positive"), std::string::npos) << events[1].message;
  EXPECT_NE(events[2].message.find("in the future"), std::string::npos) << events[2].message;

  sim.advance();
  loop.drain();
  EXPECT_EQ(sim.vehicle().state().position, world.start);
}

TEST(SimNode, AbortEndsTheMissionWithTheReason) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  SimNode sim(lcm, lockstepOptions(), corridor());
  Node listener("listener", lcm);
  std::vector<sim_event_t> events;
  listener.subscribe<sim_event_t>(
      "SIM_EVENT", [&](const sim_event_t& event, const MessageInfo&) { events.push_back(event); });
  sim.start();
  sim.abort("no planner");
  loop.drain();
  EXPECT_TRUE(sim.finished());
  EXPECT_EQ(sim.endReason(), "aborted: no planner");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].outcome, +sim_event_t::OUTCOME_ABORTED);
  EXPECT_EQ(events[1].message, "aborted: no planner");
  sim.advance();
  EXPECT_EQ(sim.vehicle().cycle(), 0);
}

}  // namespace
}  // namespace thicket::sim

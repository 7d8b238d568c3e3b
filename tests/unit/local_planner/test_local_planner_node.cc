// thicket-local-planner's node in a memq:// composite: goals are checked and refused with a
// reason, the ESDF mirror asks for a snapshot when it has none, a new map revision plans exactly
// once as soon as the state estimate at its time is in (trajectory first, then the cycle's final
// status, then the timing), bad estimates are refused, explorer answers for cycles that are not
// waiting are ignored, a stuck cycle waits for the explorer, a revision that blocks the committed
// trajectory publishes a stop and STATE_STOPPING, and setpoints follow the committed trajectory
// with yaw along the velocity.
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <thicket/goal_t.hpp>
#include <thicket/map_request_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/module_timing_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>
#include <thicket/setpoint_t.hpp>

#include "local_planner_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/map_update.h"
#include "thicket/common/polynomial_trajectory.h"

namespace thicket::local_planner {
namespace {

constexpr int64_t kSecond = 1'000'000;
constexpr int64_t kMapId = 42;
const Eigen::Vector3d kStart(0, 0, 1.5);

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// Everything the planner publishes, and the order it came in.
class Recorder : public Node {
 public:
  explicit Recorder(lcm::LCM& lcm) : Node("recorder", lcm) {
    subscribe<planner_status_t>(
        "PLANNER_STATUS",
        [this](const planner_status_t& m, const MessageInfo&) {
          statuses.push_back(m);
          order.push_back("PLANNER_STATUS");
        },
        1000);
    subscribe<polynomial_trajectory_t>(
        "PLANNER_TRAJECTORY",
        [this](const polynomial_trajectory_t& m, const MessageInfo&) {
          trajectories.push_back(m);
          order.push_back("PLANNER_TRAJECTORY");
        },
        1000);
    subscribe<map_request_t>(
        "MAP_REQUEST",
        [this](const map_request_t& m, const MessageInfo&) {
          requests.push_back(m);
          order.push_back("MAP_REQUEST");
        },
        1000);
    subscribe<setpoint_t>(
        "CONTROL_SETPOINT",
        [this](const setpoint_t& m, const MessageInfo&) {
          setpoints.push_back(m);
          order.push_back("CONTROL_SETPOINT");
        },
        1000);
    subscribe<module_timing_t>(
        "MODULE_TIMING",
        [this](const module_timing_t& m, const MessageInfo&) {
          timings.push_back(m);
          order.push_back("MODULE_TIMING");
        },
        1000);
  }

  void clear() {
    statuses.clear();
    trajectories.clear();
    requests.clear();
    setpoints.clear();
    timings.clear();
    order.clear();
  }

  std::vector<planner_status_t> statuses;
  std::vector<polynomial_trajectory_t> trajectories;
  std::vector<map_request_t> requests;
  std::vector<setpoint_t> setpoints;
  std::vector<module_timing_t> timings;
  std::vector<std::string> order;
};

goal_t goalMsg(int64_t id, const std::vector<Eigen::Vector3d>& waypoints,
               int8_t source = goal_t::SOURCE_OPERATOR) {
  goal_t msg{};
  msg.utime = 1;
  msg.goal_id = id;
  msg.source = source;
  msg.cycle = -1;
  msg.status = goal_t::STATUS_OK;
  msg.yaw_policy = goal_t::YAW_ALONG_VELOCITY;
  msg.num_waypoints = static_cast<int32_t>(waypoints.size());
  for (const Eigen::Vector3d& w : waypoints) {
    msg.waypoints.push_back({w.x(), w.y(), w.z()});
    msg.yaws.push_back(0);
  }
  return msg;
}

odometry_t odometryAt(int64_t utime, const Eigen::Vector3d& position,
                      const Eigen::Vector3d& velocity = Eigen::Vector3d::Zero()) {
  odometry_t msg{};
  msg.utime = utime;
  msg.sequence = utime / 1000;
  for (int i = 0; i < 3; ++i) {
    msg.position[i] = position[i];
    msg.linear_velocity[i] = velocity[i];
  }
  msg.orientation[0] = 1;
  msg.quality = odometry_t::QUALITY_GOOD;
  return msg;
}

// An ESDF of observed voxels around the start, x in [-3.2, 6.4), y in [-3.2, 3.2), z in
// [0, 3.2), with the distance `distance` at each voxel centre.
EsdfLayer esdfAround(const std::function<double(const Eigen::Vector3d&)>& distance) {
  EsdfLayer layer(0.2);
  for (int bx = -1; bx <= 1; ++bx) {
    for (int by = -1; by <= 0; ++by) {
      Block<EsdfVoxel>& block = layer.allocateBlock(BlockIndex(bx, by, 0));
      for (int i = 0; i < kVoxelsPerBlock; ++i) {
        const Eigen::Vector3d center = layer.voxelCenter(voxelOfBlock(block.index, i));
        EsdfVoxel& voxel = block.voxels[static_cast<size_t>(i)];
        voxel.distance = static_cast<float>(distance(center));
        voxel.observed = true;
        voxel.fixed = false;
      }
    }
  }
  return layer;
}

// All free (2 m, the ESDF's maximum distance, beyond the collision potential's reach).
EsdfLayer freeEsdf() {
  return esdfAround([](const Eigen::Vector3d&) { return 2.0; });
}

// A wall 1 m thick across x in [face, face + 1]: the signed distance to the slab, capped at 2 m.
EsdfLayer wallEsdf(double face = 2.5) {
  return esdfAround([face](const Eigen::Vector3d& p) {
    return std::min(2.0, std::max(face - p.x(), p.x() - face - 1));
  });
}

std::vector<map_update_t> snapshot(const EsdfLayer& layer, int64_t utime, int64_t revision) {
  MapRevision r;
  r.utime = utime;
  r.map_id = kMapId;
  r.revision = revision;
  r.full_snapshot = true;
  return encodeMapUpdate(layer, r, {}, {});
}

LocalPlannerNodeOptions nodeOptions(bool use_explorer = false) {
  LocalPlannerNodeOptions options;
  options.planner.use_explorer = use_explorer;
  return options;
}

class LocalPlannerNodeTest : public ::testing::Test {
 protected:
  explicit LocalPlannerNodeTest(bool use_explorer = false)
      : planner{lcm, nodeOptions(use_explorer)} {}

  void publishAll(const std::vector<map_update_t>& parts) {
    for (const map_update_t& part : parts) world.publish("MAP_ESDF", part);
  }

  // `goal` as the mission, an estimate at rest at kStart at t and an all-free snapshot at t (map
  // revision `revision`: a snapshot of the revision the mirror has is ignored): one planned
  // cycle. Returns whether it planned.
  bool planFromStart(const goal_t& goal, int64_t t, int64_t revision = 1) {
    world.publish("MISSION_GOAL", goal);
    world.publish("STATE_ESTIMATE", odometryAt(t, kStart));
    publishAll(snapshot(freeEsdf(), t, revision));
    loop.drain();
    if (recorder.statuses.size() != 1u) return false;
    EXPECT_EQ(recorder.statuses[0].state, +planner_status_t::STATE_PLANNED)
        << recorder.statuses[0].reason;
    return recorder.statuses[0].state == planner_status_t::STATE_PLANNED &&
           planner.planner().committed().has_value();
  }
  // The same toward a mission goal to the north-east.
  bool planNorthEast(int64_t t, int64_t revision = 1) {
    return planFromStart(goalMsg(51, {Eigen::Vector3d(10, 10, 1.5)}), t, revision);
  }

  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  LocalPlannerNode planner;
  Recorder recorder{lcm};
  Node world{"world", lcm};  // operator, mapper, estimator and explorer stand-ins
};

class LocalPlannerNodeExplorerTest : public LocalPlannerNodeTest {
 protected:
  LocalPlannerNodeExplorerTest() : LocalPlannerNodeTest(true) {}
};

// ---- goals ----

TEST_F(LocalPlannerNodeTest, RefusesBadMissionGoalsWithAReason) {
  ASSERT_TRUE(lcm.good());
  const auto expectRejected = [&](const goal_t& msg, const std::string& what,
                                  const std::string& reason_part) {
    recorder.clear();
    ASSERT_TRUE(world.publish("MISSION_GOAL", msg)) << what;
    loop.drain();
    ASSERT_EQ(recorder.statuses.size(), 1u) << what;
    const planner_status_t& status = recorder.statuses[0];
    EXPECT_EQ(status.state, +planner_status_t::STATE_REJECTED_GOAL) << what;
    EXPECT_EQ(status.goal_id, msg.goal_id) << what;
    EXPECT_TRUE(contains(status.reason, reason_part))
        << what << ": the reason was '" << status.reason << "'";
    EXPECT_FALSE(planner.planner().missionGoal()) << what;
    EXPECT_TRUE(recorder.trajectories.empty()) << what;
  };

  expectRejected(goalMsg(1, {Eigen::Vector3d(5, std::nan(""), 1.5)}), "NaN waypoint", "not finite");
  expectRejected(goalMsg(2, {Eigen::Vector3d(5, 0, 1.5), Eigen::Vector3d(5, 0, 500)}),
                 "outside the flight volume", "outside the flight volume");
  goal_t bad_yaw = goalMsg(3, {Eigen::Vector3d(5, 0, 1.5)});
  bad_yaw.yaw_policy = 7;
  expectRejected(bad_yaw, "unknown yaw policy", "yaw policy");
  goal_t nan_yaw = goalMsg(6, {Eigen::Vector3d(5, 0, 1.5)});
  nan_yaw.yaw_policy = goal_t::YAW_FIXED;
  nan_yaw.yaws[0] = INFINITY;
  expectRejected(nan_yaw, "infinite yaw", "yaw of waypoint 0 is not finite");
  expectRejected(goalMsg(4, {}), "no waypoints", "no waypoints");
  goal_t negative = goalMsg(5, {Eigen::Vector3d(5, 0, 1.5)});
  negative.tolerance = -1;
  expectRejected(negative, "negative tolerance", "tolerance");

  // A good goal is taken without a status; a cancel drops it.
  recorder.clear();
  world.publish("MISSION_GOAL", goalMsg(6, {Eigen::Vector3d(5, 0, 1.5)}));
  loop.drain();
  EXPECT_TRUE(recorder.statuses.empty());
  ASSERT_TRUE(planner.planner().missionGoal());
  EXPECT_EQ(planner.planner().missionGoal()->id, 6);
  EXPECT_EQ(planner.planner().missionGoal()->waypoints.at(0), Eigen::Vector3d(5, 0, 1.5));

  // A refused goal keeps the one before.
  world.publish("MISSION_GOAL", goalMsg(7, {Eigen::Vector3d(std::nan(""), 0, 1.5)}));
  loop.drain();
  ASSERT_TRUE(planner.planner().missionGoal());
  EXPECT_EQ(planner.planner().missionGoal()->id, 6);

  goal_t cancel = goalMsg(6, {});
  cancel.status = goal_t::STATUS_CANCEL;
  world.publish("MISSION_GOAL", cancel);
  loop.drain();
  EXPECT_FALSE(planner.planner().missionGoal());
  EXPECT_EQ(planner.badMessageCount(), 0);
}

// ---- the map and the cycle ----

TEST_F(LocalPlannerNodeTest, ADeltaWithoutAMapAsksForASnapshot) {
  const EsdfLayer layer = freeEsdf();
  MapRevision r;
  r.utime = 4 * kSecond;
  r.map_id = kMapId;
  r.revision = 5;
  publishAll(encodeMapUpdate(layer, r, {BlockIndex(0, 0, 0)}, {}));
  loop.drain();
  ASSERT_EQ(recorder.requests.size(), 1u);
  const map_request_t& request = recorder.requests[0];
  EXPECT_EQ(request.requester, "local_planner");
  EXPECT_EQ(request.layer, +map_update_t::LAYER_ESDF);
  EXPECT_EQ(request.last_revision, -1);
  EXPECT_FALSE(request.reason.empty());
  EXPECT_EQ(planner.mirror().layer(), nullptr);
  EXPECT_TRUE(recorder.statuses.empty());  // no map, no cycle
  EXPECT_EQ(planner.planner().cycles(), 0);
}

TEST_F(LocalPlannerNodeTest, RefusesMalformedMapUpdates) {
  std::vector<map_update_t> parts = snapshot(freeEsdf(), 4 * kSecond, 2);
  ASSERT_FALSE(parts.empty());
  for (map_update_t& part : parts) part.voxels_per_side = 8;
  publishAll(parts);
  loop.drain();
  EXPECT_EQ(planner.mirror().layer(), nullptr);
  EXPECT_EQ(planner.badMessageCount(), static_cast<int64_t>(parts.size()));
  EXPECT_TRUE(recorder.statuses.empty());
  EXPECT_EQ(planner.planner().cycles(), 0);
}

TEST_F(LocalPlannerNodeTest, ANewRevisionPlansOnceItsStateEstimateIsIn) {
  const int64_t t = 5 * kSecond;
  world.publish("MISSION_GOAL", goalMsg(11, {Eigen::Vector3d(10, 10, 1.5)}));
  // An estimate from before the map: not enough for the revision at t.
  world.publish("STATE_ESTIMATE", odometryAt(t - kSecond / 2, kStart));
  loop.drain();
  publishAll(snapshot(freeEsdf(), t, 3));
  loop.drain();
  ASSERT_NE(planner.mirror().layer(), nullptr);
  EXPECT_EQ(planner.mirror().revision(), 3);
  EXPECT_TRUE(recorder.requests.empty());
  // The revision waits for its state.
  EXPECT_TRUE(recorder.statuses.empty());
  EXPECT_TRUE(recorder.trajectories.empty());
  EXPECT_EQ(planner.planner().cycles(), 0);

  // The estimate at the revision's time: exactly one cycle, trajectory first, then the final
  // status, then the timing.
  world.publish("STATE_ESTIMATE", odometryAt(t, kStart));
  loop.drain();
  EXPECT_EQ(planner.planner().cycles(), 1);
  ASSERT_EQ(recorder.order,
            (std::vector<std::string>{"PLANNER_TRAJECTORY", "PLANNER_STATUS", "MODULE_TIMING"}));
  const planner_status_t& status = recorder.statuses[0];
  EXPECT_EQ(status.state, +planner_status_t::STATE_PLANNED) << status.reason;
  EXPECT_TRUE(status.is_final);
  EXPECT_EQ(status.cycle, 1);
  EXPECT_EQ(status.utime, t);
  EXPECT_EQ(status.map_revision, 3);
  EXPECT_EQ(status.goal_id, 11);
  EXPECT_EQ(status.goal_source, +goal_t::SOURCE_OPERATOR);
  EXPECT_EQ(status.goal[0], 10);
  EXPECT_EQ(status.goal[1], 10);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(status.start_position[i], kStart[i]);
  EXPECT_GT(status.iterations, 0);
  EXPECT_EQ(status.solver_termination, "CONVERGENCE") << status.solver_message;
  EXPECT_FALSE(status.solver_message.empty());
  EXPECT_GE(status.min_distance, planner.planner().options().loco.robot_radius);

  const polynomial_trajectory_t& msg = recorder.trajectories[0];
  EXPECT_EQ(msg.utime, t);
  EXPECT_EQ(msg.cycle, 1);
  EXPECT_EQ(msg.goal_id, 11);
  auto trajectory = PolynomialTrajectory::fromLcm(msg);
  ASSERT_TRUE(trajectory) << trajectory.error();
  ASSERT_TRUE(planner.planner().committed());
  const PolynomialTrajectory& committed = *planner.planner().committed();
  EXPECT_EQ(committed.startUtime(), t);
  ASSERT_EQ(trajectory->numSegments(), committed.numSegments());
  for (int i = 0; i < committed.numSegments(); ++i) {
    const auto& a = trajectory->segments()[static_cast<size_t>(i)];
    const auto& b = committed.segments()[static_cast<size_t>(i)];
    EXPECT_EQ(a.duration, b.duration);
    EXPECT_EQ(a.coefficients, b.coefficients);
  }
  EXPECT_NEAR((committed.evaluate(0) - kStart).norm(), 0, 1e-9);

  const module_timing_t& timing = recorder.timings[0];
  EXPECT_EQ(timing.module, "local_planner");
  EXPECT_EQ(timing.utime, t);
  EXPECT_EQ(timing.sequence, 1);
  EXPECT_EQ(timing.num_stages, static_cast<int32_t>(timing.stages.size()));
  EXPECT_EQ(timing.stages.size(), timing.durations_ms.size());
  EXPECT_FALSE(timing.stages.empty());

  // Later estimates without a new revision plan nothing.
  world.publish("STATE_ESTIMATE", odometryAt(t + kSecond / 10, kStart));
  loop.drain();
  EXPECT_EQ(planner.planner().cycles(), 1);
  EXPECT_EQ(recorder.statuses.size(), 1u);
  EXPECT_EQ(planner.badMessageCount(), 0);
}

TEST_F(LocalPlannerNodeTest, ReplanWithoutAMapHoversAndSaysWhy) {
  world.publish("STATE_ESTIMATE", odometryAt(kSecond, kStart));
  loop.drain();
  planner.replan();
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 1u);
  EXPECT_EQ(recorder.statuses[0].state, +planner_status_t::STATE_NO_MAP);
  EXPECT_TRUE(recorder.statuses[0].is_final);
  EXPECT_FALSE(recorder.statuses[0].reason.empty());
  ASSERT_EQ(recorder.trajectories.size(), 1u);  // the hover, at the estimate
  auto hover = PolynomialTrajectory::fromLcm(recorder.trajectories[0]);
  ASSERT_TRUE(hover) << hover.error();
  EXPECT_NEAR((hover->evaluate(0) - kStart).norm(), 0, 1e-12);
  EXPECT_NEAR(hover->evaluate(0.5, 1).norm(), 0, 1e-12);
}

// ---- state estimates ----

TEST_F(LocalPlannerNodeTest, RefusesBadStateEstimates) {
  const int64_t t = 3 * kSecond;
  world.publish("STATE_ESTIMATE", odometryAt(t, kStart));
  loop.drain();
  ASSERT_TRUE(planner.latestState());
  EXPECT_EQ(planner.latestState()->utime, t);
  EXPECT_EQ(planner.badMessageCount(), 0);

  const auto expectRefused = [&](const odometry_t& msg, const std::string& what) {
    const int64_t bad_before = planner.badMessageCount();
    world.publish("STATE_ESTIMATE", msg);
    loop.drain();
    EXPECT_EQ(planner.badMessageCount(), bad_before + 1) << what;
    ASSERT_TRUE(planner.latestState()) << what;
    EXPECT_EQ(planner.latestState()->utime, t) << what;
    EXPECT_EQ(planner.latestState()->position, kStart) << what;
  };
  odometry_t nan_position = odometryAt(t + kSecond, kStart);
  nan_position.position[0] = std::nan("");
  expectRefused(nan_position, "NaN position");
  odometry_t nan_velocity = odometryAt(t + kSecond, kStart);
  nan_velocity.linear_velocity[2] = INFINITY;
  expectRefused(nan_velocity, "infinite velocity");
  odometry_t zero_orientation = odometryAt(t + kSecond, kStart);
  zero_orientation.orientation[0] = 0;
  expectRefused(zero_orientation, "not a unit quaternion");
  expectRefused(odometryAt(t - kSecond, Eigen::Vector3d(1, 1, 1)), "backwards in time");
  expectRefused(odometryAt(t, Eigen::Vector3d(1, 1, 1)), "the same time again");
  odometry_t lost = odometryAt(t + kSecond, Eigen::Vector3d(1, 1, 1));
  lost.quality = odometry_t::QUALITY_LOST;
  lost.reason = "no features";
  expectRefused(lost, "estimator lost");

  // A good one is taken.
  world.publish("STATE_ESTIMATE", odometryAt(t + kSecond, Eigen::Vector3d(1, 1, 1)));
  loop.drain();
  EXPECT_EQ(planner.latestState()->utime, t + kSecond);
  EXPECT_EQ(planner.latestState()->position, Eigen::Vector3d(1, 1, 1));
}

// One estimate stamped 11 days ahead made every later one "not after the previous" for the rest
// of the mission. Now ten consecutive earlier estimates start a new timeline.
TEST_F(LocalPlannerNodeTest, AFarFutureEstimateCostsAtMostTenEstimates) {
  const int64_t t = 3 * kSecond;
  world.publish("STATE_ESTIMATE", odometryAt(t, kStart));
  world.publish("STATE_ESTIMATE", odometryAt(1'000'000 * kSecond, kStart));
  loop.drain();
  ASSERT_EQ(planner.latestState()->utime, 1'000'000 * kSecond);
  const int64_t bad_before = planner.badMessageCount();
  for (int k = 1; k <= 10; ++k) {
    world.publish("STATE_ESTIMATE", odometryAt(t + k * kSecond / 10, Eigen::Vector3d(1, 1, k)));
    loop.drain();
  }
  EXPECT_EQ(planner.badMessageCount(), bad_before + 9);
  EXPECT_EQ(planner.latestState()->utime, t + kSecond);
  EXPECT_EQ(planner.latestState()->position, Eigen::Vector3d(1, 1, 10));
  world.publish("STATE_ESTIMATE", odometryAt(t + 2 * kSecond, Eigen::Vector3d(2, 2, 2)));
  loop.drain();
  EXPECT_EQ(planner.latestState()->utime, t + 2 * kSecond);
  EXPECT_EQ(planner.badMessageCount(), bad_before + 9);
}

// ---- the explorer ----

TEST_F(LocalPlannerNodeTest, IgnoresExplorerGoalsForCyclesThatAreNotWaiting) {
  goal_t answer = goalMsg(21, {Eigen::Vector3d(1, 2, 1.5)}, goal_t::SOURCE_EXPLORER);
  answer.cycle = 5;
  answer.strategy = "local_exploration";
  world.publish("EXPLORER_GOAL", answer);
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 1u);
  const planner_status_t& status = recorder.statuses[0];
  EXPECT_EQ(status.state, +planner_status_t::STATE_REJECTED_GOAL);
  EXPECT_FALSE(status.is_final);  // it closes no cycle
  EXPECT_EQ(status.goal_id, 21);
  EXPECT_TRUE(contains(status.reason, "ignored")) << status.reason;
  EXPECT_TRUE(recorder.trajectories.empty());
  EXPECT_FALSE(planner.planner().intermediateGoal());
}

TEST_F(LocalPlannerNodeExplorerTest, AStuckCycleWaitsForTheExplorersAnswer) {
  const int64_t t = 5 * kSecond;
  // Just in front of a wall across the way to the goal.
  const Eigen::Vector3d start(1.75, 0, 1.5);
  world.publish("MISSION_GOAL", goalMsg(31, {Eigen::Vector3d(6, 0, 1.5)}));
  world.publish("STATE_ESTIMATE", odometryAt(t, start));
  publishAll(snapshot(wallEsdf(), t, 1));
  loop.drain();
  ASSERT_EQ(planner.planner().cycles(), 1);
  ASSERT_EQ(recorder.statuses.size(), 1u);
  const planner_status_t stuck = recorder.statuses[0];
  ASSERT_EQ(stuck.state, +planner_status_t::STATE_STUCK) << stuck.reason;
  EXPECT_FALSE(stuck.is_final);  // open until the explorer answers
  EXPECT_FALSE(stuck.reason.empty());
  ASSERT_TRUE(planner.planner().waitingCycle());
  EXPECT_EQ(*planner.planner().waitingCycle(), stuck.cycle);
  // A stuck cycle commits no plan; with nothing committed before, the vehicle hovers.
  ASSERT_EQ(recorder.trajectories.size(), 1u);
  EXPECT_EQ(recorder.trajectories[0].num_segments, 1);

  // An answer for another cycle is ignored and the cycle keeps waiting.
  goal_t wrong = goalMsg(40, {start + Eigen::Vector3d(0, 2.5, 0)}, goal_t::SOURCE_EXPLORER);
  wrong.cycle = stuck.cycle + 1;
  world.publish("EXPLORER_GOAL", wrong);
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 2u);
  EXPECT_EQ(recorder.statuses[1].state, +planner_status_t::STATE_REJECTED_GOAL);
  EXPECT_TRUE(planner.planner().waitingCycle());

  // The answer for the stuck cycle: an intermediate goal beside the start, planned at once; the
  // trajectory, then the final status of the same cycle.
  recorder.clear();
  goal_t answer = goalMsg(41, {start + Eigen::Vector3d(0, 2.5, 0)}, goal_t::SOURCE_EXPLORER);
  answer.cycle = stuck.cycle;
  answer.strategy = "local_exploration";
  world.publish("EXPLORER_GOAL", answer);
  loop.drain();
  ASSERT_EQ(recorder.order,
            (std::vector<std::string>{"PLANNER_TRAJECTORY", "PLANNER_STATUS", "MODULE_TIMING"}));
  const planner_status_t& planned = recorder.statuses[0];
  EXPECT_EQ(planned.state, +planner_status_t::STATE_PLANNED) << planned.reason;
  EXPECT_TRUE(planned.is_final);
  EXPECT_EQ(planned.cycle, stuck.cycle);
  EXPECT_EQ(planned.goal_id, 41);
  EXPECT_EQ(planned.goal_source, +goal_t::SOURCE_EXPLORER);
  EXPECT_EQ(recorder.trajectories[0].cycle, stuck.cycle);
  EXPECT_EQ(recorder.trajectories[0].utime, t);
  EXPECT_FALSE(planner.planner().waitingCycle());
  ASSERT_TRUE(planner.planner().intermediateGoal());
  EXPECT_EQ(planner.planner().intermediateGoal()->id, 41);
}

TEST_F(LocalPlannerNodeExplorerTest, AnUnansweredStuckCycleIsClosedAfterTheExplorerTimeout) {
  // Stuck in front of the wall, and no explorer answers (it died, or is being restarted).
  const int64_t t = 5 * kSecond;
  world.publish("MISSION_GOAL", goalMsg(31, {Eigen::Vector3d(6, 0, 1.5)}));
  world.publish("STATE_ESTIMATE", odometryAt(t, Eigen::Vector3d(1.75, 0, 1.5)));
  publishAll(snapshot(wallEsdf(), t, 1));
  loop.drain();
  ASSERT_TRUE(planner.planner().waitingCycle());
  const int64_t cycle = *planner.planner().waitingCycle();
  recorder.clear();
  // The timer's checks (wall clock in microseconds): first seen waiting at 100 s; still waiting
  // 4.9 s later; closed at 5 s, holding, with its final status.
  const int64_t seen = 100 * kSecond;
  EXPECT_FALSE(planner.expireExplorerWait(seen));
  EXPECT_FALSE(planner.expireExplorerWait(seen + 4'900'000));
  loop.drain();
  EXPECT_TRUE(recorder.statuses.empty());
  EXPECT_TRUE(planner.expireExplorerWait(seen + 5'000'000));
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 1u);
  const planner_status_t& closed = recorder.statuses[0];
  EXPECT_EQ(closed.cycle, cycle);
  EXPECT_TRUE(closed.is_final);
  EXPECT_EQ(closed.state, +planner_status_t::STATE_HOLDING);
  EXPECT_TRUE(contains(closed.reason, "no answer within 5.0 s")) << closed.reason;
  EXPECT_FALSE(planner.planner().waitingCycle());
  EXPECT_FALSE(planner.expireExplorerWait(seen + 9 * kSecond));  // nothing waits any more
  // A late answer closes nothing.
  goal_t late = goalMsg(41, {Eigen::Vector3d(1.75, 2.5, 1.5)}, goal_t::SOURCE_EXPLORER);
  late.cycle = cycle;
  world.publish("EXPLORER_GOAL", late);
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 2u);
  EXPECT_EQ(recorder.statuses[1].state, +planner_status_t::STATE_REJECTED_GOAL);
  EXPECT_FALSE(recorder.statuses[1].is_final);
}

TEST(LocalPlannerNode, WithoutAnExplorerTimeoutAStuckCycleWaits) {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  LocalPlannerNodeOptions options = nodeOptions(true);
  options.explorer_timeout = 0;
  LocalPlannerNode planner{lcm, options};
  Node world{"world", lcm};
  world.publish("MISSION_GOAL", goalMsg(31, {Eigen::Vector3d(6, 0, 1.5)}));
  world.publish("STATE_ESTIMATE", odometryAt(5 * kSecond, Eigen::Vector3d(1.75, 0, 1.5)));
  for (const map_update_t& part : snapshot(wallEsdf(), 5 * kSecond, 1)) {
    world.publish("MAP_ESDF", part);
  }
  loop.drain();
  ASSERT_TRUE(planner.planner().waitingCycle());
  EXPECT_FALSE(planner.expireExplorerWait(0));
  EXPECT_FALSE(planner.expireExplorerWait(3600 * kSecond));
  EXPECT_TRUE(planner.planner().waitingCycle());
}

// ---- the re-check ----

TEST_F(LocalPlannerNodeTest, ARevisionThatBlocksTheCommittedTrajectoryStops) {
  const int64_t t = 5 * kSecond;
  ASSERT_TRUE(planFromStart(goalMsg(61, {Eigen::Vector3d(10, 0, 1.5)}), t));
  const PolynomialTrajectory committed = *planner.planner().committed();

  // 1 s later, flying toward it (~0.3 m/s, a stop takes ~4 cm), the next revision shows a wall
  // across the way whose clearance margin begins 20 cm ahead: no plan makes progress toward the
  // goal, a stop does.
  const int64_t t1 = t + kSecond;
  const TrajectoryState reference = committed.stateAtUtime(t1);
  ASSERT_GT(reference.velocity.x(), 0.1);
  const LocoOptions& o = planner.planner().options().loco;
  const double required = o.robot_radius + o.clearance_margin;
  const double face = reference.position.x() + required + 0.2;
  recorder.clear();
  world.publish("STATE_ESTIMATE", odometryAt(t1, reference.position, reference.velocity));
  publishAll(snapshot(wallEsdf(face), t1, 2));
  loop.drain();
  ASSERT_EQ(recorder.order,
            (std::vector<std::string>{"PLANNER_TRAJECTORY", "PLANNER_STATUS", "MODULE_TIMING"}));
  const planner_status_t& status = recorder.statuses[0];
  EXPECT_EQ(status.state, +planner_status_t::STATE_STOPPING) << status.reason;
  EXPECT_TRUE(status.is_final);
  EXPECT_EQ(status.cycle, 2);
  EXPECT_EQ(status.map_revision, 2);
  EXPECT_TRUE(contains(status.reason, "the committed trajectory is blocked (sample at t="))
      << status.reason;
  EXPECT_TRUE(contains(status.reason, "stopping within")) << status.reason;
  EXPECT_TRUE(contains(status.reason, "in certified free space")) << status.reason;

  // The stop went out before the status: from the reference to rest, short of the margin.
  auto stop = PolynomialTrajectory::fromLcm(recorder.trajectories[0]);
  ASSERT_TRUE(stop) << stop.error();
  EXPECT_EQ(recorder.trajectories[0].cycle, 2);
  EXPECT_EQ(stop->startUtime(), t1);
  EXPECT_NEAR((stop->evaluate(0) - reference.position).norm(), 0, 1e-9);
  EXPECT_NEAR((stop->evaluate(0, 1) - reference.velocity).norm(), 0, 1e-9);
  EXPECT_LT(stop->evaluate(stop->duration() - 1e-12, 1).norm(), 1e-8);
  EXPECT_LE(stop->evaluate(stop->duration()).x(), face - required);
  EXPECT_TRUE(contains(planner.summary(), "1 stopping")) << planner.summary();
}

// ---- setpoints ----

TEST_F(LocalPlannerNodeTest, SetpointsFollowTheCommittedTrajectory) {
  EXPECT_FALSE(planner.publishSetpoint(kSecond));
  loop.drain();
  EXPECT_TRUE(recorder.setpoints.empty());

  const int64_t t = 5 * kSecond;
  ASSERT_TRUE(planNorthEast(t));
  const PolynomialTrajectory& committed = *planner.planner().committed();

  // Mid-flight, heading north-east.
  const int64_t at = t + 3 * kSecond / 2;
  ASSERT_TRUE(planner.publishSetpoint(at));
  loop.drain();
  ASSERT_EQ(recorder.setpoints.size(), 1u);
  // A copy: the recorder's next setpoint may move its vector.
  const setpoint_t sp = recorder.setpoints[0];
  const TrajectoryState s = committed.stateAtUtime(at);
  EXPECT_EQ(sp.utime, at);
  EXPECT_EQ(sp.cycle, 1);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(sp.position[i], s.position[i], 1e-12);
    EXPECT_NEAR(sp.velocity[i], s.velocity[i], 1e-12);
    EXPECT_NEAR(sp.acceleration[i], s.acceleration[i], 1e-12);
  }
  ASSERT_GT(s.velocity.head<2>().norm(), 0.1);
  EXPECT_NEAR(sp.yaw, std::atan2(s.velocity.y(), s.velocity.x()), 1e-12);
  EXPECT_NEAR(sp.yaw, M_PI / 4, 0.05);
  EXPECT_TRUE(std::isfinite(sp.yaw_rate));

  // After the end, at rest: the yaw is held, not atan2(0, 0) of a standing vehicle.
  ASSERT_TRUE(planner.publishSetpoint(t + 100 * kSecond));
  loop.drain();
  ASSERT_EQ(recorder.setpoints.size(), 2u);
  EXPECT_NEAR(recorder.setpoints[1].yaw, sp.yaw, 1e-12);
  const Eigen::Vector3d end = committed.evaluate(committed.duration());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(recorder.setpoints[1].position[i], end[i], 1e-12);
}

TEST_F(LocalPlannerNodeTest, AGoalWithYawsIsFlownFacingThem) {
  const int64_t t = 5 * kSecond;
  goal_t goal = goalMsg(52, {Eigen::Vector3d(10, 10, 1.5)});
  goal.yaw_policy = goal_t::YAW_FIXED;
  goal.yaws = {1.0};  // near the direction of flight (0.79 rad), so it is flown all the way
  ASSERT_TRUE(planFromStart(goal, t));
  ASSERT_EQ(recorder.trajectories.size(), 1u);
  EXPECT_EQ(recorder.trajectories[0].yaw_policy, +polynomial_trajectory_t::YAW_CONSTANT);
  EXPECT_EQ(recorder.trajectories[0].yaw, 1.0);
  // Its setpoints face the yaw, not the velocity (north-east), with no yaw rate.
  ASSERT_TRUE(planner.publishSetpoint(t + kSecond));
  loop.drain();
  ASSERT_EQ(recorder.setpoints.size(), 1u);
  EXPECT_EQ(recorder.setpoints[0].yaw, 1.0);
  EXPECT_EQ(recorder.setpoints[0].yaw_rate, 0.0);

  // A goal without yaws goes back to facing along the velocity.
  recorder.clear();
  ASSERT_TRUE(planNorthEast(t + kSecond, 2));
  ASSERT_EQ(recorder.trajectories.size(), 1u);
  EXPECT_EQ(recorder.trajectories[0].yaw_policy, +polynomial_trajectory_t::YAW_ALONG_VELOCITY);
}

TEST_F(LocalPlannerNodeTest, SetpointsNameTheCycleWhoseTrajectoryTheyFollow) {
  const int64_t t = 5 * kSecond;
  ASSERT_TRUE(planNorthEast(t));
  const PolynomialTrajectory committed = *planner.planner().committed();

  // A later cycle that commits nothing (the mission was cancelled): the vehicle still flies
  // cycle 1's trajectory, and its setpoints must say so (setpoint_t.cycle: "the planner cycle
  // whose trajectory it was sampled from").
  goal_t cancel = goalMsg(51, {});
  cancel.status = goal_t::STATUS_CANCEL;
  world.publish("MISSION_GOAL", cancel);
  world.publish("STATE_ESTIMATE",
                odometryAt(t + kSecond, committed.stateAtUtime(t + kSecond).position));
  loop.drain();
  recorder.clear();
  planner.replan();
  loop.drain();
  ASSERT_EQ(recorder.statuses.size(), 1u);
  EXPECT_EQ(recorder.statuses[0].state, +planner_status_t::STATE_HOLDING);
  EXPECT_EQ(recorder.statuses[0].cycle, 2);
  EXPECT_TRUE(recorder.trajectories.empty());

  const int64_t at = t + 3 * kSecond / 2;
  ASSERT_TRUE(planner.publishSetpoint(at));
  loop.drain();
  ASSERT_EQ(recorder.setpoints.size(), 1u);
  EXPECT_NEAR(recorder.setpoints[0].position[0], committed.stateAtUtime(at).position.x(), 1e-12);
  EXPECT_EQ(recorder.setpoints[0].cycle, 1);
}

}  // namespace
}  // namespace thicket::local_planner

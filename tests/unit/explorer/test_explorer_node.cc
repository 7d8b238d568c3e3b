// thicket-explorer's node in a memq:// composite: it answers exactly the stuck cycles that wait for
// it (not final), for the same cycle, then publishes its timing; it says when it has no map, no
// state or no candidate; its mirrors ask for a snapshot when a delta arrives first and refuse
// malformed map messages; answers are seeded by the cycle, so a replay answers the same.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <thicket/goal_t.hpp>
#include <thicket/map_request_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/module_timing_t.hpp>
#include <thicket/planner_status_t.hpp>

#include "explorer_node.h"
#include "hand_maps.h"
#include "thicket/common/esdf_query.h"
#include "thicket/common/loop.h"
#include "thicket/common/map_update.h"

namespace thicket::explorer {
namespace {

constexpr int64_t kMapId = 7;

// What the explorer publishes, and in which order.
class Recorder : public Node {
 public:
  explicit Recorder(lcm::LCM& lcm) : Node("recorder", lcm) {
    subscribe<goal_t>(
        "EXPLORER_GOAL",
        [this](const goal_t& m, const MessageInfo&) {
          goals.push_back(m);
          order.push_back("EXPLORER_GOAL");
        },
        1000);
    subscribe<module_timing_t>(
        "MODULE_TIMING",
        [this](const module_timing_t& m, const MessageInfo&) {
          timings.push_back(m);
          order.push_back("MODULE_TIMING");
        },
        1000);
    subscribe<map_request_t>(
        "MAP_REQUEST",
        [this](const map_request_t& m, const MessageInfo&) { requests.push_back(m); }, 1000);
  }
  std::vector<goal_t> goals;
  std::vector<module_timing_t> timings;
  std::vector<map_request_t> requests;
  std::vector<std::string> order;
};

planner_status_t stuckStatus(int64_t cycle, const Eigen::Vector3d& start = request(0).start,
                             bool is_final = false) {
  planner_status_t msg{};
  msg.utime = 1'000'000 * cycle;
  msg.cycle = cycle;
  msg.is_final = is_final;
  msg.state = planner_status_t::STATE_STUCK;
  msg.reason = "no feasible trajectory";
  msg.goal_id = 1;
  const Eigen::Vector3d goal = request(0).goal;
  for (int i = 0; i < 3; ++i) {
    msg.goal[i] = goal[i];
    msg.horizon_goal[i] = goal[i];
    msg.start_position[i] = start[i];
  }
  return msg;
}

template <class Voxel>
std::vector<map_update_t> snapshot(const Layer<Voxel>& layer, int64_t revision) {
  MapRevision r;
  r.utime = revision * 1'000'000;
  r.map_id = kMapId;
  r.revision = revision;
  r.full_snapshot = true;
  return encodeMapUpdate(layer, r, {}, {});
}

ExplorerNodeOptions nodeOptions(const std::string& strategy = "local_exploration") {
  ExplorerNodeOptions options;
  options.explorer = optionsFor(strategy);
  options.explorer.p_goal = 0;  // always explore, so every answer depends on the map
  options.explorer.fixed_yaw = true;
  return options;
}

// An explorer node on its own in-process LCM, with the planner and the mapper played by hand.
struct ExplorerGraph {
  explicit ExplorerGraph(const ExplorerNodeOptions& options) : explorer{lcm, options} {}
  void publishMap(const HandMap& map, int64_t revision = 1) {
    for (const map_update_t& part : snapshot(map.tsdf, revision)) world.publish("MAP_TSDF", part);
    for (const map_update_t& part : snapshot(map.esdf, revision)) world.publish("MAP_ESDF", part);
    loop.drain();
  }
  goal_t ask(const planner_status_t& status) {
    recorder.goals.clear();
    recorder.timings.clear();
    recorder.order.clear();
    world.publish("PLANNER_STATUS", status);
    loop.drain();
    EXPECT_EQ(recorder.goals.size(), 1u);
    return recorder.goals.empty() ? goal_t{} : recorder.goals[0];
  }

  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  ExplorerNode explorer;
  Recorder recorder{lcm};
  Node world{"world", lcm};  // planner and mapper stand-ins
};

class ExplorerNodeTest : public ::testing::Test, public ExplorerGraph {
 protected:
  ExplorerNodeTest() : ExplorerGraph(nodeOptions()) {}
};

TEST_F(ExplorerNodeTest, WithoutAMapItSaysSoForTheSameCycleAndTimesItself) {
  const goal_t answer = ask(stuckStatus(5));
  EXPECT_EQ(answer.status, +goal_t::STATUS_NO_MAP);
  EXPECT_EQ(answer.cycle, 5);
  EXPECT_EQ(answer.source, +goal_t::SOURCE_EXPLORER);
  EXPECT_EQ(answer.strategy, "local_exploration");
  EXPECT_EQ(answer.num_waypoints, 0);
  EXPECT_FALSE(answer.reason.empty());
  ASSERT_EQ(recorder.timings.size(), 1u);
  EXPECT_EQ(recorder.timings[0].module, "explorer");
  EXPECT_EQ(recorder.timings[0].sequence, 5);
  ASSERT_EQ(recorder.timings[0].stages, std::vector<std::string>{"goal_selection"});
  EXPECT_GE(recorder.timings[0].durations_ms[0], 0);
  EXPECT_EQ(recorder.order, (std::vector<std::string>{"EXPLORER_GOAL", "MODULE_TIMING"}));
}

TEST_F(ExplorerNodeTest, AnswersOnlyStuckCyclesThatWait) {
  planner_status_t planned = stuckStatus(1);
  planned.state = planner_status_t::STATE_PLANNED;
  world.publish("PLANNER_STATUS", planned);
  world.publish("PLANNER_STATUS", stuckStatus(2, request(0).start, /*is_final=*/true));
  planner_status_t holding = stuckStatus(3);
  holding.state = planner_status_t::STATE_HOLDING;
  world.publish("PLANNER_STATUS", holding);
  loop.drain();
  EXPECT_TRUE(recorder.goals.empty());
  EXPECT_TRUE(recorder.timings.empty());
  EXPECT_EQ(explorer.answers(), 0);
}

TEST_F(ExplorerNodeTest, ProposesAnObservedFreePointFacingUnknownSpace) {
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  publishMap(map);
  ASSERT_TRUE(explorer.tsdf().layer() != nullptr);
  ASSERT_TRUE(explorer.esdf().layer() != nullptr);
  const goal_t answer = ask(stuckStatus(9));
  ASSERT_EQ(answer.status, +goal_t::STATUS_OK) << answer.reason;
  EXPECT_EQ(answer.cycle, 9);
  ASSERT_EQ(answer.num_waypoints, 1);
  ASSERT_EQ(answer.waypoints.size(), 1u);
  ASSERT_EQ(answer.yaws.size(), 1u);
  EXPECT_EQ(answer.yaw_policy, +goal_t::YAW_FIXED);
  const Eigen::Vector3d x(answer.waypoints[0][0], answer.waypoints[0][1], answer.waypoints[0][2]);
  const EsdfSample sample = sampleEsdf(map.esdf, x);
  ASSERT_TRUE(sample.known);
  EXPECT_GE(sample.distance, nodeOptions().explorer.min_clearance);
  EXPECT_LE((x - request(0).start).norm(), nodeOptions().explorer.radius);
  // The same proposal as the strategy on the same maps: the node adds nothing of its own.
  const auto selector = makeGoalSelector(nodeOptions().explorer);
  ExplorationRequest r = request(9);
  r.utime = 9'000'000;
  const Proposal p = selector->select(r, map.view());
  ASSERT_TRUE(p.found);
  EXPECT_EQ(p.waypoints[0], x);
  EXPECT_EQ(p.yaws[0], answer.yaws[0]);
  EXPECT_EQ(recorder.order, (std::vector<std::string>{"EXPLORER_GOAL", "MODULE_TIMING"}));
}

TEST(ExplorerNode, WithoutFixedYawTheVehicleFacesAlongItsVelocity) {
  ExplorerNodeOptions options = nodeOptions();
  options.explorer.fixed_yaw = false;
  ExplorerGraph paper(options);
  paper.publishMap(observedBox({-4, -4, 0.4}, {4, 4, 2.6}));
  const goal_t answer = paper.ask(stuckStatus(9));
  ASSERT_EQ(answer.status, +goal_t::STATUS_OK) << answer.reason;
  EXPECT_EQ(answer.yaw_policy, +goal_t::YAW_ALONG_VELOCITY);
  ASSERT_EQ(answer.num_waypoints, 1);
  EXPECT_EQ(answer.yaws, std::vector<double>{0.0});
  // The same waypoint as with yaws: only the yaw policy differs.
  ExplorerGraph looking(nodeOptions());
  looking.publishMap(observedBox({-4, -4, 0.4}, {4, 4, 2.6}));
  const goal_t with_yaw = looking.ask(stuckStatus(9));
  EXPECT_EQ(with_yaw.waypoints, answer.waypoints);
  EXPECT_EQ(with_yaw.yaw_policy, +goal_t::YAW_FIXED);
}

TEST_F(ExplorerNodeTest, TheSameCycleGetsTheSameAnswerAndOthersDiffer) {
  publishMap(observedBox({-4, -4, 0.4}, {4, 4, 2.6}));
  const goal_t first = ask(stuckStatus(11));
  const goal_t again = ask(stuckStatus(11));
  const goal_t other = ask(stuckStatus(12));
  ASSERT_EQ(first.status, +goal_t::STATUS_OK);
  EXPECT_EQ(first.waypoints, again.waypoints);
  EXPECT_EQ(first.yaws, again.yaws);
  EXPECT_NE(first.goal_id, again.goal_id);  // a new goal each answer
  EXPECT_NE(first.waypoints, other.waypoints);
}

TEST_F(ExplorerNodeTest, SaysWhenThereIsNoCandidateOrNoState) {
  // Observed space only far from the start.
  publishMap(observedBox({30, 30, 0.4}, {34, 34, 2.6}));
  goal_t answer = ask(stuckStatus(3));
  EXPECT_EQ(answer.status, +goal_t::STATUS_NO_CANDIDATE);
  EXPECT_FALSE(answer.reason.empty());
  answer = ask(stuckStatus(4, Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 1)));
  EXPECT_EQ(answer.status, +goal_t::STATUS_NO_STATE);
  EXPECT_EQ(answer.num_waypoints, 0);
  EXPECT_FALSE(answer.reason.empty());
}

TEST_F(ExplorerNodeTest, MirrorsAskForASnapshotAndRefuseMalformedMaps) {
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  // A delta before any snapshot: the mirror cannot apply it and asks.
  MapRevision delta;
  delta.utime = 2'000'000;
  delta.map_id = kMapId;
  delta.revision = 2;
  BlockIndex some_block = map.esdf.blockIndices().front();
  for (const map_update_t& part : encodeMapUpdate(map.esdf, delta, {some_block}, {})) {
    world.publish("MAP_ESDF", part);
  }
  loop.drain();
  ASSERT_FALSE(recorder.requests.empty());
  EXPECT_EQ(recorder.requests.back().layer, +map_update_t::LAYER_ESDF);
  EXPECT_EQ(explorer.esdf().layer(), nullptr);
  // Malformed snapshots: refused and counted, and nothing is applied.
  std::vector<map_update_t> parts = snapshot(map.tsdf, 1);
  parts[0].voxel_size = std::numeric_limits<double>::quiet_NaN();
  world.publish("MAP_TSDF", parts[0]);
  world.publish("MAP_TSDF", snapshot(map.esdf, 1)[0]);  // an ESDF on the TSDF channel
  loop.drain();
  EXPECT_EQ(explorer.badMessageCounts().at("MAP_TSDF"), 2);
  EXPECT_EQ(explorer.tsdf().layer(), nullptr);
  // The explorer still answers, and says it has no map.
  EXPECT_EQ(ask(stuckStatus(1)).status, +goal_t::STATUS_NO_MAP);
}

}  // namespace
}  // namespace thicket::explorer

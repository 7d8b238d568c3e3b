// The RRT* baselines on hand-built maps: what each must (and must not) propose, and that the same
// request gives the same proposal in any order and any thread.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "hand_maps.h"
#include "thicket/common/esdf_query.h"
#include "thicket/explorer/goal_selector.h"

namespace thicket::explorer {
namespace {

constexpr const char* kOptimistic = "rrt_star_optimistic";
constexpr const char* kConservative = "rrt_star_conservative";

/// Signed distance to the axis-aligned box [lo, hi], negative inside.
double boxDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d q = (p - 0.5 * (lo + hi)).cwiseAbs() - 0.5 * (hi - lo);
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

// Observed [-4, 6] x [-5, 5] x [0.4, 2.6]; a wall 0.8 m thick at x = 2 across y < 3, full height:
// the only way past it in observed space is the 2 m gap 3 < y < 5, beyond the start's horizon.
const Eigen::Vector3d kWallLo(-4, -5, 0.4), kWallHi(6, 5, 2.6);
HandMap wallWithGap() {
  return observedBox(kWallLo, kWallHi, [](const Eigen::Vector3d& p) {
    return boxDistance(p, {1.6, -6, -1}, {2.4, 3, 4});
  });
}

// A dead end: observed [-6, 4] x [-3, 3] x [0.4, 2.6] with walls ahead (x = 2 .. 2.6) and on both
// sides (|y| = 2 .. 2.6), open behind the start (toward -x, where observed space ends). Unknown
// space above the box leads over the walls to the goal. Unlike observedBox, the ESDF holds the
// distance to the obstacles only, not to the box's boundary: nothing but the unknown-space policy
// keeps a tree from leaving the box through its top.
const Eigen::Vector3d kPocketLo(-6, -3, 0.4), kPocketHi(4, 3, 2.6);
HandMap deadEndPocket() {
  const ObstacleDistance walls = [](const Eigen::Vector3d& p) {
    return std::min({boxDistance(p, {2, -4, -1}, {2.6, 4, 4}),
                     boxDistance(p, {-7, 2, -1}, {2.6, 2.6, 4}),
                     boxDistance(p, {-7, -2.6, -1}, {2.6, -2, 4})});
  };
  HandMap map = observedBox(kPocketLo, kPocketHi, walls);
  const VoxelIndex a = map.esdf.voxelIndex(kPocketLo), b = map.esdf.voxelIndex(kPocketHi);
  for (int x = a.x(); x <= b.x(); ++x) {
    for (int y = a.y(); y <= b.y(); ++y) {
      for (int z = a.z(); z <= b.z(); ++z) {
        map.esdf.voxel({x, y, z})->distance =
            static_cast<float>(walls(map.esdf.voxelCenter({x, y, z})));
      }
    }
  }
  return map;
}

bool inside(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
}

/// The points of the polyline start, waypoints... at most `step` apart.
std::vector<Eigen::Vector3d> densePath(const Eigen::Vector3d& start,
                                       const std::vector<Eigen::Vector3d>& waypoints,
                                       double step = 0.05) {
  std::vector<Eigen::Vector3d> points = {start};
  Eigen::Vector3d a = start;
  for (const Eigen::Vector3d& b : waypoints) {
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step)));
    for (int i = 1; i <= n; ++i) points.push_back(a + (b - a) * (static_cast<double>(i) / n));
    a = b;
  }
  return points;
}

/// Every point of the path known in the ESDF with at least `clearance`.
void expectEsdfClear(const EsdfLayer& esdf, const Eigen::Vector3d& start,
                     const std::vector<Eigen::Vector3d>& waypoints, double clearance) {
  for (const Eigen::Vector3d& p : densePath(start, waypoints)) {
    const EsdfSample s = sampleEsdf(esdf, p);
    ASSERT_TRUE(s.known) << "unknown at " << p.transpose();
    ASSERT_GE(s.distance, clearance - 1e-9) << "too close at " << p.transpose();
  }
}

/// No point of the path in a known TSDF voxel closer than `clearance` to a surface.
void expectTsdfClearOrUnknown(const TsdfLayer& tsdf, const Eigen::Vector3d& start,
                              const std::vector<Eigen::Vector3d>& waypoints, double clearance,
                              double min_weight) {
  for (const Eigen::Vector3d& p : densePath(start, waypoints)) {
    const TsdfVoxel* v = tsdf.voxel(tsdf.voxelIndex(p));
    if (v == nullptr || v->weight < min_weight) continue;
    ASSERT_GE(v->distance, clearance) << "too close at " << p.transpose();
  }
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// Conservative: the tree stays in observed space with the clearance and finds the gap the start
// cannot see; the branch ends past the wall, closer to the goal than the start.
TEST(RrtStar, ConservativeFindsTheGapInTheWall) {
  const ExplorerOptions o = optionsFor(kConservative);
  const HandMap map = wallWithGap();
  const auto selector = makeGoalSelector(o);
  EXPECT_STREQ(selector->name(), kConservative);
  const ExplorationRequest r = request(1);
  const Proposal p = selector->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  ASSERT_FALSE(p.waypoints.empty());
  EXPECT_TRUE(p.yaws.empty());
  EXPECT_FALSE(p.map_missing);
  EXPECT_TRUE(contains(p.reason, "closest")) << p.reason;
  expectEsdfClear(map.esdf, r.start, p.waypoints, o.min_clearance);
  const Eigen::Vector3d end = p.waypoints.back();
  EXPECT_GT(end.x(), 2.5) << p.reason;
  EXPECT_LT((end - r.goal).norm(), (r.start - r.goal).norm());
  // The score is the branch's length.
  double length = 0;
  Eigen::Vector3d a = r.start;
  for (const Eigen::Vector3d& b : p.waypoints) length += (b - a).norm(), a = b;
  EXPECT_NEAR(p.score, length, 1e-9);
}

// Optimistic: unknown space is free, so the path reaches the goal 20 m away through it, keeping the
// clearance wherever the TSDF knows the distance.
TEST(RrtStar, OptimisticReachesTheGoalThroughUnknownSpace) {
  const ExplorerOptions o = optionsFor(kOptimistic);
  const HandMap map = wallWithGap();
  const auto selector = makeGoalSelector(o);
  EXPECT_STREQ(selector->name(), kOptimistic);
  const ExplorationRequest r = request(1);
  const Proposal p = selector->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_TRUE(p.yaws.empty());
  EXPECT_TRUE(contains(p.reason, "path to the goal")) << p.reason;
  EXPECT_LE((p.waypoints.back() - r.goal).norm(), o.rrt_star.goal_tolerance);
  expectTsdfClearOrUnknown(map.tsdf, r.start, p.waypoints, o.min_clearance, o.gain.min_weight);
  EXPECT_TRUE(std::any_of(p.waypoints.begin(), p.waypoints.end(),
                          [](const Eigen::Vector3d& w) { return !inside(w, kWallLo, kWallHi); }));
  // No edge longer than the range.
  Eigen::Vector3d a = r.start;
  for (const Eigen::Vector3d& b : p.waypoints) {
    EXPECT_LE((b - a).norm(), o.rrt_star.range + 1e-9);
    a = b;
  }
  // Nearly straight: RRT* shortens the path it found (the wall is passed above or beside it).
  EXPECT_LT(p.score, 1.5 * (r.goal - r.start).norm()) << p.reason;
}

// A dead end ahead: the conservative tree never leaves observed free space, so its best branch ends
// at the pocket's front wall; the optimistic one, reading the same map, leaves over the walls.
TEST(RrtStar, ConservativeStaysInADeadEndPocket) {
  const HandMap map = deadEndPocket();
  const ExplorationRequest r = request(2);
  const ExplorerOptions o = optionsFor(kConservative);
  const Proposal p = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_TRUE(contains(p.reason, "closest")) << p.reason;
  expectEsdfClear(map.esdf, r.start, p.waypoints, o.min_clearance);
  for (const Eigen::Vector3d& w : p.waypoints) {
    EXPECT_LT(w.x(), 2.0 - o.min_clearance + 0.05) << w.transpose();
    EXPECT_LT(std::abs(w.y()), 2.0 - o.min_clearance + 0.05) << w.transpose();
  }
  // The closest node it could reach: against the front wall, still 18 m from the goal.
  EXPECT_GT(p.waypoints.back().x(), 1.0) << p.reason;
  EXPECT_GT((p.waypoints.back() - r.goal).norm(), 18.0);

  const Proposal optimistic = makeGoalSelector(optionsFor(kOptimistic))->select(r, map.view());
  ASSERT_TRUE(optimistic.found) << optimistic.reason;
  EXPECT_LE((optimistic.waypoints.back() - r.goal).norm(), o.rrt_star.goal_tolerance);
}

std::vector<Eigen::Vector3d> waypoints(const std::string& strategy, const HandMap& map,
                                       int64_t cycle) {
  return makeGoalSelector(optionsFor(strategy))->select(request(cycle), map.view()).waypoints;
}

// Seeded from the configuration and the cycle only: the same request gives bit-identical waypoints
// from the same selector, a fresh one, after other cycles, and from threads running concurrently.
TEST(RrtStar, SameRequestSameProposalInAnyOrderAndThread) {
  const HandMap map = wallWithGap();
  for (const char* strategy : {kOptimistic, kConservative}) {
    SCOPED_TRACE(strategy);
    const auto selector = makeGoalSelector(optionsFor(strategy));
    const Proposal first = selector->select(request(5), map.view());
    ASSERT_TRUE(first.found) << first.reason;
    const Proposal again = selector->select(request(5), map.view());
    EXPECT_EQ(again.waypoints, first.waypoints);
    EXPECT_EQ(again.score, first.score);
    EXPECT_EQ(again.reason, first.reason);
    selector->select(request(6), map.view());
    selector->select(request(9), map.view());
    EXPECT_EQ(selector->select(request(5), map.view()).waypoints, first.waypoints);
    EXPECT_EQ(waypoints(strategy, map, 5), first.waypoints);

    std::vector<Eigen::Vector3d> a, b, c;
    std::thread ta([&] { a = waypoints(strategy, map, 5); });
    std::thread tb([&] { b = waypoints(strategy, map, 5); });
    std::thread tc([&] { c = waypoints(strategy, map, 6); });  // another request meanwhile
    ta.join();
    tb.join();
    tc.join();
    EXPECT_EQ(a, first.waypoints);
    EXPECT_EQ(b, first.waypoints);
    EXPECT_EQ(c, waypoints(strategy, map, 6));

    // Another cycle, another tree.
    EXPECT_NE(waypoints(strategy, map, 6), first.waypoints);
    EXPECT_NE(waypoints(strategy, map, 7), first.waypoints);
    // Another seed, another tree.
    ExplorerOptions o = optionsFor(strategy);
    o.seed = 4;
    EXPECT_NE(makeGoalSelector(o)->select(request(5), map.view()).waypoints, first.waypoints);
  }
}

TEST(RrtStar, SaysWhenThereIsNoMap) {
  const HandMap map = wallWithGap();
  for (const char* strategy : {kOptimistic, kConservative}) {
    const auto selector = makeGoalSelector(optionsFor(strategy));
    const Proposal p = selector->select(request(1), {});
    EXPECT_FALSE(p.found);
    EXPECT_TRUE(p.map_missing);
    EXPECT_EQ(p.reason, "no map");
  }
  // Each reads only its own layer.
  Proposal p = makeGoalSelector(optionsFor(kOptimistic))->select(request(1), {nullptr, &map.esdf});
  EXPECT_TRUE(p.map_missing);
  p = makeGoalSelector(optionsFor(kConservative))->select(request(1), {&map.tsdf, nullptr});
  EXPECT_TRUE(p.map_missing);
  p = makeGoalSelector(optionsFor(kOptimistic))->select(request(1), {&map.tsdf, nullptr});
  EXPECT_FALSE(p.map_missing);
  EXPECT_TRUE(p.found) << p.reason;
}

// A start inside an obstacle, or closer to it than half the clearance, grows no tree; neither does
// a conservative start in unknown space. The optimistic one flies from unknown space.
TEST(RrtStar, RefusesStartsItCannotLeave) {
  const HandMap map = wallWithGap();
  ExplorationRequest in_wall = request(1);
  in_wall.start = Eigen::Vector3d(2, 0, 1.5);
  ExplorationRequest too_close = request(1);
  too_close.start = Eigen::Vector3d(1.45, 0, 1.5);  // 0.15 m from the wall: below half of 0.6
  for (const char* strategy : {kOptimistic, kConservative}) {
    SCOPED_TRACE(strategy);
    const auto selector = makeGoalSelector(optionsFor(strategy));
    for (const ExplorationRequest& r : {in_wall, too_close}) {
      const Proposal p = selector->select(r, map.view());
      EXPECT_FALSE(p.found);
      EXPECT_FALSE(p.map_missing);
      EXPECT_TRUE(contains(p.reason, "start")) << p.reason;
    }
  }
  ExplorationRequest unknown = request(1);
  unknown.start = Eigen::Vector3d(-10, 0, 1.5);
  Proposal p = makeGoalSelector(optionsFor(kConservative))->select(unknown, map.view());
  EXPECT_FALSE(p.found);
  EXPECT_TRUE(contains(p.reason, "unknown")) << p.reason;
  p = makeGoalSelector(optionsFor(kOptimistic))->select(unknown, map.view());
  EXPECT_TRUE(p.found) << p.reason;
  // Outside the flight volume.
  ExplorationRequest low = request(1);
  low.start.z() = 0.2;
  p = makeGoalSelector(optionsFor(kOptimistic))->select(low, map.view());
  EXPECT_FALSE(p.found);
  EXPECT_TRUE(contains(p.reason, "flight volume")) << p.reason;
}

// A start 0.45 m from an obstacle (below min_clearance, above half of it) still leaves: the tree
// keeps the start's own clearance, and no less.
TEST(RrtStar, RelaxesTheClearanceForAStartNearAnObstacle) {
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6}, [](const Eigen::Vector3d& p) {
    return boxDistance(p, {0.45, -0.5, -1}, {1.45, 0.5, 4});
  });
  const ExplorationRequest r = request(3);
  const EsdfSample at_start = sampleEsdf(map.esdf, r.start);
  ASSERT_TRUE(at_start.known);
  ASSERT_LT(at_start.distance, 0.6);
  ASSERT_GT(at_start.distance, 0.3);
  for (const char* strategy : {kOptimistic, kConservative}) {
    SCOPED_TRACE(strategy);
    const ExplorerOptions o = optionsFor(strategy);
    const Proposal p = makeGoalSelector(o)->select(r, map.view());
    ASSERT_TRUE(p.found) << p.reason;
    if (std::string(strategy) == kConservative) {
      expectEsdfClear(map.esdf, r.start, p.waypoints, at_start.distance);
    } else {
      const TsdfVoxel* v = map.tsdf.voxel(map.tsdf.voxelIndex(r.start));
      expectTsdfClearOrUnknown(map.tsdf, r.start, p.waypoints, v->distance, o.gain.min_weight);
    }
  }
}

// A goal above the flight volume is clamped into it, and the reason says so.
TEST(RrtStar, ClampsTheGoalIntoTheFlightVolume) {
  ExplorerOptions o = optionsFor(kOptimistic);
  o.flight_volume_max.z() = 3;
  const HandMap map = wallWithGap();
  ExplorationRequest r = request(1);
  r.goal = Eigen::Vector3d(20, 0, 10);
  const Proposal p = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_TRUE(contains(p.reason, "clamped")) << p.reason;
  EXPECT_LE((p.waypoints.back() - Eigen::Vector3d(20, 0, 3)).norm(), o.rrt_star.goal_tolerance);
  for (const Eigen::Vector3d& w : p.waypoints) EXPECT_LE(w.z(), 3.0);
}

// OMPL's delayCC off (the default) and on grow the same trees: every request on both maps, each
// strategy and several cycles, gets the same proposal (waypoints, score, iterations and nodes).
TEST(RrtStar, DelayedCollisionChecksGiveTheSameProposals) {
  int found = 0;
  for (const HandMap& map : {wallWithGap(), deadEndPocket()}) {
    for (const char* strategy : {kOptimistic, kConservative}) {
      ExplorerOptions o = optionsFor(strategy);
      const auto eager = makeGoalSelector(o);
      o.rrt_star.delay_collision_checks = true;
      const auto delayed = makeGoalSelector(o);
      for (int cycle = 0; cycle < 6; ++cycle) {
        SCOPED_TRACE(std::string(strategy) + " cycle " + std::to_string(cycle));
        const Proposal a = eager->select(request(cycle), map.view());
        const Proposal b = delayed->select(request(cycle), map.view());
        EXPECT_EQ(a.found, b.found);
        EXPECT_EQ(a.waypoints, b.waypoints);
        EXPECT_EQ(a.score, b.score);
        EXPECT_EQ(a.reason, b.reason);
        found += a.found;
      }
    }
  }
  EXPECT_GE(found, 20);  // trees that went somewhere, not 24 refusals
}

// The budget is exactly rrt_star.iterations RRT* iterations, whatever happens in them.
TEST(RrtStar, RunsExactlyTheIterationBudget) {
  const HandMap map = wallWithGap();
  for (int iterations : {40, 1500}) {
    ExplorerOptions o = optionsFor(kConservative);
    o.rrt_star.iterations = iterations;
    const Proposal p = makeGoalSelector(o)->select(request(1), map.view());
    EXPECT_TRUE(contains(p.reason, "RRT* " + std::to_string(iterations) + " iterations"))
        << p.reason;
  }
}

// OMPL's console stays silent in normal use, in success and in refusal.
TEST(RrtStar, PrintsNothing) {
  const HandMap map = wallWithGap();
  ExplorationRequest in_wall = request(1);
  in_wall.start = Eigen::Vector3d(2, 0, 1.5);
  for (const char* strategy : {kOptimistic, kConservative}) {
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    const auto selector = makeGoalSelector(optionsFor(strategy));
    const Proposal found = selector->select(request(1), map.view());
    const Proposal refused = selector->select(in_wall, map.view());
    const std::string out = testing::internal::GetCapturedStdout();
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(found.found) << found.reason;
    EXPECT_FALSE(refused.found);
    EXPECT_EQ(out, "");
    EXPECT_EQ(err, "");
  }
}

}  // namespace
}  // namespace thicket::explorer

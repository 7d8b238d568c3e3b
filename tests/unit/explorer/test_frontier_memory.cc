// frontier_memory on hand-built maps: a verified path to a reachable goal (around a wall, over a
// low one only with altitude layers, around the edge of a tree's margin rather than along the chord
// that cuts it), toward a goal in unknown space, a climb to look toward it, or else a frontier
// viewpoint facing its cluster (never the goal itself), the tabu on targets asked for again from
// the same place, the way home, determinism, and what it says without a map.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hand_maps.h"
#include "thicket/common/esdf_query.h"

namespace thicket::explorer {
namespace {

ExplorerOptions frontierOptions() {
  ExplorerOptions o = optionsFor("frontier_memory");
  o.fixed_yaw = true;
  return o;
}

// Every segment of the proposal, from the start, keeps `clearance` in the ESDF (every 2 cm).
void expectFreePath(const Proposal& p, const Eigen::Vector3d& start, const EsdfLayer& esdf,
                    double clearance) {
  Eigen::Vector3d from = start;
  for (const Eigen::Vector3d& to : p.waypoints) {
    const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / 0.02)));
    for (int k = 0; k <= n; ++k) {
      const EsdfSample s = sampleEsdf(esdf, from + (to - from) * (static_cast<double>(k) / n));
      ASSERT_TRUE(s.known);
      // Cells are checked at their voxel's centre: between them the path may dip by a voxel.
      EXPECT_GE(s.distance, clearance - kVoxel);
    }
    from = to;
  }
}

// A wall x in [1.6, 2.4] for y < 1.5, everywhere in z: the way to x > 2.4 goes around its end.
double wallWithAnEnd(const Eigen::Vector3d& p) {
  const double dx = std::max({1.6 - p.x(), p.x() - 2.4, 0.0});
  const double dy = std::max(p.y() - 1.5, 0.0);
  return dx == 0 && dy == 0 ? -0.1 : std::hypot(dx, dy);
}

TEST(FrontierMemory, AReachableGoalIsProposedAlongAVerifiedPath) {
  const HandMap map = observedBox({-4, -4, 0.4}, {8, 4.5, 2.6}, wallWithAnEnd);
  const ExplorerOptions o = frontierOptions();
  const auto selector = makeGoalSelector(o);
  ExplorationRequest r = request(1);
  r.goal = Eigen::Vector3d(5, 0, 1.5);
  const Proposal p = selector->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_EQ(p.waypoints.back(), r.goal);
  EXPECT_EQ(p.yaws.size(), p.waypoints.size());
  EXPECT_GE(p.waypoints.size(), 2u);  // not straight through the wall
  expectFreePath(p, r.start, map.esdf, o.min_clearance);
  EXPECT_NE(p.reason.find("path to the goal"), std::string::npos) << p.reason;
}

// A tree (a cylinder of radius 0.2 on the axis x = 0, y = 0.83) with the start at the edge of
// its margin, 0.63 m from its surface.
double treeBesideTheStart(const Eigen::Vector3d& p) {
  return std::hypot(p.x(), p.y() - 0.83) - 0.2;
}

TEST(FrontierMemory, AGoalAcrossTheEdgeOfATreesMarginIsReachedAroundItNotAlongTheChord) {
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6}, treeBesideTheStart);
  const ExplorerOptions o = frontierOptions();
  ExplorationRequest r = request(1);
  // The goal 0.5 m away, also 0.63 m from the tree: the chord to it passes 0.59 m from the tree.
  const double a = -M_PI / 2 + 0.61;
  r.goal = Eigen::Vector3d(0.83 * std::cos(a), 0.83 + 0.83 * std::sin(a), 1.5);
  const Proposal p = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_EQ(p.waypoints.back(), r.goal);
  ASSERT_GE(p.waypoints.size(), 2u) << "bent around the tree";
  // Against the analytic tree, every 2 cm (the ESDF's interpolant overestimates a convex
  // distance by less than 1 cm between 0.2 m voxels).
  Eigen::Vector3d from = r.start;
  double least = 1e9;
  for (const Eigen::Vector3d& to : p.waypoints) {
    for (int k = 0; k <= 50; ++k)
      least = std::min(least, treeBesideTheStart(from + (to - from) * k / 50.0));
    from = to;
  }
  EXPECT_GE(least, o.min_clearance - 0.01);
  // And in the ESDF the planner reads: not the voxel of dip expectFreePath allows between cells.
  expectFreePath(p, r.start, map.esdf, o.min_clearance + kVoxel);
}

// A thick wall x in [1.6, 3.2] with a slit |y| < 0.75 straight ahead (0.65 m of clearance in
// the ESDF at its middle: passable, barely) and an opening 1.9 < y < 4.3 to the side.
double slitAndOpening(const Eigen::Vector3d& p) {
  const double dx = std::max({1.6 - p.x(), p.x() - 3.2, 0.0});
  const double y = p.y();
  const double dy = y < -0.75  ? 0.0
                    : y < 0.0  ? -0.75 - y
                    : y < 0.75 ? y - 0.75
                    : y < 1.9  ? 0.0
                    : y < 3.1  ? 1.9 - y
                    : y < 4.3  ? y - 4.3
                               : 0.0;
  // Inside the wall (dx = 0 and in a solid span): negative; beside it, the distance to its face.
  if (dy == 0) return dx == 0 ? -0.1 : dx;
  return dx == 0 ? -dy : std::hypot(dx, -dy);
}

TEST(FrontierMemory, PathsTakeAWideGapWhenItsDetourCostsLessThanTheNarrowOnesDiscomfort) {
  const HandMap map = observedBox({-4, -4, 0.4}, {9, 6, 2.6}, slitAndOpening);
  ExplorationRequest r = request(1);
  r.goal = Eigen::Vector3d(6, 0, 1.5);
  const auto widest = [](const Proposal& p) {
    double y = 0;
    for (const Eigen::Vector3d& w : p.waypoints) y = std::max(y, w.y());
    return y;
  };
  ExplorerOptions o = frontierOptions();
  // The opening is a detour of about 2.6 m; the slit's 1.6 m cost up to 1 + w_comfort times their
  // length: at w_comfort 2 the opening is the cheaper, at the default (1) the slit.
  o.frontier_memory.w_comfort = 2.0;
  const Proposal comfortable = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(comfortable.found) << comfortable.reason;
  EXPECT_EQ(comfortable.waypoints.back(), r.goal);
  EXPECT_GT(widest(comfortable), 1.9) << "through the opening";
  expectFreePath(comfortable, r.start, map.esdf, o.min_clearance);

  o.frontier_memory.w_comfort = ExplorerOptions{}.frontier_memory.w_comfort;
  const Proposal by_default = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(by_default.found) << by_default.reason;
  EXPECT_LT(widest(by_default), 0.5) << "through the slit";
  expectFreePath(by_default, r.start, map.esdf, o.min_clearance);

  o.frontier_memory.comfort = 0;  // shortest: through the slit
  const Proposal shortest = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(shortest.found) << shortest.reason;
  EXPECT_LT(widest(shortest), 0.5) << "through the slit";
  expectFreePath(shortest, r.start, map.esdf, o.min_clearance);
}

TEST(FrontierMemory, AGoalInUnknownSpaceGetsAPathTowardItOrAFrontierViewpointNeverTheGoal) {
  // Observed up to x = 4; the goal lies 20 m ahead in unknown space.
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  const ExplorerOptions o = frontierOptions();
  ExplorationRequest r = request(1);
  const Proposal toward = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(toward.found) << toward.reason;
  EXPECT_NE(toward.reason.find("toward the goal"), std::string::npos) << toward.reason;
  const Eigen::Vector3d end = toward.waypoints.back();
  EXPECT_LE((end - r.goal).norm(), (r.start - r.goal).norm() - o.frontier_memory.progress);
  EXPECT_GE(sampleEsdf(map.esdf, end).distance, o.min_clearance - kVoxel);
  EXPECT_NEAR(toward.yaws.back(), std::atan2(r.goal.y() - end.y(), r.goal.x() - end.x()), 1e-12);
  expectFreePath(toward, r.start, map.esdf, o.min_clearance);

  // From near the box's end no cell is 2 m nearer the goal: a frontier viewpoint.
  r.start = Eigen::Vector3d(2.5, 0, 1.5);
  const Proposal p = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(p.found) << p.reason;
  EXPECT_NE(p.reason.find("viewpoint"), std::string::npos) << p.reason;
  const Eigen::Vector3d v = p.waypoints.back();
  EXPECT_GT((v - r.goal).norm(), 10);
  const EsdfSample s = sampleEsdf(map.esdf, v);
  ASSERT_TRUE(s.known);
  EXPECT_GE(s.distance, o.min_clearance);
  // It faces a frontier cluster: the view from it along its yaw meets the unobserved boundary
  // within the camera's range.
  const Eigen::Vector3d ray(std::cos(p.yaws.back()), std::sin(p.yaws.back()), 0);
  bool meets_unknown = false;
  for (double d = 0; d <= 5 && !meets_unknown; d += kVoxel / 2) {
    meets_unknown = map.tsdf.voxel(map.tsdf.voxelIndex(v + d * ray)) == nullptr;
  }
  EXPECT_TRUE(meets_unknown) << p.reason;
  expectFreePath(p, r.start, map.esdf, o.min_clearance);
}

// A wall across everything up to z = 2.0, x in [1.6, 2.4]; observed up to z = 4.6.
double lowWall(const Eigen::Vector3d& p) {
  const double dx = std::max({1.6 - p.x(), p.x() - 2.4, 0.0});
  const double dz = std::max(p.z() - 2.0, 0.0);
  return dx == 0 && dz == 0 ? -0.1 : std::hypot(dx, dz);
}

TEST(FrontierMemory, ItClimbsOverALowWallOnlyWithAltitudeLayers) {
  const HandMap map = observedBox({-4, -6, 0.4}, {8, 6, 4.6}, lowWall);
  ExplorerOptions o = frontierOptions();
  ExplorationRequest r = request(1);
  r.goal = Eigen::Vector3d(5, 0, 1.5);
  const Proposal over = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(over.found) << over.reason;
  EXPECT_EQ(over.waypoints.back(), r.goal);
  double highest = 0;
  for (const Eigen::Vector3d& w : over.waypoints) highest = std::max(highest, w.z());
  EXPECT_GE(highest, 2.0 + o.min_clearance - kVoxel);
  expectFreePath(over, r.start, map.esdf, o.min_clearance);

  o.frontier_memory.layers = false;  // at the start's height there is no way past it
  const Proposal flat = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(flat.found) << flat.reason;  // a frontier on this side of the wall
  EXPECT_NE(flat.waypoints.back(), r.goal);
  for (const Eigen::Vector3d& w : flat.waypoints) {
    EXPECT_NEAR(w.z(), r.start.z(), 1e-9);
    EXPECT_LT(w.x(), 1.6);
  }
}

TEST(FrontierMemory, WithNoWayForwardItClimbsToLookTowardTheGoalFirst) {
  // Observed only up to x = 1.2 and z = 3.4 (free): no cell is 2 m nearer the goal, and the view
  // toward it is unknown from up high as from here.
  const HandMap map = observedBox({-4, -4, 0.4}, {1.2, 4, 3.4});
  ExplorerOptions o = frontierOptions();
  const ExplorationRequest r = request(1);
  const Proposal climb = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(climb.found) << climb.reason;
  EXPECT_NE(climb.reason.find("climb to"), std::string::npos) << climb.reason;
  EXPECT_GT(climb.gain_evaluations, 0);  // the views it compared are counted
  const Eigen::Vector3d up = climb.waypoints.back();
  EXPECT_GE(up.z(), r.start.z() + 0.8 - 1e-9);
  EXPECT_LE((up - r.start).head<2>().norm(), 3.0 + 1e-9);
  EXPECT_NEAR(climb.yaws.back(), std::atan2(r.goal.y() - r.start.y(), r.goal.x() - r.start.x()),
              1e-12);
  expectFreePath(climb, r.start, map.esdf, o.min_clearance);

  // Without it (or without layers), a frontier viewpoint at about the start's height.
  o.frontier_memory.climb_look = 0;
  const Proposal view = makeGoalSelector(o)->select(r, map.view());
  ASSERT_TRUE(view.found) << view.reason;
  EXPECT_NE(view.reason.find("viewpoint"), std::string::npos) << view.reason;
}

TEST(FrontierMemory, ATargetAskedForAgainFromTheSamePlaceBecomesTabu) {
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  ExplorerOptions o = frontierOptions();
  const auto selector = makeGoalSelector(o);
  // The vehicle never gets anywhere: every request comes from the start.
  std::vector<Eigen::Vector3d> targets;
  for (int cycle = 1; cycle <= 8; ++cycle) {
    const Proposal p = selector->select(request(cycle), map.view());
    ASSERT_TRUE(p.found) << p.reason;
    targets.push_back(p.waypoints.back());
    // Asking again in the same cycle gives the same answer.
    const Proposal again = selector->select(request(cycle), map.view());
    EXPECT_EQ(again.waypoints, p.waypoints);
  }
  // Proposed once, then asked again twice (tabu_attempts) from the same place: a new target, away
  // from it, and so on.
  ASSERT_EQ(o.frontier_memory.tabu_attempts, 2);
  EXPECT_EQ(targets[0], targets[1]);
  EXPECT_GE((targets[2] - targets[0]).norm(), o.frontier_memory.tabu_radius);
  EXPECT_EQ(targets[2], targets[3]);
  EXPECT_GE((targets[4] - targets[0]).norm(), o.frontier_memory.tabu_radius);
  EXPECT_GE((targets[4] - targets[2]).norm(), o.frontier_memory.tabu_radius);

  // A fresh selector given the same sequence answers the same; without memory, always the first.
  const auto replay = makeGoalSelector(o);
  for (int cycle = 1; cycle <= 8; ++cycle) {
    EXPECT_EQ(replay->select(request(cycle), map.view()).waypoints.back(),
              targets[static_cast<size_t>(cycle - 1)]);
  }
  o.frontier_memory.memory = false;
  const auto forgetful = makeGoalSelector(o);
  for (int cycle = 1; cycle <= 8; ++cycle) {
    EXPECT_EQ(forgetful->select(request(cycle), map.view()).waypoints.back(), targets[0]);
  }
}

TEST(FrontierMemory, ATargetThatDriftsByCentimetresIsStillOneTargetForTheTabu) {
  // The vehicle hovers a few centimetres from where it asked before: the search grid, aligned on
  // the start, and the target found on it move with it. The drifted target is the same target
  // (on eth 0.4 seed 17 the vehicle climbed and dove between two viewpoints, drifting by
  // millimetres as the map grew, for 100 cycles when only an identical one counted).
  const HandMap map = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  const ExplorerOptions o = frontierOptions();
  const auto selector = makeGoalSelector(o);
  std::vector<Eigen::Vector3d> targets;
  for (int cycle = 1; cycle <= 3; ++cycle) {
    ExplorationRequest r = request(cycle);
    r.start.x() += 0.05 * (cycle % 2);
    const Proposal p = selector->select(r, map.view());
    ASSERT_TRUE(p.found) << p.reason;
    targets.push_back(p.waypoints.back());
  }
  ASSERT_EQ(o.frontier_memory.tabu_attempts, 2);
  EXPECT_NEAR((targets[1] - targets[0]).norm(), 0.05, 1e-9);  // it drifted with the start
  EXPECT_GE((targets[2] - targets[0]).norm(), o.frontier_memory.tabu_radius);
}

TEST(FrontierMemory, WithNoFrontierInReachItGoesBackToAPlaceThatHadOne) {
  ExplorerOptions o = frontierOptions();
  const auto selector = makeGoalSelector(o);
  // First stuck at the start with frontiers around.
  const HandMap open = observedBox({-4, -4, 0.4}, {4, 4, 2.6});
  ASSERT_TRUE(selector->select(request(1), open.view()).found);
  // Then at (3, 0) in a closed room: everything within reach observed, walls all around, none of
  // it 2 m nearer the goal.
  const auto room = [](const Eigen::Vector3d& p) {
    return std::min({p.x() + 5, 4.5 - p.x(), p.y() + 8, 8 - p.y()});
  };
  const HandMap closed = observedBox({-12, -15, 0.4}, {19, 15, 2.6}, room);
  ExplorationRequest r = request(2);
  r.start = Eigen::Vector3d(3, 0, 1.5);
  const Proposal home = selector->select(r, closed.view());
  ASSERT_TRUE(home.found) << home.reason;
  EXPECT_EQ(home.waypoints.back(), request(1).start);
  EXPECT_NE(home.reason.find("home"), std::string::npos) << home.reason;
  // Without memory there is nowhere to go.
  o.frontier_memory.memory = false;
  const Proposal none = makeGoalSelector(o)->select(r, closed.view());
  EXPECT_FALSE(none.found);
  EXPECT_NE(none.reason.find("no reachable frontier"), std::string::npos) << none.reason;
}

TEST(FrontierMemory, SaysWhenThereIsNoMap) {
  const auto selector = makeGoalSelector(frontierOptions());
  const Proposal p = selector->select(request(1), {});
  EXPECT_FALSE(p.found);
  EXPECT_TRUE(p.map_missing);
}

}  // namespace
}  // namespace thicket::explorer

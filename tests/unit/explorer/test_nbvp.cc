// The next-best-view baseline (nbvp) on hand-built maps: what a correct implementation must
// propose.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "hand_maps.h"
#include "thicket/common/esdf_query.h"
#include "thicket/explorer/gain.h"
#include "thicket/explorer/goal_selector.h"

namespace thicket::explorer {
namespace {

using std::numbers::pi;

struct Box {
  Eigen::Vector3d lo, hi;
};

// Free space made of boxes, obstacles everywhere else: the signed distance to the boundary of the
// union (exact outside the boxes; inside, the largest distance to one box's boundary, which is a
// lower bound where boxes meet).
ObstacleDistance freeBoxes(std::vector<Box> boxes) {
  return [boxes](const Eigen::Vector3d& c) {
    double best = -1e9;
    for (const Box& b : boxes) {
      const Eigen::Vector3d outside = (b.lo - c).cwiseMax(c - b.hi).cwiseMax(0.0);
      const double d = outside.squaredNorm() > 0
                           ? -outside.norm()
                           : std::min((c - b.lo).minCoeff(), (b.hi - c).minCoeff());
      best = std::max(best, d);
    }
    return best;
  };
}

// A closed room: free inside [-3, 3] x [-3, 3] x [0.4, 2.6], walls 0.6 m thick all around (floor
// and ceiling included), unknown beyond them. With `door`, a 2 m x 1.8 m opening through the +x
// wall to the unknown space beyond.
HandMap room(bool door) {
  std::vector<Box> free = {{{-3, -3, 0.4}, {3, 3, 2.6}}};
  if (door) free.push_back({{2.5, -1, 0.6}, {4.0, 1, 2.4}});
  return observedBox({-3.6, -3.6, -0.2}, {3.6, 3.6, 3.2}, freeBoxes(free));
}

// Free inside x >= -4, |y| <= 4, 0.4 <= z <= 2.6, walled (0.6 m) at x = -4, y = +-4, on the floor
// and the ceiling, observed up to x = 4 and unknown beyond: the only unknown space a view from
// inside can see lies at x > 4, ahead of the start (0, 0, 1.5).
HandMap openAhead() {
  return observedBox({-4.6, -4.6, -0.2}, {4, 4.6, 3.2}, freeBoxes({{{-4, -4, 0.4}, {10, 4, 2.6}}}));
}

// A corridor along x (|y| <= 0.8, 0.7 <= z <= 2.3) whose walls leave a band of about +-0.15 m
// around its axis with 0.6 m of clearance, so the tree is nearly a line through the start. A 1 m
// wide window through the -y wall at -1.6 <= x <= -0.6 shows a little unknown space close to the
// start (from x < 0 only: the wall is 0.6 m thick); the corridor is closed at x = -2 and open at
// x = 6, where the unknown space beyond fills the views from its far end (x > 1 only: the camera
// sees 5 m).
HandMap corridor() {
  return observedBox(
      {-2.6, -1.4, 0.1}, {6, 1.4, 2.9},
      freeBoxes({{{-2, -0.8, 0.7}, {10, 0.8, 2.3}}, {{-1.6, -3, 1.0}, {-0.6, 0, 2.0}}}));
}

void expectSame(const Proposal& a, const Proposal& b) {
  EXPECT_EQ(a.found, b.found);
  EXPECT_EQ(a.waypoints, b.waypoints);
  EXPECT_EQ(a.yaws, b.yaws);
  EXPECT_EQ(a.score, b.score);
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.gain_evaluations, b.gain_evaluations);
}

bool same(const Proposal& a, const Proposal& b) {
  return a.found == b.found && a.waypoints == b.waypoints && a.yaws == b.yaws &&
         a.score == b.score && a.gain_evaluations == b.gain_evaluations;
}

// Behind thick walls the unknown space is in every frustum but no ray reaches it: the gain with
// occlusion is zero everywhere, so nbvp must find nothing (a gain without occlusion would send it
// anywhere). A door toward the unknown space gives it something to look at.
TEST(Nbvp, FindsNothingWhenAllUnknownSpaceIsHiddenBehindWalls) {
  const ExplorerOptions o = optionsFor("nbvp");
  const HandMap sealed = room(false);
  // The map does what the test needs: the frustum reaches past the walls from anywhere in the
  // room, yet none of those unknown points is visible.
  const ExplorationGain gain(o.gain, kVoxel);
  for (const Eigen::Vector3d& x :
       {Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(2, -2, 1.2), Eigen::Vector3d(-2, 1, 1.8)}) {
    for (int k = 0; k < 8; ++k) {
      const Pose view = ExplorationGain::cameraAt(x, -pi + k * pi / 4);
      ASSERT_GT(gain.unknownFraction(sealed.tsdf, view, o.subsample).unknown, 0);
      ASSERT_EQ(gain.visibleUnknownFraction(sealed.tsdf, view, o.subsample).unknown, 0);
    }
  }
  for (int cycle = 0; cycle < 3; ++cycle) {
    const Proposal p = makeGoalSelector(o)->select(request(cycle), sealed.view());
    EXPECT_FALSE(p.found);
    EXPECT_FALSE(p.map_missing);
    EXPECT_TRUE(p.waypoints.empty());
    EXPECT_NE(p.reason.find("nothing to explore"), std::string::npos) << p.reason;
    // Nothing beats zero_gain, so the tree grows past initial_nodes until max_nodes or the draws
    // run out.
    EXPECT_GT(p.gain_evaluations, o.nbvp.initial_nodes);
    EXPECT_LE(p.gain_evaluations, o.nbvp.max_nodes);
  }
  const HandMap door = room(true);
  for (int cycle = 0; cycle < 3; ++cycle) {
    const Proposal p = makeGoalSelector(o)->select(request(cycle), door.view());
    EXPECT_TRUE(p.found) << p.reason;
    EXPECT_GT(p.score, o.nbvp.zero_gain);
  }
}

// Unknown space ahead only: the first edge of the best branch heads toward it in a clear majority
// of cycles, and every first edge is a valid tree edge whose value the score includes.
TEST(Nbvp, FirstEdgeHeadsTowardTheUnknownSideAndIsAFreeTreeEdge) {
  const ExplorerOptions o = optionsFor("nbvp");
  const HandMap map = openAhead();
  const ExplorationGain gain(o.gain, kVoxel);
  constexpr int kCycles = 20;
  int ahead = 0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    const ExplorationRequest r = request(cycle);
    const Proposal p = makeGoalSelector(o)->select(r, map.view());
    ASSERT_TRUE(p.found) << p.reason;
    ASSERT_EQ(p.waypoints.size(), 1u);
    ASSERT_EQ(p.yaws.size(), 1u);
    const Eigen::Vector3d w = p.waypoints[0];
    ahead += w.x() > r.start.x();
    // One tree edge from the start: at most nbvp.range long, clear all along (the start has more
    // than min_clearance, so the tree keeps min_clearance).
    EXPECT_GT((w - r.start).norm(), 0);
    EXPECT_LE((w - r.start).norm(), o.nbvp.range + 1e-9);
    for (int i = 0; i <= 100; ++i) {
      const EsdfSample s = sampleEsdf(map.esdf, r.start + (w - r.start) * (i / 100.0));
      ASSERT_TRUE(s.known);
      // The tree checks every check_step (0.1 m); between checks the interpolated distance
      // changes by at most its gradient (1 m/m) times 0.05 m.
      EXPECT_GE(s.distance, o.min_clearance - 0.05);
    }
    EXPECT_GE(sampleEsdf(map.esdf, w).distance, o.min_clearance);
    EXPECT_GE(p.yaws[0], -pi);
    EXPECT_LT(p.yaws[0], pi);
    // The branch's value includes its first node's discounted gain (and the others' are >= 0).
    const Gain g =
        gain.visibleUnknownFraction(map.tsdf, ExplorationGain::cameraAt(w, p.yaws[0]), o.subsample);
    EXPECT_GE(p.score,
              g.unknown_fraction * std::exp(-o.nbvp.lambda * (w - r.start).norm()) - 1e-12);
    // Stops as soon as initial_nodes are grown and a branch is worth something.
    EXPECT_GE(p.gain_evaluations, o.nbvp.initial_nodes);
    EXPECT_LE(p.gain_evaluations, o.nbvp.max_nodes);
  }
  EXPECT_GE(ahead, 15) << "of " << kCycles;
}

// A branch's value sums its nodes' visible unknown fractions (occluded gain), each decayed by
// exp(-lambda * branch length). A tree of one node is a branch of one edge, whose value the test
// recomputes exactly; a larger tree's best branch sums several views.
TEST(Nbvp, BranchValueSumsTheDecayedVisibleGainsOfItsNodes) {
  ExplorerOptions o = optionsFor("nbvp");
  o.nbvp.initial_nodes = o.nbvp.max_nodes = 1;
  const HandMap map = openAhead();
  const ExplorationGain gain(o.gain, kVoxel);
  for (const double lambda : {0.0, 0.5, 3.0}) {
    o.nbvp.lambda = lambda;
    int found = 0;
    for (int cycle = 0; cycle < 20; ++cycle) {
      const ExplorationRequest r = request(cycle);
      const Proposal p = makeGoalSelector(o)->select(r, map.view());
      EXPECT_EQ(p.gain_evaluations, 1);
      if (!p.found) continue;
      ++found;
      const Eigen::Vector3d w = p.waypoints[0];
      const Gain g = gain.visibleUnknownFraction(map.tsdf, ExplorationGain::cameraAt(w, p.yaws[0]),
                                                 o.subsample);
      EXPECT_NEAR(p.score, g.unknown_fraction * std::exp(-lambda * (w - r.start).norm()), 1e-12);
    }
    EXPECT_GE(found, 5) << "lambda " << lambda;
  }
  // Deeper branches add their nodes' gains: with lambda = 0 and a larger tree, the best branch is
  // worth more than any single view (a gain is at most 1).
  o.nbvp.lambda = 0;
  o.nbvp.initial_nodes = o.nbvp.max_nodes = 100;
  o.max_draws = 10000;
  for (int cycle = 0; cycle < 5; ++cycle) {
    const Proposal p = makeGoalSelector(o)->select(request(cycle), map.view());
    ASSERT_TRUE(p.found) << p.reason;
    EXPECT_GT(p.score, 1) << p.reason;
  }
}

// lambda trades gain for distance. In the corridor the tree is nearly a line, the window's small
// gain is close to the start on the -x side and the open end's large gain 4 to 5 m away on the +x
// side: with lambda = 0 the best branch is the long one toward the open end, with a large lambda
// a short one near the start (the first edge then stays by the start or turns to the window).
// The tree does not depend on lambda (same draws, and a branch's value is positive for every
// lambda when it is for one), so on the same cycle the large-lambda branch is also worth less, at
// most the lambda = 0 best value decayed over its first edge.
TEST(Nbvp, LargeLambdaPrefersTheNearSmallGainToTheFarLargeOne) {
  ExplorerOptions o = optionsFor("nbvp");
  o.max_draws = 100000;   // the band the tree lives in is thin: most draws steer out of it
  o.min_clearance = 0.6;  // the corridor is 2 m wide: a wider clearance leaves the tree no room
  o.nbvp.initial_nodes = o.nbvp.max_nodes = 100;
  const HandMap map = corridor();
  constexpr double kLarge = 5;
  constexpr int kCycles = 20;
  int far_zero = 0, far_large = 0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    const ExplorationRequest r = request(cycle);
    o.nbvp.lambda = 0;
    const Proposal zero = makeGoalSelector(o)->select(r, map.view());
    o.nbvp.lambda = kLarge;
    const Proposal large = makeGoalSelector(o)->select(r, map.view());
    ASSERT_TRUE(zero.found) << zero.reason;
    ASSERT_TRUE(large.found) << large.reason;
    EXPECT_EQ(zero.gain_evaluations, large.gain_evaluations);
    EXPECT_LT(large.score, zero.score);
    EXPECT_LE(large.score,
              zero.score * std::exp(-kLarge * (large.waypoints[0] - r.start).norm()) + 1e-12);
    // A full step toward the open end.
    far_zero += zero.waypoints[0].x() - r.start.x() > 0.5;
    far_large += large.waypoints[0].x() - r.start.x() > 0.5;
  }
  EXPECT_GE(far_zero, 15) << "of " << kCycles;
  EXPECT_LE(far_large, 2) << "of " << kCycles;
}

TEST(Nbvp, SameRequestSameProposalOtherCycleOtherTree) {
  const ExplorerOptions o = optionsFor("nbvp");
  const HandMap map = openAhead();
  const auto selector = makeGoalSelector(o);
  const Proposal first = selector->select(request(7), map.view());
  ASSERT_TRUE(first.found);
  expectSame(first, selector->select(request(7), map.view()));  // the memory needs a later cycle
  expectSame(first, makeGoalSelector(o)->select(request(7), map.view()));
  const Proposal other = makeGoalSelector(o)->select(request(8), map.view());
  ASSERT_TRUE(other.found);
  EXPECT_NE(first.waypoints[0], other.waypoints[0]);
  // Another seed, another tree.
  ExplorerOptions reseeded = o;
  reseeded.seed = 4;
  EXPECT_NE(makeGoalSelector(reseeded)->select(request(7), map.view()).waypoints[0],
            first.waypoints[0]);
}

// Bircher re-seeds each tree with the rest of the previous best branch. Here the vehicle flies the
// first edge and asks again from its end: the remembered nodes change the answer, the same
// history gives the same answers, and a cycle that does not come after the remembered one (asked
// again, or a selector starting over) ignores the memory.
TEST(Nbvp, ReseedsFromThePreviousBestBranchDeterministically) {
  const ExplorerOptions o = optionsFor("nbvp");
  const HandMap map = openAhead();
  const auto fly = [&](GoalSelector& selector) {
    std::vector<Proposal> answers;
    ExplorationRequest r = request(1);
    for (int cycle = 1; cycle <= 6; ++cycle) {
      r.cycle = cycle;
      answers.push_back(selector.select(r, map.view()));
      if (!answers.back().found) break;
      r.start = answers.back().waypoints[0];
    }
    return answers;
  };
  const auto a = makeGoalSelector(o);
  const auto b = makeGoalSelector(o);
  const std::vector<Proposal> flight = fly(*a);
  const std::vector<Proposal> again = fly(*b);
  ASSERT_EQ(flight.size(), 6u);
  ASSERT_EQ(again.size(), flight.size());
  for (size_t i = 0; i < flight.size(); ++i) expectSame(flight[i], again[i]);

  // Without the memory (a fresh selector) the answers from the same starts differ somewhere.
  int differ = 0;
  ExplorationRequest r = request(1);
  for (size_t i = 1; i < flight.size(); ++i) {
    r.cycle = static_cast<int64_t>(i) + 1;
    r.start = flight[i - 1].waypoints[0];
    differ += !same(flight[i], makeGoalSelector(o)->select(r, map.view()));
  }
  EXPECT_GE(differ, 1);

  // Cycle 3 again, after cycle 6: answered as by a fresh selector, and the same twice.
  r.cycle = 3;
  r.start = flight[1].waypoints[0];
  const Proposal back = a->select(r, map.view());
  expectSame(back, makeGoalSelector(o)->select(r, map.view()));
  expectSame(back, a->select(r, map.view()));
}

TEST(Nbvp, SaysWhenThereIsNoMapOrTheStartIsNotFree) {
  const ExplorerOptions o = optionsFor("nbvp");
  const auto selector = makeGoalSelector(o);
  EXPECT_STREQ(selector->name(), "nbvp");
  const HandMap map = openAhead();
  Proposal p = selector->select(request(1), {});
  EXPECT_FALSE(p.found);
  EXPECT_TRUE(p.map_missing);
  EXPECT_EQ(p.reason, "no map");
  p = selector->select(request(1), {&map.tsdf, nullptr});
  EXPECT_TRUE(p.map_missing);
  p = selector->select(request(1), {nullptr, &map.esdf});
  EXPECT_TRUE(p.map_missing);
  // A start in unknown space (outside the observed box), and one inside a wall.
  for (const Eigen::Vector3d& start : {Eigen::Vector3d(8, 0, 1.5), Eigen::Vector3d(0, 4.3, 1.5)}) {
    ExplorationRequest r = request(1);
    r.start = start;
    p = selector->select(r, map.view());
    EXPECT_FALSE(p.found);
    EXPECT_FALSE(p.map_missing);
    EXPECT_FALSE(p.reason.empty());
    EXPECT_EQ(p.gain_evaluations, 0);
  }
}

}  // namespace
}  // namespace thicket::explorer

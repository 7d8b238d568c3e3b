// GoalFinder against analytic fields: the projection onto the horizon sphere, moving a horizon
// goal out of an obstacle by straight-line backtracking or by ESDF gradient ascent (with a
// straight-line fallback where the gradient says nothing), giving up after max_steps, never
// stepping past the start, and refusing bad input and bad options.
#include "thicket/local_planner/goal_finder.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <gtest/gtest.h>

#include "analytic_fields.h"

namespace thicket::local_planner {
namespace {

using testing::cylinderField;
using testing::freeSpace;
using testing::unknownBeyondX;

const Eigen::Vector3d kStart(0, 0, 1.5);
const Eigen::Vector3d kFarGoal(10, 0, 1.5);  // 10 m away along +x
// Free: known with at least this distance (robot radius 0.5 + clearance margin 0.1).
constexpr double kFreeDistance = 0.6;

GoalFinder finder(const std::string& method, int max_steps = 20) {
  GoalFinderOptions options;
  options.method = method;
  options.max_steps = max_steps;
  return GoalFinder(options, kFreeDistance);
}

// Distance from p to the line through a and b.
double distanceToLine(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                      const Eigen::Vector3d& b) {
  const Eigen::Vector3d u = (b - a).normalized();
  const Eigen::Vector3d d = p - a;
  return (d - d.dot(u) * u).norm();
}

// Everything known but nowhere free: distance below any free_distance, with `gradient`.
DistanceField crowded(const Eigen::Vector3d& gradient = Eigen::Vector3d::Zero()) {
  return [gradient](const Eigen::Vector3d&) { return EsdfSample{true, 0.1, gradient}; };
}

TEST(GoalFinder, ProjectsAFarGoalOntoTheHorizonSphere) {
  const GoalFinder gf = finder("gradient");
  const FoundGoal found = gf.find(kStart, kFarGoal, freeSpace());
  EXPECT_TRUE(found.projected);
  EXPECT_TRUE(found.free);
  EXPECT_EQ(found.steps, 0);
  EXPECT_NEAR((found.position - Eigen::Vector3d(3, 0, 1.5)).norm(), 0, 1e-12);

  // Along an oblique line too: exactly r_p from the start, on the line toward the goal.
  const Eigen::Vector3d start(1, -2, 0.5);
  const Eigen::Vector3d goal(7, 4, 3.5);
  const FoundGoal oblique = gf.find(start, goal, freeSpace());
  EXPECT_TRUE(oblique.projected);
  EXPECT_TRUE(oblique.free);
  EXPECT_EQ(oblique.steps, 0);
  EXPECT_NEAR((oblique.position - start).norm(), gf.options().horizon, 1e-12);
  EXPECT_NEAR(distanceToLine(oblique.position, start, goal), 0, 1e-12);
  EXPECT_GT((oblique.position - start).dot(goal - start), 0);  // toward the goal, not away

  // Another horizon is honoured.
  GoalFinderOptions options;
  options.horizon = 5;
  const FoundGoal five = GoalFinder(options, kFreeDistance).find(kStart, kFarGoal, freeSpace());
  EXPECT_NEAR((five.position - Eigen::Vector3d(5, 0, 1.5)).norm(), 0, 1e-12);
}

TEST(GoalFinder, AGoalInsideTheHorizonStaysWhereItIs) {
  for (const char* method : {"line", "gradient"}) {
    SCOPED_TRACE(method);
    const Eigen::Vector3d goal(1.2, 0.7, 2.0);
    const FoundGoal found = finder(method).find(kStart, goal, freeSpace());
    EXPECT_FALSE(found.projected);
    EXPECT_TRUE(found.free);
    EXPECT_EQ(found.steps, 0);
    EXPECT_EQ(found.position, goal);
  }
}

TEST(GoalFinder, LineBacktracksAlongTheLineUntilFree) {
  // A cylinder of radius 0.5 around the projected goal (3, 0): free from x <= 1.9 on.
  const DistanceField field = cylinderField({3, 0}, 0.5);
  const GoalFinder gf = finder("line");
  const double step = gf.options().step;
  const double free_distance = kFreeDistance;
  const Eigen::Vector3d projection(3, 0, 1.5);
  ASSERT_LT(field(projection).distance, free_distance);

  const FoundGoal found = gf.find(kStart, kFarGoal, field);
  EXPECT_TRUE(found.projected);
  EXPECT_TRUE(found.free);
  EXPECT_GT(found.steps, 0);
  // On the segment start -> projection.
  EXPECT_NEAR(distanceToLine(found.position, kStart, projection), 0, 1e-12);
  EXPECT_GE(found.position.x(), kStart.x());
  EXPECT_LE(found.position.x(), projection.x());
  // Each step is one step length back.
  EXPECT_NEAR((projection - found.position).norm(), found.steps * step, 1e-9);
  // Free here, and one step less would not have been.
  const EsdfSample here = field(found.position);
  EXPECT_TRUE(here.known);
  EXPECT_GE(here.distance, free_distance);
  const Eigen::Vector3d one_less = found.position + step * (projection - kStart).normalized();
  EXPECT_LT(field(one_less).distance, free_distance);
  // With these numbers: the first free point is x = 3 - 6 * 0.2 = 1.8.
  EXPECT_EQ(found.steps, 6);
  EXPECT_NEAR(found.position.x(), 1.8, 1e-9);
}

TEST(GoalFinder, GradientMovesTheGoalOutRadially) {
  // The cylinder's axis is 0.2 m beside the projected goal (3, 0): the gradient there is -y.
  const Eigen::Vector2d axis(3, 0.2);
  const double radius = 0.5;
  const DistanceField field = cylinderField(axis, radius);
  const GoalFinder gf = finder("gradient");
  const GoalFinderOptions& o = gf.options();
  const Eigen::Vector3d projection(3, 0, 1.5);
  ASSERT_LT(field(projection).distance, kFreeDistance);

  const FoundGoal found = gf.find(kStart, kFarGoal, field);
  EXPECT_TRUE(found.projected);
  EXPECT_TRUE(found.free);
  EXPECT_GT(found.steps, 0);
  EXPECT_LE(found.steps, o.max_steps);
  EXPECT_GE(field(found.position).distance, kFreeDistance);
  const double axis_distance_before = (projection.head<2>() - axis).norm();
  const double axis_distance_after = (found.position.head<2>() - axis).norm();
  EXPECT_GT(axis_distance_after, axis_distance_before);
  EXPECT_LE((found.position - projection).norm(), o.max_steps * o.step + 1e-9);
  // Radially: straight away from the axis (here -y), not back along the line (x unchanged).
  EXPECT_NEAR(found.position.x(), 3, 1e-9);
  EXPECT_NEAR(found.position.z(), 1.5, 1e-9);
  EXPECT_LT(found.position.y(), 0);
  // The distance grows by a step per step: 0.2 + 5 * 0.2 - 0.5 = 0.7 >= 0.6 after 5 steps.
  EXPECT_EQ(found.steps, 5);
}

TEST(GoalFinder, GradientFallsBackToStraightLineStepsInUnknownSpace) {
  // Known and free up to x = 1.9, unknown beyond: the projected goal (3, 0) is unknown, with no
  // gradient; the search steps straight back toward the start.
  const DistanceField field = unknownBeyondX(freeSpace(), 1.9);
  const GoalFinder gf = finder("gradient");
  const Eigen::Vector3d projection(3, 0, 1.5);
  ASSERT_FALSE(field(projection).known);

  const FoundGoal found = gf.find(kStart, kFarGoal, field);
  EXPECT_TRUE(found.free);
  EXPECT_GT(found.steps, 0);
  EXPECT_NEAR(distanceToLine(found.position, kStart, projection), 0, 1e-12);
  EXPECT_GE(found.position.x(), kStart.x());
  EXPECT_LE(found.position.x(), 1.9);
  EXPECT_NEAR((projection - found.position).norm(), found.steps * gf.options().step, 1e-9);
  EXPECT_TRUE(field(found.position).known);
  // One step less would still be unknown.
  EXPECT_FALSE(field(found.position + Eigen::Vector3d(gf.options().step, 0, 0)).known);
}

TEST(GoalFinder, ADeadEndGivesUpAfterMaxSteps) {
  // Straight-line backtracking through a field that is nowhere free: 5 steps, then it stops.
  {
    const GoalFinder gf = finder("line", 5);
    const FoundGoal found = gf.find(kStart, kFarGoal, crowded());
    EXPECT_FALSE(found.free);
    EXPECT_EQ(found.steps, 5);
    EXPECT_NEAR((found.position - Eigen::Vector3d(2, 0, 1.5)).norm(), 0, 1e-9);
  }
  // Gradient ascent up a gradient that never leads anywhere free: max_steps (20) steps.
  {
    const GoalFinder gf = finder("gradient");
    const FoundGoal found = gf.find(kStart, kFarGoal, crowded(Eigen::Vector3d(0, 0, 1)));
    EXPECT_FALSE(found.free);
    EXPECT_EQ(found.steps, gf.options().max_steps);
    EXPECT_NEAR((found.position - Eigen::Vector3d(3, 0, 1.5 + 20 * 0.2)).norm(), 0, 1e-9);
  }
  // max_steps 0: no search at all.
  {
    const FoundGoal found = finder("gradient", 0).find(kStart, kFarGoal, crowded());
    EXPECT_FALSE(found.free);
    EXPECT_EQ(found.steps, 0);
    EXPECT_NEAR((found.position - Eigen::Vector3d(3, 0, 1.5)).norm(), 0, 1e-12);
  }
}

TEST(GoalFinder, NeverStepsPastTheStart) {
  for (const char* method : {"line", "gradient"}) {
    SCOPED_TRACE(method);
    // Plenty of steps, nothing free, no gradient: the search ends at the start, not beyond.
    const GoalFinder gf = finder(method, 100);
    const FoundGoal found = gf.find(kStart, kFarGoal, crowded());
    EXPECT_FALSE(found.free);
    EXPECT_NEAR((found.position - kStart).norm(), 0, 1e-9);
    EXPECT_LE(found.steps, 16);  // 3 m in 0.2 m steps, and no step beyond

    // A goal 0.3 m away: one full step and one shortened step land exactly on the start.
    const Eigen::Vector3d near_goal = kStart + Eigen::Vector3d(0.3, 0, 0);
    const FoundGoal short_search = gf.find(kStart, near_goal, crowded());
    EXPECT_FALSE(short_search.projected);
    EXPECT_FALSE(short_search.free);
    EXPECT_NEAR((short_search.position - kStart).norm(), 0, 1e-12);
    EXPECT_GE((short_search.position - kStart).dot(near_goal - kStart), -1e-12);
    EXPECT_LE(short_search.steps, 2);

    // The goal at the start itself: nowhere to go.
    const FoundGoal at_start = gf.find(kStart, kStart, crowded());
    EXPECT_EQ(at_start.steps, 0);
    EXPECT_EQ(at_start.position, kStart);
  }
}

// A gradient that points back past the start (a wall across the way, seen from its near side)
// would put the horizon goal behind the vehicle and fly it away from its goal: the search steps
// back along the line instead, and ends at the start at the farthest.
TEST(GoalFinder, GradientNeverCarriesTheGoalBehindTheStart) {
  const GoalFinder gf = finder("gradient", 100);
  const FoundGoal found = gf.find(kStart, kFarGoal, crowded(Eigen::Vector3d(-1, 0, 0)));
  EXPECT_FALSE(found.free);
  EXPECT_NEAR((found.position - kStart).norm(), 0, 1e-9);
  // With a sideways component: gradient steps while they stay ahead (10 steps of 0.2 m from
  // x = 3 m), none behind.
  const FoundGoal oblique =
      finder("gradient", 10).find(kStart, kFarGoal, crowded(Eigen::Vector3d(-1, 1, 0)));
  EXPECT_GE((oblique.position - kStart).dot(kFarGoal - kStart), 0);
  EXPECT_GT(oblique.position.y(), 0.5);  // it did ascend sideways
}

TEST(GoalFinder, RefusesNonFiniteInput) {
  const GoalFinder gf = finder("gradient");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(gf.find(Eigen::Vector3d(nan, 0, 1), kFarGoal, freeSpace()), std::invalid_argument);
  EXPECT_THROW(gf.find(kStart, Eigen::Vector3d(1, nan, 1), freeSpace()), std::invalid_argument);
  EXPECT_THROW(gf.find(kStart, Eigen::Vector3d(inf, 0, 1), freeSpace()), std::invalid_argument);
}

TEST(GoalFinder, RefusesBadOptions) {
  const auto build = [](auto change, double free_distance = kFreeDistance) {
    GoalFinderOptions options;
    change(options);
    return GoalFinder(options, free_distance);
  };
  const auto unchanged = [](GoalFinderOptions&) {};
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.method = "bogus"; }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.method = ""; }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.step = 0; }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.step = -0.2; }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.step = std::nan(""); }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.horizon = 0; }), std::invalid_argument);
  EXPECT_THROW(build([](GoalFinderOptions& o) { o.max_steps = -1; }), std::invalid_argument);
  EXPECT_THROW(build(unchanged, 0), std::invalid_argument);
  EXPECT_THROW(build(unchanged, -0.6), std::invalid_argument);
  EXPECT_THROW(build(unchanged, std::nan("")), std::invalid_argument);
  EXPECT_NO_THROW(build(unchanged));
  EXPECT_NO_THROW(build([](GoalFinderOptions& o) { o.method = "line"; }));
  EXPECT_NO_THROW(build([](GoalFinderOptions& o) { o.max_steps = 0; }));
}

}  // namespace
}  // namespace thicket::local_planner

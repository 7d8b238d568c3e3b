// The emergency stop and the clearance check it shares with the acceptance test: the minimum-jerk
// stop is the optimum and ends at rest; planStop keeps the limits, stops within a physical
// distance, picks the hardest stop when only that one clears an obstacle, and says so when none
// does; planRetreat backs straight away from an obstacle, or gives nothing when it cannot;
// checkClearance samples at the trajectory's own 0.02 s grid, whatever `from` is.
#include "thicket/local_planner/stop.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "analytic_fields.h"
#include "thicket/local_planner/spline.h"

namespace thicket::local_planner {
namespace {

using testing::boxesField;
using testing::boxFromCorners;
using testing::expectFromStartToRest;
using testing::freeSpace;
using testing::inspectTrajectory;
using testing::trajectoryOf;
using testing::unknownBeyondX;

constexpr int64_t kUtime = 7'000'000;
const Eigen::Vector3d kStart(0, 0, 1.5);

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TrajectoryState stateAt(const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
                        const Eigen::Vector3d& acceleration = Eigen::Vector3d::Zero()) {
  TrajectoryState s;
  s.position = position;
  s.velocity = velocity;
  s.acceleration = acceleration;
  return s;
}

SplineEnds endsFrom(const TrajectoryState& start) {
  SplineEnds ends;
  ends.start_position = start.position;
  ends.start_velocity = start.velocity;
  ends.start_acceleration = start.acceleration;
  return ends;
}

// The minimum-jerk stop of `duration` from `start`, built from the spline as planStop builds its
// candidates: for the stops planStop did not pick.
PolynomialTrajectory stopLasting(const TrajectoryState& start, double duration) {
  const JerkSpline spline({duration}, /*free_end_position=*/true);
  const Derivatives fixed = spline.fixedDerivatives(endsFrom(start));
  return trajectoryOf(spline.segments(fixed, spline.minimumJerkStop(fixed)));
}

bool withinLimits(const PolynomialTrajectory& trajectory, const LocoOptions& o) {
  return trajectory.maxSpeed(0.01) <= o.v_max + 1e-6 &&
         trajectory.maxAcceleration(0.01) <= o.a_max + 1e-6;
}

double required(const LocoOptions& o) {
  return o.robot_radius + o.clearance_margin;
}

// The stop starts in `start` at kUtime, comes to rest where `distance` says, and keeps the limits
// at 0.01 s.
void expectStopFrom(const Stop& stop, const TrajectoryState& start, const LocoOptions& o) {
  const PolynomialTrajectory& t = stop.trajectory;
  EXPECT_EQ(t.startUtime(), kUtime);
  expectFromStartToRest(t, start);
  EXPECT_NEAR(stop.distance, (t.evaluate(t.duration()) - start.position).norm(), 1e-12);
  EXPECT_LE(t.maxSpeed(0.01), o.v_max + 1e-6);
  EXPECT_LE(t.maxAcceleration(0.01), o.a_max + 1e-6);
}

// The stop is the hardest the limits allow: none 15% shorter keeps them (planStop's durations
// grow in smaller steps than that).
void expectHardestWithinLimits(const Stop& stop, const TrajectoryState& start,
                               const LocoOptions& o) {
  EXPECT_FALSE(withinLimits(stopLasting(start, 0.85 * stop.trajectory.duration()), o))
      << "a stop of " << 0.85 * stop.trajectory.duration() << " s keeps the limits too";
}

// ---- the minimum-jerk stop ----

class MinimumJerkStopTest : public ::testing::TestWithParam<int> {
 protected:
  // Segments of 0.4 s each: one segment as planStop uses, or several.
  JerkSpline spline() const {
    return JerkSpline(std::vector<double>(static_cast<size_t>(GetParam()), 0.4), true);
  }
};

INSTANTIATE_TEST_SUITE_P(Stop, MinimumJerkStopTest, ::testing::Values(1, 3),
                         [](const auto& info) { return std::to_string(info.param) + "Segments"; });

const TrajectoryState kMoving = stateAt(Eigen::Vector3d(1, 2, 1.5), Eigen::Vector3d(0.8, -0.4, 0.2),
                                        Eigen::Vector3d(0.5, 0.6, -0.3));

TEST_P(MinimumJerkStopTest, StartsAtTheStartAndEndsAtRest) {
  const JerkSpline s = spline();
  const Derivatives fixed = s.fixedDerivatives(endsFrom(kMoving));
  const Derivatives best = s.minimumJerkStop(fixed);
  const PolynomialTrajectory t = trajectoryOf(s.segments(fixed, best));
  expectFromStartToRest(t, kMoving);
  const double end = t.duration() - 1e-12;
  EXPECT_LT((t.evaluate(end) - best.row(s.endPositionRow()).transpose()).norm(), 1e-8);
  // It moved on along the start velocity: a stop, not a return to the start.
  EXPECT_GT((t.evaluate(end) - kMoving.position).dot(kMoving.velocity), 0.05);
  for (int derivative = 0; derivative <= 4; ++derivative) {
    EXPECT_LT(t.maxDiscontinuity(derivative), 1e-7) << "derivative " << derivative;
  }
}

TEST_P(MinimumJerkStopTest, IsTheOptimumWithTheEndPositionFree) {
  const JerkSpline s = spline();
  const Derivatives fixed = s.fixedDerivatives(endsFrom(kMoving));
  const Derivatives best = s.minimumJerkStop(fixed);
  Derivatives gradient;
  const double cost = s.jerkCost(fixed, best, &gradient);
  ASSERT_GT(cost, 0);
  // Stationary in every free row, the end position's included.
  EXPECT_LT(gradient.norm(), 1e-6 * cost);
  // Finite perturbations all cost more: of everything at once, and of the end position alone
  // (which minimumJerkFree holds where it is told).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<> unit(-1, 1);
  for (int k = 0; k < 5; ++k) {
    Derivatives other = best;
    for (int i = 0; i < other.rows(); ++i) {
      for (int a = 0; a < 3; ++a) other(i, a) += 0.01 * unit(rng);
    }
    EXPECT_GT(s.jerkCost(fixed, other), cost) << "perturbation " << k;
  }
  for (int a = 0; a < 3; ++a) {
    for (const double step : {-0.01, 0.01}) {
      Derivatives moved = best;
      moved(s.endPositionRow(), a) += step;
      EXPECT_GT(s.jerkCost(fixed, moved), cost) << "end axis " << a << " by " << step;
      const Eigen::Vector3d end = moved.row(s.endPositionRow()).transpose();
      EXPECT_GT(s.jerkCost(fixed, s.minimumJerkFree(fixed, end)), cost)
          << "end axis " << a << " by " << step;
    }
  }
}

TEST(MinimumJerkStop, RefusesAFixedEnd) {
  const JerkSpline fixed_end({1.0}, false);
  const Derivatives fixed = fixed_end.fixedDerivatives(endsFrom(kMoving));
  EXPECT_THROW(fixed_end.minimumJerkStop(fixed), std::logic_error);
  // And derivatives of the wrong size.
  EXPECT_THROW(JerkSpline({1.0}, true).minimumJerkStop(Derivatives::Zero(2, 3)),
               std::invalid_argument);
}

// ---- planStop ----

TEST(PlanStop, InFreeSpaceStopsWithinTheLimitsAndAPhysicalDistance) {
  const LocoOptions o;
  const std::vector<TrajectoryState> starts = {
      stateAt(kStart, Eigen::Vector3d(1, 0, 0)),
      stateAt(kStart, Eigen::Vector3d(0, 0.5, 0)),
      stateAt(kStart, Eigen::Vector3d(0.6, -0.5, 0.3), Eigen::Vector3d(0.5, 0.5, -0.3)),
      stateAt(kStart, Eigen::Vector3d(0.7, 0.7, 0), Eigen::Vector3d(-1, -1, 0)),
  };
  for (const TrajectoryState& start : starts) {
    SCOPED_TRACE("start velocity " + std::to_string(start.velocity.x()) + ", " +
                 std::to_string(start.velocity.y()) + ", " + std::to_string(start.velocity.z()));
    const Stop stop = planStop(kUtime, start, freeSpace(), o);
    EXPECT_TRUE(stop.certified);
    expectStopFrom(stop, start, o);
    expectHardestWithinLimits(stop, start, o);
    // No stop within a_max is shorter than v²/(2 a_max); the smooth one takes ~1.6 times that.
    const double braking = start.velocity.squaredNorm() / (2 * o.a_max);
    EXPECT_GE(stop.distance, braking - 1e-9);
    EXPECT_LT(stop.distance, 2 * braking);
  }
}

TEST(PlanStop, TakesTheHardStopWhenOnlyItClearsAnObstacleAhead) {
  const LocoOptions o;
  const TrajectoryState start = stateAt(kStart, Eigen::Vector3d(1, 0, 0));
  // The hardest stop (free space certifies the first candidate) and a gentler one, 30% longer.
  const Stop hardest = planStop(kUtime, start, freeSpace(), o);
  const PolynomialTrajectory gentler = stopLasting(start, 1.3 * hardest.trajectory.duration());
  const double gentler_distance = gentler.evaluate(gentler.duration()).x() - kStart.x();
  ASSERT_GT(gentler_distance, hardest.distance + 0.02);
  // A wall whose margin begins halfway between where the two come to rest.
  const double face = kStart.x() + 0.5 * (hardest.distance + gentler_distance) + required(o);
  const DistanceField field = boxesField({boxFromCorners({face, -50, -50}, {face + 1, 50, 50})});
  ASSERT_FALSE(checkClearance(gentler, 0, field, required(o)).clear);

  const Stop stop = planStop(kUtime, start, field, o);
  EXPECT_TRUE(stop.certified);
  expectStopFrom(stop, start, o);
  expectHardestWithinLimits(stop, start, o);
  EXPECT_LT(stop.distance, gentler_distance);
  const testing::TrajectoryReport flown = inspectTrajectory(stop.trajectory, field, 0.01);
  EXPECT_TRUE(flown.all_known);
  EXPECT_GE(flown.min_distance, required(o)) << "at t = " << flown.min_distance_time << " s";
}

TEST(PlanStop, WithoutACertifiedStopTakesTheHardestWithinTheLimits) {
  const LocoOptions o;
  // Moving toward a wall 0.55 m ahead: every stop starts inside the clearance margin and comes
  // closer (moving away from one, it would be held to its own clearance and pass).
  const TrajectoryState start = stateAt(kStart, Eigen::Vector3d(0.8, 0.6, 0));
  const DistanceField ahead =
      boxesField({boxFromCorners({kStart.x() + 0.55, -50, -50}, {kStart.x() + 1.55, 50, 50})});
  const Stop stop = planStop(kUtime, start, ahead, o);
  EXPECT_FALSE(stop.certified);
  expectStopFrom(stop, start, o);
  expectHardestWithinLimits(stop, start, o);
  EXPECT_FALSE(checkClearance(stop.trajectory, 0, ahead, required(o)).clear);
  const DistanceField behind =
      boxesField({boxFromCorners({kStart.x() - 1.55, -50, -50}, {kStart.x() - 0.55, 50, 50})});
  EXPECT_TRUE(planStop(kUtime, start, behind, o).certified);
  // The same as in free space, where the hardest stop is certified.
  EXPECT_DOUBLE_EQ(stop.trajectory.duration(),
                   planStop(kUtime, start, freeSpace(), o).trajectory.duration());

  // Moving toward a wall too near to stop before its margin: the hardest stop as well.
  const TrajectoryState toward = stateAt(kStart, Eigen::Vector3d(1, 0, 0));
  const DistanceField near =
      boxesField({boxFromCorners({kStart.x() + 0.7, -50, -50}, {kStart.x() + 1.7, 50, 50})});
  const Stop late = planStop(kUtime, toward, near, o);
  EXPECT_FALSE(late.certified);
  expectStopFrom(late, toward, o);
  expectHardestWithinLimits(late, toward, o);
}

TEST(PlanStop, FromRestStaysWhereItIs) {
  const LocoOptions o;
  const TrajectoryState start = stateAt(kStart, Eigen::Vector3d::Zero());
  const Stop stop = planStop(kUtime, start, freeSpace(), o);
  EXPECT_TRUE(stop.certified);
  // Zero up to the rounding of the spline's linear solve.
  EXPECT_LT(stop.distance, 1e-9);
  for (const auto& [t, s] : stop.trajectory.sample(0.01)) {
    EXPECT_LT((s.position - kStart).norm(), 1e-9) << "t = " << t;
    EXPECT_LT(s.velocity.norm(), 1e-8) << "t = " << t;
  }
}

TEST(PlanStop, RefusesANonFiniteStart) {
  const LocoOptions o;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(planStop(kUtime, stateAt(Eigen::Vector3d(nan, 0, 1), Eigen::Vector3d::Zero()),
                        freeSpace(), o),
               std::invalid_argument);
  EXPECT_THROW(planStop(kUtime, stateAt(kStart, Eigen::Vector3d(0, inf, 0)), freeSpace(), o),
               std::invalid_argument);
  EXPECT_THROW(
      planStop(kUtime, stateAt(kStart, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, nan)),
               freeSpace(), o),
      std::invalid_argument);
}

// ---- planRetreat ----

TEST(PlanRetreat, BacksStraightAwayFromAPostToBeyondTheMargin) {
  const LocoOptions o;
  const DistanceField post = testing::cylinderField({0, 0}, 1.0);
  // At rest inside the margin (0.6 m), and just outside it (0.65 m): out to 0.1 m beyond the
  // margin along the direction of the 26 nearest the ray from the axis (the shortest way out),
  // never closer than it starts.
  for (const double clearance : {0.6, 0.65}) {
    SCOPED_TRACE("clearance " + std::to_string(clearance));
    const Eigen::Vector3d from =
        Eigen::Vector3d(0.6, 0.8, 0) * (1.0 + clearance) + Eigen::Vector3d(0, 0, 1.5);
    const TrajectoryState start = stateAt(from, Eigen::Vector3d::Zero());
    const std::optional<Retreat> back = planRetreat(kUtime, start, post, o, 0.1);
    ASSERT_TRUE(back);
    EXPECT_NEAR(back->from_distance, clearance, 1e-12);
    EXPECT_GE(back->to_distance, required(o) + 0.1);
    EXPECT_LT(back->to_distance, required(o) + 0.1 + 0.05 + 1e-12);  // the first 5 cm step beyond
    const PolynomialTrajectory& t = back->trajectory;
    EXPECT_EQ(t.startUtime(), kUtime);
    expectFromStartToRest(t, start);
    const Eigen::Vector3d end = t.evaluate(t.duration());
    EXPECT_NEAR(post(end).distance, back->to_distance, 1e-12);
    // Along (1, 1, 0), 8 degrees off the ray, at the same height: as few steps as along
    // (1, 1, -1), farther out.
    const Eigen::Vector3d way = end - from;
    EXPECT_NEAR(way.x(), way.y(), 1e-9);
    EXPECT_GT(way.x(), 0);
    EXPECT_NEAR(way.z(), 0, 1e-12);
    EXPECT_TRUE(withinLimits(t, o));
    const testing::TrajectoryReport flown = inspectTrajectory(t, post, 0.01);
    EXPECT_GE(flown.min_distance, clearance - 1e-9) << "at t = " << flown.min_distance_time;
  }
}

TEST(PlanRetreat, NothingWhenThereIsNoNeedOrNoWayOut) {
  const LocoOptions o;
  const TrajectoryState rest = stateAt(kStart, Eigen::Vector3d::Zero());
  // Already 0.1 m beyond the margin.
  EXPECT_FALSE(planRetreat(kUtime, rest, freeSpace(required(o) + 0.1), o, 0.1));
  // An unknown start.
  EXPECT_FALSE(planRetreat(kUtime, rest, unknownBeyondX(freeSpace(), -1), o, 0.1));
  // Between two walls 1.2 m apart: 0.6 m from each, no way out to the margin.
  const DistanceField gap = boxesField({boxFromCorners({-1.6, -50, -50}, {-0.6, 50, 50}),
                                        boxFromCorners({0.6, -50, -50}, {1.6, 50, 50})});
  ASSERT_NEAR(gap(kStart).distance, 0.6, 1e-12);
  EXPECT_FALSE(planRetreat(kUtime, rest, gap, o, 0.1));
  // Everything unknown beyond 2 cm from the start.
  const DistanceField post = testing::cylinderField({kStart.x() - 1.6, kStart.y()}, 1.0);
  ASSERT_NEAR(post(kStart).distance, 0.6, 1e-12);
  ASSERT_TRUE(planRetreat(kUtime, rest, post, o, 0.1));
  const DistanceField seen = testing::withUnknown(
      post, [](const Eigen::Vector3d& p) { return (p - kStart).norm() > 0.02; });
  EXPECT_FALSE(planRetreat(kUtime, rest, seen, o, 0.1));
  // A ridge between two posts 1.2 m apart: out along the ridge, where an ascent of the gradient
  // would zigzag across it.
  const DistanceField posts = [](const Eigen::Vector3d& p) {
    const EsdfSample a = testing::cylinderSample({0, 1.6}, 1.0, p);
    const EsdfSample b = testing::cylinderSample({0, -1.6}, 1.0, p);
    return a.distance < b.distance ? a : b;
  };
  const TrajectoryState between = stateAt(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d::Zero());
  const std::optional<Retreat> along = planRetreat(kUtime, between, posts, o, 0.1);
  ASSERT_TRUE(along);
  const Eigen::Vector3d out = along->trajectory.evaluate(along->trajectory.duration());
  EXPECT_NEAR(out.y(), 0, 1e-9);
  EXPECT_NEAR(out.z(), 1.5, 1e-9);
  EXPECT_GE(posts(out).distance, required(o) + 0.1);
  // Moving fast toward the post: any flight from there comes closer first.
  EXPECT_FALSE(planRetreat(kUtime, stateAt(kStart, Eigen::Vector3d(-1, 0, 0)), post, o, 0.1));
}

TEST(PlanRetreat, RefusesANonFiniteStartAndABadDistance) {
  const LocoOptions o;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const TrajectoryState rest = stateAt(kStart, Eigen::Vector3d::Zero());
  EXPECT_THROW(planRetreat(kUtime, stateAt(Eigen::Vector3d(nan, 0, 1), Eigen::Vector3d::Zero()),
                           freeSpace(), o, 0.1),
               std::invalid_argument);
  EXPECT_THROW(planRetreat(kUtime, rest, freeSpace(), o, 0), std::invalid_argument);
  EXPECT_THROW(planRetreat(kUtime, rest, freeSpace(), o, nan), std::invalid_argument);
}

// ---- checkClearance ----

// Along x from the origin at 1 m/s for `duration` seconds.
PolynomialTrajectory alongX(double duration) {
  Eigen::Matrix<double, 3, 2> coefficients;
  coefficients << 0, 1, 0, 0, 0, 0;
  return trajectoryOf({{duration, coefficients}});
}

TEST(CheckClearance, SamplesOnTheTrajectorysGridWhateverTheStart) {
  constexpr double kRequired = 0.6;
  const PolynomialTrajectory line = alongX(1.0);
  // Clear exactly at the acceptance test's sample times (x a multiple of 0.02 m on this line)
  // and too near everywhere between them: only samples taken on the grid from the trajectory's
  // start pass.
  const DistanceField on_grid_only = [](const Eigen::Vector3d& p) {
    const double k = p.x() / kClearanceCheckDt;
    const bool on_grid = std::abs(k - std::round(k)) < 1e-6;
    return EsdfSample{true, on_grid ? kRequired + 0.01 : kRequired - 0.01, Eigen::Vector3d::Zero()};
  };
  ASSERT_TRUE(checkClearance(line, 0, on_grid_only, kRequired).clear);
  ASSERT_LT(on_grid_only(line.evaluate(0.013)).distance, kRequired);
  for (const double from : {0.001, 0.013, 0.02, 0.03, 0.5, 0.77, 0.999, 1.0, 2.5}) {
    const ClearanceCheck check = checkClearance(line, from, on_grid_only, kRequired);
    EXPECT_TRUE(check.clear) << "from " << from << " s: " << check.reason;
    EXPECT_NEAR(check.min_distance, kRequired + 0.01, 1e-12) << "from " << from << " s";
  }
}

TEST(CheckClearance, FromBeyondTheEndChecksTheEndPointOnly) {
  constexpr double kRequired = 0.6;
  const PolynomialTrajectory line = alongX(2.0);
  // A post beside the line at x = 0.5: too near there, clear from x = 1.2 on.
  const DistanceField post = boxesField({boxFromCorners({0.4, 0.3, -50}, {0.6, 1.0, 50})});
  const ClearanceCheck all = checkClearance(line, 0, post, kRequired);
  EXPECT_FALSE(all.clear);
  EXPECT_TRUE(contains(all.reason, "sample at t=")) << all.reason;
  EXPECT_TRUE(contains(all.reason, "distance")) << all.reason;
  EXPECT_NEAR(all.min_distance, 0.3, 1e-9);
  EXPECT_TRUE(checkClearance(line, 1.5, post, kRequired).clear);
  const ClearanceCheck beyond = checkClearance(line, 10, post, kRequired);
  EXPECT_TRUE(beyond.clear) << beyond.reason;
  EXPECT_NEAR(beyond.min_distance, post(line.evaluate(2.0)).distance, 1e-12);

  // Ending beside the post: from beyond the end the end point alone is checked, held to its own
  // clearance (a vehicle at rest inside the margin may stay).
  const PolynomialTrajectory short_line = alongX(0.5);
  const ClearanceCheck end = checkClearance(short_line, 10, post, kRequired);
  EXPECT_TRUE(end.clear) << end.reason;
  EXPECT_NEAR(end.threshold, 0.3, 1e-9);
  EXPECT_NEAR(end.min_distance, 0.3, 1e-9);
}

TEST(CheckClearance, EscapeSlackLetsAStartAtTheMarginComeThatMuchCloserAndNoMore) {
  constexpr double kRequired = 0.6, kSlack = 0.002;
  const PolynomialTrajectory line = alongX(1.0);
  // The distance falls linearly along the line, from `start` at x = 0 by `dip` at x = 1.
  const auto falling = [](double start, double dip) -> DistanceField {
    return [start, dip](const Eigen::Vector3d& p) {
      return EsdfSample{true, start - dip * std::clamp(p.x(), 0.0, 1.0), Eigen::Vector3d::Zero()};
    };
  };
  struct Case {
    double start, dip;
    bool strict, slack;  // clear without the slack, with it
  };
  for (const Case& c : {
           Case{0.601, 0.0015, false, true},    // just outside: may dip below the margin by a hair
           Case{0.5990, 0.001, false, true},    // inside: may come the slack closer than its start
           Case{0.5990, 0.0025, false, false},  // but not more
           Case{0.603, 0.0035, false, false},   // farther outside than the slack: the margin holds
           Case{0.603, 0.0025, true, true},     // and what keeps it passes either way
       }) {
    const DistanceField field = falling(c.start, c.dip);
    const ClearanceCheck strict = checkClearance(line, 0, field, kRequired);
    const ClearanceCheck slack = checkClearance(line, 0, field, kRequired, kSlack);
    EXPECT_EQ(strict.clear, c.strict) << c.start << " " << c.dip << ": " << strict.reason;
    EXPECT_EQ(slack.clear, c.slack) << c.start << " " << c.dip << ": " << slack.reason;
    EXPECT_NEAR(slack.threshold, std::min(kRequired, c.start - kSlack), 1e-12);
  }
}

TEST(CheckClearance, UnknownSamplesFail) {
  const PolynomialTrajectory line = alongX(1.0);
  const DistanceField field = unknownBeyondX(freeSpace(), 0.5);
  EXPECT_TRUE(checkClearance(alongX(0.4), 0, field, 0.6).clear);
  const ClearanceCheck check = checkClearance(line, 0, field, 0.6);
  EXPECT_FALSE(check.clear);
  EXPECT_TRUE(contains(check.reason, "unknown")) << check.reason;
  EXPECT_EQ(check.min_distance, 0);
  const ClearanceCheck end = checkClearance(line, 3, field, 0.6);
  EXPECT_FALSE(end.clear);
  EXPECT_TRUE(contains(end.reason, "unknown")) << end.reason;
}

TEST(CheckClearance, AStartInsideTheMarginIsHeldToItsOwnClearance) {
  constexpr double kRequired = 0.6;
  const PolynomialTrajectory line = alongX(2.0);  // (0, 0, 0) to (2, 0, 0)
  // A post beside the start, 0.5 m from it: the line leaves it, never coming closer.
  const DistanceField beside = testing::cylinderField({0, 0.8}, 0.3);
  const ClearanceCheck away = checkClearance(line, 0, beside, kRequired);
  EXPECT_TRUE(away.clear) << away.reason;
  EXPECT_NEAR(away.threshold, 0.5, 1e-12);
  EXPECT_NEAR(away.min_distance, 0.5, 1e-12);
  // Checked again from later on, clear of the margin by then: the full clearance again.
  const ClearanceCheck later = checkClearance(line, 1.5, beside, kRequired);
  EXPECT_TRUE(later.clear) << later.reason;
  EXPECT_EQ(later.threshold, kRequired);
  // A vehicle at rest there may stay.
  EXPECT_TRUE(checkClearance(PolynomialTrajectory::hover(0, Eigen::Vector3d::Zero(), 1), 0, beside,
                             kRequired)
                  .clear);

  // A post ahead, 0.5 m from the start: the line comes closer, refused at its second sample.
  const DistanceField ahead = testing::cylinderField({1.3, 0}, 0.8);
  const ClearanceCheck closer = checkClearance(line, 0, ahead, kRequired);
  EXPECT_FALSE(closer.clear);
  EXPECT_NEAR(closer.threshold, 0.5, 1e-12);
  EXPECT_TRUE(contains(closer.reason, "sample at t=0.02 s")) << closer.reason;
  EXPECT_TRUE(contains(closer.reason, "< 0.5000 m (its start's, inside the margin)"))
      << closer.reason;
  // A start in unknown space escapes nothing.
  const ClearanceCheck unknown =
      checkClearance(line, 0, unknownBeyondX(freeSpace(), -1), kRequired);
  EXPECT_FALSE(unknown.clear);
  EXPECT_EQ(unknown.threshold, kRequired);
}

}  // namespace
}  // namespace thicket::local_planner

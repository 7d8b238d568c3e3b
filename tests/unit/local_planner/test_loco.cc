// Loco against ground truth: the collision potential against its formula, the cost gradient
// against finite differences, the cost terms against independent evaluations of the spline, and
// solved trajectories against exact analytic distance fields sampled every 0.01 s (ten times
// finer than the planner's own acceptance samples).
#include "thicket/local_planner/loco.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "analytic_fields.h"

namespace thicket::local_planner {
namespace {

using testing::boxesField;
using testing::boxFromCorners;
using testing::checkTrajectory;
using testing::cylinderField;
using testing::freeSpace;
using testing::trajectoryOf;
using testing::unknownBeyondX;

const Eigen::Vector3d kStart(0, 0, 1.5);
const Eigen::Vector3d kGoal(3, 0, 1.5);

SplineEnds lineEnds(const Eigen::Vector3d& start_velocity = Eigen::Vector3d::Zero()) {
  SplineEnds ends;
  ends.start_position = kStart;
  ends.start_velocity = start_velocity;
  ends.end_position = kGoal;
  return ends;
}

// Prints what a solve did; `clearance` is the analytic one at 0.01 s, NaN when not measured.
void report(const char* name, const LocoResult& r,
            double clearance = std::numeric_limits<double>::quiet_NaN()) {
  std::printf(
      "[ loco     ] %s: accepted %d, restarts %d, iterations %d, min distance %.3f m "
      "(planner, 0.1 s)",
      name, r.accepted, r.restarts, r.iterations, r.min_distance);
  if (!std::isnan(clearance)) std::printf(", %.3f m (analytic, 0.01 s)", clearance);
  std::printf(", end (%.3f, %.3f, %.3f), reason '%s'\n", r.end_position.x(), r.end_position.y(),
              r.end_position.z(), r.reason.c_str());
}

void printLimits(const LocoResult& r) {
  const PolynomialTrajectory t = trajectoryOf(r.segments);
  std::printf("[ loco     ]   max speed %.3f m/s, max acceleration %.3f m/s^2, duration %.2f s\n",
              t.maxSpeed(0.01), t.maxAcceleration(0.01), t.duration());
}

// A wall at x in [1.4, 1.6] (z in [0, 5], y in [-5, 5]) with a 1.6 m gap, y in [0.2, 1.8].
DistanceField wallWithGap() {
  return boxesField(
      {boxFromCorners({1.4, -5, 0}, {1.6, 0.2, 5}), boxFromCorners({1.4, 1.8, 0}, {1.6, 5, 5})});
}

// ---- the collision potential ----

TEST(CollisionPotential, MatchesTheFormulaInEachRegime) {
  const double r = 0.5, eps = 1.0;
  // Inside the robot radius: -d' + ε/2, slope -1 (also inside the obstacle, d < 0).
  Potential p = collisionPotential(0.2, r, eps);
  EXPECT_NEAR(p.value, 0.3 + 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(p.derivative, -1);
  p = collisionPotential(-0.4, r, eps);
  EXPECT_NEAR(p.value, 0.9 + 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(p.derivative, -1);
  // Within ε: (d' - ε)² / (2ε), slope (d' - ε) / ε.
  p = collisionPotential(0.75, r, eps);
  EXPECT_NEAR(p.value, 0.75 * 0.75 / 2, 1e-12);
  EXPECT_NEAR(p.derivative, -0.75, 1e-12);
  p = collisionPotential(1.3, r, eps);
  EXPECT_NEAR(p.value, 0.2 * 0.2 / 2, 1e-12);
  EXPECT_NEAR(p.derivative, -0.2, 1e-12);
  // Beyond: nothing.
  p = collisionPotential(1.6, r, eps);
  EXPECT_EQ(p.value, 0);
  EXPECT_EQ(p.derivative, 0);
  p = collisionPotential(100, r, eps);
  EXPECT_EQ(p.value, 0);
  EXPECT_EQ(p.derivative, 0);
  // Another radius and ε: d' = 0.1 inside ε = 0.4 -> 0.3² / 0.8.
  p = collisionPotential(0.4, 0.3, 0.4);
  EXPECT_NEAR(p.value, 0.09 / 0.8, 1e-12);
  EXPECT_NEAR(p.derivative, -0.75, 1e-12);
}

TEST(CollisionPotential, ValueAndDerivativeAreContinuousAtTheRegimeBoundaries) {
  const double r = 0.5, eps = 1.0;
  for (double boundary : {r, r + eps}) {
    const Potential below = collisionPotential(boundary - 1e-12, r, eps);
    const Potential at = collisionPotential(boundary, r, eps);
    const Potential above = collisionPotential(boundary + 1e-12, r, eps);
    EXPECT_NEAR(below.value, above.value, 1e-9) << boundary;
    EXPECT_NEAR(below.value, at.value, 1e-9) << boundary;
    EXPECT_NEAR(below.derivative, above.derivative, 1e-9) << boundary;
    EXPECT_NEAR(below.derivative, at.derivative, 1e-9) << boundary;
  }
  EXPECT_NEAR(collisionPotential(r, r, eps).value, eps / 2, 1e-12);
  EXPECT_NEAR(collisionPotential(r + eps, r, eps).value, 0, 1e-12);
}

TEST(CollisionPotential, DerivativeMatchesFiniteDifferences) {
  const double r = 0.5, eps = 1.0, h = 1e-6;
  for (double d : {-1.0, 0.1, 0.45, 0.55, 0.9, 1.2, 1.45, 1.55, 3.0}) {
    const double numeric =
        (collisionPotential(d + h, r, eps).value - collisionPotential(d - h, r, eps).value) /
        (2 * h);
    EXPECT_NEAR(collisionPotential(d, r, eps).derivative, numeric, 1e-6) << "distance " << d;
  }
}

// ---- the cost ----

// The minimum-jerk free derivatives of `problem`, every entry moved by up to `scale`.
Derivatives perturbedMinimumJerk(const LocoProblem& problem, double scale, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<> unit(-1, 1);
  Derivatives free = problem.spline().minimumJerkFree(problem.fixed(), kGoal);
  for (int i = 0; i < free.rows(); ++i) {
    for (int a = 0; a < 3; ++a) free(i, a) += scale * unit(rng);
  }
  return free;
}

class LocoCostTest : public ::testing::TestWithParam<bool> {
 protected:
  bool freeEnd() const { return GetParam(); }
  LocoOptions options_;
};

INSTANTIATE_TEST_SUITE_P(Loco, LocoCostTest, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "FreeEnd" : "FixedEnd"; });

// A cylinder 0.2 m off the line: the path runs through it, so the potential's linear and
// quadratic regimes both contribute, and its distance gradient has a lateral component.
TEST_P(LocoCostTest, GradientMatchesFiniteDifferencesNearACylinder) {
  for (const Eigen::Vector3d& start_velocity :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.5, 0.2, 0)}) {
    SCOPED_TRACE("start velocity " + std::to_string(start_velocity.x()));
    const LocoProblem problem(options_, JerkSpline(segmentTimes(3.0, 1, 2), freeEnd()),
                              lineEnds(start_velocity), cylinderField({1.5, 0.2}, 0.3));
    Derivatives free = perturbedMinimumJerk(problem, 0.05, 7);
    if (freeEnd()) {
      free.row(problem.spline().endPositionRow()) += Eigen::RowVector3d(-0.3, 0.2, 0.1);
    }
    Derivatives gradient;
    const LocoCost cost = problem.cost(free, &gradient);
    ASSERT_GT(cost.collision, 0);
    if (freeEnd()) {
      ASSERT_GT(cost.goal, 0.1);
    } else {
      EXPECT_EQ(cost.goal, 0);
    }
    // The samples reach both regimes of a nonzero potential: inside the robot radius, and within
    // ε of it (from 1.5 m the cylinder is within reach everywhere; free space has the third).
    const DistanceField field = cylinderField({1.5, 0.2}, 0.3);
    double nearest = 1e9, farthest = 0;
    const PolynomialTrajectory t = trajectoryOf(problem.spline().segments(problem.fixed(), free));
    for (const auto& [time, state] : t.sample(options_.sample_dt)) {
      nearest = std::min(nearest, field(state.position).distance);
      farthest = std::max(farthest, field(state.position).distance);
    }
    EXPECT_LT(nearest, options_.robot_radius);
    EXPECT_GT(farthest, options_.robot_radius + options_.clearance_margin);
    ASSERT_EQ(gradient.rows(), free.rows());
    const double h = 1e-6;
    for (int i = 0; i < free.rows(); ++i) {
      for (int a = 0; a < 3; ++a) {
        Derivatives plus = free, minus = free;
        plus(i, a) += h;
        minus(i, a) -= h;
        const double numeric = (problem.cost(plus).total - problem.cost(minus).total) / (2 * h);
        EXPECT_NEAR(gradient(i, a), numeric, 1e-4 * std::max(1.0, std::abs(numeric)))
            << "row " << i << " axis " << a;
      }
    }
    // The collision and goal terms make a real part of the gradient, not just the jerk.
    Derivatives jerk_gradient;
    problem.spline().jerkCost(problem.fixed(), free, &jerk_gradient);
    EXPECT_GT((gradient - options_.w_d * jerk_gradient).norm(), 1e-2);
  }
}

// Σ_k ||v(t_k)|| Δt at t_k = k Δt and at the end, straight from the trajectory.
double sampledSpeedIntegral(const PolynomialTrajectory& t, double dt) {
  double sum = 0;
  for (int k = 0; k * dt < t.duration() - 1e-9; ++k) sum += t.evaluate(k * dt, 1).norm() * dt;
  return sum + t.evaluate(t.duration(), 1).norm() * dt;
}

TEST_P(LocoCostTest, FreeSpaceCostsOnlyJerkAndGoal) {
  const LocoProblem problem(options_, JerkSpline(segmentTimes(3.0, 1, 2), freeEnd()),
                            lineEnds({0.4, -0.3, 0.1}), freeSpace());
  const Derivatives free = perturbedMinimumJerk(problem, 0.2, 11);
  const LocoCost cost = problem.cost(free);
  EXPECT_EQ(cost.collision, 0);
  const double jerk = problem.spline().jerkCost(problem.fixed(), free);
  EXPECT_DOUBLE_EQ(cost.derivative, jerk);
  double goal = 0;
  if (freeEnd()) {
    const double error = (free.row(problem.spline().endPositionRow()).transpose() - kGoal).norm();
    const double delta = options_.goal_smoothing;
    goal = std::sqrt(error * error + delta * delta) - delta;
    EXPECT_GT(goal, 0.05);
  }
  EXPECT_NEAR(cost.goal, goal, 1e-12);
  EXPECT_NEAR(cost.total, options_.w_d * jerk + options_.w_g * goal, 1e-12 * cost.total);
}

// Unknown space reads d = 0; a constant distance within ε gives the middle regime. Either way J_c
// is the constant potential times (Σ_k ||v(t_k)|| Δt + v_max Δt for the end at rest), evaluated
// here on the trajectory itself. The potential is measured from robot_radius + clearance_margin
// + potential_buffer (a little beyond the clearance acceptance asks for); with both 0 unknown
// space costs exactly robot_radius + ε/2.
TEST_P(LocoCostTest, ConstantPotentialWeightsTheSampledSpeedIntegral) {
  const DistanceField unknown = [](const Eigen::Vector3d&) { return EsdfSample{}; };
  const DistanceField near = [](const Eigen::Vector3d&) {
    return EsdfSample{true, 0.9, Eigen::Vector3d(1, 0, 0)};
  };
  for (double margin : {0.0, 0.1}) {
    LocoOptions options;
    options.clearance_margin = margin;
    if (margin == 0) options.potential_buffer = 0;
    const double radius =
        options.robot_radius + margin + options.potential_buffer;  // where the potential starts
    const double eps = options.epsilon();
    const double in_unknown = radius + eps / 2;
    const double in_band = (0.9 - radius - eps) * (0.9 - radius - eps) / (2 * eps);
    if (margin == 0) {
      EXPECT_DOUBLE_EQ(in_unknown, options.robot_radius + options.epsilon() / 2);
    }
    for (const auto& [field, c] : {std::pair{unknown, in_unknown}, std::pair{near, in_band}}) {
      const LocoProblem problem(options, JerkSpline(segmentTimes(3.0, 1, 2), freeEnd()),
                                lineEnds({0.3, 0.1, 0}), field);
      const Derivatives free = perturbedMinimumJerk(problem, 0.1, 13);
      const LocoCost cost = problem.cost(free);
      const PolynomialTrajectory t = trajectoryOf(problem.spline().segments(problem.fixed(), free));
      const double integral =
          sampledSpeedIntegral(t, options.sample_dt) + options.v_max * options.sample_dt;
      EXPECT_GT(integral, 2.5);  // about the length of the 3 m move
      EXPECT_NEAR(cost.collision, c * integral, 1e-9 * cost.collision)
          << "clearance margin " << margin << ", c " << c;
      EXPECT_NEAR(
          cost.total,
          options.w_d * cost.derivative + options.w_c * cost.collision + options.w_g * cost.goal,
          1e-12 * cost.total);
    }
  }
}

// ---- solving ----

struct SolveCase {
  bool free_end;
  Eigen::Vector3d start_velocity;
  std::string name;
};

// For test listings (gtest would otherwise dump the struct's bytes, padding included).
void PrintTo(const SolveCase& c, std::ostream* os) {
  *os << c.name;
}

class LocoSolveTest : public ::testing::TestWithParam<SolveCase> {};

INSTANTIATE_TEST_SUITE_P(Loco, LocoSolveTest,
                         ::testing::Values(SolveCase{false, {0, 0, 0}, "FixedEndFromRest"},
                                           SolveCase{true, {0, 0, 0}, "FreeEndFromRest"},
                                           SolveCase{false, {0.5, 0, 0}, "FixedEndMoving"},
                                           SolveCase{true, {0.5, 0, 0}, "FreeEndMoving"}),
                         [](const auto& info) { return info.param.name; });

// A cylinder of radius 0.3 right on the line from start to goal: the planned trajectory keeps the
// robot radius from it at every 0.01 s, within the limits, from the requested start state.
TEST_P(LocoSolveTest, AvoidsACylinderOnTheLine) {
  const SolveCase& c = GetParam();
  const Loco loco{LocoOptions{}};
  const SplineEnds ends = lineEnds(c.start_velocity);
  const DistanceField field = cylinderField({1.5, 0}, 0.3);
  const LocoResult result = loco.solve(ends, c.free_end, field, 1);
  ASSERT_TRUE(result.accepted) << result.reason;
  EXPECT_TRUE(result.reason.empty());
  const double clearance = checkTrajectory(result, field, loco.options());
  report(c.name.c_str(), result, clearance);
  EXPECT_GE(clearance, loco.options().robot_radius);
  EXPECT_GE(result.min_distance, loco.options().robot_radius + loco.options().clearance_margin);

  const PolynomialTrajectory t = trajectoryOf(result.segments);
  EXPECT_LT((t.evaluate(0, 0) - ends.start_position).norm(), 1e-9);
  EXPECT_LT((t.evaluate(0, 1) - ends.start_velocity).norm(), 1e-9);
  EXPECT_LT((t.evaluate(0, 2) - ends.start_acceleration).norm(), 1e-9);
  const Eigen::Vector3d end = t.evaluate(t.duration());
  EXPECT_LT((end - result.end_position).norm(), 1e-9);
  EXPECT_LT(t.evaluate(t.duration(), 1).norm(), 1e-9);  // at rest
  if (c.free_end) {
    // The soft goal's pull, w_g (f(T) - g) / sqrt(||f(T) - g||² + δ²), keeps its full strength
    // down to a few δ = goal_smoothing = 1 cm from the goal, against which the jerk of ending a
    // few mm earlier weighs little: observed 4 mm.
    EXPECT_LT((end - kGoal).norm(), 0.05);
  } else {
    EXPECT_LT((end - kGoal).norm(), 1e-6);
  }
  for (int derivative = 0; derivative <= 4; ++derivative) {
    EXPECT_LT(t.maxDiscontinuity(derivative), 1e-6) << derivative;
  }
}

// The only way to the goal leads sideways through a gap; the line and the distance gradient
// along it (normal to the wall) lead into the wall. Default options, seed chosen up front.
TEST(Loco, FindsTheGapInAWall) {
  const Loco loco{LocoOptions{}};
  const DistanceField field = wallWithGap();
  const LocoResult result = loco.solve(lineEnds(), false, field, 1);
  ASSERT_FALSE(result.segments.empty());
  const PolynomialTrajectory t = trajectoryOf(result.segments);
  const testing::TrajectoryReport path = testing::inspectTrajectory(t, field, 0.01);
  report("wall with gap", result, path.min_distance);
  std::printf(
      "[ loco     ] wall with gap: max speed %.3f m/s, max acceleration %.3f m/s^2, "
      "duration %.2f s\n",
      path.max_speed, path.max_acceleration, t.duration());
  // The best attempt goes through the gap, clear of the wall everywhere...
  EXPECT_GE(path.min_distance, loco.options().robot_radius);
  for (const auto& [time, state] : t.sample(0.01)) {
    if (std::abs(state.position.x() - 1.5) < 0.1) {
      EXPECT_GT(state.position.y(), 0.7) << time;
      EXPECT_LT(state.position.y(), 1.3) << time;
    }
  }
  // ...and is accepted: within v_max and a_max as well.
  EXPECT_TRUE(result.accepted) << result.reason;
  if (result.accepted) checkTrajectory(result, field, loco.options());
}

TEST(Loco, SameSeedSameTrajectory) {
  const Loco loco{LocoOptions{}};
  const DistanceField field = wallWithGap();
  const LocoResult a = loco.solve(lineEnds(), false, field, 42);
  const LocoResult b = loco.solve(lineEnds(), false, field, 42);
  ASSERT_EQ(a.segments.size(), b.segments.size());
  for (size_t s = 0; s < a.segments.size(); ++s) {
    EXPECT_EQ(a.segments[s].duration, b.segments[s].duration);
    EXPECT_TRUE(a.segments[s].coefficients == b.segments[s].coefficients) << "segment " << s;
  }
  EXPECT_EQ(a.accepted, b.accepted);
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.restarts, b.restarts);
  EXPECT_EQ(a.termination, b.termination);
  EXPECT_EQ(a.termination_message, b.termination_message);
}

// The result keeps how Ceres ended the solve it comes from, in Ceres's own words.
TEST(Loco, KeepsTheSolversTermination) {
  LocoOptions options;
  const LocoResult converged = Loco(options).solve(lineEnds(), false, freeSpace(), 0);
  EXPECT_TRUE(converged.accepted) << converged.reason;
  EXPECT_EQ(converged.termination, "CONVERGENCE") << converged.termination_message;
  EXPECT_FALSE(converged.termination_message.empty());
  options.max_iterations = 1;
  const LocoResult cut = Loco(options).solve(lineEnds(), false, wallWithGap(), 0);
  EXPECT_EQ(cut.termination, "NO_CONVERGENCE") << cut.termination_message;
}

// A pocket (walls on three sides, floor and ceiling) closed toward the goal: nothing reaches it,
// every restart is tried, and the result says why.
TEST(Loco, GivesUpInADeadEnd) {
  const Loco loco{LocoOptions{}};
  const DistanceField field = boxesField({
      boxFromCorners({1.0, -1.5, -1}, {1.2, 1.5, 4}),  // the closed end, toward the goal
      boxFromCorners({-5, 1.3, -1}, {1.0, 1.5, 4}),    // left
      boxFromCorners({-5, -1.5, -1}, {1.0, -1.3, 4}),  // right
      boxFromCorners({-5, -1.3, -1}, {1.0, 1.3, 0}),   // floor
      boxFromCorners({-5, -1.3, 3}, {1.0, 1.3, 4}),    // ceiling
  });
  ASSERT_GE(field(kStart).distance, 1.0);  // the start is well inside the pocket
  const LocoResult result = loco.solve(lineEnds(), false, field, 3);
  report("dead end", result);
  EXPECT_FALSE(result.accepted);
  EXPECT_FALSE(result.reason.empty());
  EXPECT_EQ(result.restarts, loco.options().restarts);
  EXPECT_LT(result.min_distance, loco.options().robot_radius + loco.options().clearance_margin);
  EXPECT_FALSE(result.segments.empty());  // the best attempt is still reported
}

TEST(Loco, FromInsideTheMarginOnlyAPlanThatLeavesItIsAccepted) {
  const Loco loco{LocoOptions{}};
  const double required = loco.options().robot_radius + loco.options().clearance_margin;
  // A post 0.55 m beside the start, inside the margin.
  const DistanceField post = cylinderField({0, 0.85}, 0.3);
  ASSERT_LT(post(kStart).distance, required);
  const LocoResult away = loco.solve(lineEnds(), false, post, 3);
  EXPECT_TRUE(away.accepted) << away.reason;
  EXPECT_GE(away.min_distance, post(kStart).distance - 1e-9);
  // An end 0.3 m on, still inside the margin: never closer than the start, yet refused.
  SplineEnds short_hop = lineEnds();
  short_hop.end_position = kStart + Eigen::Vector3d(0.3, 0, 0);
  ASSERT_LT(post(short_hop.end_position).distance, required);
  const LocoResult stays = loco.solve(short_hop, false, post, 3);
  EXPECT_FALSE(stays.accepted);
  EXPECT_NE(stays.reason.find("ends there too"), std::string::npos) << stays.reason;
}

TEST(Loco, RefusesAGoalInUnknownSpace) {
  const Loco loco{LocoOptions{}};
  const LocoResult result = loco.solve(lineEnds(), false, unknownBeyondX(freeSpace(), 2.0), 5);
  report("unknown beyond x = 2", result);
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("unknown"), std::string::npos) << result.reason;
  EXPECT_EQ(result.min_distance, 0);
}

TEST(Loco, RefusesBadInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  LocoOptions o;
  o.w_c = nan;
  EXPECT_THROW(Loco{o}, std::invalid_argument);
  o = LocoOptions{};
  o.restarts = -1;
  EXPECT_THROW(Loco{o}, std::invalid_argument);
  o = LocoOptions{};
  o.v_max = 0;
  EXPECT_THROW(Loco{o}, std::invalid_argument);
  // The constructor keeps the rules of the YAML declaration (it used to accept both of these).
  o = LocoOptions{};
  o.segments = 11;
  EXPECT_THROW(loadParamsFromString<LocoOptions>("segments: 11", "yaml"), ParamError);
  try {
    Loco refused{o};
    ADD_FAILURE() << "11 segments accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("segments"), std::string::npos) << e.what();
  }
  o = LocoOptions{};
  o.escape_slack = 0.5;
  EXPECT_THROW(Loco{o}, std::invalid_argument);
  EXPECT_NO_THROW(Loco{LocoOptions{}});

  const Loco loco{LocoOptions{}};
  SplineEnds ends = lineEnds();
  ends.start_position.y() = nan;
  EXPECT_THROW(loco.solve(ends, false, freeSpace(), 0), std::invalid_argument);
  EXPECT_THROW(loco.solve(ends, true, freeSpace(), 0), std::invalid_argument);
}

// 1 m/s toward a goal 0.5 m ahead: braking within the first segment times already keeps
// v_max (the start speed itself) and a_max, so the first attempt is accepted as it is.
TEST(Loco, BrakesForAGoalJustAheadWithinTheLimits) {
  const Loco loco{LocoOptions{}};
  SplineEnds ends;
  ends.start_position = kStart;
  ends.start_velocity = Eigen::Vector3d(1, 0, 0);
  ends.end_position = kStart + Eigen::Vector3d(0.5, 0, 0);
  const DistanceField field = freeSpace();
  for (bool free_end : {false, true}) {
    SCOPED_TRACE(free_end ? "free end" : "fixed end");
    const LocoResult result = loco.solve(ends, free_end, field, 0);
    report(free_end ? "1 m/s, goal 0.5 m ahead, free end" : "1 m/s, goal 0.5 m ahead, fixed end",
           result);
    ASSERT_TRUE(result.accepted) << result.reason;
    checkTrajectory(result, field, loco.options());
    printLimits(result);
    EXPECT_LT((trajectoryOf(result.segments).evaluate(0, 1) - ends.start_velocity).norm(), 1e-9);
  }
}

// 1 m/s away from a goal 0.5 m behind: turning around within the first segment times (1.2 s)
// takes more than a_max, so time is stretched until the limits hold.
TEST(Loco, StretchesTimeToKeepTheLimits) {
  const Loco loco{LocoOptions{}};
  SplineEnds ends;
  ends.start_position = kStart;
  ends.start_velocity = Eigen::Vector3d(1, 0, 0);
  ends.end_position = kStart - Eigen::Vector3d(0.5, 0, 0);
  const DistanceField field = freeSpace();
  const double first_duration = 1.2 * velocityRampTime(0.5, 1.0, 2.0);
  for (bool free_end : {false, true}) {
    SCOPED_TRACE(free_end ? "free end" : "fixed end");
    const LocoResult result = loco.solve(ends, free_end, field, 0);
    report(free_end ? "1 m/s, goal 0.5 m behind, free end" : "1 m/s, goal 0.5 m behind, fixed end",
           result);
    ASSERT_TRUE(result.accepted) << result.reason;
    checkTrajectory(result, field, loco.options());
    printLimits(result);
    // Stretching is not a restart.
    EXPECT_EQ(result.restarts, 0);
    EXPECT_GT(trajectoryOf(result.segments).duration(), first_duration * 1.04);
  }
}

// A start faster than v_max cannot be fixed by time: refused at once, saying why.
TEST(Loco, RefusesAStartAboveTheLimits) {
  const Loco loco{LocoOptions{}};
  SplineEnds ends = lineEnds(Eigen::Vector3d(1.5, 0, 0));
  LocoResult result = loco.solve(ends, false, freeSpace(), 0);
  report("1.5 m/s start", result);
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("exceeds the limits: 1.500 m/s"), std::string::npos)
      << result.reason;
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(result.termination, "");  // no solve ran
  ends = lineEnds(Eigen::Vector3d(0.5, 0, 0));
  ends.start_acceleration = Eigen::Vector3d(0, 3, 0);
  result = loco.solve(ends, false, freeSpace(), 0);
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("3.000 m/s^2"), std::string::npos) << result.reason;
}

}  // namespace
}  // namespace thicket::local_planner

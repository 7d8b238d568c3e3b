// The loco spline: boundary conditions and continuity hold on the evaluated trajectory, the
// closed-form jerk cost equals a numerical integral of the squared jerk, its gradient matches
// finite differences, and the minimum-jerk solution is the known optimum.
#include "thicket/local_planner/spline.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace thicket::local_planner {
namespace {

SplineEnds someEnds() {
  SplineEnds ends;
  ends.start_position = Eigen::Vector3d(1, 2, 1.5);
  ends.start_velocity = Eigen::Vector3d(0.6, -0.2, 0.1);
  ends.start_acceleration = Eigen::Vector3d(0.3, 0.5, -0.4);
  ends.end_position = Eigen::Vector3d(3.5, 3, 1.8);
  return ends;
}

Derivatives randomFree(const JerkSpline& spline, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<> unit(-1, 1);
  Derivatives d(spline.numFree(), 3);
  for (int i = 0; i < d.rows(); ++i) {
    for (int a = 0; a < 3; ++a) d(i, a) = unit(rng);
  }
  return d;
}

PolynomialTrajectory trajectory(const JerkSpline& spline, const Derivatives& fixed,
                                const Derivatives& free) {
  auto t = PolynomialTrajectory::create(0, spline.segments(fixed, free));
  if (!t) throw std::runtime_error(t.error());
  return *t;
}

// Simpson's rule over each segment of ||jerk||².
double integratedJerk(const PolynomialTrajectory& t) {
  double total = 0;
  double start = 0;
  for (const PolynomialSegment& s : t.segments()) {
    const int n = 2000;
    const double h = s.duration / n;
    for (int i = 0; i <= n; ++i) {
      const double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
      // Inside the segment, so the later segment's jerk is not used at its start.
      const double tau = std::clamp(i * h, 1e-12, s.duration - 1e-12);
      total += w * h / 3 * t.evaluate(start + tau, 3).squaredNorm();
    }
    start += s.duration;
  }
  return total;
}

class JerkSplineTest : public ::testing::TestWithParam<bool> {
 protected:
  bool freeEnd() const { return GetParam(); }
};

INSTANTIATE_TEST_SUITE_P(Spline, JerkSplineTest, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "FreeEnd" : "FixedEnd"; });

TEST_P(JerkSplineTest, SizesFollowTheBoundaryConditions) {
  const JerkSpline spline({0.8, 0.8, 0.8}, freeEnd());
  // 4 vertices x 5 derivatives: start p, v, a and end v, a fixed, the end position if not free.
  EXPECT_EQ(spline.numFixed(), freeEnd() ? 5 : 6);
  EXPECT_EQ(spline.numFree(), freeEnd() ? 15 : 14);
  EXPECT_EQ(spline.endPositionRow() >= 0, freeEnd());
  EXPECT_DOUBLE_EQ(spline.duration(), 2.4);
}

TEST_P(JerkSplineTest, BoundaryConditionsAndContinuityHold) {
  const JerkSpline spline({0.7, 1.1, 0.9}, freeEnd());
  const SplineEnds ends = someEnds();
  const Derivatives fixed = spline.fixedDerivatives(ends);
  const Derivatives free = randomFree(spline, 3);
  const PolynomialTrajectory t = trajectory(spline, fixed, free);
  const double tol = 1e-8;
  EXPECT_LT((t.evaluate(0, 0) - ends.start_position).norm(), tol);
  EXPECT_LT((t.evaluate(0, 1) - ends.start_velocity).norm(), tol);
  EXPECT_LT((t.evaluate(0, 2) - ends.start_acceleration).norm(), tol);
  // Just before the end, inside the last segment (after it the trajectory holds still anyway).
  const double end = t.duration() - 1e-12;
  const Eigen::Vector3d expected_end =
      freeEnd() ? free.row(spline.endPositionRow()).transpose() : ends.end_position;
  EXPECT_LT((t.evaluate(end, 0) - expected_end).norm(), tol);
  EXPECT_LT(t.evaluate(end, 1).norm(), tol);
  EXPECT_LT(t.evaluate(end, 2).norm(), tol);
  for (int derivative = 0; derivative <= 4; ++derivative) {
    EXPECT_LT(t.maxDiscontinuity(derivative), 1e-7) << "derivative " << derivative;
  }
}

TEST_P(JerkSplineTest, JerkCostIsTheIntegralOfSquaredJerk) {
  const JerkSpline spline({0.7, 1.1, 0.9}, freeEnd());
  const Derivatives fixed = spline.fixedDerivatives(someEnds());
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const Derivatives free = randomFree(spline, seed);
    const double closed_form = spline.jerkCost(fixed, free);
    const double numeric = integratedJerk(trajectory(spline, fixed, free));
    EXPECT_NEAR(closed_form, numeric, 1e-6 * numeric) << "seed " << seed;
  }
}

TEST_P(JerkSplineTest, GradientMatchesFiniteDifferences) {
  const JerkSpline spline({0.7, 1.1, 0.9}, freeEnd());
  const Derivatives fixed = spline.fixedDerivatives(someEnds());
  const Derivatives free = randomFree(spline, 5);
  Derivatives gradient;
  spline.jerkCost(fixed, free, &gradient);
  ASSERT_EQ(gradient.rows(), spline.numFree());
  const double h = 1e-5;
  for (int i = 0; i < free.rows(); ++i) {
    for (int a = 0; a < 3; ++a) {
      Derivatives plus = free, minus = free;
      plus(i, a) += h;
      minus(i, a) -= h;
      const double numeric =
          (spline.jerkCost(fixed, plus) - spline.jerkCost(fixed, minus)) / (2 * h);
      EXPECT_NEAR(gradient(i, a), numeric, 1e-5 * std::max(1.0, std::abs(numeric)))
          << "row " << i << " axis " << a;
    }
  }
}

TEST_P(JerkSplineTest, MinimumJerkIsStationaryAndBeatsPerturbations) {
  const JerkSpline spline({0.7, 1.1, 0.9}, freeEnd());
  const SplineEnds ends = someEnds();
  const Derivatives fixed = spline.fixedDerivatives(ends);
  const Derivatives best = spline.minimumJerkFree(fixed, ends.end_position);
  Derivatives gradient;
  const double cost = spline.jerkCost(fixed, best, &gradient);
  if (freeEnd()) {
    // The end was held at the goal; every other row is stationary.
    EXPECT_LT((best.row(spline.endPositionRow()).transpose() - ends.end_position).norm(), 1e-9);
    gradient.row(spline.endPositionRow()).setZero();
  }
  EXPECT_LT(gradient.norm(), 1e-6 * std::max(1.0, cost));
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    Derivatives other = best + 0.01 * randomFree(spline, seed);
    if (freeEnd()) other.row(spline.endPositionRow()) = best.row(spline.endPositionRow());
    EXPECT_GT(spline.jerkCost(fixed, other), cost);
  }
}

// Rest to rest along a line, over one segment or three, the minimum-jerk trajectory is symmetric:
// halfway in time, halfway in space.
TEST(JerkSpline, RestToRestIsSymmetric) {
  for (int segments : {1, 3}) {
    const JerkSpline spline(std::vector<double>(static_cast<size_t>(segments), 2.0 / segments),
                            false);
    SplineEnds ends;
    ends.end_position = Eigen::Vector3d(4, -2, 1);
    const Derivatives fixed = spline.fixedDerivatives(ends);
    const PolynomialTrajectory t =
        trajectory(spline, fixed, spline.minimumJerkFree(fixed, ends.end_position));
    EXPECT_LT((t.evaluate(1.0) - Eigen::Vector3d(2, -1, 0.5)).norm(), 1e-9) << segments;
    EXPECT_LT((t.evaluate(0.5) + t.evaluate(1.5) - ends.end_position).norm(), 1e-9) << segments;
  }
}

TEST(JerkSpline, SegmentTimesFollowTheVelocityRamp) {
  // 1 m/s, 2 m/s²: reaching v_max takes 0.5 s and 0.25 m; braking the same.
  EXPECT_DOUBLE_EQ(velocityRampTime(3.0, 1.0, 2.0), 3.0 + 0.5);
  EXPECT_DOUBLE_EQ(velocityRampTime(0.5, 1.0, 2.0), 1.0);    // exactly reaches v_max
  EXPECT_DOUBLE_EQ(velocityRampTime(0.125, 1.0, 2.0), 0.5);  // triangular
  EXPECT_DOUBLE_EQ(velocityRampTime(0, 1.0, 2.0), 0);
  const std::vector<double> times = segmentTimes(3.0, 1.0, 2.0);
  ASSERT_EQ(times.size(), 3u);
  for (double t : times) EXPECT_DOUBLE_EQ(t, 1.2 * 3.5 / 3);
  EXPECT_DOUBLE_EQ(segmentTimes(0, 1.0, 2.0, 3, 1.2, 0.3)[0], 0.1);  // the minimum total
}

TEST(JerkSpline, RefusesBadInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(JerkSpline({}, false), std::invalid_argument);
  EXPECT_THROW(JerkSpline({1.0, 0.0}, false), std::invalid_argument);
  EXPECT_THROW(JerkSpline({1.0, nan}, false), std::invalid_argument);
  EXPECT_THROW(JerkSpline({-1.0}, true), std::invalid_argument);
  EXPECT_THROW(velocityRampTime(-1, 1, 2), std::invalid_argument);
  EXPECT_THROW(velocityRampTime(1, 0, 2), std::invalid_argument);
  EXPECT_THROW(velocityRampTime(1, 1, nan), std::invalid_argument);
  EXPECT_THROW(segmentTimes(1, 1, 2, 0), std::invalid_argument);

  const JerkSpline spline({1.0, 1.0, 1.0}, false);
  SplineEnds ends = someEnds();
  ends.start_velocity.y() = nan;
  EXPECT_THROW(spline.fixedDerivatives(ends), std::invalid_argument);
  ends = someEnds();
  ends.end_position.x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(spline.fixedDerivatives(ends), std::invalid_argument);
  // A free end ignores the goal.
  EXPECT_NO_THROW(JerkSpline({1.0}, true).fixedDerivatives(ends));
  const Derivatives fixed = spline.fixedDerivatives(someEnds());
  EXPECT_THROW(spline.jerkCost(fixed, Derivatives::Zero(3, 3)), std::invalid_argument);
  EXPECT_THROW(spline.segments(Derivatives::Zero(2, 3), Derivatives::Zero(14, 3)),
               std::invalid_argument);
}

}  // namespace
}  // namespace thicket::local_planner

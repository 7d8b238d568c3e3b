#include "thicket/common/polynomial_trajectory.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace thicket {
namespace {

using Coefficients = Eigen::Matrix<double, 3, Eigen::Dynamic>;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int64_t kStartUtime = 1'700'000'000'000'000;

PolynomialTrajectory makeTrajectory(std::vector<PolynomialSegment> segments) {
  Expected<PolynomialTrajectory> trajectory = PolynomialTrajectory::create(kStartUtime, segments);
  EXPECT_TRUE(trajectory.ok()) << trajectory.error();
  return std::move(trajectory).value();
}

Coefficients randomCoefficients(std::mt19937& rng, int num_coefficients) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Coefficients c(3, num_coefficients);
  for (int a = 0; a < 3; ++a) {
    for (int k = 0; k < num_coefficients; ++k) c(a, k) = uniform(rng);
  }
  return c;
}

// The same polynomial written in tau' = tau - shift (its Taylor expansion around shift):
// c'_j = sum_{k >= j} C(k, j) shift^(k-j) c_k.
Coefficients reexpand(const Coefficients& c, double shift) {
  Coefficients result = Coefficients::Zero(3, c.cols());
  for (Eigen::Index j = 0; j < c.cols(); ++j) {
    double binomial = 1;  // C(k, j), starting at k = j
    for (Eigen::Index k = j; k < c.cols(); ++k) {
      result.col(j) += binomial * std::pow(shift, static_cast<double>(k - j)) * c.col(k);
      binomial = binomial * static_cast<double>(k + 1) / static_cast<double>(k + 1 - j);
    }
  }
  return result;
}

void expectRejected(const Expected<PolynomialTrajectory>& result,
                    const std::vector<std::string>& words) {
  ASSERT_FALSE(result.ok());
  for (const std::string& word : words) EXPECT_THAT(result.error(), HasSubstr(word));
}

TEST(PolynomialTrajectoryTest, EvaluatesQuinticAndItsDerivativesAnalytically) {
  Coefficients c(3, 6);
  c << 1.0, -2.0, 0.5, 3.0, -1.0, 0.25,  //
      0.0, 1.0, 2.0, -3.0, 4.0, -5.0,    //
      -3.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  const PolynomialTrajectory trajectory = makeTrajectory({{2.0, c}});
  auto col = [&](int k) -> Eigen::Vector3d { return c.col(k); };
  for (double t : {0.0, 0.3, 1.0, 1.7, 2.0}) {
    const double t2 = t * t, t3 = t2 * t, t4 = t3 * t, t5 = t4 * t;
    const std::vector<Eigen::Vector3d> expected = {
        col(0) + col(1) * t + col(2) * t2 + col(3) * t3 + col(4) * t4 + col(5) * t5,
        col(1) + 2 * col(2) * t + 3 * col(3) * t2 + 4 * col(4) * t3 + 5 * col(5) * t4,
        2 * col(2) + 6 * col(3) * t + 12 * col(4) * t2 + 20 * col(5) * t3,
        6 * col(3) + 24 * col(4) * t + 60 * col(5) * t2,
        24 * col(4) + 120 * col(5) * t,
        120 * col(5),
        Eigen::Vector3d::Zero(),
        Eigen::Vector3d::Zero(),
    };
    for (int r = 0; r < static_cast<int>(expected.size()); ++r) {
      EXPECT_LE((trajectory.evaluate(t, r) - expected[r]).norm(), 1e-12 * (1 + expected[r].norm()))
          << "t " << t << " derivative " << r;
    }
  }
  const TrajectoryState state = trajectory.state(1.0);
  EXPECT_EQ(state.position, trajectory.evaluate(1.0, 0));
  EXPECT_EQ(state.velocity, trajectory.evaluate(1.0, 1));
  EXPECT_EQ(state.acceleration, trajectory.evaluate(1.0, 2));
  EXPECT_EQ(state.jerk, trajectory.evaluate(1.0, 3));
}

TEST(PolynomialTrajectoryTest, DerivativesMatchCentralFiniteDifferences) {
  std::mt19937 rng(20180516);
  std::vector<PolynomialSegment> segments;
  std::uniform_real_distribution<double> duration(0.5, 1.2);
  for (int s = 0; s < 3; ++s) segments.push_back({duration(rng), randomCoefficients(rng, 10)});
  const PolynomialTrajectory trajectory = makeTrajectory(segments);

  constexpr double h = 1e-5;
  std::uniform_int_distribution<int> pick_segment(0, 2);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int s = pick_segment(rng);
    double segment_start = 0;
    for (int i = 0; i < s; ++i) segment_start += segments[i].duration;
    // Stay 2h inside the segment so that both difference points see the same polynomial.
    const double t = segment_start + 2 * h + unit(rng) * (segments[s].duration - 4 * h);
    for (int r = 1; r <= 5; ++r) {
      const Eigen::Vector3d analytic = trajectory.evaluate(t, r);
      const Eigen::Vector3d numeric =
          (trajectory.evaluate(t + h, r - 1) - trajectory.evaluate(t - h, r - 1)) / (2 * h);
      EXPECT_LT((analytic - numeric).norm(), 1e-5 * (1 + analytic.norm()))
          << "t " << t << " derivative " << r;
    }
  }
}

TEST(PolynomialTrajectoryTest, SplitPolynomialEvaluatesLikeTheUnsplitOne) {
  std::mt19937 rng(7);
  const Coefficients c = randomCoefficients(rng, 10);
  const PolynomialTrajectory whole = makeTrajectory({{3.0, c}});
  const std::vector<double> splits = {0.0, 0.7, 1.9, 3.0};
  std::vector<PolynomialSegment> pieces;
  for (size_t i = 0; i + 1 < splits.size(); ++i) {
    pieces.push_back({splits[i + 1] - splits[i], reexpand(c, splits[i])});
  }
  const PolynomialTrajectory split = makeTrajectory(pieces);

  EXPECT_EQ(split.numSegments(), 3);
  EXPECT_NEAR(split.duration(), 3.0, 1e-15);
  for (int r = 0; r <= 2; ++r) EXPECT_LT(split.maxDiscontinuity(r), 1e-9) << "derivative " << r;
  for (int i = 0; i <= 300; ++i) {
    const double t = 0.01 * i;
    for (int r = 0; r <= 4; ++r) {
      EXPECT_LT((split.evaluate(t, r) - whole.evaluate(t, r)).norm(), 1e-9)
          << "t " << t << " derivative " << r;
    }
  }
}

TEST(PolynomialTrajectoryTest, MaxDiscontinuityReportsTheLargestJump) {
  Coefficients first(3, 2), second(3, 2), third(3, 2);
  first << 0, 1, 0, 0, 0, 0;   // ends at (1, 0, 0) with velocity (1, 0, 0)
  second << 1, 1, 3, 0, 4, 2;  // starts at (1, 3, 4): a 5 m jump; velocity jumps by 2
  third << 2, 1, 3, 0, 6, 2;   // continuous with the end of second
  const PolynomialTrajectory trajectory =
      makeTrajectory({{1.0, first}, {1.0, second}, {1.0, third}});
  EXPECT_DOUBLE_EQ(trajectory.maxDiscontinuity(0), 5.0);
  EXPECT_DOUBLE_EQ(trajectory.maxDiscontinuity(1), 2.0);
  EXPECT_DOUBLE_EQ(trajectory.maxDiscontinuity(2), 0.0);
  EXPECT_THROW(trajectory.maxDiscontinuity(-1), std::invalid_argument);
  EXPECT_EQ(PolynomialTrajectory::hover(0, Eigen::Vector3d(1, 2, 3), 1.0).maxDiscontinuity(0), 0.0);
}

TEST(PolynomialTrajectoryTest, ExactBoundaryBelongsToTheLaterSegment) {
  // Deliberately discontinuous constant segments, so the value tells which segment answered.
  std::vector<PolynomialSegment> segments;
  for (int s = 0; s < 3; ++s) {
    segments.push_back({0.1 * (s + 1), Coefficients::Constant(3, 1, static_cast<double>(s))});
  }
  const PolynomialTrajectory trajectory = makeTrajectory(segments);
  const double first_boundary = 0.1;
  const double second_boundary = 0.1 + 0.2;  // 0.30000000000000004, accumulated like the class
  EXPECT_EQ(trajectory.evaluate(std::nextafter(first_boundary, 0.0)).x(), 0.0);
  EXPECT_EQ(trajectory.evaluate(first_boundary).x(), 1.0);
  EXPECT_EQ(trajectory.evaluate(std::nextafter(second_boundary, 0.0)).x(), 1.0);
  EXPECT_EQ(trajectory.evaluate(second_boundary).x(), 2.0);
  EXPECT_EQ(trajectory.evaluate(trajectory.duration()).x(), 2.0);

  // Linear segments: the local time restarts at zero on the boundary.
  Coefficients ramp(3, 2), steep(3, 2);
  ramp << 0, 1, 0, 0, 0, 0;
  steep << 10, 2, 0, 0, 0, 0;
  const PolynomialTrajectory linear = makeTrajectory({{1.0, ramp}, {2.0, steep}});
  EXPECT_DOUBLE_EQ(linear.evaluate(1.0).x(), 10.0);
  EXPECT_DOUBLE_EQ(linear.evaluate(1.0, 1).x(), 2.0);
  EXPECT_DOUBLE_EQ(linear.evaluate(0.5).x(), 0.5);
  EXPECT_DOUBLE_EQ(linear.evaluate(0.5, 1).x(), 1.0);
  EXPECT_DOUBLE_EQ(linear.evaluate(3.0).x(), 14.0);
  EXPECT_DOUBLE_EQ(linear.evaluate(3.0, 1).x(), 2.0);  // the end itself is still inside
}

TEST(PolynomialTrajectoryTest, StartStateBeforeStartAndRestAfterEnd) {
  Coefficients c(3, 6);
  c << 1, 2, 3, 4, 5, 6,  //
      -1, 0.5, -0.25, 1, 0, 2, 0, 0, 1, 0, 0, 1;
  const PolynomialTrajectory trajectory = makeTrajectory({{0.8, c}, {0.7, reexpand(c, 0.8)}});
  const double end = trajectory.duration();
  for (int r = 0; r <= 4; ++r) {
    EXPECT_EQ(trajectory.evaluate(-1.0, r), trajectory.evaluate(0.0, r)) << r;
    EXPECT_EQ(trajectory.evaluate(-kInf, r), trajectory.evaluate(0.0, r)) << r;
  }
  ASSERT_FALSE(trajectory.evaluate(end, 1).isZero());  // so that holding at rest is a real change
  for (double t : {std::nextafter(end, kInf), end + 1.0, kInf}) {
    EXPECT_EQ(trajectory.evaluate(t), trajectory.evaluate(end)) << t;
    for (int r = 1; r <= 4; ++r) EXPECT_TRUE(trajectory.evaluate(t, r).isZero()) << t << " " << r;
  }
  const TrajectoryState after = trajectory.state(end + 2.0);
  EXPECT_EQ(after.position, trajectory.evaluate(end));
  EXPECT_TRUE(after.velocity.isZero());
  EXPECT_TRUE(after.acceleration.isZero());
  EXPECT_TRUE(after.jerk.isZero());
}

TEST(PolynomialTrajectoryTest, RefusesNegativeDerivativeAndNaNTime) {
  const PolynomialTrajectory trajectory =
      PolynomialTrajectory::hover(0, Eigen::Vector3d::Zero(), 1);
  EXPECT_THROW(trajectory.evaluate(0.5, -1), std::invalid_argument);
  EXPECT_THROW(trajectory.evaluate(kNaN), std::invalid_argument);
}

TEST(PolynomialTrajectoryTest, AccessorsDescribeTheSegments) {
  std::mt19937 rng(3);
  const PolynomialTrajectory trajectory = makeTrajectory({{0.5, randomCoefficients(rng, 4)},
                                                          {1.0, randomCoefficients(rng, 4)},
                                                          {1.5, randomCoefficients(rng, 4)}});
  EXPECT_EQ(trajectory.startUtime(), kStartUtime);
  EXPECT_EQ(trajectory.numSegments(), 3);
  EXPECT_EQ(trajectory.numCoefficients(), 4);
  EXPECT_DOUBLE_EQ(trajectory.duration(), 3.0);
  ASSERT_EQ(trajectory.segments().size(), 3u);
  EXPECT_EQ(trajectory.segments()[1].duration, 1.0);
}

TEST(PolynomialTrajectoryTest, SamplesOnAnIndexedGridAndEndsExactlyAtT1) {
  Coefficients c(3, 2);
  c << 0, 1, 0, 2, 0, 0;
  const PolynomialTrajectory trajectory = makeTrajectory({{1.0, c}});

  const auto samples = trajectory.sample(0.3);
  ASSERT_EQ(samples.size(), 5u);  // 0, 0.3, 0.6, 0.9, 1.0
  for (size_t i = 0; i + 1 < samples.size(); ++i) {
    EXPECT_EQ(samples[i].first, static_cast<double>(i) * 0.3);
  }
  EXPECT_EQ(samples.front().first, 0.0);
  EXPECT_EQ(samples.back().first, 1.0);
  for (const auto& [t, state] : samples) {
    EXPECT_EQ(state.position, trajectory.evaluate(t));
    EXPECT_EQ(state.velocity, trajectory.evaluate(t, 1));
  }

  // An end on the grid, exactly or within 1e-9 s, is not sampled twice.
  EXPECT_EQ(trajectory.sample(0.25).size(), 5u);
  EXPECT_EQ(trajectory.sample(0.1).size(), 11u);
  const auto nearly = trajectory.sample((1.0 - 5e-10) / 4);
  ASSERT_EQ(nearly.size(), 5u);
  EXPECT_EQ(nearly.back().first, 1.0);

  // A sub-interval, reaching past the end, and a degenerate one.
  const auto window = trajectory.sample(0.25, 0.5, 1.6);
  ASSERT_EQ(window.size(), 6u);  // 0.5, 0.75, 1.0, 1.25, 1.5, 1.6
  EXPECT_EQ(window.front().first, 0.5);
  EXPECT_EQ(window.back().first, 1.6);
  EXPECT_TRUE(window.back().second.velocity.isZero());
  ASSERT_EQ(trajectory.sample(0.1, 0.4, 0.4).size(), 1u);

  // 10000 steps of 0.1 s accumulated would drift; indexed times do not.
  const auto many = trajectory.sample(0.1, 0.0, 1000.0);
  ASSERT_EQ(many.size(), 10001u);
  EXPECT_EQ(many[7777].first, 7777 * 0.1);
  EXPECT_EQ(many.back().first, 1000.0);
}

TEST(PolynomialTrajectoryTest, SampleRefusesBadStepsAndIntervals) {
  const PolynomialTrajectory trajectory =
      PolynomialTrajectory::hover(0, Eigen::Vector3d::Zero(), 1);
  for (double dt : {0.0, -0.1, kNaN, kInf}) {
    EXPECT_THROW(trajectory.sample(dt), std::invalid_argument) << dt;
  }
  EXPECT_THROW(trajectory.sample(0.1, 0.5, 0.4), std::invalid_argument);
  EXPECT_THROW(trajectory.sample(0.1, 0.0, kInf), std::invalid_argument);
  EXPECT_THROW(trajectory.sample(0.1, kNaN, 1.0), std::invalid_argument);
  EXPECT_THROW(trajectory.maxSpeed(0.0), std::invalid_argument);
}

TEST(PolynomialTrajectoryTest, MaxSpeedAndAccelerationOverSamples) {
  // A constant-velocity line at 3 m/s, in two continuous segments.
  Coefficients line(3, 2);
  line << 1, 1, 2, 2, 3, 2;
  const PolynomialTrajectory straight = makeTrajectory({{1.0, line}, {2.0, reexpand(line, 1.0)}});
  EXPECT_NEAR(straight.maxSpeed(0.1), 3.0, 1e-12);
  EXPECT_NEAR(straight.maxAcceleration(0.1), 0.0, 1e-12);

  // Uniform acceleration of 2 m/s² from rest: the top speed is at the end, off the 0.3 s grid.
  Coefficients parabola(3, 3);
  parabola << 0, 0, 1, 0, 0, 0, 0, 0, 0;
  const PolynomialTrajectory accelerating = makeTrajectory({{2.0, parabola}});
  EXPECT_DOUBLE_EQ(accelerating.maxSpeed(0.3), 4.0);
  EXPECT_DOUBLE_EQ(accelerating.maxAcceleration(0.3), 2.0);
}

TEST(PolynomialTrajectoryTest, HoverHoldsAPositionAtRest) {
  const Eigen::Vector3d position(1.5, -2.0, 1.2);
  const PolynomialTrajectory hover = PolynomialTrajectory::hover(kStartUtime, position, 2.5);
  EXPECT_EQ(hover.startUtime(), kStartUtime);
  EXPECT_EQ(hover.numSegments(), 1);
  EXPECT_EQ(hover.numCoefficients(), 1);
  EXPECT_EQ(hover.duration(), 2.5);
  for (double t : {-1.0, 0.0, 1.3, 2.5, 4.0}) {
    EXPECT_EQ(hover.evaluate(t), position);
    EXPECT_TRUE(hover.evaluate(t, 1).isZero());
  }
  EXPECT_EQ(hover.maxSpeed(0.1), 0.0);
  EXPECT_THROW(PolynomialTrajectory::hover(0, position, 0.0), std::invalid_argument);
  EXPECT_THROW(PolynomialTrajectory::hover(0, Eigen::Vector3d(kNaN, 0, 0), 1.0),
               std::invalid_argument);
}

TEST(PolynomialTrajectoryTest, StateAtUtimeConvertsMicroseconds) {
  Coefficients c(3, 4);
  c << 0, 1, 0.5, 0.1, 1, 0, -1, 0.2, 2, 0.3, 0, 0;
  const PolynomialTrajectory trajectory = makeTrajectory({{3.0, c}});
  const TrajectoryState mid = trajectory.stateAtUtime(kStartUtime + 1'250'000);
  EXPECT_EQ(mid.position, trajectory.evaluate(1.25));
  EXPECT_EQ(mid.velocity, trajectory.evaluate(1.25, 1));
  EXPECT_EQ(mid.acceleration, trajectory.evaluate(1.25, 2));
  EXPECT_EQ(mid.jerk, trajectory.evaluate(1.25, 3));
  EXPECT_EQ(trajectory.stateAtUtime(kStartUtime - 1'000'000).position, trajectory.evaluate(0.0));
  EXPECT_TRUE(trajectory.stateAtUtime(kStartUtime + 3'000'001).velocity.isZero());
}

TEST(PolynomialTrajectoryTest, LcmRoundTripIsBitExact) {
  std::mt19937 rng(42);
  std::vector<PolynomialSegment> segments;
  for (int s = 0; s < 3; ++s) {
    Coefficients c = randomCoefficients(rng, 10) * std::pow(10.0, 3 * s - 3);
    c(0, 0) = 1.0 / 3.0;
    c(1, 9) = -0.0;
    c(2, 5) = std::numeric_limits<double>::denorm_min();
    segments.push_back({0.1 + s / 7.0, c});
  }
  const PolynomialTrajectory original = makeTrajectory(segments);
  const polynomial_trajectory_t sent =
      original.toLcm(17, 4, polynomial_trajectory_t::YAW_CONSTANT, 0.75);

  std::vector<uint8_t> buffer(sent.getEncodedSize());
  ASSERT_EQ(sent.encode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  polynomial_trajectory_t received;
  ASSERT_EQ(received.decode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  EXPECT_EQ(received.utime, kStartUtime);
  EXPECT_EQ(received.cycle, 17);
  EXPECT_EQ(received.goal_id, 4);
  EXPECT_EQ(static_cast<int>(received.yaw_policy),
            static_cast<int>(polynomial_trajectory_t::YAW_CONSTANT));
  EXPECT_EQ(received.yaw, 0.75);

  const Expected<PolynomialTrajectory> decoded = PolynomialTrajectory::fromLcm(received);
  ASSERT_TRUE(decoded.ok()) << decoded.error();
  EXPECT_EQ(decoded->startUtime(), original.startUtime());
  ASSERT_EQ(decoded->numSegments(), original.numSegments());
  ASSERT_EQ(decoded->numCoefficients(), original.numCoefficients());
  for (int s = 0; s < original.numSegments(); ++s) {
    const PolynomialSegment& a = original.segments()[s];
    const PolynomialSegment& b = decoded->segments()[s];
    EXPECT_EQ(std::memcmp(&a.duration, &b.duration, sizeof(double)), 0) << s;
    EXPECT_EQ(std::memcmp(a.coefficients.data(), b.coefficients.data(),
                          sizeof(double) * a.coefficients.size()),
              0)
        << s;
  }
}

TEST(PolynomialTrajectoryTest, ToLcmRefusesBadYaw) {
  const PolynomialTrajectory hover = PolynomialTrajectory::hover(0, Eigen::Vector3d::Zero(), 1);
  EXPECT_THROW(hover.toLcm(0, -1, 5), std::invalid_argument);
  EXPECT_THROW(hover.toLcm(0, -1, polynomial_trajectory_t::YAW_CONSTANT, kNaN),
               std::invalid_argument);
  EXPECT_EQ(static_cast<int>(hover.toLcm(0, -1).yaw_policy),
            static_cast<int>(polynomial_trajectory_t::YAW_ALONG_VELOCITY));
}

TEST(PolynomialTrajectoryTest, CreateRefusesInvalidSegmentsAndSaysWhy) {
  const Coefficients six = Coefficients::Ones(3, 6);
  const auto withSegment = [&](int index, PolynomialSegment bad) {
    std::vector<PolynomialSegment> segments(3, PolynomialSegment{1.0, six});
    segments[index] = std::move(bad);
    return PolynomialTrajectory::create(0, std::move(segments));
  };
  Coefficients nan_y3 = six, inf_z0 = six;
  nan_y3(1, 3) = kNaN;
  inf_z0(2, 0) = -kInf;

  expectRejected(PolynomialTrajectory::create(0, {}), {"at least one segment"});
  expectRejected(withSegment(2, {-0.5, six}), {"segment 2", "duration -0.5 s is not positive"});
  expectRejected(withSegment(0, {0.0, six}), {"segment 0", "duration 0 s is not positive"});
  expectRejected(withSegment(1, {kNaN, six}), {"segment 1", "duration", "not finite"});
  expectRejected(withSegment(1, {kInf, six}), {"segment 1", "duration", "not finite"});
  expectRejected(withSegment(1, {1.0, nan_y3}), {"segment 1", "tau^3", "axis y", "not finite"});
  expectRejected(withSegment(2, {1.0, inf_z0}), {"segment 2", "tau^0", "axis z", "not finite"});
  expectRejected(withSegment(1, {1.0, Coefficients(3, 0)}), {"segment 1", "no coefficients"});
  expectRejected(withSegment(2, {1.0, Coefficients::Ones(3, 4)}),
                 {"segment 2", "4 coefficients", "segment 0 has 6"});
  expectRejected(PolynomialTrajectory::create(0, {{1.0, Coefficients(3, 0)}}),
                 {"segment 0", "no coefficients"});
}

TEST(PolynomialTrajectoryTest, FromLcmRefusesInconsistentMessagesAndSaysWhy) {
  std::mt19937 rng(11);
  const polynomial_trajectory_t valid =
      makeTrajectory({{1.0, randomCoefficients(rng, 6)}, {2.0, randomCoefficients(rng, 6)}})
          .toLcm(3, 9);
  ASSERT_TRUE(PolynomialTrajectory::fromLcm(valid).ok());
  const auto mutated = [&](const auto& mutate) {
    polynomial_trajectory_t msg = valid;
    mutate(msg);
    return PolynomialTrajectory::fromLcm(msg);
  };
  using Msg = polynomial_trajectory_t;
  expectRejected(mutated([](Msg& m) { m.num_segments = 0; }), {"num_segments 0"});
  expectRejected(mutated([](Msg& m) { m.num_segments = -3; }), {"num_segments -3"});
  expectRejected(mutated([](Msg& m) { m.num_segments = 1001; }), {"num_segments 1001", "1000"});
  expectRejected(mutated([](Msg& m) { m.num_coefficients = 0; }), {"num_coefficients 0"});
  expectRejected(mutated([](Msg& m) { m.num_coefficients = 33; }), {"num_coefficients 33", "32"});
  expectRejected(mutated([](Msg& m) { m.num_segments = 3; }),
                 {"durations has 2 entries", "num_segments is 3"});
  expectRejected(mutated([](Msg& m) { m.durations.pop_back(); }),
                 {"durations has 1 entries", "num_segments is 2"});
  expectRejected(mutated([](Msg& m) { m.coefficients.pop_back(); }),
                 {"coefficients has 1 segments", "num_segments is 2"});
  expectRejected(mutated([](Msg& m) { m.coefficients[1].pop_back(); }),
                 {"segment 1", "2 axes, not 3"});
  expectRejected(mutated([](Msg& m) { m.coefficients[0][2].push_back(1.0); }),
                 {"segment 0", "axis z", "7 coefficients", "num_coefficients is 6"});
  expectRejected(mutated([](Msg& m) { m.num_coefficients = 5; }),
                 {"segment 0", "axis x", "6 coefficients", "num_coefficients is 5"});
  expectRejected(mutated([](Msg& m) { m.durations[1] = kNaN; }),
                 {"segment 1", "duration", "not finite"});
  expectRejected(mutated([](Msg& m) { m.durations[0] = -1.0; }),
                 {"segment 0", "duration -1 s is not positive"});
  expectRejected(mutated([](Msg& m) { m.coefficients[1][0][2] = kInf; }),
                 {"segment 1", "tau^2", "axis x", "not finite"});
  expectRejected(mutated([](Msg& m) { m.coefficients[0][1][5] = kNaN; }),
                 {"segment 0", "tau^5", "axis y", "not finite"});
  expectRejected(mutated([](Msg& m) { m.yaw_policy = 7; }), {"unknown yaw_policy 7"});
  expectRejected(mutated([](Msg& m) { m.yaw = kNaN; }), {"yaw", "not finite"});
  expectRejected(mutated([](Msg& m) { m.yaw = -kInf; }), {"yaw", "not finite"});
}

}  // namespace
}  // namespace thicket

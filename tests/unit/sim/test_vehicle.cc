// The simulated vehicle against analytic expectations: where it is after executing known
// polynomials, where it first touches a cylinder, which trajectories it refuses.
#include <gtest/gtest.h>

#include <cmath>

#include "sim_test_support.h"
#include "thicket/sim/vehicle.h"

namespace thicket::sim {
namespace {

using testing::corridor;
using testing::restToRest;

// x(t) = x0 + v t per axis, one segment.
polynomial_trajectory_t line(int64_t start_utime, const Eigen::Vector3d& from,
                             const Eigen::Vector3d& velocity, double duration) {
  PolynomialSegment segment{duration, Eigen::Matrix<double, 3, Eigen::Dynamic>(3, 2)};
  segment.coefficients.col(0) = from;
  segment.coefficients.col(1) = velocity;
  return PolynomialTrajectory::create(start_utime, {segment})->toLcm(0, 1);
}

struct VehicleTest : ::testing::Test {
  World world = corridor();
  GroundTruth truth{world};
};

TEST_F(VehicleTest, HoldsAtTheStartWithoutATrajectory) {
  Vehicle vehicle(truth, {});
  const StepReport report = vehicle.step();
  EXPECT_EQ(report.samples.size(), 100u);
  EXPECT_EQ(report.outcome, Outcome::kRunning);
  EXPECT_EQ(vehicle.cycle(), 1);
  EXPECT_EQ(vehicle.utime(), 1'000'000);
  EXPECT_EQ(vehicle.state().position, world.start);
  EXPECT_EQ(vehicle.pathLength(), 0.0);
  EXPECT_DOUBLE_EQ(vehicle.state().yaw, 0.0);  // facing the goal along +x
  EXPECT_FALSE(vehicle.hasTrajectory());
}

TEST_F(VehicleTest, ExecutesOneReplanPeriodPerStep) {
  Vehicle vehicle(truth, {});
  ASSERT_EQ(vehicle.commit(line(0, world.start, Eigen::Vector3d(0.6, 0.8, 0), 30)), std::nullopt);
  for (int i = 0; i < 3; ++i) vehicle.step();
  EXPECT_TRUE(vehicle.state().position.isApprox(world.start + Eigen::Vector3d(1.8, 2.4, 0), 1e-12));
  EXPECT_NEAR(vehicle.pathLength(), 3.0, 1e-9);
  EXPECT_NEAR(vehicle.state().yaw, std::atan2(0.8, 0.6), 1e-12);
  EXPECT_EQ(vehicle.path().size(), 301u);
  EXPECT_EQ(vehicle.path()[150].utime, 1'500'000);
  EXPECT_TRUE(vehicle.feasible());
  EXPECT_NEAR(vehicle.maxSpeed(), 1.0, 1e-12);
}

TEST_F(VehicleTest, TurnsTowardTheCommandedYawNoFasterThanTheLimit) {
  VehicleOptions options;
  options.max_yaw_rate = 2.0;
  Vehicle vehicle(truth, options);
  ASSERT_EQ(vehicle.commit(line(0, world.start, Eigen::Vector3d(0.5, 0, 0), 30)), std::nullopt);
  vehicle.step();
  vehicle.step();
  // Flying back: along the velocity means a half turn, which takes pi / 2 s at 2 rad/s.
  ASSERT_EQ(
      vehicle.commit(line(2'000'000, vehicle.state().position, Eigen::Vector3d(-0.5, 0, 0), 30)),
      std::nullopt);
  vehicle.step();
  double previous = 0;
  for (size_t i = 201; i < vehicle.path().size(); ++i) {
    const double yaw = vehicle.path()[i].yaw;
    EXPECT_LE(std::abs(std::remainder(yaw - previous, 2 * M_PI)), 2.0 * 0.01 + 1e-12) << i;
    previous = yaw;
  }
  EXPECT_NEAR(std::abs(vehicle.state().yaw), 2.0, 1e-9);  // still turning after 1 s
  vehicle.step();
  EXPECT_NEAR(std::abs(vehicle.state().yaw), M_PI, 1e-9);  // then along the velocity

  // A constant-yaw trajectory: the vehicle turns to that yaw whatever its velocity, and holds it.
  polynomial_trajectory_t constant =
      line(4'000'000, vehicle.state().position, Eigen::Vector3d(0.5, 0, 0), 30);
  constant.yaw_policy = polynomial_trajectory_t::YAW_CONSTANT;
  constant.yaw = M_PI / 2;
  ASSERT_EQ(vehicle.commit(constant), std::nullopt);
  vehicle.step();
  EXPECT_NEAR(vehicle.state().yaw, M_PI / 2, 1e-9);
  EXPECT_NEAR(vehicle.path()[400 + 50].yaw, M_PI - 1.0, 1e-9);  // halfway through the turn
}

TEST_F(VehicleTest, ReportsTheFirstSampleInsideTheRobotRadius) {
  world = corridor({{5.0, 5.0, 0.5, 4.0}});
  GroundTruth with_tree(world);
  Vehicle vehicle(with_tree, {});
  ASSERT_FALSE(vehicle.commit(line(0, world.start, Eigen::Vector3d(1, 0, 0), 30)));
  StepReport report;
  while (vehicle.outcome() == Outcome::kRunning) report = vehicle.step();
  EXPECT_EQ(vehicle.outcome(), Outcome::kCollision);
  ASSERT_TRUE(report.collision.has_value());
  // Clearance to the cylinder is (5 - x) - 0.5: below the 0.5 m radius once x > 4.
  EXPECT_NEAR(report.collision->position.x(), 4.01, 1e-9);
  EXPECT_LT(report.collision->clearance, 0.5);
  EXPECT_EQ(vehicle.cycle(), 4);
  EXPECT_EQ(report.samples.back().utime, report.collision->utime);  // execution stops there
  EXPECT_NEAR(vehicle.minClearance(), report.collision->clearance, 1e-12);
  EXPECT_TRUE(vehicle.commit(line(vehicle.utime(), world.start, Eigen::Vector3d::Zero(), 1)));
}

TEST_F(VehicleTest, ReachesTheGoalAndStops) {
  Vehicle vehicle(truth, {});
  ASSERT_FALSE(vehicle.commit(restToRest(0, world.start, world.goal, 15.0)));
  while (vehicle.outcome() == Outcome::kRunning) vehicle.step();
  EXPECT_EQ(vehicle.outcome(), Outcome::kGoalReached);
  // 0.2 m short of 9 m on a cubic profile is reached between 13 and 14 s.
  EXPECT_EQ(vehicle.cycle(), 14);
  EXPECT_LE(vehicle.distanceToGoal(), 0.2);
  EXPECT_TRUE(vehicle.feasible());
  const size_t samples = vehicle.path().size();
  EXPECT_EQ(vehicle.step().outcome, Outcome::kGoalReached);
  EXPECT_EQ(vehicle.path().size(), samples);
}

TEST_F(VehicleTest, EndsAtTheReplanLimit) {
  VehicleOptions options;
  options.replan_limit = 3;
  Vehicle vehicle(truth, options);
  vehicle.step();
  vehicle.step();
  EXPECT_EQ(vehicle.outcome(), Outcome::kRunning);
  vehicle.step();
  EXPECT_EQ(vehicle.outcome(), Outcome::kReplanLimit);
}

TEST_F(VehicleTest, HoldsTheEndOfAFinishedTrajectory) {
  Vehicle vehicle(truth, {});
  const Eigen::Vector3d end = world.start + Eigen::Vector3d(1, 0, 0);
  ASSERT_FALSE(vehicle.commit(restToRest(0, world.start, end, 1.5)));
  vehicle.step();
  vehicle.step();
  vehicle.step();
  EXPECT_TRUE(vehicle.state().position.isApprox(end, 1e-12));
  EXPECT_EQ(vehicle.state().velocity, Eigen::Vector3d::Zero());
}

TEST_F(VehicleTest, FlagsLimitViolationsAndTheCeiling) {
  Vehicle fast(truth, {});
  ASSERT_FALSE(fast.commit(line(0, world.start, Eigen::Vector3d(2, 0, 0), 10)));
  fast.step();
  EXPECT_FALSE(fast.feasible());

  Vehicle climber(truth, {});
  ASSERT_FALSE(climber.commit(line(0, world.start, Eigen::Vector3d(0, 0, 1), 10)));
  while (climber.outcome() == Outcome::kRunning) climber.step();
  EXPECT_EQ(climber.outcome(), Outcome::kCollision);
  EXPECT_GT(climber.state().position.z(), world.bounds_max.z());
}

TEST_F(VehicleTest, RefusesMalformedAndMistimedTrajectoriesAndKeepsTheOldOne) {
  Vehicle vehicle(truth, {});
  ASSERT_FALSE(vehicle.commit(line(0, world.start, Eigen::Vector3d(1, 0, 0), 30)));
  vehicle.step();
  vehicle.step();
  vehicle.step();  // now at 3 s

  polynomial_trajectory_t nan = line(3'000'000, world.start, Eigen::Vector3d(0, 1, 0), 5);
  nan.coefficients[0][1][0] = std::nan("");
  auto refused = vehicle.commit(nan);
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("malformed"), std::string::npos) << *refused;

  polynomial_trajectory_t empty = nan;
  empty.num_segments = 0;
  empty.durations.clear();
  empty.coefficients.clear();
  EXPECT_TRUE(vehicle.commit(empty));

  refused = vehicle.commit(line(3'200'000, world.start, Eigen::Vector3d(0, 1, 0), 5));
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("in the future"), std::string::npos) << *refused;
  refused = vehicle.commit(line(500'000, world.start, Eigen::Vector3d(0, 1, 0), 5));
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("ago"), std::string::npos) << *refused;

  vehicle.step();
  EXPECT_TRUE(vehicle.state().position.isApprox(world.start + Eigen::Vector3d(4, 0, 0), 1e-12));
}

TEST(VehicleOptions, RefusesNonsense) {
  World world = corridor();
  GroundTruth truth(world);
  VehicleOptions options;
  options.sample_period = 0;
  EXPECT_THROW(Vehicle(truth, options), std::invalid_argument);
  options = {};
  options.sample_period = 2.0;
  EXPECT_THROW(Vehicle(truth, options), std::invalid_argument);
  // The rules of its YAML declaration hold for options built in code too: a 2 s sample period
  // within a 5 s replan period and a zero speed limit used to be accepted.
  options = {};
  options.replan_period = 5.0;
  options.sample_period = 2.0;
  EXPECT_THROW(Vehicle(truth, options), std::invalid_argument);
  options = {};
  options.v_max = 0;
  EXPECT_THROW(Vehicle(truth, options), std::invalid_argument);
  EXPECT_NO_THROW(Vehicle(truth, VehicleOptions{}));
}

}  // namespace
}  // namespace thicket::sim

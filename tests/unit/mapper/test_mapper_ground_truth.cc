// The whole mapping pipeline against the simulator's ground truth: depth frames rendered along a
// flight through forest50 go through the Mapper (pose pairing, TSDF, incremental ESDF), and the
// ESDF the planner reads is compared with the true distance to the nearest obstacle.
//
// The planner accepts a sample when its interpolated ESDF distance is at least robot radius +
// clearance margin. That is safe only if, wherever the vehicle would be in collision (true
// distance below the robot radius), the map reads less than robot radius + margin: the mapper
// certifies this bound, measured on flown maps of every scenario by `thicket-bench clearance`
// (README, "The certified clearance"), and the planner's margin is derived from it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "forest_views.h"
#include "thicket/common/esdf_query.h"
#include "thicket/mapper/mapper.h"

namespace thicket::mapper {
namespace {

// The certified bound at the default 0.1 m voxels: wherever the true clearance is below the robot
// radius, the interpolated ESDF reads at most this much above the robot radius [m].
constexpr double kCertifiedBound = 0.11;
constexpr double kRobotRadius = 0.5;
constexpr double kHorizon = 3.0;

// The paper world (density 0.3, seed 0), whose walls the vehicle sees at a slant when it flies
// along them.
const sim::World& paperWorld() {
  static const sim::World world = benchmarkWorld("paper", 0.3, 0);
  return world;
}

// A flight from `from` toward `to` that also looks at tree tops, flanks and walls: a view every
// 0.5 m, the altitude stepping through 1.5, 2.5 and 3.5 m and the heading swinging 30 degrees
// either way of the direction of flight; views within the robot radius of an obstacle skipped.
std::vector<Frame> variedFlight(const sim::World& world, const Eigen::Vector3d& from,
                                const Eigen::Vector3d& to, int count) {
  const sim::GroundTruth truth(world);
  const sim::DepthRenderer renderer(world, sim::DepthCameraOptions{});
  const Eigen::Vector3d direction = (to - from).normalized();
  const double heading = std::atan2(direction.y(), direction.x());
  std::vector<Frame> frames;
  for (double s = 0; static_cast<int>(frames.size()) < count; s += 0.5) {
    if (s > (to - from).norm()) throw std::runtime_error("variedFlight: too many views");
    const int k = static_cast<int>(frames.size());
    Eigen::Vector3d p = from + s * direction;
    p.z() = 1.5 + (k % 3);
    if (truth.distance(p) <= world.robot_radius) continue;
    const double yaw = heading + (k % 4 - 1.5) * 0.35;
    frames.push_back(renderFrame(renderer, Pose::fromYaw(p, yaw), (k + 1) * 1'000'000));
  }
  return frames;
}

// Through the forest along its start-goal diagonal, and along the paper world's wall at y = 0, 1 m
// from it.
std::vector<Frame> forestFlight() {
  const sim::World& world = forest();
  return variedFlight(world, world.start + 2.0 * (world.goal - world.start).normalized(),
                      world.goal, 30);
}
std::vector<Frame> wallFlight() {
  return variedFlight(paperWorld(), {1.5, 1.0, 1.5}, {13.5, 1.0, 1.5}, 12);
}

struct Overestimate {
  int points = 0;            // mapped points in collision (true distance below the robot radius)
  double above_radius = -1;  // the largest ESDF reading there minus the robot radius [m]
  double worst_error = 0;    // the largest ESDF - true distance there [m]
};

// After every frame of `frames`, random points within the horizon of the vehicle.
Overestimate flyAndMeasure(const sim::World& world, const MapperOptions& options,
                           const std::vector<Frame>& frames) {
  const sim::GroundTruth truth(world);
  Mapper mapper{options};
  Overestimate result;
  std::vector<MapRevisionUpdate> updates;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const Frame& frame : frames) {
    EXPECT_TRUE(mapper.addPose(frame.image.utime, frame.world_T_body).accepted());
    EXPECT_EQ(mapper.addFrame(frame.image).status, FrameOutcome::Status::kPending);
    for (const FrameOutcome& outcome : mapper.integrateReady(updates)) {
      EXPECT_EQ(outcome.status, FrameOutcome::Status::kIntegrated) << outcome.reason;
    }
    for (int i = 0; i < 20000; ++i) {
      const Eigen::Vector3d offset(unit(rng), unit(rng), unit(rng));
      if (offset.squaredNorm() > 1) continue;
      const Eigen::Vector3d p = frame.world_T_body.position + kHorizon * offset;
      const double d = truth.distance(p);
      if (!(d > 0 && d < kRobotRadius)) continue;
      const EsdfSample e = sampleEsdf(mapper.esdf(), p);
      if (!e.known || !tsdfObservedAround(mapper.tsdf(), p)) continue;
      ++result.points;
      result.above_radius = std::max(result.above_radius, e.distance - kRobotRadius);
      result.worst_error = std::max(result.worst_error, e.distance - d);
    }
  }
  return result;
}

TEST(MapperGroundTruth, WhereTheVehicleWouldCollideTheEsdfStaysBelowTheCertifiedBound) {
  for (const auto& [name, world, frames] : {std::tuple{"forest", &forest(), forestFlight()},
                                            std::tuple{"wall", &paperWorld(), wallFlight()}}) {
    const Overestimate defaults = flyAndMeasure(*world, MapperOptions{}, frames);
    std::printf(
        "%s: %d points in collision; the ESDF reads up to %.3f m above the robot radius "
        "(certified %.2f), up to %.3f m above the true distance\n",
        name, defaults.points, defaults.above_radius, kCertifiedBound, defaults.worst_error);
    EXPECT_GT(defaults.points, 2000) << name;
    EXPECT_LE(defaults.above_radius, kCertifiedBound) << name;
  }
}

// The bound is the defaults' doing: distances along the line of sight stretch where a surface is
// seen at a slant, and without sites at the TSDF's zero crossings nothing marks the surface
// between the stretched values on either side of it. Flying along a wall breaks the bound then.
TEST(MapperGroundTruth, LineOfSightDistancesWithoutCrossingSitesBreakTheBound) {
  MapperOptions options;
  options.tsdf.normal_distances = false;
  options.esdf.crossing_sites = false;
  const Overestimate plain = flyAndMeasure(paperWorld(), options, wallFlight());
  std::printf("along the wall, line of sight and band sites only: up to %.3f m above the radius\n",
              plain.above_radius);
  EXPECT_GT(plain.above_radius, kCertifiedBound + 0.05);
}

}  // namespace
}  // namespace thicket::mapper

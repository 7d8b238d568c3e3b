// The simulator's dynamic obstacle: where and when it appears, that the ground truth and the
// cameras see it from its first frame on, that it blocks the committed path, and which options
// are refused. The node runs on a memq:// LCM, stepped by hand or by a scripted lockstep planner.
#include "thicket/sim/dynamic_obstacle.h"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <thicket/depth_image_t.hpp>
#include <thicket/sim_world_t.hpp>
#include <thicket/stereo_image_t.hpp>

#include "sim_node.h"
#include "sim_test_support.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/loop.h"

namespace thicket::sim {
namespace {

using testing::restToRest;

// The corridor with one tree beyond the goal; the mission flies along y = 5 in +x.
World corridor(uint64_t seed = 7) {
  World world = testing::corridor({{14.0, 5.0, 0.5, 4.0}});
  world.seed = seed;
  return world;
}

SimOptions obstacleOptions(double appear_time) {
  SimOptions options;
  options.depth_camera.width = 64;
  options.depth_camera.height = 48;
  options.dynamic_obstacle.enabled = true;
  options.dynamic_obstacle.appear_time = appear_time;
  return options;
}

// A SimNode stepped by hand (no lockstep) with what it publishes.
struct Trial {
  Trial(const SimOptions& options, World world) : sim(lcm, options, std::move(world)) {
    planner.subscribe<sim_event_t>(
        "SIM_EVENT", [this](const sim_event_t& msg, const MessageInfo&) { events.push_back(msg); });
    planner.subscribe<sim_world_t>(
        "SIM_WORLD", [this](const sim_world_t& msg, const MessageInfo&) { worlds.push_back(msg); });
    planner.subscribe<depth_image_t>(
        "CAMERA_DEPTH", [this](const depth_image_t& msg, const MessageInfo&) {
          auto image = decodeDepthImage(msg);
          ASSERT_TRUE(image) << image.error();
          frames.push_back(std::move(*image));
          const PathSample& state = sim.vehicle().state();
          frame_poses.push_back(Pose::fromYaw(state.position, state.yaw));
        });
  }
  void commit(const polynomial_trajectory_t& trajectory) {
    planner.publish("PLANNER_TRAJECTORY", trajectory);
    loop.drain();
  }
  void start() {
    sim.start();
    loop.drain();
  }
  void step() {
    sim.advance();
    loop.drain();
  }

  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  Node planner{"planner", lcm};
  SimNode sim;
  std::vector<sim_event_t> events;
  std::vector<sim_world_t> worlds;
  std::vector<DepthImage> frames;
  std::vector<Pose> frame_poses;  // the body pose each frame was rendered from
};

// Flies the corridor mission straight to the goal (15 s, no replanning) until the obstacle
// appears, at most `frames` frames.
AppearedObstacle appearOnTheMission(const SimOptions& options, const World& world, int frames = 5) {
  Trial trial(options, world);
  trial.commit(restToRest(0, world.start, world.goal, 15));
  trial.start();
  for (int i = 1; i < frames && !trial.sim.dynamicObstacle(); ++i) trial.step();
  EXPECT_TRUE(trial.sim.dynamicObstacle());
  return trial.sim.dynamicObstacle().value_or(AppearedObstacle{});
}

TEST(SimDynamicObstacle, DrawsAreSeededAndWithinTheOptions) {
  DynamicObstacleOptions options;
  const DynamicObstacleDraw a = drawDynamicObstacle(options, 7);
  const DynamicObstacleDraw b = drawDynamicObstacle(options, 7);
  EXPECT_EQ(a.distance_ahead, b.distance_ahead);
  EXPECT_EQ(a.lateral_offset, b.lateral_offset);
  const DynamicObstacleDraw c = drawDynamicObstacle(options, 8);
  EXPECT_NE(a.distance_ahead, c.distance_ahead);
  EXPECT_NE(a.lateral_offset, c.lateral_offset);
  bool left = false, right = false;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    const DynamicObstacleDraw draw = drawDynamicObstacle(options, seed);
    EXPECT_GE(draw.distance_ahead, options.distance_ahead_min);
    EXPECT_LE(draw.distance_ahead, options.distance_ahead_max);
    EXPECT_LE(std::abs(draw.lateral_offset), options.lateral_offset);
    left |= draw.lateral_offset > 0;
    right |= draw.lateral_offset < 0;
  }
  EXPECT_TRUE(left && right);
}

// Along the parabola (1 + t, 5 + t^2, 1.5) the path length from t = a to b is F(b) - F(a) with
// F(t) = t sqrt(1 + 4 t^2) / 2 + asinh(2 t) / 4.
TEST(SimDynamicObstacle, TheAxisIsTheDrawnPathLengthAheadAndOffsetToTheLeft) {
  PolynomialSegment segment{3.0, Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, 3)};
  segment.coefficients.col(0) = Eigen::Vector3d(1, 5, 1.5);
  segment.coefficients(0, 1) = 1;
  segment.coefficients(1, 2) = 1;
  const PolynomialTrajectory parabola = *PolynomialTrajectory::create(0, {segment});
  const auto F = [](double t) { return t * std::sqrt(1 + 4 * t * t) / 2 + std::asinh(2 * t) / 4; };
  const double t0 = 0.5;
  const DynamicObstacleDraw draw{2.0, 0.3};
  double lo = t0, hi = 3.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = (lo + hi) / 2;
    (F(mid) - F(t0) < draw.distance_ahead ? lo : hi) = mid;
  }
  const Eigen::Vector2d foot(1 + lo, 5 + lo * lo);
  const Eigen::Vector2d left = Eigen::Vector2d(-2 * lo, 1).normalized();  // tangent (1, 2t)

  const auto axis = dynamicObstacleAxis(parabola, 500'000, draw, 1e-4);
  ASSERT_TRUE(axis);
  EXPECT_NEAR((*axis - (foot + 0.3 * left)).norm(), 0, 1e-3);
  // The vehicle's own sampling (0.01 s) puts it within a centimetre.
  EXPECT_NEAR((*dynamicObstacleAxis(parabola, 500'000, draw, 0.01) - *axis).norm(), 0, 0.01);

  // Not when less path is left.
  const double remaining = F(3.0) - F(t0);
  EXPECT_FALSE(dynamicObstacleAxis(parabola, 500'000, {remaining + 0.01, 0}, 1e-4));
  EXPECT_TRUE(dynamicObstacleAxis(parabola, 500'000, {remaining - 0.01, 0}, 1e-4));
  EXPECT_FALSE(dynamicObstacleAxis(parabola, 3'000'000, {0.01, 0}, 1e-4));
}

TEST(SimDynamicObstacle, AppearsAtTheFirstFrameAtOrAfterItsTimeAtTheDrawnDistanceAhead) {
  const World world = corridor(7);
  const SimOptions options = obstacleOptions(1.5);
  Trial trial(options, world);
  trial.commit(restToRest(0, world.start, world.goal, 15));
  trial.start();
  trial.step();
  EXPECT_FALSE(trial.sim.dynamicObstacle());  // frame 1, t = 1 s
  EXPECT_EQ(trial.worlds.size(), 1u);
  trial.step();
  ASSERT_TRUE(trial.sim.dynamicObstacle());  // frame 2, t = 2 s
  const AppearedObstacle& obstacle = *trial.sim.dynamicObstacle();
  EXPECT_EQ(obstacle.utime, 2'000'000);
  EXPECT_EQ(obstacle.frame, 2);

  // The path is straight along +x, so the drawn distance ahead is along x and left is +y.
  const DynamicObstacleDraw draw = drawDynamicObstacle(options.dynamic_obstacle, 7);
  const Eigen::Vector3d& position = trial.sim.vehicle().state().position;
  EXPECT_NEAR(obstacle.cylinder.x, position.x() + draw.distance_ahead, 1e-9);
  EXPECT_NEAR(obstacle.cylinder.y, 5 + draw.lateral_offset, 1e-9);
  EXPECT_NE(draw.lateral_offset, 0);
  EXPECT_EQ(obstacle.cylinder.radius, 0.5);
  EXPECT_EQ(obstacle.cylinder.height, world.bounds_max.z());  // height 0: the height limit
  // Where it appears, the vehicle's clearance to it (so far the smallest).
  EXPECT_NEAR(obstacle.min_clearance, std::hypot(draw.distance_ahead, draw.lateral_offset) - 0.5,
              1e-9);

  // In the world, re-published on SIM_WORLD and announced on SIM_EVENT, before frame 2.
  ASSERT_EQ(trial.sim.world().cylinders.size(), 2u);
  EXPECT_EQ(trial.sim.world().cylinders.back().x, obstacle.cylinder.x);
  ASSERT_EQ(trial.worlds.size(), 2u);
  EXPECT_EQ(trial.worlds[1].utime, 2'000'000);
  ASSERT_EQ(trial.worlds[1].num_cylinders, 2);
  EXPECT_EQ(trial.worlds[1].cylinder_x[1], obstacle.cylinder.x);
  EXPECT_EQ(trial.worlds[1].cylinder_y[1], obstacle.cylinder.y);
  EXPECT_EQ(trial.worlds[1].cylinder_radius[1], 0.5);
  const sim_event_t& info = trial.events.back();
  EXPECT_EQ(info.type, +sim_event_t::TYPE_INFO);
  EXPECT_EQ(info.utime, 2'000'000);
  EXPECT_EQ(info.message.rfind("dynamic obstacle appeared at frame 2 (t = 2.00 s)", 0), 0u)
      << info.message;
  EXPECT_EQ(trial.frames.size(), 3u);

  // Nothing more appears later.
  trial.step();
  EXPECT_EQ(trial.sim.world().cylinders.size(), 2u);
  EXPECT_EQ(trial.worlds.size(), 2u);
}

TEST(SimDynamicObstacle, TheSameSeedPlacesItTheSameWayAnotherSeedNot) {
  const SimOptions options = obstacleOptions(2.0);
  const AppearedObstacle a = appearOnTheMission(options, corridor(7));
  const AppearedObstacle b = appearOnTheMission(options, corridor(7));
  const AppearedObstacle c = appearOnTheMission(options, corridor(8));
  EXPECT_EQ(a.cylinder.x, b.cylinder.x);
  EXPECT_EQ(a.cylinder.y, b.cylinder.y);
  EXPECT_EQ(a.utime, c.utime);
  EXPECT_NE(a.cylinder.x, c.cylinder.x);
  EXPECT_NE(a.cylinder.y, c.cylinder.y);
}

// The depth along the pixel nearest to the direction of `target`, and the range to the
// obstacle's side along that pixel's ray, as optical z, computed analytically.
struct PixelDepth {
  double rendered = 0;
  double analytic = 0;
};
PixelDepth depthToward(const DepthImage& image, const Pose& world_T_body,
                       const Eigen::Vector3d& target, const Cylinder& cylinder) {
  const Pose world_T_camera = world_T_body * image.camera_in_body;
  const auto uv = image.camera.project(world_T_camera.inverse().transform(target));
  EXPECT_TRUE(uv && image.camera.inImage(*uv));
  if (!uv) return {};
  const int u = static_cast<int>(std::lround(uv->x()));
  const int v = static_cast<int>(std::lround(uv->y()));
  // The ray with optical z = 1 meets the side at the parameter that is its depth.
  const Eigen::Vector3d ray =
      world_T_camera.orientation.toRotationMatrix() * image.camera.backProject(u, v, 1.0);
  const Eigen::Vector2d d = ray.head<2>();
  const Eigen::Vector2d o =
      world_T_camera.position.head<2>() - Eigen::Vector2d(cylinder.x, cylinder.y);
  const double a = d.squaredNorm(), b = 2 * d.dot(o),
               c = o.squaredNorm() - std::pow(cylinder.radius, 2);
  PixelDepth depth;
  depth.analytic = (-b - std::sqrt(b * b - 4 * a * c)) / (2 * a);
  depth.rendered = image.depth[static_cast<size_t>(v) * image.camera.width + u];
  return depth;
}

TEST(SimDynamicObstacle, TheGroundTruthAndTheCamerasSeeItFromItsFirstFrameOnly) {
  const World world = corridor(7);
  SimOptions options = obstacleOptions(2.0);
  options.dynamic_obstacle.lateral_offset = 0;  // straight ahead, in the middle of the image
  Trial trial(options, world);
  const polynomial_trajectory_t mission = restToRest(0, world.start, world.goal, 15);
  trial.commit(mission);
  trial.start();
  trial.step();
  // Frame 1, before: where it is going to stand is free.
  const std::optional<Eigen::Vector2d> axis =
      dynamicObstacleAxis(*PolynomialTrajectory::fromLcm(mission), 2'000'000,
                          drawDynamicObstacle(options.dynamic_obstacle, 7), 0.01);
  ASSERT_TRUE(axis);
  // 0.3 m in front of its side, higher than the ground's distance.
  const Eigen::Vector3d in_front(axis->x() - 0.8, 5, 2.5);
  EXPECT_EQ(trial.sim.groundTruth().distance(in_front), 2.5);  // the ground
  trial.step();
  ASSERT_TRUE(trial.sim.dynamicObstacle());
  const Cylinder& cylinder = trial.sim.dynamicObstacle()->cylinder;
  EXPECT_EQ(Eigen::Vector2d(cylinder.x, cylinder.y), *axis);
  EXPECT_NEAR(trial.sim.groundTruth().distance(in_front), 0.3, 1e-9);
  EXPECT_DOUBLE_EQ(trial.sim.groundTruth().distance(in_front),
                   cylinderDistance(cylinder, in_front));

  ASSERT_EQ(trial.frames.size(), 3u);
  for (int frame : {1, 2}) {
    const Eigen::Vector3d eye = trial.frame_poses[frame].position;
    const Eigen::Vector3d target(cylinder.x - cylinder.radius, cylinder.y, eye.z());
    const PixelDepth depth =
        depthToward(trial.frames[frame], trial.frame_poses[frame], target, cylinder);
    EXPECT_GT(depth.analytic, 1.0);
    if (frame == 2) {
      EXPECT_NEAR(depth.rendered, depth.analytic, 1e-3);  // millimetre depth encoding
    } else {
      EXPECT_GT(depth.rendered, depth.analytic + 5.0);  // the tree at x = 14 or the wall
    }
  }
}

TEST(SimDynamicObstacle, TheStereoPairShowsItToo) {
  const World world = corridor(7);
  SimOptions options = obstacleOptions(2.0);
  options.sensor = "stereo";
  options.stereo_camera.width = 64;
  options.stereo_camera.height = 48;
  Trial trial(options, world);
  std::vector<std::vector<uint8_t>> lefts;
  trial.planner.subscribe<stereo_image_t>(
      "STEREO",
      [&](const stereo_image_t& msg, const MessageInfo&) { lefts.push_back(msg.left.data); });
  trial.commit(restToRest(0, world.start, world.goal, 15));
  trial.start();
  trial.step();
  trial.step();
  ASSERT_TRUE(trial.sim.dynamicObstacle());
  ASSERT_EQ(lefts.size(), 3u);

  // The frame is what a renderer of the world with the obstacle sees, not one without it.
  const PathSample& state = trial.sim.vehicle().state();
  const Pose body = Pose::fromYaw(state.position, state.yaw);
  std::vector<uint8_t> left, right;
  StereoRenderer(trial.sim.world(), options.stereo_camera).render(body, left, right);
  EXPECT_EQ(lefts[2], left);
  StereoRenderer(world, options.stereo_camera).render(body, left, right);
  EXPECT_NE(lefts[2], left);
}

// Answers every depth frame with a final status; commits one trajectory to the goal on the first
// and never replans, as a planner without a re-check of its committed path would.
class BlindPlanner : public Node {
 public:
  BlindPlanner(lcm::LCM& lcm, const World& world) : Node("planner", lcm) {
    subscribe<depth_image_t>(
        "CAMERA_DEPTH", [this, world](const depth_image_t& msg, const MessageInfo&) {
          if (frames++ == 0) {
            publish("PLANNER_TRAJECTORY", restToRest(msg.utime, world.start, world.goal, 15));
          }
          planner_status_t status{};
          status.utime = msg.utime;
          status.is_final = true;
          publish("PLANNER_STATUS", status);
        });
    subscribe<sim_event_t>(
        "SIM_EVENT", [this](const sim_event_t& msg, const MessageInfo&) { events.push_back(msg); });
  }
  int frames = 0;
  std::vector<sim_event_t> events;
};

struct Mission {
  Outcome outcome;
  std::string end_reason;
  std::optional<AppearedObstacle> obstacle;
  double min_clearance;
  std::vector<sim_event_t> events;
};

Mission flyBlindly(SimOptions options, const World& world) {
  options.lockstep = true;
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  SimNode sim(lcm, options, world);
  BlindPlanner planner(lcm, world);
  sim.start();
  while (loop.drain() > 0 && !sim.finished()) {
  }
  EXPECT_TRUE(sim.finished());
  return {sim.vehicle().outcome(), sim.endReason(), sim.dynamicObstacle(),
          sim.vehicle().minClearance(), planner.events};
}

TEST(SimDynamicObstacle, AVehicleThatKeepsFlyingItsCommittedPathHitsIt) {
  const World world = corridor(7);
  SimOptions options = obstacleOptions(3.0);
  options.dynamic_obstacle.enabled = false;
  const Mission clear = flyBlindly(options, world);
  EXPECT_EQ(clear.outcome, Outcome::kGoalReached);
  EXPECT_FALSE(clear.obstacle);

  options.dynamic_obstacle.enabled = true;
  const Mission blocked = flyBlindly(options, world);
  EXPECT_EQ(blocked.outcome, Outcome::kCollision);
  EXPECT_EQ(blocked.end_reason, "collision");
  ASSERT_TRUE(blocked.obstacle);
  EXPECT_EQ(blocked.obstacle->utime, 3'000'000);
  EXPECT_LT(blocked.obstacle->min_clearance, world.robot_radius);
  EXPECT_DOUBLE_EQ(blocked.min_clearance, blocked.obstacle->min_clearance);

  // Announced, then the collision against it, then the end.
  ASSERT_GE(blocked.events.size(), 4u);
  const size_t n = blocked.events.size();
  EXPECT_EQ(blocked.events[n - 3].type, +sim_event_t::TYPE_INFO);
  EXPECT_EQ(blocked.events[n - 2].type, +sim_event_t::TYPE_COLLISION);
  EXPECT_EQ(blocked.events[n - 1].type, +sim_event_t::TYPE_TRIAL_END);
  EXPECT_EQ(blocked.events[n - 1].outcome, +sim_event_t::OUTCOME_COLLISION);
  const Eigen::Vector3d hit(blocked.events[n - 2].position[0], blocked.events[n - 2].position[1],
                            blocked.events[n - 2].position[2]);
  const double to_obstacle = cylinderDistance(blocked.obstacle->cylinder, hit);
  EXPECT_LT(to_obstacle, world.robot_radius);
  EXPECT_GT(to_obstacle, world.robot_radius - 0.02);  // the first sample inside, at <= 1 m/s
}

TEST(SimDynamicObstacle, WaitsForATrajectoryWithEnoughPathLeft) {
  const World world = corridor(7);
  const SimOptions options = obstacleOptions(0.0);
  Trial trial(options, world);
  trial.start();
  EXPECT_FALSE(trial.sim.dynamicObstacle());  // frame 0: no trajectory yet
  // A hop of 2 m, less than any drawn distance, ending at t = 3 s.
  const Eigen::Vector3d hop = world.start + Eigen::Vector3d(2, 0, 0);
  trial.commit(restToRest(0, world.start, hop, 3));
  for (int frame = 1; frame <= 3; ++frame) {
    trial.step();
    EXPECT_FALSE(trial.sim.dynamicObstacle()) << "frame " << frame;
  }
  EXPECT_EQ(trial.sim.vehicle().state().position, hop);
  trial.commit(restToRest(3'000'000, hop, world.goal, 10));
  trial.step();
  ASSERT_TRUE(trial.sim.dynamicObstacle());
  EXPECT_EQ(trial.sim.dynamicObstacle()->frame, 4);
  EXPECT_EQ(trial.sim.dynamicObstacle()->utime, 4'000'000);
  const DynamicObstacleDraw draw = drawDynamicObstacle(options.dynamic_obstacle, 7);
  EXPECT_NEAR(trial.sim.dynamicObstacle()->cylinder.x,
              trial.sim.vehicle().state().position.x() + draw.distance_ahead, 1e-9);
}

TEST(SimDynamicObstacle, WaitsWhileThePathWindsBackOntoTheVehicle) {
  const World world = corridor(7);
  SimOptions options = obstacleOptions(0.0);
  options.dynamic_obstacle.distance_ahead_min = 2.2;
  options.dynamic_obstacle.distance_ahead_max = 2.2;
  options.dynamic_obstacle.lateral_offset = 0;
  // 1.5 m out along +x and back, 3 s each way: 2.2 m of path ahead end 0.8 m from the start.
  const auto leg = [](const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    return *PolynomialTrajectory::fromLcm(restToRest(0, from, to, 3));
  };
  const Eigen::Vector3d turn = world.start + Eigen::Vector3d(1.5, 0, 0);
  std::vector<PolynomialSegment> segments = leg(world.start, turn).segments();
  segments.push_back(leg(turn, world.start).segments().front());
  const PolynomialTrajectory there_and_back = *PolynomialTrajectory::create(0, segments);
  const auto axis = dynamicObstacleAxis(there_and_back, 0, {2.2, 0}, 0.01);
  ASSERT_TRUE(axis);  // enough path is left at frame 0: the vehicle's clearance is what waits
  EXPECT_NEAR(axis->x(), world.start.x() + 0.8, 1e-6);

  Trial trial(options, world);
  trial.commit(there_and_back.toLcm(0, 1));
  trial.start();
  for (int frame = 1; frame <= 8; ++frame) trial.step();
  EXPECT_FALSE(trial.sim.dynamicObstacle());
  EXPECT_EQ(trial.sim.vehicle().outcome(), Outcome::kRunning);
  EXPECT_EQ(trial.worlds.size(), 1u);
}

TEST(SimDynamicObstacle, BadOptionsAreRefused) {
  for (const char* yaml :
       {"dynamic_obstacle: {radius: 0}", "dynamic_obstacle: {lateral_offset: -0.1}",
        "dynamic_obstacle: {appear_time: -1}", "dynamic_obstacle: {height: -1}",
        "dynamic_obstacle: {distance_ahead_min: 0}", "dynamic_obstacle: {distance_ahead_max: 0}",
        "dynamic_obstacle: {enabled: 1.5}"}) {
    EXPECT_THROW(loadParamsFromString<SimOptions>(yaml, "test"), ParamError) << yaml;
  }
  EXPECT_NO_THROW(loadParamsFromString<SimOptions>(
      "dynamic_obstacle: {enabled: true, distance_ahead_min: 3, distance_ahead_max: 3}", "test"));

  lcm::LCM lcm("memq://");
  const auto refusal = [&](const SimOptions& options, const World& world) -> std::string {
    try {
      SimNode sim(lcm, options, world);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  SimOptions options = obstacleOptions(1.0);
  EXPECT_EQ(refusal(options, corridor()), "");
  // Too close to clear a 0.5 m obstacle with a 0.5 m robot.
  options.dynamic_obstacle.distance_ahead_min = 1.0;
  EXPECT_NE(refusal(options, corridor()).find("distance_ahead_min (1 m) must exceed radius"),
            std::string::npos)
      << refusal(options, corridor());
  // The same options are fine for a smaller robot, and when the obstacle is off.
  World small_robot = corridor();
  small_robot.robot_radius = 0.4;
  EXPECT_EQ(refusal(options, small_robot), "");
  options.dynamic_obstacle.enabled = false;
  EXPECT_EQ(refusal(options, corridor()), "");
  // Options built in code skip the Params checks, so the node checks them itself.
  options = obstacleOptions(1.0);
  options.dynamic_obstacle.distance_ahead_max = 1.9;
  EXPECT_NE(refusal(options, corridor()).find("distance_ahead_max"), std::string::npos);
  options = obstacleOptions(1.0);
  options.dynamic_obstacle.radius = -1;
  EXPECT_NE(refusal(options, corridor()).find("radius"), std::string::npos);
}

}  // namespace
}  // namespace thicket::sim

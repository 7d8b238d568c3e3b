#include "sim_node.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <thicket/goal_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/sim_world_t.hpp>
#include <thicket/stereo_image_t.hpp>

#include "thicket/common/depth_image.h"
#include "thicket/common/time.h"

namespace thicket::sim {

void SimOptions::declare(Params& p) {
  p("scenario", scenario, "world scenario: a name in worlds_dir or a path to a .yaml");
  p("density", density, "cylinders per m^2 of the obstacle region", Range::between(0, 10));
  p("seed", seed, "world seed (trial i of a benchmark uses seed base + i)");
  p("worlds_dir", worlds_dir, "where scenario names are looked up; empty: config/worlds");
  p.choice("sensor", sensor, {"depth", "stereo"}, "publish CAMERA_DEPTH or STEREO");
  p("lockstep", lockstep, "wait for the planner's final status of each frame before stepping");
  p("rate", rate, "cycles per wall-clock second without lockstep [Hz]",
    Range::between(0.001, 1000));
  p("lockstep_timeout", lockstep_timeout,
    "wall-clock seconds without any final planner status in lockstep before aborting [s]",
    Range::positive());
  p("lockstep_step_on", lockstep_step_on,
    "wall-clock seconds a frame waits for its final planner status in lockstep before the "
    "simulator steps on without it, as in real time (a restarted or starved module gets a new "
    "frame and estimate); 0: never [s]",
    Range::atLeast(0));
  p("odometry_rate", odometry_rate, "odometry messages per simulated second [Hz]",
    Range::between(0.1, 1000));
  p.group("vehicle", vehicle, "the simulated vehicle and mission limits");
  p.group("depth_camera", depth_camera, "the depth camera (sensor: depth)");
  p.group("stereo_camera", stereo_camera, "the stereo camera (sensor: stereo)");
  p.group("odometry", odometry, "VIO-like drift and noise on VIO_ODOMETRY (off by default)");
  p.group("dynamic_obstacle", dynamic_obstacle,
          "a cylinder that appears in the committed path during the trial (off by default)");
}

namespace {

image_t grayImage(int64_t utime, const std::string& camera, int width, int height,
                  std::vector<uint8_t> pixels) {
  image_t image{};
  image.utime = utime;
  image.camera_id = camera;
  image.width = width;
  image.height = height;
  image.row_stride = width;
  image.pixel_format = image_t::PIXEL_GRAY8;
  image.encoding = image_t::ENCODING_RAW;
  image.data = std::move(pixels);
  image.size = static_cast<int32_t>(image.data.size());
  return image;
}

}  // namespace

SimNode::SimNode(lcm::LCM& lcm, const SimOptions& options, World world)
    : Node("sim", lcm),
      options_(options),
      world_(std::move(world)),
      truth_(world_),
      vehicle_(truth_, options.vehicle),
      odometry_(options.odometry) {
  if (options_.dynamic_obstacle.enabled) {
    if (const std::string error =
            dynamicObstacleError(options_.dynamic_obstacle, world_.robot_radius);
        !error.empty()) {
      throw std::invalid_argument("dynamic_obstacle: " + error);
    }
    dynamic_draw_ = drawDynamicObstacle(options_.dynamic_obstacle, world_.seed);
  }
  buildCamera();
  last_odometry_ = vehicle_.state();
  subscribe<polynomial_trajectory_t>(
      "PLANNER_TRAJECTORY",
      [this](const polynomial_trajectory_t& msg, const MessageInfo&) { onTrajectory(msg); });
  subscribe<planner_status_t>(
      "PLANNER_STATUS",
      [this](const planner_status_t& msg, const MessageInfo&) { onPlannerStatus(msg); }, 1000);
}

void SimNode::buildCamera() {
  if (options_.sensor == "stereo") {
    stereo_ = std::make_unique<StereoRenderer>(world_, options_.stereo_camera);
  } else {
    depth_ = std::make_unique<DepthRenderer>(world_, options_.depth_camera);
  }
}

void SimNode::start() {
  publishWorld();
  // The simulated operator: the world's goal is the mission.
  publishMissionGoal();
  publishEvent(sim_event_t::TYPE_TRIAL_START,
               "scenario " + world_.scenario + ", density " + std::to_string(world_.density) +
                   ", seed " + std::to_string(world_.seed) + ", " +
                   std::to_string(world_.cylinders.size()) + " cylinders");
  publishOdometry(vehicle_.state());
  updateDynamicObstacle();
  publishFrame();
}

void SimNode::publishMissionGoal() {
  goal_t goal{};
  goal.utime = vehicle_.utime();
  goal.goal_id = 1;
  goal.source = goal_t::SOURCE_OPERATOR;
  goal.cycle = -1;
  goal.status = goal_t::STATUS_OK;
  goal.yaw_policy = goal_t::YAW_ALONG_VELOCITY;
  goal.waypoints = {{world_.goal.x(), world_.goal.y(), world_.goal.z()}};
  goal.yaws = {0.0};
  goal.num_waypoints = 1;
  publish("MISSION_GOAL", goal);
  goal_sent_for_frame_ = frame_;
}

void SimNode::publishWorld() {
  sim_world_t msg{};
  msg.utime = vehicle_.utime();
  msg.scenario = world_.scenario;
  msg.density = world_.density;
  msg.seed = static_cast<int64_t>(world_.seed);
  for (int i = 0; i < 3; ++i) {
    msg.bounds_min[i] = world_.bounds_min[i];
    msg.bounds_max[i] = world_.bounds_max[i];
    msg.start[i] = world_.start[i];
    msg.goal[i] = world_.goal[i];
  }
  msg.robot_radius = world_.robot_radius;
  for (const Cylinder& c : world_.cylinders) {
    msg.cylinder_x.push_back(c.x);
    msg.cylinder_y.push_back(c.y);
    msg.cylinder_radius.push_back(c.radius);
    msg.cylinder_height.push_back(c.height);
  }
  msg.num_cylinders = static_cast<int32_t>(world_.cylinders.size());
  publish("SIM_WORLD", msg);
}

void SimNode::updateDynamicObstacle() {
  const DynamicObstacleOptions& o = options_.dynamic_obstacle;
  if (!o.enabled || dynamic_obstacle_) return;
  const PathSample& state = vehicle_.state();
  const int64_t since_start = state.utime - vehicle_.path().front().utime;
  if (toSeconds(since_start) < o.appear_time) return;
  // Postponed to a later frame while there is no committed path to block, less of it is left
  // than the drawn distance, or it winds back so that the obstacle would stand nearer the vehicle
  // than the shortest draw on a straight path puts it: a vehicle cannot be asked to stop short of
  // an obstacle that appears beside it.
  const PolynomialTrajectory* trajectory = vehicle_.trajectory();
  if (!trajectory) return;
  const std::optional<Eigen::Vector2d> axis =
      dynamicObstacleAxis(*trajectory, state.utime, dynamic_draw_, options_.vehicle.sample_period);
  if (!axis) return;
  const Cylinder cylinder{axis->x(), axis->y(), o.radius,
                          o.height > 0 ? o.height : world_.bounds_max.z()};
  const double clearance = cylinderDistance(cylinder, state.position);
  if (!(clearance >= o.distance_ahead_min - o.radius)) return;

  world_.cylinders.push_back(cylinder);
  // The vehicle holds a reference to truth_: assigning keeps it valid and shows it the obstacle.
  truth_ = GroundTruth(world_);
  buildCamera();
  dynamic_obstacle_ = AppearedObstacle{cylinder, state.utime, frame_, clearance};
  publishWorld();
  char text[320];
  std::snprintf(text, sizeof(text),
                "dynamic obstacle appeared at frame %lld (t = %.2f s): axis (%.3f, %.3f), radius "
                "%.3f m, height %.3f m, %.3f m ahead along the committed path, %.3f m lateral "
                "offset, clearance %.3f m",
                static_cast<long long>(frame_), toSeconds(since_start), cylinder.x, cylinder.y,
                cylinder.radius, cylinder.height, dynamic_draw_.distance_ahead,
                dynamic_draw_.lateral_offset, clearance);
  publishEvent(sim_event_t::TYPE_INFO, text);
}

void SimNode::publishOdometry(const PathSample& sample) {
  publish("SIM_TRUTH", OdometrySimulator::truth(sample, last_odometry_, odometry_sequence_));
  publish("VIO_ODOMETRY", odometry_.estimate(sample, last_odometry_, odometry_sequence_));
  ++odometry_sequence_;
  last_odometry_ = sample;
}

void SimNode::publishFrame() {
  const PathSample& state = vehicle_.state();
  const Pose body = Pose::fromYaw(state.position, state.yaw);
  if (depth_) {
    depth_image_t msg =
        encodeDepthImage(depth_->renderImage(body, state.utime, static_cast<uint64_t>(frame_)));
    msg.camera_id = "sim_depth";
    publish("CAMERA_DEPTH", msg);
  } else {
    std::vector<uint8_t> left, right;
    stereo_->render(body, left, right);
    const PinholeCamera camera = stereo_->camera();
    stereo_image_t msg{};
    msg.utime = state.utime;
    msg.calibration_id = options_.stereo_camera.calibration_id;
    msg.rectified = true;
    msg.left = grayImage(state.utime, "left", camera.width, camera.height, std::move(left));
    msg.right = grayImage(state.utime, "right", camera.width, camera.height, std::move(right));
    publish("STEREO", msg);
  }
  ++frame_;
  if (options_.lockstep) waiting_for_ = state.utime;
}

void SimNode::publishEvent(int8_t type, const std::string& message, int8_t outcome) {
  const PathSample& state = vehicle_.state();
  sim_event_t event{};
  event.utime = state.utime;
  event.type = type;
  event.outcome = outcome;
  event.cycle = vehicle_.cycle();
  for (int i = 0; i < 3; ++i) event.position[i] = state.position[i];
  event.clearance = state.clearance;
  event.message = message;
  event.num_replans = vehicle_.cycle();
  event.path_length = vehicle_.pathLength();
  event.path_time = toSeconds(state.utime - vehicle_.path().front().utime);
  event.min_clearance = vehicle_.minClearance();
  event.distance_to_goal = vehicle_.distanceToGoal();
  publish("SIM_EVENT", event);
}

void SimNode::onTrajectory(const polynomial_trajectory_t& msg) {
  if (finished_) return;
  if (auto refused = vehicle_.commit(msg)) {
    publishEvent(sim_event_t::TYPE_TRAJECTORY_REFUSED,
                 "cycle " + std::to_string(msg.cycle) + ": " + *refused);
  }
}

void SimNode::onPlannerStatus(const planner_status_t& msg) {
  // A planner without a goal (restarted, or started after the goal went out) is sent the mission
  // again, once per frame: the operator's goal is latched here, where it was given.
  if (!finished_ && msg.is_final && msg.goal_id < 0 &&
      msg.state != planner_status_t::STATE_GOAL_REACHED && goal_sent_for_frame_ != frame_) {
    publishEvent(sim_event_t::TYPE_INFO, "the planner has no goal: the mission goal sent again");
    publishMissionGoal();
  }
  // The planner closes the frame it planned for with a final status planned from the state at
  // (or after) the frame's time; earlier or non-final statuses do not step the simulation.
  if (!options_.lockstep || finished_ || !waiting_for_ || !msg.is_final ||
      msg.utime < *waiting_for_) {
    return;
  }
  advance();
}

void SimNode::stepOn(double waited_s) {
  if (finished_ || !waiting_for_) return;
  char text[160];
  std::snprintf(text, sizeof(text),
                "no final planner status for frame %lld within %.1f s: stepping on without it",
                static_cast<long long>(*waiting_for_), waited_s);
  publishEvent(sim_event_t::TYPE_INFO, text);
  ++steps_on_;
  advance();
}

void SimNode::advance() {
  if (finished_) return;
  waiting_for_.reset();
  const StepReport report = vehicle_.step();
  if (dynamic_obstacle_) {
    for (const PathSample& sample : report.samples) {
      dynamic_obstacle_->min_clearance =
          std::min(dynamic_obstacle_->min_clearance,
                   cylinderDistance(dynamic_obstacle_->cylinder, sample.position));
    }
  }
  const int64_t odometry_period = secondsToUtime(1.0 / options_.odometry_rate);
  for (const PathSample& sample : report.samples) {
    if (sample.utime - last_odometry_.utime >= odometry_period ||
        &sample == &report.samples.back()) {
      publishOdometry(sample);
    }
  }
  if (report.collision) {
    char text[160];
    std::snprintf(text, sizeof(text), "collision at (%.2f, %.2f, %.2f): clearance %.3f m",
                  report.collision->position.x(), report.collision->position.y(),
                  report.collision->position.z(), report.collision->clearance);
    publishEvent(sim_event_t::TYPE_COLLISION, text);
  }
  switch (report.outcome) {
    case Outcome::kRunning:
      updateDynamicObstacle();
      publishFrame();
      break;
    case Outcome::kGoalReached:
      finish("goal reached", sim_event_t::OUTCOME_GOAL_REACHED);
      break;
    case Outcome::kReplanLimit:
      finish("replan limit reached", sim_event_t::OUTCOME_REPLAN_LIMIT);
      break;
    case Outcome::kCollision:
      // The vehicle also fails by leaving the flight volume through the top, clear of obstacles.
      finish(report.collision && report.collision->clearance >= world_.robot_radius
                 ? "left the flight volume"
                 : "collision",
             sim_event_t::OUTCOME_COLLISION);
      break;
  }
}

void SimNode::finish(const std::string& reason, int8_t outcome) {
  publishEvent(sim_event_t::TYPE_TRIAL_END, reason, outcome);
  end_reason_ = reason;
  finished_ = true;
  waiting_for_.reset();
}

void SimNode::abort(const std::string& reason) {
  if (!finished_) finish("aborted: " + reason, sim_event_t::OUTCOME_ABORTED);
}

}  // namespace thicket::sim

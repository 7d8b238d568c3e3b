// thicket-sim as an LCM node: publishes the world, odometry and sensor frames of the simulated
// vehicle, executes the planner's trajectories, and reports collisions and the mission outcome.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>
#include <thicket/sim_event_t.hpp>

#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/sim/dynamic_obstacle.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/odometry.h"
#include "thicket/sim/render.h"
#include "thicket/sim/vehicle.h"
#include "thicket/sim/world.h"

namespace thicket::sim {

struct SimOptions {
  std::string scenario = "paper";
  double density = 0.2;
  int64_t seed = 0;
  std::string worlds_dir;  // empty: the source tree's config/worlds
  std::string sensor = "depth";
  bool lockstep = false;
  double rate = 1.0;               // cycles per wall-clock second without lockstep
  double lockstep_timeout = 30.0;  // wall-clock seconds without any final status: abort
  double lockstep_step_on = 3.0;   // wall-clock seconds a frame waits before stepping on; 0: never
  double odometry_rate = 20.0;     // odometry messages per simulated second
  VehicleOptions vehicle;
  DepthCameraOptions depth_camera;
  StereoCameraOptions stereo_camera;
  OdometryNoiseOptions odometry;
  DynamicObstacleOptions dynamic_obstacle;

  void declare(Params& p);
};

class SimNode : public Node {
 public:
  /// Throws std::invalid_argument for dynamic obstacle options that do not suit the world (see
  /// dynamicObstacleError), and for camera or vehicle options that make no camera or vehicle.
  SimNode(lcm::LCM& lcm, const SimOptions& options, World world);

  /// Publishes the world, the mission goal (the world's goal, on MISSION_GOAL as the operator),
  /// the trial start and the first frame.
  void start();
  /// Executes one replan period and publishes the next frame, or the trial end. Called by the
  /// planner's final status in lockstep, by a timer otherwise.
  void advance();
  /// Ends the mission now (e.g. the planner stopped answering), with the reason.
  void abort(const std::string& reason);
  /// In lockstep, steps on without the final status of the frame waited on (it waited `waited_s`
  /// of wall time), as the real-time simulator would: the vehicle flies what it committed (and
  /// hovers at its end), and a new estimate and frame go out, which a restarted module, or one
  /// whose messages were lost, takes up. Said in a TYPE_INFO SIM_EVENT.
  void stepOn(double waited_s);
  /// How many frames stepOn stepped past.
  int stepsOn() const { return steps_on_; }

  bool finished() const { return finished_; }
  /// How the mission ended ("goal reached", "aborted: ..."), empty while it runs.
  const std::string& endReason() const { return end_reason_; }
  const Vehicle& vehicle() const { return vehicle_; }
  /// The world as it is now: with the dynamic obstacle (the last cylinder) once it appeared.
  const World& world() const { return world_; }
  const GroundTruth& groundTruth() const { return truth_; }
  /// The dynamic obstacle and the vehicle's smallest clearance to it so far, once it appeared.
  /// It appears (options.dynamic_obstacle) at the first frame at or after appear_time at which
  /// the committed trajectory has at least the drawn distance of path left and the vehicle is
  /// clear of where it would stand; until then each frame postpones it to the next (without a
  /// trajectory, hovering, or stopping short, it may never appear). When it appears, the world,
  /// ground truth and cameras include it, SIM_WORLD is published again and a TYPE_INFO SIM_EVENT
  /// says where.
  const std::optional<AppearedObstacle>& dynamicObstacle() const { return dynamic_obstacle_; }
  /// The frame the simulator waits on in lockstep (its utime), if any.
  std::optional<int64_t> waitingFor() const { return waiting_for_; }

 private:
  // (Re)builds the renderer of options_.sensor for world_.
  void buildCamera();
  void publishWorld();
  // The operator's mission: the world's goal on MISSION_GOAL (goal id 1).
  void publishMissionGoal();
  void publishFrame();
  // Adds the dynamic obstacle when it is due and can be placed (see dynamicObstacle()).
  void updateDynamicObstacle();
  void publishOdometry(const PathSample& sample);
  void publishEvent(int8_t type, const std::string& message, int8_t outcome = 0);
  void finish(const std::string& reason, int8_t outcome);
  void onTrajectory(const polynomial_trajectory_t& msg);
  void onPlannerStatus(const planner_status_t& msg);

  SimOptions options_;
  World world_;
  GroundTruth truth_;
  Vehicle vehicle_;
  OdometrySimulator odometry_;
  std::unique_ptr<DepthRenderer> depth_;
  std::unique_ptr<StereoRenderer> stereo_;
  DynamicObstacleDraw dynamic_draw_;
  std::optional<AppearedObstacle> dynamic_obstacle_;
  PathSample last_odometry_;
  int64_t odometry_sequence_ = 0;
  int64_t frame_ = 0;
  std::optional<int64_t> waiting_for_;
  int64_t goal_sent_for_frame_ = -1;  // the frame_ at which MISSION_GOAL was last sent
  int steps_on_ = 0;
  bool finished_ = false;
  std::string end_reason_;
};

}  // namespace thicket::sim

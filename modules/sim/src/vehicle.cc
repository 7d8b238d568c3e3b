#include "thicket/sim/vehicle.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "thicket/common/time.h"

namespace thicket::sim {
namespace {

// Below this horizontal speed the heading is undefined; the vehicle keeps its yaw.
constexpr double kYawMinSpeed = 0.05;
constexpr double kLimitSlack = 0.01;

}  // namespace

void VehicleOptions::declare(Params& p) {
  p("replan_period", replan_period, "simulated seconds executed per cycle [s]", Range::positive());
  p("sample_period", sample_period, "executed path sampling [s]", Range::between(1e-4, 1.0));
  p("replan_limit", replan_limit, "cycles before the mission ends unfinished", Range::atLeast(1));
  p("goal_tolerance", goal_tolerance, "goal reached within this distance [m]", Range::positive());
  p("max_start_lag", max_start_lag, "oldest accepted trajectory start before now [s]",
    Range::atLeast(0));
  p("max_start_lead", max_start_lead, "latest accepted trajectory start after now [s]",
    Range::atLeast(0));
  p("v_max", v_max, "speed limit checked on the executed path [m/s]", Range::positive());
  p("a_max", a_max, "acceleration limit checked on the executed path [m/s^2]", Range::positive());
  p("max_yaw_rate", max_yaw_rate, "the vehicle turns toward the commanded yaw no faster [rad/s]",
    Range::positive());
}

const char* outcomeName(Outcome outcome) {
  switch (outcome) {
    case Outcome::kRunning:
      return "running";
    case Outcome::kGoalReached:
      return "goal_reached";
    case Outcome::kReplanLimit:
      return "replan_limit";
    case Outcome::kCollision:
      return "collision";
  }
  return "unknown";
}

Vehicle::Vehicle(const GroundTruth& truth, VehicleOptions options, int64_t start_utime)
    : truth_(truth), options_(options), hold_position_(truth.world().start), utime_(start_utime) {
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("VehicleOptions: " + error);
  }
  if (options_.sample_period > options_.replan_period) {
    throw std::invalid_argument("VehicleOptions: sample_period exceeds replan_period");
  }
  const World& world = truth_.world();
  state_.utime = utime_;
  state_.position = world.start;
  const Eigen::Vector3d to_goal = world.goal - world.start;
  state_.yaw = std::atan2(to_goal.y(), to_goal.x());
  state_.clearance = truth_.distance(world.start);
  min_clearance_ = state_.clearance;
  path_.push_back(state_);
}

std::optional<std::string> Vehicle::commit(const polynomial_trajectory_t& msg) {
  if (outcome_ != Outcome::kRunning) {
    return std::string("the mission has ended (") + outcomeName(outcome_) + ")";
  }
  auto trajectory = PolynomialTrajectory::fromLcm(msg);
  if (!trajectory) return "malformed trajectory: " + trajectory.error();
  const double lead = toSeconds(trajectory->startUtime() - utime_);
  if (lead > options_.max_start_lead) {
    return "trajectory starts " + std::to_string(lead) + " s in the future";
  }
  if (-lead > options_.max_start_lag) {
    return "trajectory started " + std::to_string(-lead) + " s ago";
  }
  trajectory_ = std::move(*trajectory);
  yaw_policy_ = msg.yaw_policy;
  trajectory_yaw_ = msg.yaw;
  return std::nullopt;
}

PathSample Vehicle::sampleAt(int64_t utime, const PathSample& previous) const {
  PathSample sample;
  sample.utime = utime;
  if (trajectory_) {
    const TrajectoryState s = trajectory_->stateAtUtime(utime);
    sample.position = s.position;
    sample.velocity = s.velocity;
    sample.acceleration = s.acceleration;
  } else {
    sample.position = hold_position_;
  }
  double target = previous.yaw;
  if (trajectory_ && yaw_policy_ == polynomial_trajectory_t::YAW_CONSTANT) {
    target = trajectory_yaw_;
  } else if (sample.velocity.head<2>().norm() > kYawMinSpeed) {
    target = std::atan2(sample.velocity.y(), sample.velocity.x());
  }
  const double max_turn = options_.max_yaw_rate * toSeconds(utime - previous.utime);
  const double turn = std::remainder(target - previous.yaw, 2 * M_PI);
  sample.yaw = std::remainder(previous.yaw + std::clamp(turn, -max_turn, max_turn), 2 * M_PI);
  sample.clearance = truth_.distance(sample.position);
  return sample;
}

StepReport Vehicle::step() {
  StepReport report;
  report.outcome = outcome_;
  if (outcome_ != Outcome::kRunning) return report;

  const World& world = truth_.world();
  const int64_t start = utime_;
  const int64_t steps = std::llround(options_.replan_period / options_.sample_period);
  for (int64_t i = 1; i <= steps; ++i) {
    const int64_t utime = start + secondsToUtime(options_.replan_period * static_cast<double>(i) /
                                                 static_cast<double>(steps));
    const PathSample sample = sampleAt(utime, state_);
    path_length_ += (sample.position - state_.position).norm();
    min_clearance_ = std::min(min_clearance_, sample.clearance);
    max_speed_ = std::max(max_speed_, sample.velocity.norm());
    max_acceleration_ = std::max(max_acceleration_, sample.acceleration.norm());
    state_ = sample;
    path_.push_back(sample);
    report.samples.push_back(sample);
    // Leaving the flight volume through the top counts like hitting the ground or a wall.
    if (sample.clearance < world.robot_radius || sample.position.z() > world.bounds_max.z()) {
      report.collision = sample;
      outcome_ = Outcome::kCollision;
      break;
    }
  }
  utime_ = state_.utime;
  ++cycle_;
  if (outcome_ == Outcome::kRunning) {
    if (distanceToGoal() <= options_.goal_tolerance) {
      outcome_ = Outcome::kGoalReached;
    } else if (cycle_ >= options_.replan_limit) {
      outcome_ = Outcome::kReplanLimit;
    }
  }
  report.outcome = outcome_;
  return report;
}

bool Vehicle::feasible() const {
  return max_speed_ <= options_.v_max + kLimitSlack &&
         max_acceleration_ <= options_.a_max + kLimitSlack;
}

double Vehicle::distanceToGoal() const {
  return (state_.position - truth_.world().goal).norm();
}

}  // namespace thicket::sim

#include "local_planner_node.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <thicket/module_timing_t.hpp>
#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>
#include <thicket/setpoint_t.hpp>

#include "thicket/common/geometry.h"
#include "thicket/common/statistics.h"

namespace thicket::local_planner {

void LocalPlannerNodeOptions::declare(Params& p) {
  p.group("planner", planner, "goal state machine, goal finding and trajectory optimization");
  p("state_channel", state_channel, "state estimates in (odometry_t)");
  p("replan_rate", replan_rate,
    "cycles per second on the vehicle; 0: one cycle per new ESDF revision (simulation, replay) "
    "[Hz]",
    Range::between(0, 100));
  p("setpoint_rate", setpoint_rate, "CONTROL_SETPOINT messages per second; 0: none [Hz]",
    Range::between(0, 1000));
  p("explorer_timeout", explorer_timeout,
    "a stuck cycle the explorer has not answered within this many wall-clock seconds is closed "
    "holding (the explorer died or restarted); 0: wait [s]",
    Range::between(0, 3600));
}

namespace {

int8_t statusState(CycleState state) {
  switch (state) {
    case CycleState::kPlanned:
      return planner_status_t::STATE_PLANNED;
    case CycleState::kStuck:
      return planner_status_t::STATE_STUCK;
    case CycleState::kGoalReached:
      return planner_status_t::STATE_GOAL_REACHED;
    case CycleState::kHolding:
      return planner_status_t::STATE_HOLDING;
    case CycleState::kNoMap:
      return planner_status_t::STATE_NO_MAP;
    case CycleState::kNoState:
      return planner_status_t::STATE_NO_STATE;
    case CycleState::kStopping:
      return planner_status_t::STATE_STOPPING;
  }
  return planner_status_t::STATE_HOLDING;
}

void copy(const Eigen::Vector3d& v, double out[3]) {
  for (int i = 0; i < 3; ++i) out[i] = v[i];
}

// A goal_t as the planner's Goal, or why it is malformed.
Expected<Goal> goalFromMessage(const goal_t& msg) {
  if (msg.num_waypoints < 0 || static_cast<size_t>(msg.num_waypoints) != msg.waypoints.size()) {
    return unexpected("num_waypoints does not match the waypoints");
  }
  if (msg.yaw_policy != goal_t::YAW_ALONG_VELOCITY && msg.yaw_policy != goal_t::YAW_FIXED) {
    return unexpected("unknown yaw policy " + std::to_string(msg.yaw_policy));
  }
  Goal goal;
  goal.id = msg.goal_id;
  goal.from_explorer = msg.source == goal_t::SOURCE_EXPLORER;
  goal.strategy = msg.strategy;
  goal.tolerance = msg.tolerance;
  for (const auto& w : msg.waypoints) goal.waypoints.emplace_back(w[0], w[1], w[2]);
  if (msg.yaw_policy == goal_t::YAW_FIXED) goal.yaws = msg.yaws;
  return goal;
}

}  // namespace

LocalPlannerNode::LocalPlannerNode(lcm::LCM& lcm, const LocalPlannerNodeOptions& options,
                                   std::function<double()> now_ms)
    : Node("local_planner", lcm),
      options_(options),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      planner_(options.planner, now_ms_),
      state_counts_(kNumCycleStates, 0) {
  // A full snapshot arrives as many parts at once.
  subscribe<map_update_t>(
      "MAP_ESDF", [this](const map_update_t& msg, const MessageInfo&) { onMap(msg); }, 1000);
  subscribe<odometry_t>(
      options_.state_channel, [this](const odometry_t& msg, const MessageInfo&) { onState(msg); },
      1000);
  subscribe<goal_t>("MISSION_GOAL",
                    [this](const goal_t& msg, const MessageInfo&) { onMissionGoal(msg); });
  subscribe<goal_t>("EXPLORER_GOAL",
                    [this](const goal_t& msg, const MessageInfo&) { onExplorerGoal(msg); });
}

void LocalPlannerNode::onMap(const map_update_t& msg) {
  const auto result = mirror_.apply(msg);
  using Outcome = MapMirror<EsdfVoxel>::Outcome;
  if (result.outcome == Outcome::kNeedSnapshot) {
    publish("MAP_REQUEST", mirror_.request(msg.utime, name()));
  } else if (result.outcome == Outcome::kRefused) {
    reportBadMessage("MAP_ESDF", result.reason);
  } else if (result.outcome == Outcome::kApplied && options_.replan_rate == 0) {
    pending_ = mirror_.utime();
    runPending();
  }
}

void LocalPlannerNode::onState(const odometry_t& msg) {
  if (msg.quality == odometry_t::QUALITY_LOST) {
    reportBadMessage(options_.state_channel,
                     "the estimator reports it is lost (" + msg.reason + ")");
    return;
  }
  const Expected<Pose> pose = poseFromArrays(msg.position, msg.orientation);
  if (!pose) {
    reportBadMessage(options_.state_channel, "bad pose: " + pose.error());
    return;
  }
  VehicleState state;
  state.utime = msg.utime;
  state.position = pose->position;
  state.velocity =
      Eigen::Vector3d(msg.linear_velocity[0], msg.linear_velocity[1], msg.linear_velocity[2]);
  state.yaw = pose->yaw();
  if (!state.velocity.allFinite()) {
    reportBadMessage(options_.state_channel, "velocity not finite");
    return;
  }
  // Estimates must come in time order; a run of earlier ones (a restarted estimator, or one
  // corrupt far-future stamp overtaken) starts a new timeline, said on stderr.
  const Timeline::Result time = state_times_.offer(msg.utime);
  if (!time.accepted()) {
    reportBadMessage(options_.state_channel, time.reason);
    return;
  }
  if (time.verdict == Timeline::Verdict::kReanchored) {
    std::fprintf(stderr, "[%s] %s: %s\n", name().c_str(), options_.state_channel.c_str(),
                 time.reason.c_str());
  }
  state_ = state;
  runPending();
}

void LocalPlannerNode::runPending() {
  // A revision plans once the estimate at its time is in (the simulator and the estimator
  // publish it before the frame the map is built from).
  if (!pending_ || !state_ || state_->utime < *pending_) return;
  const int64_t utime = *pending_;
  pending_.reset();
  runCycle(utime);
}

void LocalPlannerNode::replan() {
  if (!state_) {
    runCycle(mirror_.utime());
    return;
  }
  runCycle(state_->utime);
}

std::optional<DistanceField> LocalPlannerNode::mirrorField() const {
  if (!mirror_.layer()) return std::nullopt;
  return esdfField(*mirror_.layer());
}

void LocalPlannerNode::runCycle(int64_t utime) {
  const double t0 = now_ms_();
  const std::optional<DistanceField> field = mirrorField();
  const CycleReport report =
      planner_.plan(utime, field ? &*field : nullptr, mirror_.utime(), mirror_.revision(), state_);
  publishReport(report, now_ms_() - t0);
}

void LocalPlannerNode::publishReport(const CycleReport& report, double total_ms) {
  if (report.trajectory) {
    publish("PLANNER_TRAJECTORY",
            report.trajectory->toLcm(report.cycle, report.goal_id,
                                     report.yaw ? polynomial_trajectory_t::YAW_CONSTANT
                                                : polynomial_trajectory_t::YAW_ALONG_VELOCITY,
                                     report.yaw.value_or(0)));
  }
  if (report.loco.iterations > 0) solve_ms_.push_back(report.solve_ms);
  if (report.is_final) ++state_counts_[static_cast<size_t>(report.state)];
  planner_status_t status{};
  status.utime = report.utime;
  status.cycle = report.cycle;
  status.is_final = report.is_final;
  status.state = statusState(report.state);
  status.reason = report.reason;
  status.map_revision = report.map_revision;
  status.goal_id = report.goal_id;
  status.goal_source =
      report.goal_from_explorer ? goal_t::SOURCE_EXPLORER : goal_t::SOURCE_OPERATOR;
  copy(report.goal, status.goal);
  copy(report.horizon_goal, status.horizon_goal);
  copy(report.start.position, status.start_position);
  copy(report.start.velocity, status.start_velocity);
  copy(report.start.acceleration, status.start_acceleration);
  status.cost_total = report.loco.cost.total;
  status.cost_derivative = report.loco.cost.derivative;
  status.cost_collision = report.loco.cost.collision;
  status.cost_goal = report.loco.cost.goal;
  status.min_distance = report.loco.min_distance;
  status.iterations = report.loco.iterations;
  status.restarts = report.loco.restarts;
  status.solver_termination = report.loco.termination;
  status.solver_message = report.loco.termination_message;
  status.solve_time_ms = report.solve_ms;
  publish("PLANNER_STATUS", status);

  module_timing_t timing;
  timing.utime = report.utime;
  timing.module = "local_planner";
  timing.sequence = report.cycle;
  timing.stages = {"trajectory_optimization", "cycle"};
  timing.durations_ms = {report.solve_ms, total_ms};
  timing.num_stages = 2;
  publish("MODULE_TIMING", timing);
}

void LocalPlannerNode::publishRejection(const goal_t& msg, const std::string& reason) {
  planner_status_t status{};
  status.utime = msg.utime;
  status.cycle = planner_.cycles();
  status.is_final = false;
  status.state = planner_status_t::STATE_REJECTED_GOAL;
  status.reason = reason;
  status.map_revision = mirror_.revision();
  status.goal_id = msg.goal_id;
  status.goal_source = msg.source;
  publish("PLANNER_STATUS", status);
}

void LocalPlannerNode::onMissionGoal(const goal_t& msg) {
  if (msg.status == goal_t::STATUS_CANCEL) {
    planner_.cancel();
    return;
  }
  auto goal = goalFromMessage(msg);
  if (!goal) {
    publishRejection(msg, "mission goal refused: " + goal.error());
    return;
  }
  if (auto refused = planner_.setMissionGoal(*goal)) {
    publishRejection(msg, "mission goal refused: " + *refused);
  }
}

void LocalPlannerNode::onExplorerGoal(const goal_t& msg) {
  const std::optional<int64_t> waiting = planner_.waitingCycle();
  if (!waiting || msg.cycle != *waiting) {
    publishRejection(msg, "explorer goal for cycle " + std::to_string(msg.cycle) +
                              " ignored: no such cycle is waiting");
    return;
  }
  std::optional<Goal> goal;
  std::string reason = msg.reason;
  if (msg.status == goal_t::STATUS_OK) {
    auto parsed = goalFromMessage(msg);
    if (parsed) {
      goal = *parsed;
    } else {
      reason = "malformed explorer goal: " + parsed.error();
    }
  }
  const double t0 = now_ms_();
  const std::optional<DistanceField> field = mirrorField();
  const CycleReport report = planner_.answer(goal, reason, field ? &*field : nullptr);
  publishReport(report, now_ms_() - t0);
}

bool LocalPlannerNode::expireExplorerWait(int64_t now_us) {
  const std::optional<int64_t> waiting = planner_.waitingCycle();
  if (!waiting || options_.explorer_timeout <= 0) {
    waiting_since_.reset();
    return false;
  }
  if (!waiting_since_ || waiting_since_->first != *waiting) {
    waiting_since_ = std::make_pair(*waiting, now_us);
    return false;
  }
  const double waited = static_cast<double>(now_us - waiting_since_->second) * 1e-6;
  if (waited < options_.explorer_timeout) return false;
  waiting_since_.reset();
  char reason[120];
  std::snprintf(reason, sizeof reason, "no answer within %.1f s (is the explorer running?)",
                waited);
  const std::optional<DistanceField> field = mirrorField();
  publishReport(planner_.answer(std::nullopt, reason, field ? &*field : nullptr), 0);
  return true;
}

bool LocalPlannerNode::publishSetpoint(int64_t utime) {
  const auto& trajectory = planner_.committed();
  if (!trajectory) return false;
  const TrajectoryState s = trajectory->stateAtUtime(utime);
  setpoint_t msg{};
  msg.utime = utime;
  msg.cycle = planner_.committedCycle();
  copy(s.position, msg.position);
  copy(s.velocity, msg.velocity);
  copy(s.acceleration, msg.acceleration);
  // The trajectory's constant yaw, or along the horizontal velocity, held while (nearly) hovering.
  const double speed_xy_sq = s.velocity.head<2>().squaredNorm();
  constexpr double kMinSpeed = 0.05;
  if (planner_.committedYaw()) {
    last_yaw_ = *planner_.committedYaw();
  } else if (speed_xy_sq > kMinSpeed * kMinSpeed) {
    last_yaw_ = std::atan2(s.velocity.y(), s.velocity.x());
    msg.yaw_rate =
        (s.velocity.x() * s.acceleration.y() - s.velocity.y() * s.acceleration.x()) / speed_xy_sq;
  }
  msg.yaw = last_yaw_;
  return publish("CONTROL_SETPOINT", msg);
}

std::string LocalPlannerNode::summary() const {
  std::string text = std::to_string(planner_.cycles()) + " cycles (";
  const char* separator = "";
  for (size_t i = 0; i < state_counts_.size(); ++i) {
    if (state_counts_[i] == 0) continue;
    text += separator + std::to_string(state_counts_[i]) + " " +
            cycleStateName(static_cast<CycleState>(i));
    separator = ", ";
  }
  char tail[120];
  std::snprintf(tail, sizeof(tail), "); trajectory_optimization median %.2f ms, p95 %.2f ms",
                median(solve_ms_), quantile(solve_ms_, 0.95));
  return text + tail;
}

}  // namespace thicket::local_planner

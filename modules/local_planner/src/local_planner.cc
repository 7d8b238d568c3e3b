#include "thicket/local_planner/local_planner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "thicket/common/random.h"
#include "thicket/common/time.h"
#include "thicket/local_planner/stop.h"

namespace thicket::local_planner {

const char* cycleStateName(CycleState state) {
  switch (state) {
    case CycleState::kPlanned:
      return "planned";
    case CycleState::kStuck:
      return "stuck";
    case CycleState::kGoalReached:
      return "goal reached";
    case CycleState::kHolding:
      return "holding";
    case CycleState::kNoMap:
      return "no map";
    case CycleState::kNoState:
      return "no state";
    case CycleState::kStopping:
      return "stopping";
  }
  return "?";
}

void LocalPlannerOptions::declare(Params& p) {
  p.group("loco", loco, "the trajectory optimization");
  p.group("goal_finder", goal_finder, "the horizon goal and how it is moved out of collision");
  p("soft_goal", soft_goal, "let the trajectory's end move (the soft goal cost)");
  p("goal_tolerance", goal_tolerance, "waypoints are reached within this [m]", Range::positive());
  p("min_progress", min_progress,
    "a trajectory must end this much closer to the horizon goal than it starts [m]",
    Range::atLeast(0));
  p("max_divergence", max_divergence,
    "plan from the estimate when it is farther than this from the reference [m]",
    Range::positive());
  p("max_state_age", max_state_age, "older state estimates are stale [s]", Range::positive());
  p("max_map_age", max_map_age, "older maps are stale [s]", Range::positive());
  p("flight_volume_min", flight_volume_min,
    "goals and trajectories stay in this box: its low corner [m]");
  p("flight_volume_max", flight_volume_max, "... and its high corner [m]");
  p("use_explorer", use_explorer,
    "an explorer is running: stuck cycles wait for its intermediate goal");
  p("seed", seed, "random restarts draw from seed and the cycle");
  p("hover_duration", hover_duration, "duration of a hover trajectory [s]", Range::positive());
  p("yaw_tolerance", yaw_tolerance,
    "a waypoint with a yaw is reached once the vehicle's yaw is this close to it [rad]",
    Range::between(0, M_PI));
  p("stall_cycles", stall_cycles,
    "stall watchdog: give a goal up when the reference moved less than stall_distance over this "
    "many consecutive cycles on one waypoint; 0: off",
    Range::between(0, 1000));
  p("stall_distance", stall_distance, "... that distance [m]", Range::positive());
  p("max_yaw_offset", max_yaw_offset,
    "a trajectory is flown at its waypoint's yaw only if its direction is this close to it, else "
    "facing its end, and when that yaw is farther than this from the vehicle's, it stops and turns "
    "first, so the camera sees where it flies [rad]",
    Range::between(0, M_PI));
  p("carrot", carrot,
    "follow a goal's waypoints as a path: end each trajectory, at rest, at the farthest point of "
    "the polyline within the horizon a free straight segment reaches (the soft goal as fallback); "
    "false: a soft goal toward each waypoint in turn (the paper)");
  p("retreat", retreat,
    "a stuck cycle left with nothing to fly, its reference less than this outside the clearance "
    "margin or inside it, backs straight away from the nearest obstacle to this much outside the "
    "margin; 0: off (the paper) [m]",
    Range::between(0, 1));
}

bool Watchdog::stalled(int64_t goal_id, size_t waypoint, int64_t cycle,
                       const Eigen::Vector3d& reference, int cycles, double distance) {
  if (goal_id != goal_id_ || waypoint != waypoint_ || cycle != last_cycle_ + 1) {
    references_.clear();
    goal_id_ = goal_id;
    waypoint_ = waypoint;
  }
  last_cycle_ = cycle;
  references_.push_back(reference);
  while (references_.size() > static_cast<size_t>(cycles) + 1) references_.pop_front();
  if (cycles == 0 || references_.size() < static_cast<size_t>(cycles) + 1) return false;
  // The whole window, then the window one cycle shorter at the same mean speed.
  for (const int over : {cycles, cycles - 1}) {
    const double moved =
        (references_.back() - references_[static_cast<size_t>(cycles - over)]).norm();
    if (over > 0 && moved < distance * over / cycles) {
      moved_ = moved;
      over_ = over;
      return true;
    }
  }
  return false;
}

namespace {

std::string format(const char* pattern, double a, double b = 0, double c = 0) {
  char text[160];
  std::snprintf(text, sizeof(text), pattern, a, b, c);
  return text;
}

}  // namespace

LocalPlanner::LocalPlanner(LocalPlannerOptions options, std::function<double()> now_ms)
    : options_(std::move(options)),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      loco_(options_.loco),
      goal_finder_(options_.goal_finder, options_.loco.requiredClearance()) {
  // The rules of LocalPlannerOptions::declare (the loco and goal finder groups checked above),
  // and the one it cannot state: a flight volume with its corners in order.
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("LocalPlanner: " + error);
  }
  if (!options_.flight_volume_min.allFinite() || !options_.flight_volume_max.allFinite() ||
      !(options_.flight_volume_min.array() < options_.flight_volume_max.array()).all()) {
    throw std::invalid_argument("LocalPlanner: the flight volume's corners are not in order");
  }
}

std::optional<std::string> LocalPlanner::validate(const Goal& goal) const {
  if (goal.waypoints.empty()) return "the goal has no waypoints";
  if (!goal.yaws.empty() && goal.yaws.size() != goal.waypoints.size()) {
    return "the goal has " + std::to_string(goal.yaws.size()) + " yaws for " +
           std::to_string(goal.waypoints.size()) + " waypoints";
  }
  if (!(std::isfinite(goal.tolerance) && goal.tolerance >= 0)) {
    return "the goal tolerance must be finite and >= 0";
  }
  for (size_t i = 0; i < goal.waypoints.size(); ++i) {
    const Eigen::Vector3d& w = goal.waypoints[i];
    if (!w.allFinite()) return "waypoint " + std::to_string(i) + " is not finite";
    if (!goal.yaws.empty() && !std::isfinite(goal.yaws[i])) {
      return "the yaw of waypoint " + std::to_string(i) + " is not finite";
    }
    if ((w.array() < options_.flight_volume_min.array()).any() ||
        (w.array() > options_.flight_volume_max.array()).any()) {
      return "waypoint " + std::to_string(i) +
             format(" (%.2f, %.2f, %.2f) is outside the flight volume", w.x(), w.y(), w.z());
    }
  }
  return std::nullopt;
}

std::optional<std::string> LocalPlanner::setMissionGoal(const Goal& goal) {
  if (auto refused = validate(goal)) return refused;
  mission_ = goal;
  mission_progress_ = {};
  intermediate_.reset();
  return std::nullopt;
}

void LocalPlanner::cancel() {
  mission_.reset();
  intermediate_.reset();
}

std::optional<int64_t> LocalPlanner::waitingCycle() const {
  if (!waiting_) return std::nullopt;
  return waiting_->cycle;
}

namespace {

double tolerance(const Goal& goal, const LocalPlannerOptions& options) {
  return goal.tolerance > 0 ? goal.tolerance : options.goal_tolerance;
}

std::optional<double> waypointYaw(const Goal& goal, size_t waypoint) {
  if (goal.yaws.empty()) return std::nullopt;
  return goal.yaws[waypoint];
}

}  // namespace

std::optional<double> LocalPlanner::flightYaw(const std::optional<double>& yaw,
                                              const PolynomialTrajectory& trajectory) const {
  if (!yaw) return std::nullopt;
  const Eigen::Vector3d travel =
      trajectory.evaluate(trajectory.duration()) - trajectory.evaluate(0);
  if (travel.head<2>().norm() < options_.goal_tolerance) return yaw;
  const double heading = std::atan2(travel.y(), travel.x());
  if (std::abs(std::remainder(heading - *yaw, 2 * M_PI)) <= options_.max_yaw_offset) return yaw;
  return heading;
}

bool LocalPlanner::yawToReach(const Goal& goal, size_t i) const {
  return !goal.yaws.empty() && (!options_.carrot || i + 1 == goal.waypoints.size());
}

bool LocalPlanner::advanceWaypoints(const Goal& goal, size_t& waypoint,
                                    const CycleReport& report) const {
  const auto reached = [&](size_t i) {
    if ((goal.waypoints[i] - report.start.position).norm() > tolerance(goal, options_)) {
      return false;
    }
    return !yawToReach(goal, i) || std::abs(std::remainder(report.vehicle_yaw - goal.yaws[i],
                                                           2 * M_PI)) <= options_.yaw_tolerance;
  };
  while (waypoint < goal.waypoints.size() && reached(waypoint)) ++waypoint;
  return waypoint == goal.waypoints.size();
}

void LocalPlanner::commit(const PolynomialTrajectory& trajectory, const std::optional<double>& yaw,
                          CycleReport& report) {
  committed_ = trajectory;
  committed_yaw_ = yaw;
  committed_cycle_ = report.cycle;
  report.trajectory = trajectory;
  report.yaw = yaw;
}

bool LocalPlanner::look(const Goal& goal, size_t waypoint, const DistanceField& field,
                        CycleReport& report) {
  if (!yawToReach(goal, waypoint) ||
      (goal.waypoints[waypoint] - report.start.position).norm() > tolerance(goal, options_)) {
    return false;
  }
  const double yaw = goal.yaws[waypoint];
  report.goal_id = goal.id;
  report.goal_from_explorer = goal.from_explorer;
  report.goal = goal.waypoints[waypoint];
  report.horizon_goal = report.goal;
  // Stop where it is (stay, if it is at rest) and turn.
  commit(planStop(report.utime, report.start, field, options_.loco).trajectory, yaw, report);
  report.state = CycleState::kPlanned;
  report.reason =
      format("looking: turning from yaw %.2f to %.2f rad at the waypoint", report.vehicle_yaw, yaw);
  return true;
}

LocalPlanner::Tracked LocalPlanner::track(const Goal& goal, Progress& progress,
                                          const DistanceField& field, CycleReport& report) {
  const size_t before = progress.waypoint;
  if (advanceWaypoints(goal, progress.waypoint, report)) return Tracked::kReached;
  if (progress.waypoint != before) progress.carrot.reset();
  const size_t waypoint = progress.waypoint;
  if (progress.watchdog.stalled(goal.id, waypoint, report.cycle, report.start.position,
                                options_.stall_cycles, options_.stall_distance)) {
    report.goal_id = goal.id;
    report.goal_from_explorer = goal.from_explorer;
    report.goal = goal.waypoints[waypoint];
    report.reason = format("stalled: the reference moved %.2f m in the last %.0f cycles",
                           progress.watchdog.moved(), progress.watchdog.over());
    return Tracked::kFailed;
  }
  if (look(goal, waypoint, field, report)) return Tracked::kCommitted;
  return planToward(goal, progress, field, report) ? Tracked::kCommitted : Tracked::kFailed;
}

void LocalPlanner::retreat(const DistanceField& field, CycleReport& report) {
  if (options_.retreat <= 0) return;
  const std::optional<Retreat> back =
      planRetreat(report.utime, report.start, field, options_.loco, options_.retreat);
  if (!back) return;
  commit(back->trajectory, report.vehicle_yaw, report);
  report.state = CycleState::kPlanned;
  report.horizon_goal = back->trajectory.evaluate(back->trajectory.duration());
  report.reason += format("; backing away from the nearest obstacle, clearance %.3f to %.3f m",
                          back->from_distance, back->to_distance);
}

void LocalPlanner::hold(CycleReport& report, CycleState state, const std::string& reason,
                        const std::optional<Eigen::Vector3d>& position) {
  report.state = state;
  report.reason = reason;
  if (!committed_ && position) {
    commit(PolynomialTrajectory::hover(report.utime, *position, options_.hover_duration),
           std::nullopt, report);
  }
}

DistanceField LocalPlanner::fenced(const DistanceField& field) const {
  const Eigen::Vector3d lo = options_.flight_volume_min, hi = options_.flight_volume_max;
  const double clearance = options_.loco.requiredClearance();
  return [&field, lo, hi, clearance](const Eigen::Vector3d& p) {
    EsdfSample sample = field(p);
    if (!sample.known) return sample;
    // The nearest face, by the distance inside (negative outside) and its inward normal.
    double face = std::numeric_limits<double>::infinity();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
      if (p[i] - lo[i] < face) face = p[i] - lo[i], normal = Eigen::Vector3d::Unit(i);
      if (hi[i] - p[i] < face) face = hi[i] - p[i], normal = -Eigen::Vector3d::Unit(i);
    }
    if (face + clearance < sample.distance) {
      sample.distance = face + clearance;
      sample.gradient = normal;
    }
    return sample;
  };
}

void LocalPlanner::recheck(const DistanceField& field, CycleReport& report) {
  const double from = toSeconds(report.utime - committed_->startUtime());
  const ClearanceCheck check = checkClearance(
      *committed_, from, field, options_.loco.requiredClearance(), options_.loco.escape_slack);
  if (check.clear) return;
  const Stop stop = planStop(report.utime, report.start, field, options_.loco);
  commit(stop.trajectory, committed_yaw_, report);
  report.blocked =
      std::string(kBlockedTrajectoryReason) + " (" + check.reason + "); " +
      (stop.certified ? format("stopping within %.2f m in certified free space", stop.distance)
                      : format("no stop stays in certified free space: the hardest stop the "
                               "limits allow, %.2f m",
                               stop.distance));
}

void LocalPlanner::reportStop(CycleReport& report) {
  if (report.blocked.empty()) return;
  if (report.state == CycleState::kPlanned) {
    report.reason = report.blocked + "; replanned";
    return;
  }
  report.reason = report.blocked + "; " + report.reason;
  if (report.is_final && report.state != CycleState::kGoalReached) {
    report.state = CycleState::kStopping;
  }
}

std::optional<std::string> LocalPlanner::optimizeToward(const SplineEnds& ends, bool free_end,
                                                        const Eigen::Vector3d& target,
                                                        const DistanceField& field,
                                                        CycleReport& report) {
  // Every optimization of a cycle draws its restarts from its own seed: a second attempt at the
  // same goal in the same cycle (an explorer that proposes the goal that just failed) must not
  // repeat the first bit for bit.
  const int attempt = report.attempts++;
  const uint64_t cycle_seed = mixSeed(options_.seed, report.cycle);
  report.loco =
      loco_.solve(ends, free_end, field,
                  attempt == 0 ? cycle_seed : mixSeed(static_cast<int64_t>(cycle_seed), attempt));
  if (!report.loco.accepted) {
    return format("no acceptable trajectory toward (%.2f, %.2f, %.2f): ", target.x(), target.y(),
                  target.z()) +
           report.loco.reason;
  }
  // A plan that ends at the horizon goal or at the waypoint itself is progress, however short.
  const Eigen::Vector3d& horizon_goal = ends.end_position;
  const double start_gap = (horizon_goal - ends.start_position).norm();
  const double end_gap = (horizon_goal - report.loco.end_position).norm();
  const double target_gap = (target - report.loco.end_position).norm();
  if (end_gap > options_.goal_tolerance && target_gap > options_.goal_tolerance &&
      end_gap > start_gap - options_.min_progress) {
    return format("no progress toward (%.2f, %.2f, %.2f): ", target.x(), target.y(), target.z()) +
           format("the best trajectory ends %.2f m from the horizon goal, %.2f m at the start",
                  end_gap, start_gap);
  }
  return std::nullopt;
}

std::optional<LocalPlanner::Carrot> LocalPlanner::carrot(const Goal& goal, const Progress& progress,
                                                         const Eigen::Vector3d& start,
                                                         const DistanceField& field,
                                                         double extra) const {
  const double step = 0.1, horizon = options_.goal_finder.horizon;
  const double needed = options_.loco.requiredClearance() + extra;
  const auto freeFrom = [&](const Eigen::Vector3d& end) {
    const int n = std::max(1, static_cast<int>(std::ceil((end - start).norm() / step)));
    for (int k = 1; k <= n; ++k) {
      const EsdfSample sample = field(start + (end - start) * (static_cast<double>(k) / n));
      if (!sample.known || sample.distance < needed) return false;
    }
    return true;
  };
  std::vector<Eigen::Vector3d> path;
  if (progress.carrot) path.push_back(*progress.carrot);
  path.insert(path.end(), goal.waypoints.begin() + static_cast<long>(progress.waypoint),
              goal.waypoints.end());
  // The points of the path every `step` up to where it first leaves the horizon, in order; the
  // carrot is the last of them a free segment reaches, so they are tried from the far end.
  std::vector<Carrot> points;
  bool inside = true;
  Eigen::Vector3d from = start;
  for (size_t j = 0; j < path.size() && inside; ++j) {
    const Eigen::Vector3d& to = path[j];
    const size_t i = progress.waypoint + (progress.carrot && j > 0 ? j - 1 : j);
    const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / step)));
    for (int k = 1; k <= n && inside; ++k) {
      const Eigen::Vector3d p = from + (to - from) * (static_cast<double>(k) / n);
      inside = (p - start).norm() <= horizon;
      if (inside) points.push_back(Carrot{p, i});
    }
    from = to;
  }
  for (auto it = points.rbegin(); it != points.rend(); ++it) {
    if ((it->position - start).norm() <= options_.goal_tolerance) continue;  // no flight
    if (freeFrom(it->position)) return *it;
  }
  return std::nullopt;
}

bool LocalPlanner::planToward(const Goal& goal, Progress& progress, const DistanceField& field,
                              CycleReport& report) {
  const size_t waypoint = progress.waypoint;
  report.goal_id = goal.id;
  report.goal_from_explorer = goal.from_explorer;
  const double t0 = now_ms_();
  SplineEnds ends;
  ends.start_position = report.start.position;
  ends.start_velocity = report.start.velocity;
  ends.start_acceleration = report.start.acceleration;
  size_t to = waypoint;  // the waypoint the committed plan flies toward
  std::optional<std::string> refused;
  // The carrot: a fixed end on the path, passing the waypoints before it. A segment along the
  // clearance itself leaves the smooth trajectory to its end no room: when it bends by millimetres
  // and misses the acceptance, a carrot reached with the collision potential's buffer as well is
  // tried.
  report.carrot = false;
  std::optional<Carrot> c;
  for (const double extra : {0.0, options_.loco.potential_buffer}) {
    if (!options_.carrot || report.carrot) break;  // off, or the first carrot was flown
    const std::optional<Carrot> tried = carrot(goal, progress, report.start.position, field, extra);
    if (!tried || (c && tried->position == c->position)) break;
    c = tried;
    to = c->waypoint;
    report.goal = goal.waypoints[to];
    report.horizon_goal = ends.end_position = c->position;
    refused = optimizeToward(ends, /*free_end=*/false, report.goal, field, report);
    report.carrot = !refused;
  }
  if (!report.carrot) {  // no carrot, or none that could be flown: the soft goal
    to = waypoint;
    const Eigen::Vector3d& target = goal.waypoints[to];
    report.goal = target;
    const FoundGoal found = goal_finder_.find(report.start.position, target, field);
    report.horizon_goal = ends.end_position = found.position;
    // No plan without a free horizon goal (unless the soft goal may end short of one), nor from
    // a search that came back to the start itself (the line ahead unknown or blocked, no gradient
    // to follow): a spline of no length has no shape to optimize.
    std::optional<std::string> no_goal;
    if (!found.free && !options_.soft_goal) {
      no_goal = format("no free horizon goal found; the search ended at (%.2f, %.2f, %.2f)",
                       found.position.x(), found.position.y(), found.position.z());
    } else if (found.steps > 0 && found.position == report.start.position) {
      no_goal = format(
          "no horizon goal away from the start: the search toward (%.2f, %.2f, "
          "%.2f) came back to it",
          target.x(), target.y(), target.z());
    }
    if (no_goal) {
      report.loco = LocoResult{};
      report.solve_ms += now_ms_() - t0;
      report.reason = *no_goal;
      return false;
    }
    refused = optimizeToward(ends, options_.soft_goal, target, field, report);
    // The final approach: when the horizon goal is the waypoint itself and free, a refused soft
    // plan (its end balanced against the collision potential short of a waypoint near obstacles,
    // every cycle the same) is followed by one whose end is fixed at the waypoint.
    if (refused && options_.soft_goal && found.free && found.position == target) {
      refused = optimizeToward(ends, /*free_end=*/false, target, field, report);
    }
  }
  report.solve_ms += now_ms_() - t0;
  if (refused) {
    report.reason = *refused;
    return false;
  }
  auto trajectory = PolynomialTrajectory::create(report.utime, report.loco.segments);
  if (!trajectory) {
    report.reason = "the optimizer returned an invalid trajectory: " + trajectory.error();
    return false;
  }
  progress.waypoint = to;
  // A soft-goal flight leaves the polyline: the path restarts from where it ends (a carrot kept
  // from before could lie behind it, and the next cycle fly back to it).
  progress.carrot = report.carrot ? std::optional<Eigen::Vector3d>(c->position) : std::nullopt;
  const std::optional<double> yaw = flightYaw(waypointYaw(goal, to), *trajectory);
  report.state = CycleState::kPlanned;
  report.reason.clear();
  const Eigen::Vector3d travel =
      trajectory->evaluate(trajectory->duration()) - report.start.position;
  if (yaw && travel.head<2>().norm() >= options_.goal_tolerance &&
      std::abs(std::remainder(*yaw - report.vehicle_yaw, 2 * M_PI)) > options_.max_yaw_offset) {
    // Turn first, then fly: the camera must see where the vehicle goes (a map can hold free
    // space that has since been taken), and the yaw lags at the vehicle's yaw rate.
    commit(planStop(report.utime, report.start, field, options_.loco).trajectory, yaw, report);
    progress.watchdog.skip();
    report.reason =
        format("turning from yaw %.2f to %.2f rad before flying", report.vehicle_yaw, *yaw);
    return true;
  }
  commit(*trajectory, yaw, report);
  return true;
}

CycleReport LocalPlanner::plan(int64_t utime, const DistanceField* field, int64_t map_utime,
                               int64_t map_revision, const std::optional<VehicleState>& estimate) {
  CycleReport report = planCycle(utime, field, map_utime, map_revision, estimate);
  reportStop(report);
  return report;
}

CycleReport LocalPlanner::planCycle(int64_t utime, const DistanceField* map_field,
                                    int64_t map_utime, int64_t map_revision,
                                    const std::optional<VehicleState>& estimate) {
  CycleReport report;
  report.utime = utime;
  report.cycle = ++cycle_;
  report.map_revision = map_revision;
  // A stuck cycle the explorer never answered is abandoned by the next one.
  waiting_.reset();

  if (!estimate) {
    hold(report, CycleState::kNoState, "no state estimate yet", std::nullopt);
    return report;
  }
  if (const double age = toSeconds(utime - estimate->utime); age > options_.max_state_age) {
    hold(report, CycleState::kNoState, format("the state estimate is %.2f s old", age),
         estimate->position);
    return report;
  }
  report.vehicle_yaw = estimate->yaw;
  // The reference: the committed trajectory now, unless the vehicle is elsewhere.
  if (committed_) report.start = committed_->stateAtUtime(utime);
  if (!committed_ ||
      (report.start.position - estimate->position).norm() > options_.max_divergence) {
    report.start = TrajectoryState{};
    report.start.position = estimate->position;
    report.start.velocity = estimate->velocity;
  }
  if (map_field == nullptr) {
    hold(report, CycleState::kNoMap, "no map yet", report.start.position);
    return report;
  }
  if (const double age = toSeconds(utime - map_utime); age > options_.max_map_age) {
    hold(report, CycleState::kNoMap, format("the map is %.2f s old", age), report.start.position);
    return report;
  }
  const DistanceField field = fenced(*map_field);
  if (committed_) recheck(field, report);
  if (!mission_) {
    hold(report, CycleState::kHolding, "no goal", report.start.position);
    return report;
  }

  std::string dropped;
  if (intermediate_) {
    switch (track(*intermediate_, intermediate_progress_, field, report)) {
      case Tracked::kCommitted:
        return report;
      case Tracked::kReached:
        break;
      case Tracked::kFailed:
        dropped = "intermediate goal " + std::to_string(intermediate_->id) + " dropped (" +
                  report.reason + "); ";
        break;
    }
    intermediate_.reset();
    mission_progress_.carrot.reset();  // the vehicle has moved: the path restarts from here
  }
  switch (track(*mission_, mission_progress_, field, report)) {
    case Tracked::kCommitted:
      return report;
    case Tracked::kReached:
      report.goal_id = mission_->id;
      report.goal = mission_->waypoints.back();
      report.horizon_goal = report.goal;
      report.state = CycleState::kGoalReached;
      report.reason = "goal reached";
      return report;
    case Tracked::kFailed:
      break;
  }
  hold(report, CycleState::kStuck, dropped + report.reason, report.start.position);
  if (options_.use_explorer) {
    report.is_final = false;
    waiting_ = report;
  }
  return report;
}

CycleReport LocalPlanner::answer(const std::optional<Goal>& goal, const std::string& reason,
                                 const DistanceField* field) {
  if (!waiting_) throw std::logic_error("LocalPlanner::answer: no cycle is waiting");
  CycleReport report = answerCycle(goal, reason, field);
  reportStop(report);
  return report;
}

CycleReport LocalPlanner::answerCycle(const std::optional<Goal>& goal, const std::string& reason,
                                      const DistanceField* map_field) {
  CycleReport report = *waiting_;
  waiting_.reset();
  report.is_final = true;
  report.trajectory.reset();
  const std::string stuck = report.reason;
  const auto give_up = [&](const std::string& why) {
    report.state = CycleState::kHolding;
    report.reason = "stuck (" + stuck + "); " + why;
    if (map_field != nullptr) retreat(fenced(*map_field), report);
    return report;
  };
  if (!mission_) return give_up("the mission was cancelled");
  if (!goal) return give_up("the explorer has no intermediate goal: " + reason);
  if (auto refused = validate(*goal)) return give_up("intermediate goal refused: " + *refused);
  if (map_field == nullptr) return give_up("no map");
  intermediate_ = *goal;
  intermediate_->from_explorer = true;
  intermediate_progress_ = {};
  switch (track(*intermediate_, intermediate_progress_, fenced(*map_field), report)) {
    case Tracked::kCommitted:
      return report;
    case Tracked::kReached:
      intermediate_.reset();
      return give_up("the intermediate goal is where the vehicle already is");
    case Tracked::kFailed:
      break;
  }
  intermediate_.reset();
  return give_up("the intermediate goal is infeasible too: " + report.reason);
}

}  // namespace thicket::local_planner

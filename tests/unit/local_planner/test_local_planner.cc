// The local planner's core (the goal state machine around goal finding and loco) driven with
// analytic distance fields and explicit times: goal validation, holding without state or map,
// planning from the reference, flying to a goal and through waypoints, getting stuck and asking
// the explorer, intermediate goals, the re-check of the committed trajectory on a new map and the
// stop it commits, determinism. Every trajectory the planner commits here is checked every 0.01 s
// against the exact field: distance >= robot radius, v_max and a_max kept.
#include "thicket/local_planner/local_planner.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "analytic_fields.h"
#include "thicket/local_planner/stop.h"

namespace thicket::local_planner {

// Readable CycleStates in gtest messages.
void PrintTo(CycleState state, std::ostream* os) {
  *os << cycleStateName(state);
}

namespace {

using testing::boxesField;
using testing::boxFromCorners;
using testing::cylinderField;
using testing::freeSpace;
using testing::inspectTrajectory;

constexpr int64_t kSecond = 1'000'000;
constexpr int64_t kT0 = 100 * kSecond;
const Eigen::Vector3d kStart(0, 0, 1.5);
const Eigen::Vector3d kMission(10, 0, 1.5);

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

Goal goalAt(int64_t id, std::vector<Eigen::Vector3d> waypoints, bool from_explorer = false) {
  Goal goal;
  goal.id = id;
  goal.from_explorer = from_explorer;
  if (from_explorer) goal.strategy = "local_exploration";
  goal.waypoints = std::move(waypoints);
  return goal;
}

VehicleState stateAt(int64_t utime, const Eigen::Vector3d& position,
                     const Eigen::Vector3d& velocity = Eigen::Vector3d::Zero()) {
  VehicleState state;
  state.utime = utime;
  state.position = position;
  state.velocity = velocity;
  return state;
}

// A wall across the way to kMission: x in [2.5, 3.5], spanning y and z far beyond the flight.
DistanceField wall() {
  return boxesField({boxFromCorners({2.5, -50, -50}, {3.5, 50, 150})});
}

bool sameSegments(const PolynomialTrajectory& a, const PolynomialTrajectory& b) {
  if (a.startUtime() != b.startUtime() || a.numSegments() != b.numSegments()) return false;
  for (int i = 0; i < a.numSegments(); ++i) {
    const PolynomialSegment& sa = a.segments()[static_cast<size_t>(i)];
    const PolynomialSegment& sb = b.segments()[static_cast<size_t>(i)];
    if (sa.duration != sb.duration || sa.coefficients.cols() != sb.coefficients.cols() ||
        sa.coefficients != sb.coefficients) {
      return false;
    }
  }
  return true;
}

// The independent check of every accepted trajectory: every 0.01 s against the exact field.
void expectSafe(const PolynomialTrajectory& trajectory, const DistanceField& field,
                const LocoOptions& o) {
  const testing::TrajectoryReport r = inspectTrajectory(trajectory, field, 0.01);
  EXPECT_TRUE(r.all_known);
  EXPECT_GE(r.min_distance, o.robot_radius) << "at t = " << r.min_distance_time << " s";
  EXPECT_LE(r.max_speed, o.v_max + 1e-6);
  EXPECT_LE(r.max_acceleration, o.a_max + 1e-6);
}

// A committed trajectory starts at the cycle's time from the state the cycle planned from.
void expectStartsAtReport(const CycleReport& report) {
  ASSERT_TRUE(report.trajectory);
  EXPECT_EQ(report.trajectory->startUtime(), report.utime);
  const TrajectoryState s = report.trajectory->state(0);
  EXPECT_NEAR((s.position - report.start.position).norm(), 0, 1e-9);
  EXPECT_NEAR((s.velocity - report.start.velocity).norm(), 0, 1e-9);
  EXPECT_NEAR((s.acceleration - report.start.acceleration).norm(), 0, 1e-9);
}

// A planner and a vehicle that flies exactly what it commits: each cycle's estimate is the
// committed trajectory's state at the cycle's time (the start, at rest, before anything is
// committed), the map is fresh, and the cycles are 1 s apart.
class Pilot {
 public:
  explicit Pilot(LocalPlannerOptions options = {}, const Eigen::Vector3d& start = kStart)
      : planner(std::move(options)), start_(start) {}

  VehicleState estimate() const {
    VehicleState state = stateAt(t, start_);
    if (planner.committed()) {
      const TrajectoryState s = planner.committed()->stateAtUtime(t);
      state = stateAt(t, s.position, s.velocity);
    }
    state.yaw = yaw;
    return state;
  }

  // One cycle at t on `field`; checks what it commits; advances t by 1 s, turning the vehicle
  // toward the committed yaw (or its velocity) at no more than yaw_rate, like the simulator.
  CycleReport cycle(const DistanceField& field) {
    const CycleReport report = planner.plan(t, &field, t, ++revision, estimate());
    check(report, field);
    t += kSecond;
    double target = yaw;
    if (planner.committedYaw()) {
      target = *planner.committedYaw();
    } else if (planner.committed()) {
      const Eigen::Vector3d v = planner.committed()->stateAtUtime(t).velocity;
      if (v.head<2>().norm() > 0.05) target = std::atan2(v.y(), v.x());
    }
    yaw += std::clamp(std::remainder(target - yaw, 2 * M_PI), -yaw_rate, yaw_rate);
    return report;
  }

  // Checks a report's trajectory (a plan() or an answer()).
  void check(const CycleReport& report, const DistanceField& field) const {
    if (report.state == CycleState::kPlanned) {
      EXPECT_TRUE(report.trajectory) << "cycle " << report.cycle;
      // A planned cycle explains itself only when it replaced a blocked trajectory, looks,
      // turns before it flies, or backs away from an obstacle.
      EXPECT_EQ(report.reason.empty(), report.blocked.empty() &&
                                           !report.reason.starts_with("looking") &&
                                           !report.reason.starts_with("turning") &&
                                           !contains(report.reason, "backing away"))
          << report.reason;
    }
    if (!report.trajectory) return;
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    expectStartsAtReport(report);
    expectSafe(*report.trajectory, field, planner.options().loco);
    ASSERT_TRUE(planner.committed());
    EXPECT_TRUE(sameSegments(*planner.committed(), *report.trajectory));
  }

  LocalPlanner planner;
  int64_t t = kT0;
  int64_t revision = 0;
  double yaw = 0;       ///< the vehicle's heading [rad]
  double yaw_rate = 1;  ///< its largest turn per cycle [rad]

 private:
  Eigen::Vector3d start_;
};

// ---- goals ----

TEST(LocalPlanner, RefusesMalformedGoalsWithAReason) {
  const LocalPlanner planner{LocalPlannerOptions{}};
  EXPECT_FALSE(planner.validate(goalAt(1, {kMission})));
  EXPECT_FALSE(planner.validate(goalAt(1, {kMission, Eigen::Vector3d(3, 4, 2)})));

  const auto refusal = [&](const Goal& goal) {
    const std::optional<std::string> why = planner.validate(goal);
    return why ? *why : std::string("(accepted)");
  };
  Goal nan_goal = goalAt(1, {kMission, Eigen::Vector3d(1, std::nan(""), 1)});
  EXPECT_TRUE(contains(refusal(nan_goal), "waypoint 1")) << refusal(nan_goal);
  EXPECT_TRUE(contains(refusal(nan_goal), "not finite")) << refusal(nan_goal);
  const Goal empty = goalAt(2, {});
  EXPECT_TRUE(contains(refusal(empty), "no waypoints")) << refusal(empty);
  const Goal outside = goalAt(3, {Eigen::Vector3d(5, 0, -1)});  // below the ground (z >= 0)
  EXPECT_TRUE(contains(refusal(outside), "outside the flight volume")) << refusal(outside);
  const Goal far_away = goalAt(4, {Eigen::Vector3d(2000, 0, 1)});
  EXPECT_TRUE(contains(refusal(far_away), "outside the flight volume")) << refusal(far_away);
  Goal negative = goalAt(5, {kMission});
  negative.tolerance = -0.1;
  EXPECT_TRUE(contains(refusal(negative), "tolerance")) << refusal(negative);
  Goal few_yaws = goalAt(7, {kMission, Eigen::Vector3d(3, 4, 2)});
  few_yaws.yaws = {0.5};
  EXPECT_TRUE(contains(refusal(few_yaws), "1 yaws for 2 waypoints")) << refusal(few_yaws);
  Goal nan_yaw = goalAt(8, {kMission});
  nan_yaw.yaws = {std::nan("")};
  EXPECT_TRUE(contains(refusal(nan_yaw), "yaw of waypoint 0")) << refusal(nan_yaw);
  Goal nan_tolerance = goalAt(6, {kMission});
  nan_tolerance.tolerance = std::nan("");
  EXPECT_TRUE(contains(refusal(nan_tolerance), "tolerance")) << refusal(nan_tolerance);

  // A custom flight volume is honoured.
  LocalPlannerOptions options;
  options.flight_volume_min = Eigen::Vector3d(-5, -5, 0.5);
  options.flight_volume_max = Eigen::Vector3d(5, 5, 3);
  const LocalPlanner boxed(options);
  EXPECT_TRUE(boxed.validate(goalAt(1, {kMission})));  // x = 10 > 5
  EXPECT_FALSE(boxed.validate(goalAt(1, {Eigen::Vector3d(4, -4, 1)})));
}

TEST(LocalPlanner, ARefusedMissionGoalKeepsThePreviousOne) {
  LocalPlanner planner{LocalPlannerOptions{}};
  EXPECT_FALSE(planner.missionGoal());
  ASSERT_FALSE(planner.setMissionGoal(goalAt(7, {kMission})));
  ASSERT_TRUE(planner.missionGoal());

  const std::optional<std::string> refused =
      planner.setMissionGoal(goalAt(8, {Eigen::Vector3d(std::nan(""), 0, 1)}));
  ASSERT_TRUE(refused);
  EXPECT_TRUE(contains(*refused, "not finite")) << *refused;
  ASSERT_TRUE(planner.missionGoal());
  EXPECT_EQ(planner.missionGoal()->id, 7);
  ASSERT_EQ(planner.missionGoal()->waypoints.size(), 1u);
  EXPECT_EQ(planner.missionGoal()->waypoints[0], kMission);

  EXPECT_TRUE(planner.setMissionGoal(goalAt(9, {})));
  EXPECT_EQ(planner.missionGoal()->id, 7);

  // The kept goal is the one planned toward.
  const DistanceField field = freeSpace();
  const CycleReport report = planner.plan(kT0, &field, kT0, 1, stateAt(kT0, kStart));
  EXPECT_EQ(report.state, CycleState::kPlanned) << report.reason;
  EXPECT_EQ(report.goal_id, 7);
  EXPECT_EQ(report.goal, kMission);

  planner.cancel();
  EXPECT_FALSE(planner.missionGoal());
  EXPECT_FALSE(planner.intermediateGoal());
}

// ---- holding ----

TEST(LocalPlanner, HoldsWithoutAFreshStateEstimate) {
  LocalPlanner planner{LocalPlannerOptions{}};
  ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = freeSpace();

  const CycleReport none = planner.plan(kT0, &field, kT0, 1, std::nullopt);
  EXPECT_EQ(none.state, CycleState::kNoState);
  EXPECT_TRUE(none.is_final);
  EXPECT_FALSE(none.reason.empty());
  EXPECT_FALSE(none.trajectory);  // nowhere to hover
  EXPECT_FALSE(planner.committed());
  EXPECT_EQ(none.cycle, 1);
  EXPECT_EQ(none.utime, kT0);

  // max_state_age is 0.5 s: 0.6 s is stale.
  const int64_t t = kT0 + kSecond;
  const CycleReport stale = planner.plan(t, &field, t, 2, stateAt(t - 600'000, kStart));
  EXPECT_EQ(stale.state, CycleState::kNoState);
  EXPECT_TRUE(stale.is_final);
  EXPECT_TRUE(contains(stale.reason, "old")) << stale.reason;
  EXPECT_EQ(stale.cycle, 2);
  EXPECT_EQ(planner.cycles(), 2);

  // 0.4 s is not.
  const CycleReport fresh = planner.plan(t, &field, t, 3, stateAt(t - 400'000, kStart));
  EXPECT_EQ(fresh.state, CycleState::kPlanned) << fresh.reason;
}

TEST(LocalPlanner, HoversWithoutAMapAndSaysWhy) {
  LocalPlanner planner{LocalPlannerOptions{}};
  ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
  const Eigen::Vector3d here(1, 2, 1.5);

  // No map and nothing committed: a hover at the estimate's position is committed.
  const CycleReport no_map = planner.plan(kT0, nullptr, 0, -1, stateAt(kT0, here));
  EXPECT_EQ(no_map.state, CycleState::kNoMap);
  EXPECT_TRUE(no_map.is_final);
  EXPECT_FALSE(no_map.reason.empty());
  ASSERT_TRUE(no_map.trajectory);
  ASSERT_TRUE(planner.committed());
  EXPECT_TRUE(sameSegments(*planner.committed(), *no_map.trajectory));
  const PolynomialTrajectory& hover = *planner.committed();
  EXPECT_EQ(hover.startUtime(), kT0);
  EXPECT_DOUBLE_EQ(hover.duration(), planner.options().hover_duration);
  for (double s : {0.0, 0.5 * hover.duration(), hover.duration(), 5.0}) {
    EXPECT_NEAR((hover.evaluate(s) - here).norm(), 0, 1e-12) << "t = " << s;
    EXPECT_NEAR(hover.evaluate(s, 1).norm(), 0, 1e-12) << "t = " << s;
  }
  EXPECT_EQ(no_map.start.position, here);

  // Still no map, but something is committed: nothing new.
  const CycleReport again =
      planner.plan(kT0 + kSecond, nullptr, 0, -1, stateAt(kT0 + kSecond, here));
  EXPECT_EQ(again.state, CycleState::kNoMap);
  EXPECT_FALSE(again.trajectory);
  EXPECT_TRUE(sameSegments(*planner.committed(), hover));

  // A stale map (max_map_age 2 s; this one is 2.5 s old) is no map either.
  const DistanceField field = freeSpace();
  const int64_t t = kT0 + 2 * kSecond;
  const CycleReport stale = planner.plan(t, &field, t - 2'500'000, 4, stateAt(t, here));
  EXPECT_EQ(stale.state, CycleState::kNoMap);
  EXPECT_TRUE(contains(stale.reason, "old")) << stale.reason;
  EXPECT_EQ(stale.map_revision, 4);
  EXPECT_FALSE(stale.trajectory);
  EXPECT_TRUE(sameSegments(*planner.committed(), hover));

  // A stale map with nothing committed also hovers.
  LocalPlanner fresh_planner{LocalPlannerOptions{}};
  ASSERT_FALSE(fresh_planner.setMissionGoal(goalAt(1, {kMission})));
  const CycleReport stale_first = fresh_planner.plan(t, &field, t - 2'500'000, 4, stateAt(t, here));
  EXPECT_EQ(stale_first.state, CycleState::kNoMap);
  ASSERT_TRUE(stale_first.trajectory);
  EXPECT_NEAR((stale_first.trajectory->evaluate(0) - here).norm(), 0, 1e-12);
}

TEST(LocalPlanner, HoldsWithoutAGoal) {
  LocalPlanner planner{LocalPlannerOptions{}};
  const DistanceField field = freeSpace();
  const CycleReport report = planner.plan(kT0, &field, kT0, 1, stateAt(kT0, kStart));
  EXPECT_EQ(report.state, CycleState::kHolding);
  EXPECT_TRUE(report.is_final);
  EXPECT_FALSE(report.reason.empty());
  EXPECT_EQ(report.goal_id, -1);
  EXPECT_FALSE(planner.waitingCycle());

  // After a cancel too.
  ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
  planner.cancel();
  const CycleReport cancelled =
      planner.plan(kT0 + kSecond, &field, kT0 + kSecond, 2, stateAt(kT0 + kSecond, kStart));
  EXPECT_EQ(cancelled.state, CycleState::kHolding);
  EXPECT_FALSE(cancelled.trajectory);
}

// ---- planning from the reference ----

TEST(LocalPlanner, PlansFromTheReferenceUnlessTheEstimateDiverges) {
  LocalPlanner planner{LocalPlannerOptions{}};
  const LocoOptions& loco = planner.options().loco;
  ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = freeSpace();

  // The first cycle starts from the estimate.
  const CycleReport first = planner.plan(kT0, &field, kT0, 1, stateAt(kT0, kStart));
  ASSERT_EQ(first.state, CycleState::kPlanned) << first.reason;
  EXPECT_TRUE(first.is_final);
  EXPECT_EQ(first.cycle, 1);
  EXPECT_EQ(first.map_revision, 1);
  EXPECT_EQ(first.goal_id, 1);
  EXPECT_FALSE(first.goal_from_explorer);
  EXPECT_EQ(first.goal, kMission);
  EXPECT_NEAR((first.horizon_goal - Eigen::Vector3d(3, 0, 1.5)).norm(), 0, 1e-12);
  EXPECT_EQ(first.start.position, kStart);
  EXPECT_TRUE(first.loco.accepted);
  ASSERT_TRUE(first.trajectory);
  ASSERT_TRUE(planner.committed());
  EXPECT_TRUE(sameSegments(*planner.committed(), *first.trajectory));
  expectStartsAtReport(first);
  expectSafe(*first.trajectory, field, loco);
  // It heads for the goal.
  const Eigen::Vector3d end = first.trajectory->evaluate(first.trajectory->duration());
  EXPECT_LT((end - kMission).norm(), (kStart - kMission).norm() - 2.0);

  // 1 s later, an estimate 0.1 m beside the reference (< max_divergence 0.5 m): the cycle starts
  // from the reference, exactly.
  const int64_t t1 = kT0 + kSecond;
  const TrajectoryState reference = planner.committed()->stateAtUtime(t1);
  ASSERT_GT(reference.velocity.norm(), 0.1);  // it is flying
  const CycleReport second = planner.plan(
      t1, &field, t1, 2,
      stateAt(t1, reference.position + Eigen::Vector3d(0, 0.1, 0), reference.velocity * 0.9));
  ASSERT_EQ(second.state, CycleState::kPlanned) << second.reason;
  EXPECT_EQ(second.start.position, reference.position);
  EXPECT_EQ(second.start.velocity, reference.velocity);
  EXPECT_EQ(second.start.acceleration, reference.acceleration);
  expectStartsAtReport(second);
  expectSafe(*second.trajectory, field, loco);

  // 1 s later, an estimate 1 m off (> max_divergence): the cycle starts from the estimate.
  const int64_t t2 = t1 + kSecond;
  const TrajectoryState reference2 = planner.committed()->stateAtUtime(t2);
  const Eigen::Vector3d off = reference2.position + Eigen::Vector3d(0, 1, 0);
  const Eigen::Vector3d velocity(0.3, 0.1, 0);
  const CycleReport third = planner.plan(t2, &field, t2, 3, stateAt(t2, off, velocity));
  ASSERT_EQ(third.state, CycleState::kPlanned) << third.reason;
  EXPECT_EQ(third.start.position, off);
  EXPECT_EQ(third.start.velocity, velocity);
  EXPECT_EQ(third.start.acceleration, Eigen::Vector3d::Zero());
  expectStartsAtReport(third);
  expectSafe(*third.trajectory, field, loco);
  EXPECT_EQ(planner.cycles(), 3);
}

// ---- flying ----

TEST(LocalPlanner, FliesToTheGoalInFreeSpace) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = freeSpace();
  std::optional<CycleReport> last;
  int planned = 0;
  for (int k = 0; k < 60; ++k) {
    last = pilot.cycle(field);
    if (last->state != CycleState::kPlanned) break;
    ++planned;
  }
  ASSERT_TRUE(last);
  ASSERT_EQ(last->state, CycleState::kGoalReached) << last->reason;
  EXPECT_GT(planned, 3);
  EXPECT_TRUE(last->is_final);
  EXPECT_FALSE(last->trajectory);
  EXPECT_EQ(last->goal_id, 1);
  EXPECT_EQ(last->goal, kMission);
  EXPECT_LE((last->start.position - kMission).norm(), pilot.planner.options().goal_tolerance);
  // It stays reached, and the vehicle rests near the goal.
  const CycleReport after = pilot.cycle(field);
  EXPECT_EQ(after.state, CycleState::kGoalReached);
  const PolynomialTrajectory& committed = *pilot.planner.committed();
  EXPECT_LE((committed.evaluate(committed.duration()) - kMission).norm(),
            pilot.planner.options().goal_tolerance);
}

TEST(LocalPlanner, TracksWaypointsInOrder) {
  Pilot pilot;
  const Eigen::Vector3d w0(4, 0, 1.5);
  const Eigen::Vector3d w1(4, 4, 1.5);
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(3, {w0, w1})));
  const DistanceField field = freeSpace();
  const double tolerance = pilot.planner.options().goal_tolerance;

  int toward_w0 = 0, toward_w1 = 0;
  bool reached = false;
  for (int k = 0; k < 60 && !reached; ++k) {
    const CycleReport report = pilot.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    EXPECT_EQ(report.goal_id, 3);
    if (report.state == CycleState::kGoalReached) {
      reached = true;
      EXPECT_EQ(report.goal, w1);
      break;
    }
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    if (report.goal == w0) {
      EXPECT_EQ(toward_w1, 0) << "back to waypoint 0 after waypoint 1";
      ++toward_w0;
      // The horizon goal lies on the way to waypoint 0.
      const Eigen::Vector3d to_goal = w0 - report.start.position;
      const Eigen::Vector3d to_horizon = report.horizon_goal - report.start.position;
      EXPECT_NEAR(to_horizon.normalized().dot(to_goal.normalized()), 1, 1e-9);
      if (toward_w0 == 1) {
        EXPECT_NEAR((report.horizon_goal - Eigen::Vector3d(3, 0, 1.5)).norm(), 0, 1e-12);
      }
    } else {
      ASSERT_EQ(report.goal, w1);
      if (toward_w1 == 0) {
        // Switched only once waypoint 0 was reached.
        EXPECT_LE((report.start.position - w0).norm(), tolerance);
      }
      ++toward_w1;
    }
  }
  EXPECT_TRUE(reached);
  EXPECT_GT(toward_w0, 0);
  EXPECT_GT(toward_w1, 0);
}

// The yaw a trajectory toward a waypoint with `yaw` must be flown at: that yaw when the
// trajectory's horizontal direction is within max_yaw_offset of it (or it barely moves), else its
// direction, so the camera sees where the vehicle flies.
double expectedFlightYaw(const PolynomialTrajectory& trajectory, double yaw,
                         const LocalPlannerOptions& options) {
  const Eigen::Vector3d travel =
      trajectory.evaluate(trajectory.duration()) - trajectory.evaluate(0);
  if (travel.head<2>().norm() < options.goal_tolerance) return yaw;
  const double heading = std::atan2(travel.y(), travel.x());
  return std::abs(std::remainder(heading - yaw, 2 * M_PI)) <= options.max_yaw_offset ? yaw
                                                                                     : heading;
}

// The distance from p to the polyline through `points` [m].
double distanceToPolyline(const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& points) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const Eigen::Vector3d a = points[i], ab = points[i + 1] - a;
    const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + t * ab - p).norm());
  }
  return best;
}

TEST(LocalPlanner, TheCarrotFollowsAWaypointPathWithoutStoppingAtItsCorners) {
  // A wall x in [2.5, 3.5] up to y = 1.5; the path goes around its end at y = 3, 1.5 m from it.
  const DistanceField field = boxesField({boxFromCorners({2.5, -50, -50}, {3.5, 1.5, 150})});
  const std::vector<Eigen::Vector3d> path = {Eigen::Vector3d(0, 3, 1.5), Eigen::Vector3d(6, 3, 1.5),
                                             Eigen::Vector3d(6, 0, 1.5)};
  Goal goal = goalAt(6, path);
  goal.yaws = {M_PI / 2, 0, -M_PI / 2};
  std::vector<Eigen::Vector3d> whole_path = {kStart};
  whole_path.insert(whole_path.end(), path.begin(), path.end());

  LocalPlannerOptions options;
  options.carrot = true;
  Pilot pilot(options);
  ASSERT_FALSE(pilot.planner.setMissionGoal(goal));
  const double tolerance = options.goal_tolerance;
  const double clearance = options.loco.robot_radius + options.loco.clearance_margin;
  bool reached = false, cut_a_corner = false;
  long passed = 0;  // the waypoint tracked in the last cycle
  int carrots = 0, cycles = 0, turns = 0;
  std::optional<Eigen::Vector3d> last_carrot;
  for (; cycles < 40 && !reached; ++cycles) {
    const VehicleState before = pilot.estimate();
    const CycleReport report = pilot.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    if (report.state == CycleState::kGoalReached) {
      reached = true;
      EXPECT_LE((before.position - path.back()).norm(), tolerance);
      // Only the last waypoint's yaw must be reached.
      EXPECT_LE(std::abs(std::remainder(before.yaw + M_PI / 2, 2 * M_PI)), options.yaw_tolerance);
      break;
    }
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    // Only the last waypoint is a place to stop and turn.
    if (report.reason.starts_with("looking")) {
      EXPECT_EQ(report.goal, path.back());
      continue;
    }
    if (report.reason.starts_with("turning")) {  // turning first, then flying
      ++turns;
      continue;
    }
    ASSERT_TRUE(report.trajectory);
    const auto index = std::find(path.begin(), path.end(), report.goal) - path.begin();
    ASSERT_LT(index, 3);
    ASSERT_GE(index, passed);
    passed = index;
    if (!report.carrot) continue;  // the soft goal toward the waypoint: it found no carrot
    ++carrots;
    // Every plan ends at rest on the path (or on the way from the reference to the last carrot
    // or to the waypoint), at a point a straight free segment reaches, within the horizon.
    const Eigen::Vector3d end = report.trajectory->evaluate(report.trajectory->duration());
    EXPECT_NEAR((end - report.horizon_goal).norm(), 0, 1e-3);
    double off_path =
        std::min(distanceToPolyline(report.horizon_goal, whole_path),
                 distanceToPolyline(report.horizon_goal, {report.start.position, report.goal}));
    if (last_carrot) {
      off_path = std::min(
          off_path, distanceToPolyline(report.horizon_goal, {report.start.position, *last_carrot}));
    }
    EXPECT_LT(off_path, 1e-9);
    last_carrot = report.horizon_goal;
    EXPECT_LE((report.horizon_goal - report.start.position).norm(),
              options.goal_finder.horizon + 1e-9);
    for (double s = 0; s <= 1; s += 0.01) {
      const EsdfSample sample =
          field(report.start.position + s * (report.horizon_goal - report.start.position));
      // Checked every 0.1 m: between samples it may graze the wall's edge by a few cm.
      EXPECT_GE(sample.distance, clearance - 0.05) << "s = " << s;
    }
    // It flies facing the yaw of the waypoint its carrot leads to, unless that would not face
    // where it flies.
    ASSERT_TRUE(report.yaw);
    EXPECT_EQ(*report.yaw, expectedFlightYaw(*report.trajectory,
                                             goal.yaws[static_cast<size_t>(index)], options));
    // Toward a later waypoint while still far from an earlier one: the corner is cut.
    for (long i = 0; i < index; ++i) {
      if ((report.start.position - path[static_cast<size_t>(i)]).norm() > 2 * tolerance) {
        cut_a_corner = true;
      }
    }
  }
  EXPECT_TRUE(reached);
  EXPECT_TRUE(cut_a_corner);
  EXPECT_GT(carrots, 5);

  // The paper's planner flies the same path waypoint by waypoint, through each corner, and takes
  // longer: 21 cycles here against the carrot's 15 of flight, plus 4 that turn in place before the
  // first leg and at the corner (the paper's planner turns while it flies, looking where it goes
  // only once it is under way).
  Pilot paper;
  ASSERT_FALSE(paper.planner.setMissionGoal(goal));
  int paper_cycles = 0;
  for (; paper_cycles < 80; ++paper_cycles) {
    if (paper.cycle(field).state == CycleState::kGoalReached) break;
  }
  EXPECT_LT(cycles - turns + 3, paper_cycles);
  EXPECT_LE(cycles, paper_cycles);
}

TEST(LocalPlanner, AWaypointWithAYawIsFlownFacingItAndReachedOnlyFacingIt) {
  Pilot pilot;
  pilot.yaw_rate = 0.1;  // it turns slower than it flies: it arrives before it faces the yaw
  const Eigen::Vector3d w(3, 0, 1.5);
  Goal goal = goalAt(4, {w});
  goal.yaws = {M_PI / 2};
  ASSERT_FALSE(pilot.planner.setMissionGoal(goal));
  const DistanceField field = freeSpace();
  const double tolerance = pilot.planner.options().goal_tolerance;
  const double yaw_tolerance = pilot.planner.options().yaw_tolerance;

  int looks = 0;
  bool reached = false;
  for (int k = 0; k < 40 && !reached; ++k) {
    const VehicleState before = pilot.estimate();
    const CycleReport report = pilot.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    if (report.state == CycleState::kGoalReached) {
      reached = true;
      EXPECT_LE((before.position - w).norm(), tolerance);
      EXPECT_LE(std::abs(std::remainder(before.yaw - M_PI / 2, 2 * M_PI)), yaw_tolerance);
      break;
    }
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    // Every trajectory toward the waypoint is flown facing where it goes (the yaw is 90 degrees
    // off that), the looks at the waypoint facing its yaw.
    ASSERT_TRUE(report.yaw);
    ASSERT_TRUE(report.trajectory);
    EXPECT_EQ(*report.yaw,
              expectedFlightYaw(*report.trajectory, M_PI / 2, pilot.planner.options()));
    if (!report.reason.starts_with("looking")) {
      EXPECT_LT(std::abs(*report.yaw), 0.1);
    } else {
      EXPECT_EQ(*report.yaw, M_PI / 2);
    }
    EXPECT_EQ(pilot.planner.committedYaw(), report.yaw);
    if (report.reason.starts_with("looking")) {
      // At the waypoint but not yet facing the yaw: it stays there and turns.
      ++looks;
      EXPECT_LE((report.start.position - w).norm(), tolerance);
      ASSERT_TRUE(report.trajectory);
      const Eigen::Vector3d rest = report.trajectory->evaluate(report.trajectory->duration());
      EXPECT_LE((rest - w).norm(), tolerance);
      EXPECT_GT(std::abs(std::remainder(before.yaw - M_PI / 2, 2 * M_PI)), yaw_tolerance);
    }
  }
  EXPECT_TRUE(reached);
  EXPECT_GE(looks, 5);  // about 14 cycles of turning, fewer than 5 of them flying there

  // A yaw near the direction of flight is flown all the way.
  Goal near = goalAt(6, {Eigen::Vector3d(6, 3, 1.5)});
  near.yaws = {0.5};  // the flight heads north-east, about 0.79 rad
  ASSERT_FALSE(pilot.planner.setMissionGoal(near));
  const CycleReport toward = pilot.cycle(field);
  ASSERT_EQ(toward.state, CycleState::kPlanned) << toward.reason;
  ASSERT_TRUE(toward.yaw);
  EXPECT_EQ(*toward.yaw, 0.5);

  // A goal without yaws is flown along the velocity.
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(5, {Eigen::Vector3d(3, 3, 1.5)})));
  const CycleReport plain = pilot.cycle(field);
  ASSERT_EQ(plain.state, CycleState::kPlanned) << plain.reason;
  EXPECT_FALSE(plain.yaw);
  EXPECT_FALSE(pilot.planner.committedYaw());
}

TEST(LocalPlanner, ItTurnsInPlaceBeforeItFliesAWaypointBehindIt) {
  // A waypoint 4 m behind the vehicle (which faces +x), to be looked at facing away from it.
  Pilot pilot;
  pilot.yaw_rate = 0.4;  // about 8 cycles to turn around
  const Eigen::Vector3d w(-4, 0, 1.5);
  Goal goal = goalAt(7, {w});
  goal.yaws = {M_PI};
  ASSERT_FALSE(pilot.planner.setMissionGoal(goal));
  const DistanceField field = freeSpace();
  const LocalPlannerOptions& options = pilot.planner.options();

  int turns = 0, flights = 0;
  bool reached = false;
  for (int k = 0; k < 40 && !reached; ++k) {
    const VehicleState before = pilot.estimate();
    const CycleReport report = pilot.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    if (report.state == CycleState::kGoalReached) {
      reached = true;
      EXPECT_LE((before.position - w).norm(), options.goal_tolerance);
      break;
    }
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    ASSERT_TRUE(report.trajectory);
    ASSERT_TRUE(report.yaw);
    EXPECT_EQ(*report.yaw, M_PI);
    const double off = std::abs(std::remainder(before.yaw - M_PI, 2 * M_PI));
    const Eigen::Vector3d end = report.trajectory->evaluate(report.trajectory->duration());
    if (report.reason.starts_with("turning")) {
      // Not yet facing where it would go: it stops where it is (at rest, it stays) and turns.
      ++turns;
      EXPECT_EQ(flights, 0) << "turned again after it flew";
      EXPECT_GT(off, options.max_yaw_offset);
      EXPECT_LT((end - before.position).head<2>().norm(), 1e-6);
      EXPECT_LT((before.position - kStart).norm(), 1e-6) << "moved before it faced the waypoint";
    } else if (!report.reason.starts_with("looking")) {
      // Flying: only once it faces the way it flies.
      ++flights;
      EXPECT_LE(off, options.max_yaw_offset);
      EXPECT_LT(end.x(), before.position.x());
    }
  }
  EXPECT_TRUE(reached);
  // From yaw 0 to within 0.6 rad of pi at 0.4 rad per cycle: 7 cycles of turning, then flight.
  EXPECT_EQ(turns, 7);
  EXPECT_GT(flights, 2);

  // A goal without yaws (the paper's planner) flies at once, turning along its velocity.
  Pilot paper;
  paper.yaw_rate = 0.4;
  ASSERT_FALSE(paper.planner.setMissionGoal(goalAt(8, {w})));
  const CycleReport first = paper.cycle(field);
  ASSERT_EQ(first.state, CycleState::kPlanned) << first.reason;
  ASSERT_TRUE(first.trajectory);
  EXPECT_TRUE(first.reason.empty()) << first.reason;
  EXPECT_LT(first.trajectory->evaluate(first.trajectory->duration()).x(), -0.5);
}

// ---- stuck, the explorer, intermediate goals ----

// Flies toward kMission through `field` until a cycle is stuck (at most 30 cycles).
std::optional<CycleReport> flyUntilStuck(Pilot& pilot, const DistanceField& field) {
  for (int k = 0; k < 30; ++k) {
    const CycleReport report = pilot.cycle(field);
    if (report.state == CycleState::kStuck) return report;
    EXPECT_EQ(report.state, CycleState::kPlanned) << report.reason;
    if (report.state != CycleState::kPlanned) return std::nullopt;
  }
  return std::nullopt;
}

TEST(LocalPlanner, AFullyBlockingWallIsStuckAndCommitsNothing) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  // Fly up to the wall until it can go no further.
  std::optional<PolynomialTrajectory> before;
  std::optional<CycleReport> stuck;
  for (int k = 0; k < 30 && !stuck; ++k) {
    before = pilot.planner.committed();
    const CycleReport report = pilot.cycle(field);
    if (report.state == CycleState::kStuck) {
      stuck = report;
    } else {
      ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    }
  }
  ASSERT_TRUE(stuck);
  EXPECT_TRUE(stuck->is_final);  // no explorer to wait for
  EXPECT_FALSE(stuck->trajectory);
  EXPECT_FALSE(stuck->reason.empty());
  EXPECT_EQ(stuck->goal, kMission);
  EXPECT_EQ(stuck->goal_id, 1);
  EXPECT_FALSE(pilot.planner.waitingCycle());
  ASSERT_TRUE(before);
  ASSERT_TRUE(pilot.planner.committed());
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), *before));
  // It stopped on the near side of the wall.
  EXPECT_LT(stuck->start.position.x(), 2.5 - pilot.planner.options().loco.robot_radius);
  // And stays stuck (nothing committed) on the next cycle.
  const CycleReport again = pilot.cycle(field);
  EXPECT_EQ(again.state, CycleState::kStuck);
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), *before));
}

// A wall 2 m high across the way, infinite sideways, and a mission waypoint above it: the vehicle
// flies over the wall and never above the flight volume's ceiling, 3.6 m.
TEST(LocalPlanner, TrajectoriesStayBelowTheCeiling) {
  const DistanceField field = boxesField({boxFromCorners({2.5, -50, -50}, {3.5, 50, 2.0})});
  LocalPlannerOptions options;
  options.flight_volume_min = Eigen::Vector3d(-20, -20, 0);
  options.flight_volume_max = Eigen::Vector3d(20, 20, 3.6);
  Pilot pilot(options);
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {Eigen::Vector3d(3, 0, 3.0), kMission})));
  double highest = 0;
  CycleReport last;
  for (int k = 0; k < 40; ++k) {
    last = pilot.cycle(field);
    if (last.trajectory) {
      for (double t = 0; t <= last.trajectory->duration(); t += 0.01) {
        highest = std::max(highest, last.trajectory->evaluate(t).z());
      }
    }
    if (last.state != CycleState::kPlanned) break;
  }
  EXPECT_EQ(last.state, CycleState::kGoalReached) << last.reason;
  EXPECT_GT(highest, 2.0 + options.loco.robot_radius);  // it did fly over the wall
  EXPECT_LE(highest, 3.6 + 1e-9);
}

// Climbing at 1 m/s 0.1 m below the ceiling, every trajectory overshoots it (the stopping distance
// at a_max is 0.25 m): none is acceptable, though the map is free (the vehicle hovers and the
// report says why). Under a high ceiling it plans.
TEST(LocalPlanner, RefusesTrajectoriesThatLeaveTheFlightVolume) {
  for (const double ceiling : {3.0, 100.0}) {
    LocalPlannerOptions options;
    options.flight_volume_max.z() = ceiling;
    LocalPlanner planner(options);
    ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
    const DistanceField field = freeSpace();
    const CycleReport report = planner.plan(
        kT0, &field, kT0, 1, stateAt(kT0, Eigen::Vector3d(0, 0, 2.9), Eigen::Vector3d(0, 0, 1)));
    if (ceiling < 10) {
      EXPECT_EQ(report.state, CycleState::kStuck);
      EXPECT_TRUE(contains(report.reason, "distance")) << report.reason;
    } else {
      EXPECT_EQ(report.state, CycleState::kPlanned) << report.reason;
    }
  }
}

TEST(LocalPlanner, AThickWallIsStuckTooNotPlannedInPlace) {
  // A wall 17.5 m thick: the horizon goal is deep inside it, and the nearest way out of it (the
  // ESDF gradient) leads back toward the vehicle. Hovering in front of the wall is no progress
  // toward the goal: the planner must say it is stuck (so that an explorer is asked), not
  // "planned" with a trajectory that goes nowhere.
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {Eigen::Vector3d(30, 0, 1.5)})));
  const DistanceField field = boxesField({boxFromCorners({2.5, -50, -50}, {20, 50, 150})});
  std::optional<CycleReport> stuck;
  for (int k = 0; k < 30 && !stuck; ++k) {
    const CycleReport report = pilot.cycle(field);
    if (report.state == CycleState::kStuck) stuck = report;
  }
  ASSERT_TRUE(stuck) << "never stuck in front of the wall; the vehicle is at x = "
                     << pilot.estimate().position.x();
  EXPECT_FALSE(stuck->trajectory);
  EXPECT_LT(stuck->start.position.x(), 2.5 - pilot.planner.options().loco.robot_radius);
}

// Unknown space from 5 cm ahead of the vehicle on: the horizon goal's search backs along the line
// to the start itself (unknown space has no gradient). A plan toward the start goes nowhere:
// stuck, with a reason that says so, and no optimization of a spline of no length (which broke
// down to a trajectory through the origin).
TEST(LocalPlanner, ASearchBackToTheStartIsStuckWithoutOptimizing) {
  // Free space, unknown from `ahead` in front of the start on.
  const DistanceField free = freeSpace();
  const auto unknownFrom = [&free](double ahead) -> DistanceField {
    return [&free, ahead](const Eigen::Vector3d& p) {
      return p.x() > kStart.x() + ahead ? EsdfSample{} : free(p);
    };
  };
  LocalPlanner planner({});
  ASSERT_FALSE(planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = unknownFrom(0.05);
  const CycleReport report = planner.plan(kT0, &field, kT0, 1, stateAt(kT0, kStart));
  EXPECT_EQ(report.state, CycleState::kStuck);
  EXPECT_TRUE(contains(report.reason, "no horizon goal away from the start")) << report.reason;
  EXPECT_EQ(report.loco.iterations, 0);
  ASSERT_TRUE(report.trajectory);  // a hover where it is
  EXPECT_NEAR((report.trajectory->evaluate(report.trajectory->duration()) - kStart).norm(), 0,
              1e-9);
  // With the unknown space 2 m ahead, the horizon goal lies before it and the vehicle flies.
  const DistanceField farther = unknownFrom(2.0);
  LocalPlanner other({});
  ASSERT_FALSE(other.setMissionGoal(goalAt(1, {kMission})));
  EXPECT_EQ(other.plan(kT0, &farther, kT0, 1, stateAt(kT0, kStart)).state, CycleState::kPlanned);
}

LocalPlannerOptions withExplorer() {
  LocalPlannerOptions options;
  options.use_explorer = true;
  return options;
}

TEST(LocalPlanner, AStuckCycleWaitsForTheExplorer) {
  Pilot pilot(withExplorer());
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  EXPECT_THROW(pilot.planner.answer(std::nullopt, "nothing", &field), std::logic_error);

  const std::optional<CycleReport> stuck = flyUntilStuck(pilot, field);
  ASSERT_TRUE(stuck);
  EXPECT_FALSE(stuck->is_final);
  EXPECT_FALSE(stuck->trajectory);
  ASSERT_TRUE(pilot.planner.waitingCycle());
  EXPECT_EQ(*pilot.planner.waitingCycle(), stuck->cycle);
  const std::optional<PolynomialTrajectory> before = pilot.planner.committed();

  // The explorer has nothing: the cycle closes holding, and says the explorer found nothing.
  const CycleReport none = pilot.planner.answer(std::nullopt, "no candidate", &field);
  EXPECT_EQ(none.cycle, stuck->cycle);
  EXPECT_EQ(none.state, CycleState::kHolding);
  EXPECT_TRUE(none.is_final);
  EXPECT_TRUE(contains(none.reason, "explorer")) << none.reason;
  EXPECT_TRUE(contains(none.reason, "no candidate")) << none.reason;
  EXPECT_FALSE(none.trajectory);
  EXPECT_FALSE(pilot.planner.waitingCycle());
  EXPECT_FALSE(pilot.planner.intermediateGoal());
  ASSERT_TRUE(pilot.planner.committed());
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), *before));
  // Nothing is waiting any more.
  EXPECT_THROW(pilot.planner.answer(std::nullopt, "again", &field), std::logic_error);

  // Stuck again on the next cycle; a new plan() abandons the waiting cycle, and a plan that
  // succeeds (the wall is gone from the map) leaves nothing waiting.
  const CycleReport again = pilot.cycle(field);
  ASSERT_EQ(again.state, CycleState::kStuck) << again.reason;
  ASSERT_TRUE(pilot.planner.waitingCycle());
  EXPECT_EQ(*pilot.planner.waitingCycle(), again.cycle);
  const CycleReport stuck_again = pilot.cycle(field);
  ASSERT_EQ(stuck_again.state, CycleState::kStuck);
  EXPECT_EQ(*pilot.planner.waitingCycle(), stuck_again.cycle);  // the new one, not the old
  const CycleReport planned = pilot.cycle(freeSpace());
  EXPECT_EQ(planned.state, CycleState::kPlanned) << planned.reason;
  EXPECT_TRUE(planned.is_final);
  EXPECT_FALSE(pilot.planner.waitingCycle());
  EXPECT_THROW(pilot.planner.answer(std::nullopt, "late", &field), std::logic_error);
}

TEST(LocalPlanner, TracksAnIntermediateGoalThenReturnsToTheMission) {
  Pilot pilot(withExplorer());
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  const std::optional<CycleReport> stuck = flyUntilStuck(pilot, field);
  ASSERT_TRUE(stuck);
  ASSERT_TRUE(pilot.planner.waitingCycle());

  // An intermediate goal on the near side of the wall, 2.5 m to the side.
  const Eigen::Vector3d side = stuck->start.position + Eigen::Vector3d(-0.5, 2.5, 0);
  const CycleReport answered =
      pilot.planner.answer(goalAt(77, {side}, /*from_explorer=*/true), "best gain", &field);
  pilot.check(answered, field);
  EXPECT_EQ(answered.cycle, stuck->cycle);
  ASSERT_EQ(answered.state, CycleState::kPlanned) << answered.reason;
  EXPECT_TRUE(answered.is_final);
  EXPECT_TRUE(answered.goal_from_explorer);
  EXPECT_EQ(answered.goal_id, 77);
  EXPECT_EQ(answered.goal, side);
  ASSERT_TRUE(answered.trajectory);
  EXPECT_EQ(answered.trajectory->startUtime(), stuck->utime);
  EXPECT_EQ(answered.start.position, stuck->start.position);
  ASSERT_TRUE(pilot.planner.intermediateGoal());
  EXPECT_EQ(pilot.planner.intermediateGoal()->id, 77);
  EXPECT_FALSE(pilot.planner.waitingCycle());

  // Later cycles track it until it is reached, then return to the mission goal.
  const double tolerance = pilot.planner.options().goal_tolerance;
  int toward_side = 0;
  std::optional<CycleReport> back;
  for (int k = 0; k < 30 && !back; ++k) {
    const CycleReport report = pilot.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(report.cycle));
    if (report.goal_id == 77) {
      ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
      EXPECT_TRUE(report.goal_from_explorer);
      EXPECT_EQ(report.goal, side);
      ++toward_side;
    } else {
      back = report;
    }
  }
  ASSERT_TRUE(back);
  EXPECT_GT(toward_side, 0);
  EXPECT_EQ(back->goal_id, 1);
  EXPECT_EQ(back->goal, kMission);
  EXPECT_FALSE(back->goal_from_explorer);
  EXPECT_LE((back->start.position - side).norm(), tolerance);
  EXPECT_FALSE(pilot.planner.intermediateGoal());
}

TEST(LocalPlanner, AnInfeasibleIntermediateGoalIsDropped) {
  Pilot pilot(withExplorer());
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  const std::optional<CycleReport> stuck = flyUntilStuck(pilot, field);
  ASSERT_TRUE(stuck);
  const std::optional<PolynomialTrajectory> before = pilot.planner.committed();

  // Beyond the wall: infeasible as the answer itself; the cycle closes holding, nothing committed.
  const CycleReport beyond = pilot.planner.answer(
      goalAt(78, {Eigen::Vector3d(5, 0, 1.5)}, /*from_explorer=*/true), "beyond", &field);
  EXPECT_EQ(beyond.state, CycleState::kHolding);
  EXPECT_TRUE(beyond.is_final);
  EXPECT_TRUE(contains(beyond.reason, "infeasible")) << beyond.reason;
  EXPECT_FALSE(beyond.trajectory);
  EXPECT_FALSE(pilot.planner.intermediateGoal());
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), *before));

  // An answer outside the flight volume is refused.
  const CycleReport again = pilot.cycle(field);
  ASSERT_EQ(again.state, CycleState::kStuck) << again.reason;
  const CycleReport refused = pilot.planner.answer(
      goalAt(79, {Eigen::Vector3d(0, 0, -3)}, /*from_explorer=*/true), "under", &field);
  EXPECT_EQ(refused.state, CycleState::kHolding);
  EXPECT_TRUE(contains(refused.reason, "outside the flight volume")) << refused.reason;
  EXPECT_FALSE(pilot.planner.intermediateGoal());

  // An answer without a map cannot be planned.
  const CycleReport stuck_without_map = pilot.cycle(field);
  ASSERT_EQ(stuck_without_map.state, CycleState::kStuck) << stuck_without_map.reason;
  const CycleReport no_map = pilot.planner.answer(
      goalAt(81, {stuck_without_map.start.position + Eigen::Vector3d(0, 2.5, 0)}, true), "side",
      nullptr);
  EXPECT_EQ(no_map.state, CycleState::kHolding);
  EXPECT_TRUE(no_map.is_final);
  EXPECT_TRUE(contains(no_map.reason, "no map")) << no_map.reason;
  EXPECT_FALSE(no_map.trajectory);
  EXPECT_FALSE(pilot.planner.intermediateGoal());

  // A feasible one straight to the side (+y)...
  const CycleReport stuck_again = pilot.cycle(field);
  ASSERT_EQ(stuck_again.state, CycleState::kStuck) << stuck_again.reason;
  const Eigen::Vector3d start = stuck_again.start.position;
  const Eigen::Vector3d side = start + Eigen::Vector3d(0, 2.5, 0);
  const CycleReport answered =
      pilot.planner.answer(goalAt(80, {side}, /*from_explorer=*/true), "side", &field);
  pilot.check(answered, field);
  ASSERT_EQ(answered.state, CycleState::kPlanned) << answered.reason;
  ASSERT_TRUE(pilot.planner.intermediateGoal());

  // ... then a map revision 1 ms later shows a second wall across the way to it (0.75 m to the
  // side), while the wall toward the mission goal turns out not to be there: the intermediate goal
  // is dropped and the same cycle plans toward the mission goal.
  const DistanceField side_wall =
      boxesField({boxFromCorners({-50, start.y() + 0.75, -50}, {50, start.y() + 1.05, 150})});
  const int64_t t = stuck_again.utime + 1000;
  const TrajectoryState reference = pilot.planner.committed()->stateAtUtime(t);
  const CycleReport dropped =
      pilot.planner.plan(t, &side_wall, t, 100, stateAt(t, reference.position, reference.velocity));
  pilot.check(dropped, side_wall);
  EXPECT_EQ(dropped.state, CycleState::kPlanned) << dropped.reason;
  // The trajectory toward the intermediate goal crossed the new wall: the re-check refused it
  // before the cycle replanned.
  EXPECT_TRUE(contains(dropped.blocked, "the committed trajectory is blocked")) << dropped.blocked;
  EXPECT_TRUE(contains(dropped.reason, "replanned")) << dropped.reason;
  EXPECT_EQ(dropped.goal_id, 1);
  EXPECT_EQ(dropped.goal, kMission);
  EXPECT_FALSE(dropped.goal_from_explorer);
  EXPECT_FALSE(pilot.planner.intermediateGoal());
}

// Flies toward kMission into wall() until a cycle is stuck planning from rest.
CycleReport stuckAtRest(Pilot& pilot, const DistanceField& field) {
  std::optional<CycleReport> stuck = flyUntilStuck(pilot, field);
  const auto moving = [](const TrajectoryState& s) {
    return s.velocity.norm() > 0 || s.acceleration.norm() > 0;
  };
  for (int k = 0; k < 10 && stuck && moving(stuck->start); ++k) stuck = pilot.cycle(field);
  EXPECT_TRUE(stuck && stuck->state == CycleState::kStuck);
  EXPECT_TRUE(stuck && !moving(stuck->start));
  return stuck.value_or(CycleReport{});
}

TEST(LocalPlanner, AnIntermediateGoalAtTheVehicleIsALookInPlace) {
  Pilot pilot(withExplorer());
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  const CycleReport stuck = stuckAtRest(pilot, field);
  ASSERT_TRUE(pilot.planner.waitingCycle());
  const Eigen::Vector3d here = stuck.start.position;

  Goal look = goalAt(78, {here}, /*from_explorer=*/true);
  look.yaws = {M_PI};  // behind it: the vehicle faces the wall (+x)
  const CycleReport answered = pilot.planner.answer(look, "look back", &field);
  pilot.check(answered, field);
  ASSERT_EQ(answered.state, CycleState::kPlanned) << answered.reason;
  EXPECT_TRUE(answered.reason.starts_with("looking")) << answered.reason;
  ASSERT_TRUE(answered.yaw);
  EXPECT_EQ(*answered.yaw, M_PI);
  ASSERT_TRUE(answered.trajectory);
  for (double s = 0; s <= answered.trajectory->duration() + 1; s += 0.1) {
    EXPECT_NEAR((answered.trajectory->evaluate(s) - here).norm(), 0, 1e-9) << "t = " << s;
  }

  // It turns in place (1 rad per cycle) until it faces back, then returns to the mission.
  int looks = 0;
  std::optional<CycleReport> back;
  for (int k = 0; k < 10 && !back; ++k) {
    const CycleReport report = pilot.cycle(field);
    if (report.goal_id != 78) {
      back = report;
      break;
    }
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    EXPECT_NEAR((report.start.position - here).norm(), 0, 1e-9);
    ++looks;
  }
  ASSERT_TRUE(back);
  EXPECT_EQ(looks, 3);  // at yaw 0, 1 and 2; 3 is within 0.2 rad of pi
  EXPECT_EQ(back->goal_id, 1);
  EXPECT_EQ(back->state, CycleState::kStuck) << back->reason;
  EXPECT_FALSE(pilot.planner.intermediateGoal());
}

TEST(LocalPlanner, TheStallWatchdogGivesUpGoalsTheVehicleDoesNotMoveToward) {
  LocalPlannerOptions options = withExplorer();
  options.stall_cycles = 3;
  options.stall_distance = 0.3;
  Pilot pilot(options);
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  const CycleReport stuck = stuckAtRest(pilot, field);

  // A look the vehicle cannot complete (it does not turn): planned every cycle, going nowhere.
  pilot.yaw_rate = 0;
  Goal look = goalAt(79, {stuck.start.position}, /*from_explorer=*/true);
  look.yaws = {M_PI};
  ASSERT_EQ(pilot.planner.answer(look, "look back", &field).state, CycleState::kPlanned);
  for (int k = 0; k < 2; ++k) {
    const CycleReport report = pilot.cycle(field);
    ASSERT_EQ(report.goal_id, 79);
    ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
  }
  // The third cycle after the answer gives it up; the mission goal is stuck as before.
  const CycleReport dropped = pilot.cycle(field);
  EXPECT_EQ(dropped.state, CycleState::kStuck);
  EXPECT_TRUE(contains(dropped.reason, "intermediate goal 79 dropped (stalled")) << dropped.reason;
  EXPECT_FALSE(pilot.planner.intermediateGoal());
  ASSERT_TRUE(pilot.planner.waitingCycle());

  // Unanswered, the mission goal itself is reported stalled after 3 more cycles on it.
  for (int k = 0; k < 2; ++k) {
    const CycleReport report = pilot.cycle(field);
    EXPECT_EQ(report.state, CycleState::kStuck);
    EXPECT_FALSE(contains(report.reason, "stalled")) << report.reason;
  }
  const CycleReport stalled = pilot.cycle(field);
  EXPECT_EQ(stalled.state, CycleState::kStuck);
  EXPECT_TRUE(stalled.reason.starts_with("stalled: the reference moved 0.00 m in the last 3"))
      << stalled.reason;
}

TEST(Watchdog, CountsConsecutiveCyclesOnOneWaypointOfOneGoal) {
  const Eigen::Vector3d p(1, 2, 3), step(0.1, 0, 0);
  Watchdog still;
  EXPECT_FALSE(still.stalled(1, 0, 10, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(1, 0, 11, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(1, 0, 12, p, 3, 0.3));
  EXPECT_TRUE(still.stalled(1, 0, 13, p + 0.5 * step, 3, 0.3));
  EXPECT_NEAR(still.moved(), 0.05, 1e-12);
  EXPECT_TRUE(still.stalled(1, 0, 14, p, 3, 0.3));  // the window slides
  // A new waypoint, a new goal or a skipped cycle starts over.
  EXPECT_FALSE(still.stalled(1, 1, 15, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(2, 1, 16, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(2, 1, 18, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(2, 1, 19, p, 3, 0.3));
  EXPECT_FALSE(still.stalled(2, 1, 20, p, 3, 0.3));
  EXPECT_TRUE(still.stalled(2, 1, 21, p, 3, 0.3));

  // Moving more than stall_distance over the window is progress, however slowly.
  Watchdog moving;
  for (int k = 0; k < 10; ++k) {
    EXPECT_FALSE(moving.stalled(1, 0, k, p + k * 1.01 * step, 3, 0.3)) << k;
  }
  // Back and forth within stall_distance is not.
  Watchdog dithering;
  bool stalled = false;
  for (int k = 0; k < 10; ++k) stalled = dithering.stalled(1, 0, k, p + (k % 2) * step, 3, 0.3);
  EXPECT_TRUE(stalled);
  // Back and forth between two points farther apart than stall_distance is too, at either parity
  // of the window: the reference returns to where it was.
  for (const int cycles : {3, 4}) {
    Watchdog swinging;
    int first = -1;
    for (int k = 0; k < 10 && first < 0; ++k) {
      if (swinging.stalled(1, 0, k, p + (k % 2) * 5 * step, cycles, 0.3)) first = k;
    }
    EXPECT_EQ(first, cycles) << cycles;  // as soon as the window is full
    EXPECT_NEAR(swinging.moved(), 0, 1e-12);
    EXPECT_EQ(swinging.over(), cycles % 2 == 0 ? cycles : cycles - 1);
  }
  // A cycle that stops to turn before flying does not count, nor break the window.
  Watchdog turning;
  for (int k = 0; k < 3; ++k) EXPECT_FALSE(turning.stalled(1, 0, k, p, 3, 0.3));
  EXPECT_TRUE(turning.stalled(1, 0, 3, p, 3, 0.3));
  turning.skip();
  EXPECT_TRUE(turning.stalled(1, 0, 4, p, 3, 0.3));
  Watchdog flying;  // every other cycle stops to turn, the others fly on
  for (int k = 0; k < 8; ++k) {
    EXPECT_FALSE(flying.stalled(1, 0, 2 * k, p + k * 1.01 * step, 3, 0.3)) << k;
    flying.stalled(1, 0, 2 * k + 1, p + k * 1.01 * step, 3, 0.3);
    flying.skip();
  }
  // 0 cycles: off.
  Watchdog off;
  for (int k = 0; k < 10; ++k) EXPECT_FALSE(off.stalled(1, 0, k, p, 0, 0.3));
}

TEST(LocalPlanner, ACancelWhileWaitingClosesTheCycleWithoutFlyingToTheAnswer) {
  Pilot pilot(withExplorer());
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField field = wall();
  const std::optional<CycleReport> stuck = flyUntilStuck(pilot, field);
  ASSERT_TRUE(stuck);
  ASSERT_TRUE(pilot.planner.waitingCycle());
  const std::optional<PolynomialTrajectory> before = pilot.planner.committed();

  // The operator cancels while the explorer is still thinking; its answer arrives afterwards.
  // The cycle must still close (the simulator waits for its final status), but the vehicle must
  // not set off toward a goal of a mission that no longer exists.
  pilot.planner.cancel();
  EXPECT_FALSE(pilot.planner.missionGoal());
  const Eigen::Vector3d side = stuck->start.position + Eigen::Vector3d(0, 2.5, 0);
  CycleReport answered;
  if (pilot.planner.waitingCycle()) {
    answered = pilot.planner.answer(goalAt(90, {side}, /*from_explorer=*/true), "late", &field);
    EXPECT_EQ(answered.cycle, stuck->cycle);
    EXPECT_TRUE(answered.is_final);
    EXPECT_EQ(answered.state, CycleState::kHolding) << answered.reason;
    EXPECT_FALSE(answered.trajectory);
  }
  EXPECT_FALSE(pilot.planner.intermediateGoal());
  ASSERT_TRUE(pilot.planner.committed());
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), *before));
}

// ---- the re-check of the committed trajectory ----

TEST(LocalPlanner, AnUnchangedMapNeverBlocksTheCommittedTrajectory) {
  // Through a gap 2 cm of clearance wider than the acceptance test asks for on the centre line,
  // with maps that come 1.01 s apart (off the 0.02 s sample grid): the re-check must ask for what
  // the acceptance test asked, where it asked.
  Pilot pilot;
  const LocoOptions& loco = pilot.planner.options().loco;
  const double half_gap = loco.robot_radius + loco.clearance_margin + 0.02;
  const DistanceField field = boxesField({boxFromCorners({4.4, -5, 0}, {4.6, -half_gap, 5}),
                                          boxFromCorners({4.4, half_gap, 0}, {4.6, 5, 5})});
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  CycleReport last;
  for (int k = 0; k < 60; ++k) {
    last = pilot.cycle(field);
    pilot.t += kSecond / 100;
    EXPECT_TRUE(last.blocked.empty()) << "cycle " << last.cycle << ": " << last.blocked;
    if (last.state != CycleState::kPlanned) break;
  }
  EXPECT_EQ(last.state, CycleState::kGoalReached) << last.reason;
}

// The strictest map on which `trajectory` still passes the acceptance test: known everywhere,
// clear (`required`) exactly at its samples (every kClearanceCheckDt from its start, and its end),
// 1 cm too near everywhere else.
DistanceField clearOnlyAtTheSamplesOf(const PolynomialTrajectory& trajectory, double required) {
  std::vector<Eigen::Vector3d> samples;
  for (int k = 0; k * kClearanceCheckDt < trajectory.duration(); ++k) {
    samples.push_back(trajectory.evaluate(k * kClearanceCheckDt));
  }
  samples.push_back(trajectory.evaluate(trajectory.duration()));
  return [samples, required](const Eigen::Vector3d& p) {
    for (const Eigen::Vector3d& s : samples) {
      if (p == s) return EsdfSample{true, required, Eigen::Vector3d::Zero()};
    }
    return EsdfSample{true, required - 0.01, Eigen::Vector3d::Zero()};
  };
}

TEST(LocalPlanner, TheRecheckSamplesWhereTheAcceptanceTestDid) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  ASSERT_EQ(pilot.cycle(freeSpace()).state, CycleState::kPlanned);
  const PolynomialTrajectory committed = *pilot.planner.committed();
  const LocoOptions& o = pilot.planner.options().loco;
  const DistanceField strict =
      clearOnlyAtTheSamplesOf(committed, o.robot_radius + o.clearance_margin);

  // 1.013 s into it, between two samples: the rest still passes (nothing else does: from there,
  // inside the margin, a plan would have to end outside it, so the cycle is stuck and the
  // committed trajectory stands).
  pilot.t = committed.startUtime() + 1'013'000;
  const CycleReport report = pilot.cycle(strict);
  EXPECT_TRUE(report.blocked.empty()) << report.blocked;
  EXPECT_EQ(report.state, CycleState::kStuck) << report.reason;
  EXPECT_FALSE(report.trajectory);
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), committed));
}

TEST(LocalPlanner, AnObstacleOnThePartAlreadyFlownBlocksNothing) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  // Fly until the vehicle is well past where it started.
  for (int k = 0; k < 10 && pilot.estimate().position.x() < kStart.x() + 1.5; ++k) {
    ASSERT_EQ(pilot.cycle(freeSpace()).state, CycleState::kPlanned);
  }
  ASSERT_GE(pilot.estimate().position.x(), kStart.x() + 1.5);
  // A post where it took off: on the committed trajectory, but behind the vehicle.
  const DistanceField post = cylinderField(kStart.head<2>(), 0.3);
  ASSERT_LT(post(pilot.planner.committed()->evaluate(0)).distance, 0.6);
  const CycleReport report = pilot.cycle(post);
  EXPECT_TRUE(report.blocked.empty()) << report.blocked;
  EXPECT_EQ(report.state, CycleState::kPlanned) << report.reason;
}

// Plans toward kMission in free space, then returns the map the pilot's next cycle will see: a
// wall across the whole way (y and z far beyond the flight) whose clearance margin begins `gap`
// beyond where the hardest stop from the reference comes to rest (before it when negative).
DistanceField wallAfterTakeOff(Pilot& pilot, double gap) {
  const CycleReport first = pilot.cycle(freeSpace());
  EXPECT_EQ(first.state, CycleState::kPlanned) << first.reason;
  const LocoOptions& o = pilot.planner.options().loco;
  const TrajectoryState reference = pilot.planner.committed()->stateAtUtime(pilot.t);
  EXPECT_GT(reference.velocity.x(), 0.1);  // flying toward it
  const double stop = planStop(pilot.t, reference, freeSpace(), o).distance;
  const double face = reference.position.x() + stop + o.robot_radius + o.clearance_margin + gap;
  return boxesField({boxFromCorners({face, -50, -50}, {face + 1, 50, 150})});
}

// The cycle's trajectory is a stop: from the reference to rest.
void expectStop(const CycleReport& report) {
  ASSERT_TRUE(report.trajectory);
  testing::expectFromStartToRest(*report.trajectory, report.start);
}

TEST(LocalPlanner, AWallAcrossTheCommittedTrajectoryStopsTheVehicle) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField wall = wallAfterTakeOff(pilot, 0.15);
  const LocoOptions& o = pilot.planner.options().loco;

  const CycleReport stopping = pilot.cycle(wall);
  ASSERT_EQ(stopping.state, CycleState::kStopping) << stopping.reason;
  EXPECT_TRUE(stopping.is_final);
  EXPECT_TRUE(contains(stopping.blocked, "the committed trajectory is blocked (sample at t="))
      << stopping.blocked;
  EXPECT_TRUE(contains(stopping.blocked, "in certified free space")) << stopping.blocked;
  EXPECT_FALSE(contains(stopping.blocked, "no stop")) << stopping.blocked;
  EXPECT_TRUE(contains(stopping.reason, stopping.blocked)) << stopping.reason;
  expectStop(stopping);
  ASSERT_TRUE(stopping.trajectory);
  // Certified: flown, it keeps the clearance the acceptance asks for from the new wall.
  const testing::TrajectoryReport flown = inspectTrajectory(*stopping.trajectory, wall, 0.01);
  EXPECT_GE(flown.min_distance, o.robot_radius + o.clearance_margin)
      << "at t = " << flown.min_distance_time << " s";

  // It stays there: the stop passes the re-check, and nothing gets nearer the wall.
  const Eigen::Vector3d rest = stopping.trajectory->evaluate(stopping.trajectory->duration());
  for (int k = 0; k < 3; ++k) {
    const CycleReport next = pilot.cycle(wall);
    EXPECT_EQ(next.state, CycleState::kStuck) << next.reason;
    EXPECT_TRUE(next.blocked.empty()) << next.blocked;
    EXPECT_LT((pilot.estimate().position - rest).norm(), 1e-9) << "cycle " << next.cycle;
  }
}

TEST(LocalPlanner, AWallTooNearForACertifiedStopTakesTheHardestStop) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  // The hardest stop ends 8 cm inside the margin (still beyond the robot radius).
  const DistanceField wall = wallAfterTakeOff(pilot, -0.08);

  const CycleReport stopping = pilot.cycle(wall);
  ASSERT_EQ(stopping.state, CycleState::kStopping) << stopping.reason;
  EXPECT_TRUE(stopping.is_final);
  EXPECT_TRUE(contains(stopping.blocked, "the committed trajectory is blocked (sample at t="))
      << stopping.blocked;
  EXPECT_TRUE(contains(stopping.blocked, "no stop stays in certified free space"))
      << stopping.blocked;
  expectStop(stopping);
  ASSERT_TRUE(stopping.trajectory);

  // At rest inside the margin the stop is no longer blocked (it comes no closer), and whatever
  // follows never brings the vehicle closer to the wall than where it stopped.
  const Eigen::Vector3d rest = stopping.trajectory->evaluate(stopping.trajectory->duration());
  for (int k = 0; k < 3; ++k) {
    const CycleReport next = pilot.cycle(wall);
    EXPECT_NE(next.state, CycleState::kStopping) << next.reason;
    EXPECT_TRUE(next.blocked.empty()) << next.blocked;
    EXPECT_GE(wall(pilot.estimate().position).distance, wall(rest).distance - 1e-9)
        << "cycle " << next.cycle;
    if (next.trajectory) {
      EXPECT_GE(inspectTrajectory(*next.trajectory, wall, 0.01).min_distance,
                wall(rest).distance - 0.01)
          << "cycle " << next.cycle;
    }
  }
}

// With an explorer, flies toward kMission until a wall appears across the way
// (wallAfterTakeOff(pilot, 0.15)); the cycle that sees it is stuck, waits for the explorer, and
// its first status already commits the stop.
std::pair<DistanceField, CycleReport> stuckAtANewWall(Pilot& pilot) {
  EXPECT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const DistanceField wall = wallAfterTakeOff(pilot, 0.15);
  const CycleReport stuck = pilot.cycle(wall);
  EXPECT_EQ(stuck.state, CycleState::kStuck) << stuck.reason;
  EXPECT_FALSE(stuck.is_final);
  EXPECT_TRUE(contains(stuck.reason, "the committed trajectory is blocked")) << stuck.reason;
  expectStop(stuck);
  EXPECT_TRUE(pilot.planner.waitingCycle());
  return {wall, stuck};
}

TEST(LocalPlanner, ABlockedCycleStopsBeforeItAsksTheExplorer) {
  Pilot pilot(withExplorer());
  const auto [wall, stuck] = stuckAtANewWall(pilot);
  ASSERT_TRUE(stuck.trajectory);
  ASSERT_TRUE(pilot.planner.waitingCycle());
  const PolynomialTrajectory stop = *stuck.trajectory;

  // The explorer has nothing: the cycle closes on the stop.
  const CycleReport none = pilot.planner.answer(std::nullopt, "no candidate", &wall);
  EXPECT_EQ(none.cycle, stuck.cycle);
  EXPECT_EQ(none.state, CycleState::kStopping) << none.reason;
  EXPECT_TRUE(none.is_final);
  EXPECT_TRUE(contains(none.reason, "the committed trajectory is blocked")) << none.reason;
  EXPECT_TRUE(contains(none.reason, "no candidate")) << none.reason;
  EXPECT_FALSE(none.trajectory);  // the stop went out with the first status
  ASSERT_TRUE(pilot.planner.committed());
  EXPECT_TRUE(sameSegments(*pilot.planner.committed(), stop));
}

TEST(LocalPlanner, AnExplorerGoalReplacesTheStop) {
  Pilot pilot(withExplorer());
  const auto [wall, stuck] = stuckAtANewWall(pilot);
  ASSERT_TRUE(stuck.trajectory);
  ASSERT_TRUE(pilot.planner.waitingCycle());

  // An intermediate goal to the side, along the wall.
  const Eigen::Vector3d side = stuck.start.position + Eigen::Vector3d(0, 2.5, 0);
  const CycleReport answered =
      pilot.planner.answer(goalAt(77, {side}, /*from_explorer=*/true), "side", &wall);
  pilot.check(answered, wall);
  ASSERT_EQ(answered.state, CycleState::kPlanned) << answered.reason;
  EXPECT_TRUE(answered.is_final);
  EXPECT_TRUE(contains(answered.reason, "the committed trajectory is blocked")) << answered.reason;
  EXPECT_TRUE(contains(answered.reason, "replanned")) << answered.reason;
  ASSERT_TRUE(answered.trajectory);
  EXPECT_FALSE(sameSegments(*answered.trajectory, *stuck.trajectory));
  EXPECT_EQ(answered.goal_id, 77);
}

TEST(LocalPlanner, AnObstacleWithAWayAroundIsReplannedInTheSameCycle) {
  Pilot pilot;
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  ASSERT_EQ(pilot.cycle(freeSpace()).state, CycleState::kPlanned);
  // A post on the line, where the committed trajectory ends (x = 3).
  const DistanceField post = cylinderField({2.0, 0.0}, 0.3);
  ASSERT_FALSE(checkClearance(*pilot.planner.committed(), 0, post, 0.6).clear);

  // Pilot::check flies the new trajectory against the post.
  const CycleReport replanned = pilot.cycle(post);
  ASSERT_EQ(replanned.state, CycleState::kPlanned) << replanned.reason;
  EXPECT_TRUE(contains(replanned.blocked, "the committed trajectory is blocked (sample at t="))
      << replanned.blocked;
  EXPECT_EQ(replanned.reason, replanned.blocked + "; replanned");
  EXPECT_TRUE(replanned.loco.accepted);

  // Past the post to the goal; the map no longer changes, so nothing is blocked again.
  CycleReport last = replanned;
  for (int k = 0; k < 40 && last.state == CycleState::kPlanned; ++k) {
    last = pilot.cycle(post);
    EXPECT_TRUE(last.blocked.empty()) << "cycle " << last.cycle << ": " << last.blocked;
  }
  EXPECT_EQ(last.state, CycleState::kGoalReached) << last.reason;
}

TEST(LocalPlanner, AVehicleInsideTheMarginLeavesItWithoutComingCloser) {
  // At rest 0.55 m from a post, inside the clearance acceptance needs (0.62 m): every trajectory
  // used to fail its first sample, so the vehicle could never leave.
  const DistanceField post = cylinderField({0, 0.85}, 0.3);
  Pilot pilot;
  const double required =
      pilot.planner.options().loco.robot_radius + pilot.planner.options().loco.clearance_margin;
  ASSERT_LT(post(kStart).distance, required);
  ASSERT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
  const CycleReport first = pilot.cycle(post);
  ASSERT_EQ(first.state, CycleState::kPlanned) << first.reason;
  const testing::TrajectoryReport r = inspectTrajectory(*first.trajectory, post, 0.01);
  EXPECT_GE(r.min_distance, post(kStart).distance - 1e-9);
  // It flies on to the goal, never closer than each cycle starts or than the full clearance
  // (up to the 1 cm dip between acceptance samples).
  bool reached = false;
  for (int k = 0; k < 30 && !reached; ++k) {
    const CycleReport report = pilot.cycle(post);
    reached = report.state == CycleState::kGoalReached;
    if (!reached) {
      ASSERT_EQ(report.state, CycleState::kPlanned) << report.reason;
    }
    if (report.trajectory) {
      EXPECT_GE(inspectTrajectory(*report.trajectory, post, 0.01).min_distance,
                std::min(required, post(report.start.position).distance) - 0.01);
    }
  }
  EXPECT_TRUE(reached);
}

TEST(LocalPlanner, AStuckVehicleAtTheMarginBacksAwayWhenNothingElseFlies) {
  // At rest 0.6 m before a wall across the way (inside the 0.62 m acceptance clearance), the
  // mission beyond it: every plan is refused, and so is the explorer's goal behind the wall.
  const DistanceField field = wall();
  const Eigen::Vector3d start(1.9, 0, 1.5);
  LocalPlannerOptions options = withExplorer();
  const double required = options.loco.robot_radius + options.loco.clearance_margin;
  ASSERT_LT(field(start).distance, required);
  const auto stuckAnswer = [&](double retreat) {
    options.retreat = retreat;
    Pilot pilot(options, start);
    EXPECT_FALSE(pilot.planner.setMissionGoal(goalAt(1, {kMission})));
    const CycleReport stuck = pilot.cycle(field);
    EXPECT_EQ(stuck.state, CycleState::kStuck) << stuck.reason;
    const CycleReport answered = pilot.planner.answer(
        goalAt(5, {Eigen::Vector3d(5, 0.5, 1.5)}, /*from_explorer=*/true), "behind", &field);
    pilot.check(answered, field);
    return answered;
  };
  // Off (the paper's planner): it holds where it is.
  const CycleReport held = stuckAnswer(0);
  EXPECT_EQ(held.state, CycleState::kHolding);
  EXPECT_FALSE(held.trajectory);
  // On: it backs straight away from the wall to 0.1 m outside the margin, never closer than it
  // started, and says so after why it was stuck.
  const CycleReport backed = stuckAnswer(0.1);
  ASSERT_EQ(backed.state, CycleState::kPlanned) << backed.reason;
  EXPECT_TRUE(backed.is_final);
  EXPECT_TRUE(backed.reason.starts_with("stuck (")) << backed.reason;
  EXPECT_TRUE(contains(backed.reason, "the intermediate goal is infeasible too")) << backed.reason;
  EXPECT_TRUE(contains(backed.reason, "backing away from the nearest obstacle, clearance 0.600 to"))
      << backed.reason;
  ASSERT_TRUE(backed.trajectory);
  const PolynomialTrajectory& t = *backed.trajectory;
  const Eigen::Vector3d end = t.evaluate(t.duration());
  EXPECT_NEAR(end.y(), 0, 1e-9);
  EXPECT_NEAR(end.z(), 1.5, 1e-9);
  EXPECT_GE(field(end).distance, required + 0.1 - 1e-9);
  EXPECT_LT(field(end).distance, required + 0.1 + 0.05);
  EXPECT_GE(inspectTrajectory(t, field, 0.01).min_distance, field(start).distance - 1e-9);
  EXPECT_LT(t.evaluate(t.duration(), 1).norm(), 1e-9);  // at rest at the end
}

// ---- determinism ----

TEST(LocalPlanner, SameInputsGiveIdenticalTrajectories) {
  // A cylinder just off the straight line, so the optimizer has work to do.
  const DistanceField field = cylinderField({4.5, 0.15}, 0.5);
  LocalPlannerOptions options;
  options.seed = 12345;
  Pilot a(options), b(options);
  ASSERT_FALSE(a.planner.setMissionGoal(goalAt(1, {kMission})));
  ASSERT_FALSE(b.planner.setMissionGoal(goalAt(1, {kMission})));
  int compared = 0;
  for (int k = 0; k < 8; ++k) {
    const CycleReport ra = a.cycle(field);
    const CycleReport rb = b.cycle(field);
    SCOPED_TRACE("cycle " + std::to_string(ra.cycle));
    ASSERT_EQ(ra.state, rb.state);
    EXPECT_EQ(ra.reason, rb.reason);
    EXPECT_EQ(ra.horizon_goal, rb.horizon_goal);
    EXPECT_EQ(ra.loco.iterations, rb.loco.iterations);
    EXPECT_EQ(ra.loco.restarts, rb.loco.restarts);
    ASSERT_EQ(ra.trajectory.has_value(), rb.trajectory.has_value());
    if (ra.trajectory) {
      EXPECT_TRUE(sameSegments(*ra.trajectory, *rb.trajectory));
      ++compared;
    }
  }
  EXPECT_GT(compared, 3);
}

// ---- options ----

TEST(LocalPlanner, RefusesBadOptions) {
  const auto build = [](auto change) {
    LocalPlannerOptions options;
    change(options);
    return LocalPlanner(options);
  };
  EXPECT_NO_THROW(build([](LocalPlannerOptions&) {}));
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.goal_tolerance = 0; }), std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.max_divergence = -1; }), std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.max_state_age = std::nan(""); }),
               std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.flight_volume_max.z() = -1; }),
               std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.goal_finder.method = "bogus"; }),
               std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.loco.v_max = 0; }), std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.retreat = -0.1; }), std::invalid_argument);
  EXPECT_THROW(build([](LocalPlannerOptions& o) { o.retreat = std::nan(""); }),
               std::invalid_argument);
}

}  // namespace
}  // namespace thicket::local_planner

// The local planner's core (docs/design.md §1–2): the goal state machine around goal finding and
// loco.
//
// Goals. The operator's mission goal (waypoints, tracked in order) is the global goal. When a
// cycle cannot plan toward it, the cycle is "stuck": with an explorer in the graph the planner
// asks for an intermediate goal and waits for the answer before closing the cycle; an
// intermediate goal (or waypoint list) is then tracked until it is reached or cannot be planned
// toward, and the planner returns to the global goal. Waypoints are reached within a tolerance.
// A goal may give each waypoint a yaw: the trajectory toward it is flown facing that yaw (unless
// that would not face where it flies: max_yaw_offset; when the vehicle faces farther than that
// from the yaw, it stops and turns before it flies), and the waypoint is reached only when the
// vehicle is there at that yaw (it stops and turns if it arrives before it has turned). The stall
// watchdog (off by default) gives up a goal the reference has not really moved toward for a few
// cycles, even when every cycle planned.
//
// Commitment. Each cycle plans from the *reference*: the committed trajectory at the cycle's
// time (the estimate only when there is no committed trajectory or the two diverge). A cycle that
// finds no acceptable trajectory commits nothing, so the vehicle keeps flying the previous
// trajectory, which ends at rest in space that was free (it hovers there). Without a plan, a map,
// a fresh one or a state estimate the planner holds: it commits a hover trajectory if nothing is
// committed yet, and says why.
//
// Re-check. Every cycle on a fresh map first re-checks the rest of the committed trajectory with
// the acceptance test. When it fails (the map now sees an obstacle on it, or knows less), a
// stopping trajectory (stop.h) is committed at once, before anything else is tried; a plan found
// later in the cycle replaces it. A cycle that ends on the stop reports kStopping.
//
// No LCM and no clock inside: time comes from the caller (message utimes); wall-clock time is
// only measured (now_ms) for the reported solve time.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/params.h"
#include "thicket/common/polynomial_trajectory.h"
#include "thicket/local_planner/goal_finder.h"
#include "thicket/local_planner/loco.h"

namespace thicket::local_planner {

/// A goal as the planner tracks it (goal_t without the transport).
struct Goal {
  int64_t id = -1;
  bool from_explorer = false;
  std::string strategy;  ///< the exploration strategy that proposed it
  std::vector<Eigen::Vector3d> waypoints;
  /// Empty: the vehicle faces along its velocity. Else one yaw per waypoint [rad]: the vehicle
  /// flies toward waypoint i facing yaws[i] (or its direction of flight when yaws[i] is more than
  /// max_yaw_offset off it), and the waypoint counts as reached only once a frame was taken there
  /// at that yaw (a waypoint at the vehicle's position is a look: hover and turn).
  std::vector<double> yaws;
  double tolerance = 0;  ///< a waypoint is reached within this [m]; 0: the planner's default
};

/// A state estimate of the vehicle.
struct VehicleState {
  int64_t utime = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  double yaw = 0;  ///< heading of the body (and the camera) [rad]
};

enum class CycleState { kPlanned, kStuck, kGoalReached, kHolding, kNoMap, kNoState, kStopping };

/// How a cycle's reason (PLANNER_STATUS) starts when its re-check found the committed trajectory
/// blocked, whether it then stopped or replanned.
inline constexpr const char* kBlockedTrajectoryReason = "the committed trajectory is blocked";
constexpr int kNumCycleStates = 7;
const char* cycleStateName(CycleState state);

/// What one cycle (or the answer to a stuck cycle) did.
struct CycleReport {
  int64_t utime = 0;  ///< the time planned from [µs]
  int64_t cycle = 0;
  bool is_final = true;
  CycleState state = CycleState::kHolding;
  std::string reason;  ///< why, in words (empty when planned)
  int64_t map_revision = -1;
  /// The goal tracked: id -1 when there is none.
  int64_t goal_id = -1;
  bool goal_from_explorer = false;
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  Eigen::Vector3d horizon_goal = Eigen::Vector3d::Zero();
  /// The plan ends at the carrot on the goal's path (LocalPlannerOptions::carrot), fixed.
  bool carrot = false;
  TrajectoryState start;   ///< the reference the cycle planned from
  double vehicle_yaw = 0;  ///< the estimate's yaw at the cycle [rad]
  /// Why the rest of the committed trajectory failed the re-check and which stop replaced it;
  /// empty when it passed (or nothing was committed).
  std::string blocked;
  LocoResult loco;      ///< the last optimization of the cycle (empty if none ran)
  int attempts = 0;     ///< optimizations the cycle ran (each seeds its restarts apart)
  double solve_ms = 0;  ///< wall-clock time of goal finding and optimization (measured)
  /// A trajectory committed by this cycle, to publish; absent when the committed one stands.
  std::optional<PolynomialTrajectory> trajectory;
  /// The constant yaw the vehicle flies it with [rad]; absent: along the velocity.
  std::optional<double> yaw;
};

struct LocalPlannerOptions {
  LocoOptions loco;
  GoalFinderOptions goal_finder;
  /// Let the end point move (the soft goal J_g); false fixes the end at the horizon goal.
  bool soft_goal = true;
  double goal_tolerance = 0.2;  ///< waypoints are reached within this unless the goal says [m]
  /// A trajectory must end at least this much closer to the horizon goal than it starts (or
  /// within goal_tolerance of it); one that does not is no plan: the cycle is stuck [m].
  double min_progress = 0.2;
  /// Plan from the estimate instead of the reference when they are farther apart [m].
  double max_divergence = 0.5;
  double max_state_age = 0.5;  ///< an estimate older than this at the cycle's time is stale [s]
  double max_map_age = 2.0;    ///< a map older than this at the cycle's time is stale [s]
  /// Goals must lie in this box [m].
  Eigen::Vector3d flight_volume_min = Eigen::Vector3d(-1000, -1000, 0);
  Eigen::Vector3d flight_volume_max = Eigen::Vector3d(1000, 1000, 100);
  /// An explorer is in the graph: a stuck cycle asks it for an intermediate goal and stays open
  /// until it answers.
  bool use_explorer = false;
  int64_t seed = 0;  ///< random restarts draw from seed ⊕ cycle
  /// The duration of a hover trajectory [s].
  double hover_duration = 1.0;
  /// A waypoint with a yaw is reached once the vehicle's yaw is within this of it [rad].
  double yaw_tolerance = 0.2;
  /// The stall watchdog: a goal is given up (an intermediate goal dropped, the mission goal
  /// reported stuck so the explorer decides) when the reference moved less than stall_distance
  /// over the last stall_cycles consecutive cycles tracking the same waypoint, planned or not
  /// (cycles that stop to turn before flying do not count), or less than as much per cycle over
  /// the last stall_cycles - 1: a back and forth between two points returns within one window or
  /// the other, and is a stall however far apart they are. 0 turns it off (the paper's planner).
  int stall_cycles = 0;
  double stall_distance = 0.3;  ///< [m]
  /// A trajectory toward a waypoint with a yaw is flown at that yaw only when its horizontal
  /// direction (start to end) is within this of it; otherwise facing its end, so that the camera
  /// (90 degrees wide in the simulation) always sees the space the vehicle flies into and an
  /// obstacle that appears there. A cycle whose flight yaw is more than this off the vehicle's
  /// yaw commits a stop at that yaw instead (turn first, then fly). The yaw is taken once the
  /// vehicle is at the waypoint [rad].
  double max_yaw_offset = 0.6;
  /// Follow a goal's waypoints as a path (off: the paper's planner, a soft goal toward each
  /// waypoint in turn). Each cycle first tries the carrot: the farthest point of the polyline
  /// (the reference, then the waypoints left) within the horizon that a straight segment from the
  /// reference reaches with the acceptance clearance, as a fixed end at rest; the soft goal toward
  /// the current waypoint is the fallback. Waypoints before the carrot are passed, and only the
  /// last one's yaw must be reached (the others' yaws are flown toward them).
  bool carrot = false;
  /// When a stuck cycle ends with nothing to fly (the explorer's answer refused too, or none)
  /// and the reference is less than this outside the clearance margin, or inside it, the vehicle
  /// backs straight away from the nearest obstacle to this much outside the margin (planRetreat,
  /// stop.h), facing as it is: from there the next cycle's plans need not graze the margin. 0:
  /// off (the paper's planner) [m].
  double retreat = 0;

  void declare(Params& p);
};

/// The stall watchdog of one goal slot (mission or intermediate): the references of the last
/// consecutive cycles that tracked the same waypoint of the same goal.
class Watchdog {
 public:
  /// Records this cycle's reference; true when the last `cycles` cycles moved it less than
  /// `distance`, or the last `cycles` - 1 less than `distance` * (`cycles` - 1) / `cycles` (a
  /// back and forth of any amplitude returns within one or the other); never with cycles = 0.
  bool stalled(int64_t goal_id, size_t waypoint, int64_t cycle, const Eigen::Vector3d& reference,
               int cycles, double distance);
  /// How far the reference moved, and over how many cycles, when stalled() last returned true.
  double moved() const { return moved_; }
  int over() const { return over_; }
  /// This cycle does not count (it stopped to turn before flying on purpose): its reference is
  /// dropped, and the window goes on with the next cycle.
  void skip() {
    if (!references_.empty()) references_.pop_back();
  }

 private:
  int64_t goal_id_ = -1;
  size_t waypoint_ = 0;
  int64_t last_cycle_ = -1;
  std::deque<Eigen::Vector3d> references_;
  double moved_ = 0;
  int over_ = 0;
};

class LocalPlanner {
 public:
  /// now_ms measures the solve time (never used to decide). Throws std::invalid_argument on bad
  /// options.
  explicit LocalPlanner(LocalPlannerOptions options, std::function<double()> now_ms = {});

  const LocalPlannerOptions& options() const { return options_; }

  /// Checks a goal (waypoints present, finite, in the flight volume, tolerance >= 0); returns
  /// why it is refused, or nothing.
  std::optional<std::string> validate(const Goal& goal) const;
  /// Replaces the global goal (and drops any intermediate goal). Returns the refusal, if any;
  /// a refused goal changes nothing.
  std::optional<std::string> setMissionGoal(const Goal& goal);
  /// Drops every goal: the vehicle finishes its trajectory and holds.
  void cancel();

  /// One planning cycle at `utime` on `field` (nullptr: no map) whose newest data is from
  /// `map_utime`, revision `map_revision`, with the newest state estimate (if any).
  CycleReport plan(int64_t utime, const DistanceField* field, int64_t map_utime,
                   int64_t map_revision, const std::optional<VehicleState>& estimate);

  /// The cycle waiting for an intermediate goal, if any.
  std::optional<int64_t> waitingCycle() const;
  /// Answers the waiting cycle: `goal` is an intermediate goal, or nothing when the explorer
  /// found none (`reason` says why). Plans toward it on `field` and closes the cycle. Throws
  /// std::logic_error when no cycle is waiting.
  CycleReport answer(const std::optional<Goal>& goal, const std::string& reason,
                     const DistanceField* field);

  /// The committed trajectory, if any.
  const std::optional<PolynomialTrajectory>& committed() const { return committed_; }
  /// The constant yaw it is flown with; absent: along its velocity.
  const std::optional<double>& committedYaw() const { return committed_yaw_; }
  /// The cycle that committed it, or -1.
  int64_t committedCycle() const { return committed_cycle_; }
  const std::optional<Goal>& missionGoal() const { return mission_; }
  const std::optional<Goal>& intermediateGoal() const { return intermediate_; }
  int64_t cycles() const { return cycle_; }

 private:
  // The flight volume as a wall the vehicle's centre may touch but not cross: where it is nearer
  // than the map's obstacles, the field reads the distance to the nearest face plus the clearance
  // the acceptance needs, so the collision potential keeps trajectories inside and the clearance
  // check refuses any sample outside (goal finding too). Unknown space stays unknown.
  DistanceField fenced(const DistanceField& field) const;
  // Re-checks the rest of the committed trajectory from the report's time on the (fenced) field;
  // when it fails, commits a stop from the report's start and says why in report.blocked.
  void recheck(const DistanceField& field, CycleReport& report);
  // The state and reason of a cycle that ends on a stop committed by recheck().
  static void reportStop(CycleReport& report);
  // One optimization from `ends` toward `target` (the waypoint; ends.end_position is its horizon
  // goal), its result in report.loco: why it is refused (not accepted, or no progress), or nothing.
  std::optional<std::string> optimizeToward(const SplineEnds& ends, bool free_end,
                                            const Eigen::Vector3d& target,
                                            const DistanceField& field, CycleReport& report);
  // How far a goal is followed: its current waypoint, the last carrot committed toward it (on
  // the path; the path continues from there), and the stall watchdog.
  struct Progress {
    size_t waypoint = 0;
    std::optional<Eigen::Vector3d> carrot;
    Watchdog watchdog;
  };
  // Plans toward the current waypoint of the tracked goal on the (fenced) field (the carrot first,
  // when on, which may pass waypoints); fills the report, commits on success.
  bool planToward(const Goal& goal, Progress& progress, const DistanceField& field,
                  CycleReport& report);
  // The carrot (LocalPlannerOptions::carrot) on `goal`'s path from `start` (through the last
  // carrot, then the waypoints left), and the waypoint its segment of the path leads to: the
  // farthest point beyond the goal tolerance that a segment with the clearance + `extra` reaches.
  struct Carrot {
    Eigen::Vector3d position;
    size_t waypoint;
  };
  std::optional<Carrot> carrot(const Goal& goal, const Progress& progress,
                               const Eigen::Vector3d& start, const DistanceField& field,
                               double extra) const;
  // The constant yaw a trajectory toward a waypoint with `yaw` is flown at (max_yaw_offset).
  std::optional<double> flightYaw(const std::optional<double>& yaw,
                                  const PolynomialTrajectory& trajectory) const;
  // Whether waypoint `i` of `goal` must be reached at its yaw (it has one, and it is the last or
  // waypoints are not followed as a path).
  bool yawToReach(const Goal& goal, size_t i) const;
  // plan() and answer() before reportStop().
  CycleReport planCycle(int64_t utime, const DistanceField* field, int64_t map_utime,
                        int64_t map_revision, const std::optional<VehicleState>& estimate);
  CycleReport answerCycle(const std::optional<Goal>& goal, const std::string& reason,
                          const DistanceField* field);
  // Reports a cycle that commits no plan; hovers at `position` when nothing is committed yet.
  void hold(CycleReport& report, CycleState state, const std::string& reason,
            const std::optional<Eigen::Vector3d>& position);
  void commit(const PolynomialTrajectory& trajectory, const std::optional<double>& yaw,
              CycleReport& report);
  // A stuck cycle's last resort (option `retreat`): commits the retreat, when there is one, and
  // reports the cycle planned, the retreat appended to its reason.
  void retreat(const DistanceField& field, CycleReport& report);
  // Advances past reached waypoints (position, and yaw where the goal has one) at the report's
  // reference and yaw; true when the whole goal is reached.
  bool advanceWaypoints(const Goal& goal, size_t& waypoint, const CycleReport& report) const;
  // The vehicle is at the current waypoint but not yet at its yaw: commits a stop from the
  // reference (a hover, once it is at rest) flown at the waypoint's yaw. True when it did (the
  // cycle is planned).
  bool look(const Goal& goal, size_t waypoint, const DistanceField& field, CycleReport& report);
  enum class Tracked { kReached, kCommitted, kFailed };
  // One cycle toward a goal: advances its waypoints, looks, checks the watchdog and plans.
  Tracked track(const Goal& goal, Progress& progress, const DistanceField& field,
                CycleReport& report);

  LocalPlannerOptions options_;
  std::function<double()> now_ms_;
  Loco loco_;
  GoalFinder goal_finder_;
  std::optional<Goal> mission_;
  Progress mission_progress_;
  std::optional<Goal> intermediate_;
  Progress intermediate_progress_;
  std::optional<PolynomialTrajectory> committed_;
  std::optional<double> committed_yaw_;
  int64_t committed_cycle_ = -1;
  int64_t cycle_ = 0;
  // The stuck cycle waiting for the explorer: its report so far.
  std::optional<CycleReport> waiting_;
};

}  // namespace thicket::local_planner

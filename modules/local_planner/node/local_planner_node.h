// thicket-local-planner as an LCM node: MAP_ESDF (mirrored), STATE_ESTIMATE, MISSION_GOAL and
// EXPLORER_GOAL in; PLANNER_TRAJECTORY, PLANNER_STATUS, CONTROL_SETPOINT, MODULE_TIMING and
// MAP_REQUEST (to heal the mirror) out.
//
// In simulation and replay (replan_rate 0) every new ESDF revision triggers one cycle at the
// revision's time, as soon as a state estimate at that time has arrived. On the vehicle
// (replan_rate > 0) the executable's timer calls replan() instead.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <thicket/goal_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/odometry_t.hpp>

#include "thicket/common/map_update.h"
#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/common/time.h"
#include "thicket/local_planner/local_planner.h"

namespace thicket::local_planner {

struct LocalPlannerNodeOptions {
  LocalPlannerOptions planner;
  std::string state_channel = "STATE_ESTIMATE";
  /// Cycles per wall-clock second on the vehicle; 0: one cycle per new ESDF revision.
  double replan_rate = 0;
  /// CONTROL_SETPOINT messages per wall-clock second (the executable's timer); 0: none.
  double setpoint_rate = 50;
  /// A stuck cycle whose explorer answer has not come within this many wall-clock seconds is
  /// closed holding (the explorer died or was restarted meanwhile); the next cycle asks again.
  /// 0: wait for the answer however long (the executable's timer checks twice a second).
  double explorer_timeout = 5;

  void declare(Params& p);
};

class LocalPlannerNode : public Node {
 public:
  /// now_ms measures durations for MODULE_TIMING (never used to decide).
  LocalPlannerNode(lcm::LCM& lcm, const LocalPlannerNodeOptions& options,
                   std::function<double()> now_ms = {});

  const LocalPlanner& planner() const { return planner_; }
  const MapMirror<EsdfVoxel>& mirror() const { return mirror_; }

  /// One cycle now, on the newest map and state, at the newest state's time (the vehicle's
  /// replan timer).
  void replan();
  /// Publishes the committed trajectory's reference at `utime` on CONTROL_SETPOINT; false when
  /// nothing is committed.
  bool publishSetpoint(int64_t utime);
  /// The newest state estimate, if any.
  const std::optional<VehicleState>& latestState() const { return state_; }
  /// The explorer timeout's check at wall-clock time `now_us` (the executable's timer): a
  /// cycle seen waiting `explorer_timeout` seconds before is closed holding, and its final
  /// status published. Returns whether it closed one.
  bool expireExplorerWait(int64_t now_us);

  /// "N cycles (planned P, stuck S, ...); optimization median X ms, p95 Y ms".
  std::string summary() const;

 private:
  void onMap(const map_update_t& msg);
  void onState(const odometry_t& msg);
  void onMissionGoal(const goal_t& msg);
  void onExplorerGoal(const goal_t& msg);
  // The mirrored ESDF as the planner reads it; nothing before the first snapshot.
  std::optional<DistanceField> mirrorField() const;
  void runPending();
  void runCycle(int64_t utime);
  // The cycle's trajectory (if any), status and timing (total_ms: the whole cycle, measured).
  void publishReport(const CycleReport& report, double total_ms);
  void publishRejection(const goal_t& msg, const std::string& reason);

  LocalPlannerNodeOptions options_;
  std::function<double()> now_ms_;
  LocalPlanner planner_;
  MapMirror<EsdfVoxel> mirror_;
  std::optional<VehicleState> state_;
  Timeline state_times_{"estimate"};
  std::optional<int64_t> pending_;  // a revision's time waiting for its state estimate
  // The cycle last seen waiting for the explorer, and the wall-clock time it was first seen [us].
  std::optional<std::pair<int64_t, int64_t>> waiting_since_;
  double last_yaw_ = 0;
  std::vector<double> solve_ms_;
  std::vector<int64_t> state_counts_;
};

}  // namespace thicket::local_planner

// `thicket-log mission`: how a simulated mission recorded in a log went, from the simulator's
// SIM_EVENT messages (its trial end carries the mission summary) and the explorer's goals.
#pragma once

#include <cstdint>
#include <string>

#include "thicket/common/expected.h"

namespace thicket::log {

struct MissionReport {
  bool ended = false;         ///< a TYPE_TRIAL_END event was logged
  bool goal_reached = false;  ///< ... with OUTCOME_GOAL_REACHED
  std::string end_message;    ///< its message ("goal reached", "replan limit", ...)
  int64_t collisions = 0;     ///< TYPE_COLLISION events
  int64_t refused_trajectories = 0;
  int32_t num_replans = 0;
  double path_length = 0;       ///< [m]
  double path_time = 0;         ///< simulated [s]
  double min_clearance = 0;     ///< [m]
  double distance_to_goal = 0;  ///< [m]
  int64_t explorer_goals = 0;   ///< EXPLORER_GOAL messages proposing a goal
  std::string read_error;       ///< why reading the log stopped early, if it did

  /// The mission succeeded: it ended at the goal without a collision.
  bool success() const { return ended && goal_reached && collisions == 0; }
  /// One line for an operator.
  std::string text() const;
};

/// Reads the log at `path`; an error when it cannot be opened.
Expected<MissionReport> missionReport(const std::string& path);

}  // namespace thicket::log

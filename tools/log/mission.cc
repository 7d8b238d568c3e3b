#include "mission.h"

#include <cstdio>
#include <stdexcept>

#include <thicket/goal_t.hpp>
#include <thicket/sim_event_t.hpp>

#include "log_events.h"

namespace thicket::log {

std::string MissionReport::text() const {
  char line[512];
  if (!ended) {
    std::snprintf(line, sizeof line,
                  "the mission did not end in the log (%lld collisions, %lld explorer goals "
                  "logged)",
                  static_cast<long long>(collisions), static_cast<long long>(explorer_goals));
    return line;
  }
  std::snprintf(line, sizeof line,
                "%s after %d replans and %.1f s: path %.2f m, %.2f m from the goal, min "
                "clearance %.3f m, %lld collisions, %lld refused trajectories, %lld intermediate "
                "goals from the explorer",
                end_message.c_str(), num_replans, path_time, path_length, distance_to_goal,
                min_clearance, static_cast<long long>(collisions),
                static_cast<long long>(refused_trajectories),
                static_cast<long long>(explorer_goals));
  return line;
}

Expected<MissionReport> missionReport(const std::string& path) {
  MissionReport report;
  LogReadResult read;
  try {
    read = readLog(path, [&](const LogEvent& event) {
      if (event.channel == "SIM_EVENT") {
        sim_event_t msg;
        if (!event.decode(msg).empty()) return;
        if (msg.type == sim_event_t::TYPE_COLLISION) ++report.collisions;
        if (msg.type == sim_event_t::TYPE_TRAJECTORY_REFUSED) ++report.refused_trajectories;
        if (msg.type != sim_event_t::TYPE_TRIAL_END) return;
        report.ended = true;
        report.goal_reached = msg.outcome == sim_event_t::OUTCOME_GOAL_REACHED;
        report.end_message = msg.message;
        report.num_replans = msg.num_replans;
        report.path_length = msg.path_length;
        report.path_time = msg.path_time;
        report.min_clearance = msg.min_clearance;
        report.distance_to_goal = msg.distance_to_goal;
      } else if (event.channel == "EXPLORER_GOAL") {
        goal_t msg;
        if (event.decode(msg).empty() && msg.status == goal_t::STATUS_OK) ++report.explorer_goals;
      }
    });
  } catch (const std::runtime_error& e) {
    return unexpected(e.what());
  }
  report.read_error = read.error;
  return report;
}

}  // namespace thicket::log

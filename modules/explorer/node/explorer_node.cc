#include "explorer_node.h"

#include <cstdio>

#include <thicket/module_timing_t.hpp>

#include "thicket/common/statistics.h"

namespace thicket::explorer {

void ExplorerNodeOptions::declare(Params& p) {
  p.group("explorer", explorer, "the goal-selection strategy and its parameters");
}

ExplorerNode::ExplorerNode(lcm::LCM& lcm, const ExplorerNodeOptions& options,
                           std::function<double()> now_ms)
    : Node("explorer", lcm),
      options_(options),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      selector_(makeGoalSelector(options.explorer)) {
  // A full snapshot arrives as many parts at once.
  subscribe<map_update_t>(
      "MAP_TSDF",
      [this](const map_update_t& msg, const MessageInfo&) { onMap(tsdf_, "MAP_TSDF", msg); }, 1000);
  subscribe<map_update_t>(
      "MAP_ESDF",
      [this](const map_update_t& msg, const MessageInfo&) { onMap(esdf_, "MAP_ESDF", msg); }, 1000);
  subscribe<planner_status_t>(
      "PLANNER_STATUS", [this](const planner_status_t& msg, const MessageInfo&) { onStatus(msg); });
}

template <class Voxel>
void ExplorerNode::onMap(MapMirror<Voxel>& mirror, const char* channel, const map_update_t& msg) {
  const auto result = mirror.apply(msg);
  using Outcome = typename MapMirror<Voxel>::Outcome;
  if (result.outcome == Outcome::kNeedSnapshot) {
    publish("MAP_REQUEST", mirror.request(msg.utime, name()));
  } else if (result.outcome == Outcome::kRefused) {
    reportBadMessage(channel, result.reason);
  }
  // The selector's tables are built as soon as the voxel size is known, not at the first request.
  if (tsdf_.layer() != nullptr && tsdf_.layer()->voxelSize() != prepared_voxel_size_) {
    prepared_voxel_size_ = tsdf_.layer()->voxelSize();  // first: a failure is reported once
    selector_->prepare(prepared_voxel_size_);
  }
}

void ExplorerNode::onStatus(const planner_status_t& msg) {
  if (msg.state != planner_status_t::STATE_STUCK || msg.is_final) return;
  const Eigen::Vector3d start(msg.start_position[0], msg.start_position[1], msg.start_position[2]);
  const Eigen::Vector3d goal(msg.goal[0], msg.goal[1], msg.goal[2]);
  goal_t answer{};
  answer.utime = msg.utime;
  answer.goal_id = next_goal_id_++;
  answer.source = goal_t::SOURCE_EXPLORER;
  answer.strategy = selector_->name();
  answer.cycle = msg.cycle;
  answer.yaw_policy = goal_t::YAW_ALONG_VELOCITY;
  const double t0 = now_ms_();
  if (!start.allFinite() || !goal.allFinite()) {
    answer.status = goal_t::STATUS_NO_STATE;
    answer.reason = "the stuck status has a non-finite start or goal";
  } else {
    const MapView maps{tsdf_.layer(), esdf_.layer()};
    const Proposal proposal = selector_->select({msg.utime, msg.cycle, start, goal}, maps);
    answer.reason = proposal.reason;
    answer.score = proposal.score;
    if (proposal.found) {
      answer.status = goal_t::STATUS_OK;
      for (const Eigen::Vector3d& w : proposal.waypoints)
        answer.waypoints.push_back({w.x(), w.y(), w.z()});
      if (options_.explorer.fixed_yaw && !proposal.yaws.empty()) {
        answer.yaws = proposal.yaws;
        answer.yaw_policy = goal_t::YAW_FIXED;
      }
      ++goals_found_;
    } else {
      answer.status = proposal.map_missing ? goal_t::STATUS_NO_MAP : goal_t::STATUS_NO_CANDIDATE;
    }
  }
  answer.num_waypoints = static_cast<int32_t>(answer.waypoints.size());
  answer.yaws.resize(answer.waypoints.size(), 0.0);
  selection_ms_.push_back(now_ms_() - t0);
  publish("EXPLORER_GOAL", answer);

  module_timing_t timing;
  timing.utime = msg.utime;
  timing.module = "explorer";
  timing.sequence = msg.cycle;
  timing.stages = {"goal_selection"};
  timing.durations_ms = {selection_ms_.back()};
  timing.num_stages = 1;
  publish("MODULE_TIMING", timing);
}

std::string ExplorerNode::summary() const {
  char text[160];
  std::snprintf(text, sizeof(text),
                "%lld requests answered (%lld with a goal); goal_selection median %.2f ms, p95 "
                "%.2f ms",
                static_cast<long long>(answers()), static_cast<long long>(goals_found_),
                median(selection_ms_), quantile(selection_ms_, 0.95));
  return text;
}

}  // namespace thicket::explorer

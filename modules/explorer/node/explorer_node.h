// thicket-explorer as an LCM node: mirrors MAP_TSDF and MAP_ESDF, and answers every stuck
// PLANNER_STATUS (not yet final) with an EXPLORER_GOAL for the same cycle: a proposal of the
// configured strategy, or a status saying why there is none (no map, no candidate). Publishes
// MODULE_TIMING per answer.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <thicket/goal_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/planner_status_t.hpp>

#include "thicket/common/map_update.h"
#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/explorer/goal_selector.h"

namespace thicket::explorer {

struct ExplorerNodeOptions {
  ExplorerOptions explorer;

  void declare(Params& p);
};

class ExplorerNode : public Node {
 public:
  /// now_ms measures durations for MODULE_TIMING (never used to decide). Throws
  /// std::invalid_argument on bad options.
  ExplorerNode(lcm::LCM& lcm, const ExplorerNodeOptions& options,
               std::function<double()> now_ms = {});

  const MapMirror<TsdfVoxel>& tsdf() const { return tsdf_; }
  const MapMirror<EsdfVoxel>& esdf() const { return esdf_; }
  int64_t answers() const { return static_cast<int64_t>(selection_ms_.size()); }
  /// "N requests answered (F with a goal); goal_selection median X ms, p95 Y ms".
  std::string summary() const;

 private:
  template <class Voxel>
  void onMap(MapMirror<Voxel>& mirror, const char* channel, const map_update_t& msg);
  void onStatus(const planner_status_t& msg);

  ExplorerNodeOptions options_;
  std::function<double()> now_ms_;
  std::unique_ptr<GoalSelector> selector_;
  MapMirror<TsdfVoxel> tsdf_;
  MapMirror<EsdfVoxel> esdf_;
  double prepared_voxel_size_ = 0;  // the selector's tables are built for this voxel size
  int64_t next_goal_id_ = 1;
  int64_t goals_found_ = 0;
  std::vector<double> selection_ms_;
};

}  // namespace thicket::explorer

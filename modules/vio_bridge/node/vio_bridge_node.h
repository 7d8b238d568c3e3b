// thicket-vio-bridge as an LCM node: VIO_ODOMETRY (in the VIO's frames) in; STATE_ESTIMATE (in
// thicket's frames, gated, renumbered) out. Dropped estimates are refused through
// reportBadMessage with the reason, so they are counted and logged like undecodable ones.
//
// Health. Every `report_period` of message time the node publishes MODULE_TIMING (stage "gate":
// the mean time per estimate since the previous report) and, when estimates were dropped or
// flagged since then, prints the bridge's health summary to stderr: at most one line per period
// however fast the VIO publishes.
#pragma once

#include <functional>
#include <string>

#include <thicket/odometry_t.hpp>

#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/vio_bridge/vio_bridge.h"

namespace thicket::vio_bridge {

struct VioBridgeNodeOptions {
  VioBridgeOptions bridge;
  std::string input_channel = "VIO_ODOMETRY";
  std::string output_channel = "STATE_ESTIMATE";
  double report_period = 1.0;  ///< [s] of message time between health reports

  void declare(Params& p);
};

class VioBridgeNode : public Node {
 public:
  /// now_ms measures the time spent per estimate for the summary (never used to decide). Throws
  /// std::invalid_argument on bad options.
  VioBridgeNode(lcm::LCM& lcm, const VioBridgeNodeOptions& options,
                std::function<double()> now_ms = {});

  const VioBridge& bridge() const { return bridge_; }
  /// The bridge's health summary, and the time spent per estimate.
  std::string summary() const;

 private:
  void onOdometry(const odometry_t& msg);
  void report(int64_t utime);

  VioBridgeNodeOptions options_;
  std::function<double()> now_ms_;
  VioBridge bridge_;
  int64_t next_sequence_ = 0;
  double total_ms_ = 0;
  double max_ms_ = 0;
  // Since the previous report.
  int64_t last_report_utime_ = 0;
  int64_t reports_ = 0;
  int64_t window_count_ = 0;
  double window_ms_ = 0;
  int64_t problems_at_report_ = 0;
};

}  // namespace thicket::vio_bridge

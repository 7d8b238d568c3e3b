#include "vio_bridge_node.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <thicket/module_timing_t.hpp>

#include "thicket/common/time.h"

namespace thicket::vio_bridge {

void VioBridgeNodeOptions::declare(Params& p) {
  p.group("bridge", bridge, "frames of the VIO and the gate");
  p("input_channel", input_channel, "the VIO's odometry, in its own frames");
  p("output_channel", output_channel, "the state estimate, in thicket's frames");
  p("report_period", report_period,
    "message time between health reports (MODULE_TIMING, and a summary on stderr when "
    "estimates were dropped or flagged) [s]",
    Range::positive());
}

VioBridgeNode::VioBridgeNode(lcm::LCM& lcm, const VioBridgeNodeOptions& options,
                             std::function<double()> now_ms)
    : Node("vio_bridge", lcm),
      options_(options),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      bridge_(options.bridge) {
  if (options_.input_channel.empty() || options_.output_channel.empty()) {
    throw std::invalid_argument("vio_bridge: input_channel and output_channel must not be empty");
  }
  if (options_.input_channel == options_.output_channel) {
    throw std::invalid_argument("vio_bridge: input_channel and output_channel must differ");
  }
  if (!(options_.report_period > 0) || !std::isfinite(options_.report_period)) {
    throw std::invalid_argument("vio_bridge: report_period must be positive");
  }
  // A VIO publishes at a few hundred Hz; a slow start of the loop must not drop estimates.
  subscribe<odometry_t>(
      options_.input_channel,
      [this](const odometry_t& msg, const MessageInfo&) { onOdometry(msg); }, 1000);
}

void VioBridgeNode::onOdometry(const odometry_t& msg) {
  const double t0 = now_ms_();
  GateResult result = bridge_.process(msg);
  const double elapsed = now_ms_() - t0;
  total_ms_ += elapsed;
  max_ms_ = std::max(max_ms_, elapsed);
  ++window_count_;
  window_ms_ += elapsed;
  if (!result.publish) {
    reportBadMessage(options_.input_channel, result.reason);
  } else {
    result.estimate.sequence = next_sequence_++;
    publish(options_.output_channel, result.estimate);
  }
  // Every estimate paces the reports, also one that was dropped: a VIO that only produces
  // garbage is reported too. A clock that went back starts a new period. A stamp that is not a
  // time paces as the nearest one, so that no difference of stamps overflows.
  const int64_t utime = std::clamp(msg.utime, int64_t{0}, kMaxUtime);
  const bool due = reports_ == 0 || utime < last_report_utime_ ||
                   toSeconds(utime - last_report_utime_) >= options_.report_period;
  if (due) report(utime);
}

void VioBridgeNode::report(int64_t utime) {
  module_timing_t timing;
  timing.utime = utime;
  timing.module = "vio_bridge";
  timing.sequence = reports_++;
  timing.stages = {"gate"};
  timing.durations_ms = {window_ms_ / static_cast<double>(window_count_)};
  timing.num_stages = 1;
  publish("MODULE_TIMING", timing);

  const VioBridgeHealth& health = bridge_.health();
  int64_t problems = health.dropped;
  for (int64_t count : health.flagged) problems += count;
  if (problems != problems_at_report_) {
    std::fprintf(stderr, "[vio_bridge] %s\n", health.summary().c_str());
    problems_at_report_ = problems;
  }
  last_report_utime_ = utime;
  window_count_ = 0;
  window_ms_ = 0;
}

std::string VioBridgeNode::summary() const {
  const int64_t received = bridge_.health().received;
  char timing[96];
  std::snprintf(timing, sizeof timing, "; gate mean %.4f ms, max %.4f ms",
                received > 0 ? total_ms_ / static_cast<double>(received) : 0.0, max_ms_);
  return bridge_.health().summary() + timing;
}

}  // namespace thicket::vio_bridge

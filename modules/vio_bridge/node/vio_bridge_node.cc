#include "vio_bridge_node.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace thicket::vio_bridge {

void VioBridgeNodeOptions::declare(Params& p) {
  p.group("bridge", bridge, "frames of the VIO and the gate");
  p("input_channel", input_channel, "the VIO's odometry, in its own frames");
  p("output_channel", output_channel, "the state estimate, in thicket's frames");
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
  if (!result.publish) {
    reportBadMessage(options_.input_channel, result.reason);
    return;
  }
  result.estimate.sequence = next_sequence_++;
  publish(options_.output_channel, result.estimate);
}

std::string VioBridgeNode::summary() const {
  const int64_t received = bridge_.health().received;
  char timing[96];
  std::snprintf(timing, sizeof timing, "; gate mean %.4f ms, max %.4f ms",
                received > 0 ? total_ms_ / static_cast<double>(received) : 0.0, max_ms_);
  return bridge_.health().summary() + timing;
}

}  // namespace thicket::vio_bridge

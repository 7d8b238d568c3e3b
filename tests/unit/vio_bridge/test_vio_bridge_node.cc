// thicket-vio-bridge's node in a memq:// composite: VIO_ODOMETRY in, STATE_ESTIMATE out in
// thicket's frames, renumbered; dropped estimates are counted as bad messages with their reason.
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <thicket/module_timing_t.hpp>
#include <thicket/odometry_t.hpp>

#include "thicket/common/loop.h"
#include "vio_bridge_node.h"

namespace thicket::vio_bridge {
namespace {

class Recorder : public Node {
 public:
  Recorder(lcm::LCM& lcm, const std::string& channel) : Node("recorder", lcm) {
    subscribe<odometry_t>(
        channel, [this](const odometry_t& m, const MessageInfo&) { received.push_back(m); }, 1000);
  }
  std::vector<odometry_t> received;
};

odometry_t vio(int64_t k, double x_offset = 0) {
  odometry_t m{};
  m.utime = 2'000'000 + k * 50'000;
  m.sequence = 100 + k;  // the VIO's own numbering
  m.position[0] = 0.05 * static_cast<double>(k) + x_offset;
  m.orientation[0] = 1;
  return m;
}

VioBridgeNodeOptions shiftedWorld() {
  VioBridgeNodeOptions options;
  options.bridge.vio_world_in_world.position = {10, 20, 1};
  return options;
}

TEST(VioBridgeNode, ConvertsRenumbersAndCountsDroppedEstimates) {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  VioBridgeNode bridge{lcm, shiftedWorld()};
  Recorder recorder{lcm, "STATE_ESTIMATE"};
  Node vio_source{"vio", lcm};

  vio_source.publish("VIO_ODOMETRY", vio(0));
  odometry_t nan = vio(1);
  nan.position[2] = std::numeric_limits<double>::quiet_NaN();
  vio_source.publish("VIO_ODOMETRY", nan);
  vio_source.publish("VIO_ODOMETRY", vio(0));  // repeats the first utime
  vio_source.publish("VIO_ODOMETRY", vio(2));
  vio_source.publish("VIO_ODOMETRY", vio(3, 4.0));  // a jump: published, lost
  loop.drain();

  ASSERT_EQ(recorder.received.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(recorder.received[i].sequence, static_cast<int64_t>(i));
  EXPECT_EQ(recorder.received[0].utime, vio(0).utime);
  EXPECT_DOUBLE_EQ(recorder.received[0].position[0], 10.0);
  EXPECT_DOUBLE_EQ(recorder.received[0].position[1], 20.0);
  EXPECT_DOUBLE_EQ(recorder.received[0].position[2], 1.0);
  EXPECT_EQ(recorder.received[1].utime, vio(2).utime);
  EXPECT_EQ(recorder.received[1].quality, +odometry_t::QUALITY_GOOD);
  EXPECT_EQ(recorder.received[2].quality, +odometry_t::QUALITY_LOST);
  EXPECT_EQ(recorder.received[2].flags, +odometry_t::FLAG_POSITION_JUMP);
  EXPECT_NE(recorder.received[2].reason.find("position jumped"), std::string::npos);

  EXPECT_EQ(bridge.badMessageCount(), 2);
  EXPECT_EQ(bridge.badMessageCounts().at("VIO_ODOMETRY"), 2);
  EXPECT_NE(bridge.lastError().find("repeats"), std::string::npos) << bridge.lastError();
  EXPECT_EQ(bridge.bridge().health().received, 5);
  EXPECT_EQ(bridge.bridge().health().dropped, 2);
  const std::string summary = bridge.summary();
  EXPECT_EQ(summary.rfind("5 estimates in, 3 published (2 good, 0 degraded, 1 lost), 2 dropped "
                          "(not_finite 1, time_backwards 1)",
                          0),
            0u)
      << summary;
  EXPECT_NE(summary.find("gate mean"), std::string::npos) << summary;
}

class TimingRecorder : public Node {
 public:
  explicit TimingRecorder(lcm::LCM& lcm) : Node("timing", lcm) {
    subscribe<module_timing_t>(
        "MODULE_TIMING",
        [this](const module_timing_t& m, const MessageInfo&) { received.push_back(m); });
  }
  std::vector<module_timing_t> received;
};

TEST(VioBridgeNode, ReportsItsHealthOncePerPeriodOfMessageTime) {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  VioBridgeNodeOptions options;
  options.report_period = 1.0;
  double clock = 0;
  VioBridgeNode bridge{lcm, options, [&clock] { return clock += 0.25; }};  // 0.25 ms per estimate
  TimingRecorder timing{lcm};
  Node vio_source{"vio", lcm};

  testing::internal::CaptureStderr();
  for (int64_t k = 0; k < 60; ++k) vio_source.publish("VIO_ODOMETRY", vio(k));  // 3 s at 20 Hz
  loop.drain();
  const std::string quiet = testing::internal::GetCapturedStderr();
  // Reports at 0, 1 and 2 s of message time; a healthy stream prints nothing.
  ASSERT_EQ(timing.received.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const module_timing_t& t = timing.received[i];
    EXPECT_EQ(t.module, "vio_bridge");
    EXPECT_EQ(t.sequence, static_cast<int64_t>(i));
    EXPECT_EQ(t.utime, vio(static_cast<int64_t>(20 * i)).utime);
    ASSERT_EQ(t.num_stages, 1);
    EXPECT_EQ(t.stages[0], "gate");
    EXPECT_DOUBLE_EQ(t.durations_ms[0], 0.25);
  }
  EXPECT_EQ(quiet, "");

  // Jumps every estimate for a second: one health line at the next report, not one per estimate.
  testing::internal::CaptureStderr();
  for (int64_t k = 60; k < 81; ++k) {
    vio_source.publish("VIO_ODOMETRY", vio(k, k % 2 == 0 ? 0.0 : 3.0));
  }
  loop.drain();
  const std::string noisy = testing::internal::GetCapturedStderr();
  ASSERT_EQ(timing.received.size(), 5u);  // at 3 and 4 s
  size_t lines = 0;
  for (char c : noisy) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, 1u) << noisy;  // at 4 s, for the 20 jumps since the report at 3 s
  EXPECT_NE(noisy.find("[vio_bridge] "), std::string::npos) << noisy;
  EXPECT_NE(noisy.find("flagged: position_jump"), std::string::npos) << noisy;
}

TEST(VioBridgeNode, AStampThatIsNotATimeDoesNotStopTheReports) {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  VioBridgeNode bridge{lcm, VioBridgeNodeOptions{}};
  TimingRecorder timing{lcm};
  Node vio_source{"vio", lcm};

  testing::internal::CaptureStderr();
  vio_source.publish("VIO_ODOMETRY", vio(0));  // reported: the first
  odometry_t garbage = vio(1);
  garbage.utime = -std::numeric_limits<int64_t>::max();
  vio_source.publish("VIO_ODOMETRY", garbage);  // dropped; before the last report: reported
  vio_source.publish("VIO_ODOMETRY", vio(20));  // a second after the first: reported
  loop.drain();
  testing::internal::GetCapturedStderr();
  ASSERT_EQ(timing.received.size(), 3u);
  EXPECT_EQ(timing.received[1].utime, 0);  // the garbage stamp, as the nearest time
  EXPECT_EQ(timing.received[2].utime, vio(20).utime);
  EXPECT_EQ(bridge.bridge().health().dropped, 1);
}

TEST(VioBridgeNode, UsesTheConfiguredChannels) {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  VioBridgeNodeOptions options;
  options.input_channel = "ROVIO_ODOMETRY";
  options.output_channel = "STATE_ESTIMATE_TEST";
  VioBridgeNode bridge{lcm, options};
  Recorder on_default{lcm, "STATE_ESTIMATE"};
  Recorder on_configured{lcm, "STATE_ESTIMATE_TEST"};
  Node vio_source{"vio", lcm};
  vio_source.publish("VIO_ODOMETRY", vio(0));
  vio_source.publish("ROVIO_ODOMETRY", vio(1));
  loop.drain();
  EXPECT_TRUE(on_default.received.empty());
  ASSERT_EQ(on_configured.received.size(), 1u);
  EXPECT_EQ(on_configured.received[0].utime, vio(1).utime);
  EXPECT_EQ(bridge.bridge().health().received, 1);
}

TEST(VioBridgeNode, RefusesBadOptions) {
  lcm::LCM lcm{"memq://"};
  VioBridgeNodeOptions options;
  options.output_channel = options.input_channel;
  EXPECT_THROW(VioBridgeNode(lcm, options), std::invalid_argument);
  options = {};
  options.bridge.body_in_vio_body.orientation = {0, 0, 0, 0};
  EXPECT_THROW(VioBridgeNode(lcm, options), std::invalid_argument);
  options = {};
  options.report_period = 0;
  EXPECT_THROW(VioBridgeNode(lcm, options), std::invalid_argument);
}

}  // namespace
}  // namespace thicket::vio_bridge

// The bridge's core on two memq:// buses (each LCM instance its own bus): what it copies each way,
// that its own copies never come back (no loop, even when both patterns take a channel), and its
// counters.
#include "bridge.h"

#include <algorithm>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

namespace thicket::bridge {
namespace {

// Everything received on one bus, as channel: payload.
struct Heard {
  explicit Heard(lcm::LCM& lcm) {
    lcm.subscribeFunction(
        ".*",
        +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, Heard* self) {
          self->messages.push_back(
              channel + ": " + std::string(static_cast<const char*>(rbuf->data), rbuf->data_size));
        },
        this);
  }
  std::vector<std::string> messages;
};

// Handles both buses until neither has anything left (memq delivers on handle()).
void drain(lcm::LCM& a, lcm::LCM& b) {
  for (int quiet = 0; quiet < 3;) {
    const int ra = a.handleTimeout(0), rb = b.handleTimeout(0);
    quiet = (ra <= 0 && rb <= 0) ? quiet + 1 : 0;
  }
}

std::vector<std::string> sorted(std::vector<std::string> v) {
  std::sort(v.begin(), v.end());
  return v;
}

void publish(lcm::LCM& lcm, const std::string& channel, const std::string& text) {
  ASSERT_EQ(lcm.publish(channel, text.data(), static_cast<unsigned>(text.size())), 0);
}

TEST(Bridge, CopiesEachWayWhatItsPatternsTake) {
  lcm::LCM vehicle("memq://"), link("memq://");
  ASSERT_TRUE(vehicle.good() && link.good());
  BridgeOptions options;
  options.up = std::regex("PLANNER_.*|STATE_ESTIMATE|MAP_.*");
  options.up_exclude = std::regex("MAP_ESDF");
  options.down = std::regex("MISSION_GOAL");
  Bridge bridge(vehicle, link, options);
  Heard on_vehicle(vehicle), on_link(link);

  publish(vehicle, "PLANNER_STATUS", "planned");
  publish(vehicle, "MAP_ESDF", "big");        // excluded
  publish(vehicle, "CAMERA_DEPTH", "image");  // not up
  publish(vehicle, "MAP_REQUEST", "request");
  publish(link, "MISSION_GOAL", "goal");
  publish(link, "PLANNER_STATUS", "spoofed");  // not down
  drain(vehicle, link);

  // Each bus in its own order; between the buses copies come after their originals.
  EXPECT_EQ(sorted(on_link.messages), sorted({"PLANNER_STATUS: planned", "MAP_REQUEST: request",
                                              "MISSION_GOAL: goal", "PLANNER_STATUS: spoofed"}));
  EXPECT_EQ(sorted(on_vehicle.messages),
            sorted({"PLANNER_STATUS: planned", "MAP_ESDF: big", "CAMERA_DEPTH: image",
                    "MAP_REQUEST: request", "MISSION_GOAL: goal"}));
  EXPECT_EQ(bridge.up().copied, 2);
  EXPECT_EQ(bridge.up().bytes, 14);
  EXPECT_EQ(bridge.up().filtered, 2);
  EXPECT_EQ(bridge.up().echoes, 1);  // MISSION_GOAL's copy on the vehicle bus
  EXPECT_EQ(bridge.down().copied, 1);
  EXPECT_EQ(bridge.down().filtered, 1);  // the spoofed status
  EXPECT_EQ(bridge.down().echoes, 2);    // the two copies it put on the link
  EXPECT_EQ(bridge.up().failed + bridge.down().failed, 0);
  EXPECT_TRUE(bridge.linkUp());
}

TEST(Bridge, ItsOwnCopiesNeverComeBackEvenWhenBothWaysTakeAChannel) {
  lcm::LCM vehicle("memq://"), link("memq://");
  BridgeOptions options;
  options.up = std::regex(".*");
  options.down = std::regex(".*");
  Bridge bridge(vehicle, link, options);
  Heard on_vehicle(vehicle), on_link(link);
  for (int i = 0; i < 3; ++i) {
    publish(vehicle, "PM_INFO", "info " + std::to_string(i));
    publish(link, "PM_ORDERS", "orders " + std::to_string(i));
  }
  // The same bytes twice on one bus: both are copied (an echo is consumed once).
  publish(vehicle, "PM_INFO", "info 0");
  drain(vehicle, link);
  EXPECT_EQ(on_vehicle.messages.size(), 7u);  // its 4 own and 3 orders, once each
  EXPECT_EQ(on_link.messages.size(), 7u);
  EXPECT_EQ(bridge.up().copied, 4);
  EXPECT_EQ(bridge.down().copied, 3);
  EXPECT_EQ(bridge.up().echoes, 3);
  EXPECT_EQ(bridge.down().echoes, 4);
}

TEST(Bridge, MessageKeysTellChannelsAndBytesApart) {
  EXPECT_NE(messageKey("A", "xy", 2), messageKey("A", "xz", 2));
  EXPECT_NE(messageKey("A", "xy", 2), messageKey("B", "xy", 2));
  EXPECT_NE(messageKey("AB", "", 0), messageKey("A", "B", 1));  // the separator
  EXPECT_EQ(messageKey("A", "xy", 2), messageKey("A", "xy", 2));
}

}  // namespace
}  // namespace thicket::bridge

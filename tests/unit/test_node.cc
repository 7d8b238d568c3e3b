// The node runtime on memq://: typed subscriptions, several nodes in one process, refusal of
// bad messages.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include <thicket/odometry_t.hpp>
#include <thicket/setpoint_t.hpp>

#include "thicket/common/loop.h"
#include "thicket/common/node.h"

namespace thicket {
namespace {

odometry_t makeOdometry(int64_t utime) {
  odometry_t msg{};
  msg.utime = utime;
  msg.sequence = utime / 10;
  msg.position[0] = 1.5;
  msg.position[2] = -2.25;
  msg.orientation[0] = 1.0;
  msg.quality = odometry_t::QUALITY_DEGRADED;
  msg.flags = odometry_t::FLAG_POSITION_JUMP;
  msg.reason = "jump of 3 m";
  return msg;
}

std::vector<uint8_t> encode(const odometry_t& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

struct MemqTest : ::testing::Test {
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
};

TEST_F(MemqTest, TypedSubscribeDeliversDecodedMessage) {
  Node receiver("receiver", lcm);
  Node sender("sender", lcm);
  std::vector<odometry_t> received;
  receiver.subscribe<odometry_t>("STATE_ESTIMATE",
                                 [&](const odometry_t& msg, const MessageInfo& info) {
                                   EXPECT_EQ(info.channel, "STATE_ESTIMATE");
                                   EXPECT_EQ(info.size, static_cast<size_t>(msg.getEncodedSize()));
                                   received.push_back(msg);
                                 });
  ASSERT_TRUE(sender.publish("STATE_ESTIMATE", makeOdometry(100)));
  ASSERT_TRUE(sender.publish("STATE_ESTIMATE", makeOdometry(200)));
  EXPECT_EQ(loop.drain(), 2);
  ASSERT_EQ(received.size(), 2u);
  EXPECT_EQ(received[0].utime, 100);
  EXPECT_EQ(received[1].utime, 200);
  EXPECT_DOUBLE_EQ(received[0].position[2], -2.25);
  EXPECT_EQ(received[0].reason, "jump of 3 m");
  EXPECT_EQ(receiver.badMessageCount(), 0);
}

// A composite: a chain of nodes, each reacting to the previous one's output, all handled by one
// drain in causal order.
TEST_F(MemqTest, NodesInOneProcessExchangeMessagesInOrder) {
  Node ping("ping", lcm);
  Node echo("echo", lcm);
  std::vector<int64_t> pongs;
  echo.subscribe<odometry_t>("PING", [&](const odometry_t& msg, const MessageInfo&) {
    odometry_t reply = msg;
    reply.sequence = msg.sequence + 1000;
    echo.publish("PONG", reply);
  });
  ping.subscribe<odometry_t>(
      "PONG", [&](const odometry_t& msg, const MessageInfo&) { pongs.push_back(msg.sequence); });
  for (int i = 1; i <= 3; ++i) ping.publish("PING", makeOdometry(i * 10));
  EXPECT_EQ(loop.drain(), 6);
  EXPECT_EQ(pongs, (std::vector<int64_t>{1001, 1002, 1003}));
}

TEST_F(MemqTest, ChannelNamesAreExactNotPatterns) {
  Node node("node", lcm);
  int calls = 0;
  node.subscribe<odometry_t>("A.B", [&](const odometry_t&, const MessageInfo&) { ++calls; });
  node.publish("AxB", makeOdometry(1));
  node.publish("A.B.C", makeOdometry(1));
  loop.drain();
  EXPECT_EQ(calls, 0);
  node.publish("A.B", makeOdometry(1));
  loop.drain();
  EXPECT_EQ(calls, 1);
}

TEST_F(MemqTest, RawSubscriptionTakesAPattern) {
  Node node("node", lcm);
  std::vector<std::string> channels;
  node.subscribeRaw("MAP_.*", [&](const void*, size_t size, const MessageInfo& info) {
    EXPECT_GT(size, 0u);
    channels.emplace_back(info.channel);
  });
  node.publish("MAP_TSDF", makeOdometry(1));
  node.publish("MAPPER_STATUS", makeOdometry(1));
  node.publish("MAP_ESDF", makeOdometry(1));
  loop.drain();
  EXPECT_EQ(channels, (std::vector<std::string>{"MAP_TSDF", "MAP_ESDF"}));
}

TEST_F(MemqTest, WrongTypeIsRefusedWithTheReason) {
  Node node("node", lcm);
  int calls = 0;
  node.subscribe<odometry_t>("STATE_ESTIMATE",
                             [&](const odometry_t&, const MessageInfo&) { ++calls; });
  setpoint_t setpoint{};
  setpoint.utime = 5;
  node.publish("STATE_ESTIMATE", setpoint);
  loop.drain();
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(node.badMessageCount(), 1);
  EXPECT_EQ(node.badMessageCounts().at("STATE_ESTIMATE"), 1);
  EXPECT_NE(node.lastError().find("fingerprint"), std::string::npos) << node.lastError();
  EXPECT_NE(node.lastError().find("odometry_t"), std::string::npos) << node.lastError();
}

TEST_F(MemqTest, TruncatedAndPaddedMessagesAreRefused) {
  Node node("node", lcm);
  int calls = 0;
  node.subscribe<odometry_t>("S", [&](const odometry_t&, const MessageInfo&) { ++calls; });
  std::vector<uint8_t> bytes = encode(makeOdometry(7));

  node.publishRaw("S", bytes.data(), bytes.size() / 2);
  loop.drain();
  EXPECT_NE(node.lastError().find("truncated"), std::string::npos) << node.lastError();

  node.publishRaw("S", bytes.data(), 3);
  loop.drain();
  EXPECT_NE(node.lastError().find("too short"), std::string::npos) << node.lastError();

  std::vector<uint8_t> padded = bytes;
  padded.resize(bytes.size() + 4, 0);
  node.publishRaw("S", padded.data(), padded.size());
  loop.drain();
  EXPECT_NE(node.lastError().find("4 unexpected bytes"), std::string::npos) << node.lastError();

  EXPECT_EQ(calls, 0);
  EXPECT_EQ(node.badMessageCount(), 3);
  node.publishRaw("S", bytes.data(), bytes.size());
  loop.drain();
  EXPECT_EQ(calls, 1);
}

// A message whose generated encoded size overflowed (negative) is refused before any buffer is
// sized from it: it used to become a vector of SIZE_MAX bytes and throw.
struct OverflowingMessage {
  static const char* getTypeName() { return "overflowing_t"; }
  int getEncodedSize() const { return -16; }
  int encode(void*, int, int) const { return -1; }
};

TEST_F(MemqTest, AMessageWhoseSizeOverflowsIsNotPublished) {
  Node node("node", lcm);
  EXPECT_FALSE(node.publish("CHANNEL", OverflowingMessage{}));
  EXPECT_NE(node.lastError().find("encoded size overflows"), std::string::npos) << node.lastError();
}

TEST_F(MemqTest, HandlerExceptionIsReportedAndTheNodeGoesOn) {
  Node node("node", lcm);
  std::vector<int64_t> handled;
  node.subscribe<odometry_t>("S", [&](const odometry_t& msg, const MessageInfo&) {
    if (msg.utime == 2) throw std::runtime_error("cannot use this one");
    handled.push_back(msg.utime);
  });
  for (int64_t t = 1; t <= 3; ++t) node.publish("S", makeOdometry(t));
  loop.drain();
  EXPECT_EQ(handled, (std::vector<int64_t>{1, 3}));
  EXPECT_EQ(node.badMessageCount(), 1);
  EXPECT_NE(node.lastError().find("cannot use this one"), std::string::npos);
}

TEST_F(MemqTest, DestroyedNodeReceivesNothing) {
  Node sender("sender", lcm);
  int calls = 0;
  {
    Node receiver("receiver", lcm);
    receiver.subscribe<odometry_t>("S", [&](const odometry_t&, const MessageInfo&) { ++calls; });
    sender.publish("S", makeOdometry(1));
    loop.drain();
    EXPECT_EQ(calls, 1);
  }
  sender.publish("S", makeOdometry(2));
  loop.drain();
  EXPECT_EQ(calls, 1);
}

TEST(DecodeMessage, ChecksFingerprintSizeAndTrailingBytes) {
  const std::vector<uint8_t> bytes = encode(makeOdometry(42));
  odometry_t msg{};
  EXPECT_EQ(decodeMessage(bytes.data(), bytes.size(), msg), "");
  EXPECT_EQ(msg.utime, 42);
  setpoint_t wrong{};
  EXPECT_NE(decodeMessage(bytes.data(), bytes.size(), wrong).find("fingerprint"),
            std::string::npos);
  EXPECT_NE(decodeMessage(bytes.data(), 0, msg), "");
}

TEST(ExactChannelPattern, EscapesEveryRegexCharacter) {
  EXPECT_EQ(exactChannelPattern("MAP_ESDF"), "MAP_ESDF");
  EXPECT_EQ(exactChannelPattern("a.b*c"), "a\\.b\\*c");
  EXPECT_EQ(exactChannelPattern("x[1]+(y)|$^?{2}\\"), "x\\[1\\]\\+\\(y\\)\\|\\$\\^\\?\\{2\\}\\\\");
}

}  // namespace
}  // namespace thicket

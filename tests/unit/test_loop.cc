// The event loop: timers on an injected clock, stopping, signals, draining.
#include <gtest/gtest.h>

#include <csignal>

#include <thicket/setpoint_t.hpp>

#include "thicket/common/loop.h"
#include "thicket/common/node.h"

namespace thicket {
namespace {

struct FakeClockTest : ::testing::Test {
  int64_t now = 1'000'000;
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm, [this] { return now; }};
};

TEST_F(FakeClockTest, TimerFiresOncePerPeriodAndSkipsMissedPeriods) {
  int fired = 0;
  loop.addTimer(100, [&] { ++fired; });
  loop.poll(0);
  EXPECT_EQ(fired, 0);
  now += 99;
  loop.poll(0);
  EXPECT_EQ(fired, 0);
  now += 1;
  loop.poll(0);
  EXPECT_EQ(fired, 1);
  loop.poll(0);
  EXPECT_EQ(fired, 1);
  now += 350;  // three and a half periods late: one call, not three
  loop.poll(0);
  EXPECT_EQ(fired, 2);
  now += 49;  // the schedule stays on the original grid: next due at +500
  loop.poll(0);
  EXPECT_EQ(fired, 2);
  now += 1;
  loop.poll(0);
  EXPECT_EQ(fired, 3);
}

TEST_F(FakeClockTest, TimerCanRemoveItselfAndOthers) {
  int a = 0, b = 0;
  Loop::TimerId id_b = 0;
  Loop::TimerId id_a = 0;
  id_a = loop.addTimer(10, [&] {
    ++a;
    loop.removeTimer(id_a);
    loop.removeTimer(id_b);
  });
  id_b = loop.addTimer(10, [&] { ++b; });
  now += 10;
  loop.poll(0);
  now += 10;
  loop.poll(0);
  EXPECT_EQ(a, 1);
  EXPECT_EQ(b, 0);
}

TEST_F(FakeClockTest, AFloodOfMessagesDoesNotStarveTimers) {
  Node node("node", lcm);
  int handled = 0;
  node.subscribe<setpoint_t>(
      "S", [&](const setpoint_t&, const MessageInfo&) { ++handled; }, 2000);
  int fired = 0;
  loop.addTimer(100, [&] { ++fired; });
  for (int i = 0; i < 1500; ++i) node.publish("S", setpoint_t{});
  now += 100;
  EXPECT_EQ(loop.poll(0), 1000);
  EXPECT_EQ(fired, 1);
  EXPECT_EQ(loop.poll(0), 500);
  EXPECT_EQ(handled, 1500);
}

TEST_F(FakeClockTest, RejectsNonPositivePeriods) {
  EXPECT_THROW(loop.addTimer(0, [] {}), std::invalid_argument);
}

TEST(Loop, RunStopsWhenAHandlerAsksIt) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Node node("node", lcm);
  int handled = 0;
  node.subscribe<setpoint_t>("STOP", [&](const setpoint_t&, const MessageInfo&) {
    ++handled;
    loop.stop();
  });
  node.publish("STOP", setpoint_t{});
  EXPECT_EQ(loop.run(), 0);
  EXPECT_EQ(handled, 1);
}

TEST(Loop, RunStopsOnSigterm) {
  Loop::installSignalHandlers();
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Node node("node", lcm);
  node.subscribe<setpoint_t>("KILL",
                             [&](const setpoint_t&, const MessageInfo&) { std::raise(SIGTERM); });
  node.publish("KILL", setpoint_t{});
  EXPECT_EQ(loop.run(), SIGTERM);
  EXPECT_TRUE(loop.stopRequested());
  Loop::clearTerminationSignal();
  EXPECT_FALSE(loop.stopRequested());
  EXPECT_EQ(Loop::terminationSignal(), 0);
}

TEST(Loop, SigintStopsEveryLoopInTheProcess) {
  Loop::installSignalHandlers();
  lcm::LCM lcm_a("memq://");
  lcm::LCM lcm_b("memq://");
  Loop a(lcm_a);
  Loop b(lcm_b);
  std::raise(SIGINT);
  EXPECT_EQ(a.run(), SIGINT);
  EXPECT_EQ(b.run(), SIGINT);
  Loop::clearTerminationSignal();
}

TEST(Loop, PollHandlesWhatIsPendingWithoutBlocking) {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Node node("node", lcm);
  int handled = 0;
  node.subscribe<setpoint_t>("S", [&](const setpoint_t&, const MessageInfo&) { ++handled; });
  EXPECT_EQ(loop.poll(0), 0);
  node.publish("S", setpoint_t{});
  node.publish("S", setpoint_t{});
  EXPECT_EQ(loop.poll(1000), 2);
  EXPECT_EQ(handled, 2);
}

TEST(Loop, RefusesAnUnusableLcm) {
  lcm::LCM lcm("nonsense://nowhere");
  ASSERT_FALSE(lcm.good());
  try {
    Loop loop(lcm);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not usable"), std::string::npos);
  }
}

}  // namespace
}  // namespace thicket

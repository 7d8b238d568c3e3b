// Logs: writing and reading in order with timestamps, torn tails, recording live traffic, and
// replay into nodes on memq://.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <thicket/odometry_t.hpp>
#include <thicket/setpoint_t.hpp>

#include "thicket/common/lcm_log.h"
#include "thicket/common/loop.h"

namespace thicket {
namespace {

namespace fs = std::filesystem;

std::string tempPath(const std::string& name) {
  return (fs::path(::testing::TempDir()) /
          (std::to_string(::getpid()) + "_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" + name))
      .string();
}

setpoint_t makeSetpoint(int64_t utime) {
  setpoint_t msg{};
  msg.utime = utime;
  msg.cycle = utime / 100;
  msg.position[0] = 0.5 * static_cast<double>(utime);
  msg.yaw = 0.25;
  return msg;
}

TEST(LcmLog, WrittenEventsReadBackInOrderWithTimestamps) {
  const std::string path = tempPath("a.lcmlog");
  {
    LogWriter writer(path);
    writer.write(1000, "SETPOINT", makeSetpoint(10));
    writer.write(1000, "OTHER", makeSetpoint(20));  // equal timestamps are fine
    writer.write(2500, "SETPOINT", makeSetpoint(30));
    EXPECT_EQ(writer.eventsWritten(), 3);
  }
  LogReader reader(path);
  const std::vector<LogEvent> events = reader.readAll();
  EXPECT_EQ(reader.error(), "");
  ASSERT_EQ(events.size(), 3u);
  const int64_t timestamps[] = {1000, 1000, 2500};
  const char* channels[] = {"SETPOINT", "OTHER", "SETPOINT"};
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].eventnum, static_cast<int64_t>(i));
    EXPECT_EQ(events[i].timestamp, timestamps[i]);
    EXPECT_EQ(events[i].channel, channels[i]);
    setpoint_t msg{};
    ASSERT_EQ(events[i].decode(msg), "");
    EXPECT_EQ(msg.utime, static_cast<int64_t>(10 * (i + 1)));
    EXPECT_DOUBLE_EQ(msg.position[0], 5.0 * static_cast<double>(i + 1));
  }
  odometry_t wrong{};
  EXPECT_NE(events[0].decode(wrong), "");
}

TEST(LcmLog, WriterRefusesTimeGoingBackwards) {
  LogWriter writer(tempPath("b.lcmlog"));
  writer.write(500, "A", makeSetpoint(1));
  EXPECT_THROW(writer.write(499, "A", makeSetpoint(2)), std::invalid_argument);
  EXPECT_EQ(writer.eventsWritten(), 1);
}

TEST(LcmLog, MissingFileIsAClearError) {
  const std::string path = tempPath("does/not/exist.lcmlog");
  try {
    LogReader reader(path);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_THROW(LogWriter writer(path), std::runtime_error);
}

// A pipe has no size: it used to read as an empty log (0 events, no error).
TEST(LcmLog, APipeIsRefusedNotReadAsEmpty) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const std::string path = "/proc/self/fd/" + std::to_string(fds[0]);
  try {
    LogReader reader(path);
    ADD_FAILURE() << "a pipe was opened as a log";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  ::close(fds[0]);
  ::close(fds[1]);
}

TEST(LcmLog, TornTailEndsTheLogWithAnError) {
  const std::string path = tempPath("torn.lcmlog");
  {
    LogWriter writer(path);
    for (int i = 0; i < 3; ++i) writer.write(100 * i, "S", makeSetpoint(i));
  }
  fs::resize_file(path, fs::file_size(path) - 5);
  LogReader reader(path);
  const auto events = reader.readAll();
  EXPECT_EQ(events.size(), 2u);
  EXPECT_NE(reader.error().find("torn"), std::string::npos) << reader.error();
  EXPECT_NE(reader.error().find("not part of the 2 events read"), std::string::npos)
      << reader.error();
}

// LCM 1.3.1 swallows a tail shorter than a sync word together with the last event.
TEST(LcmLog, ATailShorterThanASyncWordIsDamageToo) {
  const std::string path = tempPath("short_tail.lcmlog");
  {
    LogWriter writer(path);
    for (int i = 0; i < 3; ++i) writer.write(100 * i, "S", makeSetpoint(i));
  }
  std::ofstream(path, std::ios::app | std::ios::binary) << "\xed\xa1";
  LogReader reader(path);
  EXPECT_EQ(reader.readAll().size(), 3u);
  EXPECT_NE(reader.error().find("2 bytes are not part of the 3 events read"), std::string::npos)
      << reader.error();
}

// LCM 1.3.1's reader freads a data length of 2^31 - 1 into a failed allocation and crashes.
TEST(LcmLog, AnEventClaimingMoreBytesThanTheFileHoldsEndsTheReadingWithoutAllocatingThem) {
  const std::string path = tempPath("claims.lcmlog");
  {
    LogWriter writer(path);
    for (int i = 0; i < 3; ++i) writer.write(100 * i, "S", makeSetpoint(i));
  }
  const auto event_bytes = static_cast<std::streamoff>(fs::file_size(path) / 3);
  for (const uint32_t data_length : {0x7FFFFFFFu, 0x80000000u}) {
    {
      std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
      file.seekp(event_bytes + 24);  // the second event's data length
      const char bytes[4] = {static_cast<char>(data_length >> 24),
                             static_cast<char>(data_length >> 16),
                             static_cast<char>(data_length >> 8), static_cast<char>(data_length)};
      file.write(bytes, 4);
    }
    LogReader reader(path);
    EXPECT_EQ(reader.readAll().size(), 1u);
    const std::string expected =
        data_length == 0x7FFFFFFFu ? "its header claims 2147483676 bytes" : "negative data length";
    EXPECT_NE(reader.error().find("event 1 at byte " + std::to_string(event_bytes) + ": " +
                                  (data_length == 0x7FFFFFFFu ? "torn or corrupt event" : "")),
              std::string::npos)
        << reader.error();
    EXPECT_NE(reader.error().find(expected), std::string::npos) << reader.error();
    EXPECT_NE(reader.error().find("bytes are not part of the 1 events read"), std::string::npos);
  }
}

TEST(LcmLog, GarbageIsNotALog) {
  const std::string path = tempPath("garbage.lcmlog");
  std::ofstream(path) << "this is not an LCM log, just some text that happens to be here";
  LogReader reader(path);
  EXPECT_FALSE(reader.next().has_value());
  EXPECT_NE(reader.error(), "");
}

TEST(LcmLog, RecorderKeepsArrivalOrderAndPayloads) {
  const std::string path = tempPath("recorded.lcmlog");
  {
    lcm::LCM lcm("memq://");
    Loop loop(lcm);
    LogRecorder recorder(lcm, path, "S.*");
    Node node("node", lcm);
    node.publish("S1", makeSetpoint(1));
    node.publish("IGNORED", makeSetpoint(2));
    node.publish("S2", makeSetpoint(3));
    loop.drain();
    EXPECT_EQ(recorder.eventsWritten(), 2);
  }
  LogReader reader(path);
  const auto events = reader.readAll();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].channel, "S1");
  EXPECT_EQ(events[1].channel, "S2");
  EXPECT_LE(events[0].timestamp, events[1].timestamp);
  setpoint_t msg{};
  ASSERT_EQ(events[1].decode(msg), "");
  EXPECT_EQ(msg.utime, 3);
}

// Replay drives nodes exactly as logged: each event and everything it causes is handled before
// the next event is published.
TEST(LcmLog, ReplayFeedsNodesInLoggedOrder) {
  const std::string path = tempPath("replay.lcmlog");
  {
    LogWriter writer(path);
    for (int i = 0; i < 5; ++i) {
      writer.write(1000 * i, i % 2 == 0 ? "IN" : "NOISE", makeSetpoint(i));
    }
  }
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Node echo("echo", lcm);
  Node sink("sink", lcm);
  std::vector<std::string> trace;
  echo.subscribe<setpoint_t>("IN", [&](const setpoint_t& msg, const MessageInfo&) {
    trace.push_back("in " + std::to_string(msg.utime));
    echo.publish("OUT", msg);
  });
  echo.subscribe<setpoint_t>("NOISE", [&](const setpoint_t& msg, const MessageInfo&) {
    trace.push_back("noise " + std::to_string(msg.utime));
  });
  sink.subscribe<setpoint_t>("OUT", [&](const setpoint_t& msg, const MessageInfo&) {
    trace.push_back("out " + std::to_string(msg.utime));
  });

  LogReader reader(path);
  EXPECT_EQ(replayLog(reader, lcm, loop), 5);
  EXPECT_EQ(trace, (std::vector<std::string>{"in 0", "out 0", "noise 1", "in 2", "out 2", "noise 3",
                                             "in 4", "out 4"}));

  trace.clear();
  LogReader again(path);
  EXPECT_EQ(replayLog(again, lcm, loop, [](const LogEvent& e) { return e.channel == "IN"; }), 3);
  EXPECT_EQ(trace, (std::vector<std::string>{"in 0", "out 0", "in 2", "out 2", "in 4", "out 4"}));
}

}  // namespace
}  // namespace thicket

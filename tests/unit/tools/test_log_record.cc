// thicket-log record: where it writes, what it refuses, and, as a separate process on a private
// network, that it keeps a burst far longer than LCM's default subscription queue, byte for byte,
// including what was published just before it was told to stop.
#include <signal.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "procman_test_support.h"
#include "record.h"
#include "temp_dir_test.h"
#include "thicket/common/lcm_log.h"

namespace thicket::log {
namespace {

using procman::test_support::ChildProcess;
using procman::test_support::DescendantReaper;
using procman::test_support::isolatedUrl;
using procman::test_support::waitUntil;

class RecordTest : public testing::TempDirTest {
 protected:
  void touch(const std::string& path) { std::ofstream(path) << "x"; }
};

TEST_F(RecordTest, WritesTheNamedFileAndRefusesToOverwriteItUnlessForced) {
  const std::string out = tempPath("flight.lcm");
  auto path = chooseRecordPath(out, false, false);
  ASSERT_TRUE(path) << path.error();
  EXPECT_EQ(*path, out);
  touch(out);
  path = chooseRecordPath(out, false, false);
  ASSERT_FALSE(path);
  EXPECT_NE(path.error().find("exists"), std::string::npos) << path.error();
  path = chooseRecordPath(out, false, true);
  ASSERT_TRUE(path) << path.error();
  EXPECT_EQ(*path, out);
}

TEST_F(RecordTest, IncrementTakesTheFirstFreeNumberAsLcmLoggerDoes) {
  const std::string out = tempPath("sim.lcm");
  touch(out);  // the stem itself does not count
  auto path = chooseRecordPath(out, true, false);
  ASSERT_TRUE(path) << path.error();
  EXPECT_EQ(*path, out + ".00");
  touch(out + ".00");
  touch(out + ".02");
  path = chooseRecordPath(out, true, false);
  ASSERT_TRUE(path) << path.error();
  EXPECT_EQ(*path, out + ".01");
}

// Two recorders started together (the name checked, then created) used to pick the same file and
// truncate each other: choosing claims the file.
TEST_F(RecordTest, EachChoiceClaimsItsFile) {
  const std::string out = tempPath("twice.lcm");
  const auto first = chooseRecordPath(out, true, false);
  const auto second = chooseRecordPath(out, true, false);
  ASSERT_TRUE(first && second);
  EXPECT_EQ(*first, out + ".00");
  EXPECT_EQ(*second, out + ".01");
  EXPECT_TRUE(std::filesystem::exists(*first));
  const std::string plain = tempPath("once.lcm");
  ASSERT_TRUE(chooseRecordPath(plain, false, false));
  EXPECT_FALSE(chooseRecordPath(plain, false, false));
}

TEST_F(RecordTest, RefusesAMissingDirectoryADirectoryAndBadOptions) {
  EXPECT_FALSE(chooseRecordPath(tempPath("no/such/dir/x.lcm"), false, false));
  EXPECT_FALSE(chooseRecordPath(tempPath(""), false, true));
  RecordOptions options;
  options.out = tempPath("x.lcm");
  EXPECT_EQ(validateRecordOptions(options), "");
  options.channels = "SIM_(";
  EXPECT_NE(validateRecordOptions(options).find("not a regular expression"), std::string::npos);
  options.channels = ".*";
  options.queue = 0;
  EXPECT_NE(validateRecordOptions(options), "");
  options.queue = 100;
  options.drain_s = -1;
  EXPECT_NE(validateRecordOptions(options), "");
  options.drain_s = 0.2;
  options.increment = options.force = true;
  EXPECT_NE(validateRecordOptions(options), "");
  options.force = false;
  options.out.clear();
  EXPECT_NE(validateRecordOptions(options), "");
}

TEST_F(RecordTest, TheCommandLineRefusesBadArgumentsWithUsage) {
  for (const std::vector<std::string>& args : {std::vector<std::string>{"record"},
                                               {"record", tempPath("a.lcm"), "--queue", "many"},
                                               {"record", tempPath("a.lcm"), "--channels", "("},
                                               {"record", tempPath("a.lcm"), "--bogus"},
                                               {"record", tempPath("no/dir/a.lcm")}}) {
    std::vector<std::string> argv = {THICKET_LOG};
    argv.insert(argv.end(), args.begin(), args.end());
    ChildProcess recorder(argv);
    ASSERT_TRUE(recorder.waitExit(30));
    EXPECT_EQ(recorder.exitCode(), 2) << recorder.output();
    EXPECT_NE(recorder.output().find("thicket-log: "), std::string::npos) << recorder.output();
  }
}

// A message of the burst: its sequence number and a recognizable body.
std::vector<uint8_t> burstMessage(uint32_t seq) {
  std::vector<uint8_t> data(24 + seq % 40);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>(seq * 31 + i);
  std::memcpy(data.data(), &seq, sizeof seq);
  return data;
}

TEST_F(RecordTest, KeepsABurstLongerThanLcmsDefaultQueueAndTheLastMessagesBeforeTheStop) {
  DescendantReaper reaper;
  const std::string url = isolatedUrl();
  const std::string out = tempPath("bus.lcm");
  ChildProcess recorder({THICKET_LOG, "record", out, "--lcm-url", url, "--channels", "BURST|END"});
  ASSERT_TRUE(
      waitUntil([&] { return recorder.output().find("recording") != std::string::npos; }, 30))
      << recorder.output();

  // 150 messages back to back: five times LCM's default queue of 30, small enough that the
  // kernel's default socket buffer holds them all even if the recorder is not scheduled at all.
  lcm::LCM lcm(url);
  ASSERT_TRUE(lcm.good());
  constexpr uint32_t kBurst = 150;
  for (uint32_t seq = 0; seq < kBurst; ++seq) {
    const auto data = burstMessage(seq);
    ASSERT_EQ(lcm.publish("BURST", data.data(), static_cast<unsigned>(data.size())), 0);
  }
  const uint8_t other = 1;
  ASSERT_EQ(lcm.publish("OTHER", &other, 1), 0);  // not recorded: --channels
  ASSERT_EQ(lcm.publish("END", &other, 1), 0);
  // Stopped right after the last publish: the drain keeps what is still on its way.
  ASSERT_TRUE(recorder.signal(SIGINT));
  ASSERT_TRUE(recorder.waitExit(30));
  EXPECT_EQ(recorder.exitCode(), 0) << recorder.output();
  EXPECT_NE(recorder.output().find("recorded 151 events"), std::string::npos) << recorder.output();

  LogReader reader(out);
  const std::vector<LogEvent> events = reader.readAll();
  EXPECT_EQ(reader.error(), "");
  ASSERT_EQ(events.size(), kBurst + 1);
  for (uint32_t seq = 0; seq < kBurst; ++seq) {
    EXPECT_EQ(events[seq].eventnum, seq);
    EXPECT_EQ(events[seq].channel, "BURST");
    EXPECT_EQ(events[seq].data, burstMessage(seq)) << "message " << seq;
    if (seq > 0) {
      EXPECT_GE(events[seq].timestamp, events[seq - 1].timestamp);
    }
  }
  EXPECT_EQ(events.back().channel, "END");
}

}  // namespace
}  // namespace thicket::log

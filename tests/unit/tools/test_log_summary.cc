// thicket-log summary: exact counts, times, rates, sizes and types of hand-made logs; unknown
// fingerprints, mixed channels, messages that do not decode; torn, corrupt, empty and missing
// logs; the table and the JSON as the executable prints them.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>

#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/map_block_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/odometry_t.hpp>

#include "cli.h"
#include "summary.h"
#include "temp_dir_test.h"
#include "thicket/common/lcm_log.h"

namespace thicket::log {
namespace {

namespace fs = std::filesystem;
using thicket::testing::CliResult;
using thicket::testing::runCommand;

CliResult run(const std::string& args) {
  return runCommand(std::string(THICKET_LOG) + " " + args);
}

template <class Msg>
int64_t encodedSize(const Msg& msg) {
  return msg.getEncodedSize();
}

odometry_t makeOdometry(int64_t utime) {
  odometry_t msg{};
  msg.utime = utime;
  msg.orientation[0] = 1;
  return msg;
}

goal_t makeGoal(int waypoints) {
  goal_t msg{};
  msg.cycle = -1;
  msg.num_waypoints = waypoints;
  msg.waypoints.assign(static_cast<size_t>(waypoints), std::vector<double>{1, 2, 3});
  msg.yaws.assign(static_cast<size_t>(waypoints), 0.0);
  return msg;
}

// A message of a type no thicket or procman_lcm type has: fingerprint then a payload.
std::vector<uint8_t> alienMessage(size_t payload) {
  std::vector<uint8_t> bytes = {0x01, 0x23, 0x45, 0x67, 0x89, 0xab, 0xcd, 0xef};
  bytes.resize(8 + payload, 0x5a);
  return bytes;
}

// 11 SIM_TRUTH at 10 Hz over 1 s, 2 MISSION_GOAL of different sizes 0.5 s apart, 1 PM_INFO and
// 3 messages of an unknown type on ALIEN: 17 events from 1.0 s to 2.0 s.
void writeMixedLog(const std::string& path) {
  LogWriter writer(path);
  const std::vector<uint8_t> alien = alienMessage(4);
  procman_lcm::deputy_info_t info{};
  info.deputy_id = "deputy";
  for (int k = 0; k <= 10; ++k) {
    const int64_t t = 1'000'000 + 100'000 * k;
    writer.write(t, "SIM_TRUTH", makeOdometry(t));
    if (k == 2) writer.write(t, "PM_INFO", info);
    if (k % 4 == 1) writer.write(t, "ALIEN", alien.data(), alien.size());
    if (k == 0) writer.write(t + 50'000, "MISSION_GOAL", makeGoal(1));
    if (k == 5) writer.write(t + 50'000, "MISSION_GOAL", makeGoal(3));
  }
}

const ChannelSummary& channel(const thicket::log::LogSummary& summary, const std::string& name) {
  for (const ChannelSummary& c : summary.channels) {
    if (c.channel == name) return c;
  }
  throw std::runtime_error("no channel " + name);
}

// Each test writes into a fresh directory of its own, removed when it ends.
class LogSummary : public thicket::testing::TempDirTest {};

TEST_F(LogSummary, CountsTimesRatesAndSizesPerChannel) {
  const std::string path = tempPath("mixed.lcm");
  writeMixedLog(path);
  const auto summary = summarizeLog(path);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->error, "");
  EXPECT_TRUE(summary->warnings.empty());

  ASSERT_EQ(summary->channels.size(), 4u);
  EXPECT_EQ(summary->channels[0].channel, "ALIEN");  // sorted by name
  EXPECT_EQ(summary->channels[1].channel, "MISSION_GOAL");
  EXPECT_EQ(summary->channels[2].channel, "PM_INFO");
  EXPECT_EQ(summary->channels[3].channel, "SIM_TRUTH");

  const ChannelSummary& truth = channel(*summary, "SIM_TRUTH");
  EXPECT_EQ(truth.count, 11);
  EXPECT_EQ(truth.first_utime, 1'000'000);
  EXPECT_EQ(truth.last_utime, 2'000'000);
  EXPECT_DOUBLE_EQ(truth.durationSeconds(), 1.0);
  EXPECT_DOUBLE_EQ(truth.rateHz(), 10.0);
  EXPECT_EQ(truth.max_bytes, encodedSize(makeOdometry(0)));
  EXPECT_DOUBLE_EQ(truth.meanBytes(), static_cast<double>(encodedSize(makeOdometry(0))));
  EXPECT_EQ(truth.typeText(), "thicket.odometry_t");
  EXPECT_EQ(truth.decode_failures, 0);

  const ChannelSummary& goal = channel(*summary, "MISSION_GOAL");
  EXPECT_EQ(goal.count, 2);
  EXPECT_EQ(goal.first_utime, 1'050'000);
  EXPECT_EQ(goal.last_utime, 1'550'000);
  EXPECT_DOUBLE_EQ(goal.rateHz(), 2.0);
  EXPECT_EQ(goal.max_bytes, encodedSize(makeGoal(3)));
  EXPECT_DOUBLE_EQ(goal.meanBytes(),
                   0.5 * static_cast<double>(encodedSize(makeGoal(1)) + encodedSize(makeGoal(3))));
  EXPECT_EQ(goal.typeText(), "thicket.goal_t");

  const ChannelSummary& info = channel(*summary, "PM_INFO");
  EXPECT_EQ(info.count, 1);
  EXPECT_DOUBLE_EQ(info.durationSeconds(), 0.0);
  EXPECT_DOUBLE_EQ(info.rateHz(), 0.0);  // undefined for one message
  EXPECT_EQ(info.typeText(), "procman_lcm.deputy_info_t");

  const ChannelSummary& alien = channel(*summary, "ALIEN");
  EXPECT_EQ(alien.count, 3);  // k = 1, 5, 9
  EXPECT_EQ(alien.first_utime, 1'100'000);
  EXPECT_EQ(alien.last_utime, 1'900'000);
  EXPECT_DOUBLE_EQ(alien.rateHz(), 2.5);
  EXPECT_EQ(alien.max_bytes, 12);
  EXPECT_EQ(alien.typeText(), "unknown 0x0123456789abcdef");
  EXPECT_EQ(alien.decode_failures, 0);  // unknown types are not decoded

  EXPECT_EQ(summary->events, 17);
  EXPECT_EQ(summary->bytes, truth.total_bytes + goal.total_bytes + info.total_bytes + 36);
  EXPECT_EQ(summary->first_utime, 1'000'000);
  EXPECT_EQ(summary->last_utime, 2'000'000);
  EXPECT_DOUBLE_EQ(summary->spanSeconds(), 1.0);
  EXPECT_EQ(summary->file_bytes, static_cast<int64_t>(fs::file_size(path)));
}

TEST_F(LogSummary, KnowsEveryThicketAndProcmanType) {
  EXPECT_EQ(typeNameOfFingerprint(static_cast<uint64_t>(map_update_t::getHash())),
            "thicket.map_update_t");
  EXPECT_EQ(typeNameOfFingerprint(static_cast<uint64_t>(map_block_t::getHash())),
            "thicket.map_block_t");
  EXPECT_EQ(typeNameOfFingerprint(static_cast<uint64_t>(procman_lcm::orders_t::getHash())),
            "procman_lcm.orders_t");
  EXPECT_EQ(typeNameOfFingerprint(0xfeedfacecafebeefULL), "unknown 0xfeedfacecafebeef");
}

TEST_F(LogSummary, AMixedChannelListsItsTypesMostFrequentFirst) {
  const std::string path = tempPath("mixed_channel.lcm");
  {
    LogWriter writer(path);
    writer.write(0, "STATE", makeGoal(1));
    for (int i = 1; i <= 3; ++i) writer.write(i, "STATE", makeOdometry(i));
    const std::vector<uint8_t> tiny = {1, 2, 3};
    writer.write(5, "STATE", tiny.data(), tiny.size());
  }
  const auto summary = summarizeLog(path);
  ASSERT_TRUE(summary) << summary.error();
  ASSERT_EQ(summary->channels.size(), 1u);
  const ChannelSummary& state = summary->channels[0];
  ASSERT_EQ(state.types.size(), 3u);
  EXPECT_EQ(state.types[0].type, "thicket.odometry_t");
  EXPECT_EQ(state.types[0].count, 3);
  EXPECT_EQ(state.typeText(), "thicket.odometry_t + thicket.goal_t + unknown (no fingerprint)");
}

TEST_F(LogSummary, MessagesThatDoNotDecodeAsTheirTypeAreCountedAndReported) {
  const std::string path = tempPath("undecodable.lcm");
  {
    LogWriter writer(path);
    const odometry_t odometry = makeOdometry(1);
    std::vector<uint8_t> bytes(static_cast<size_t>(odometry.getEncodedSize()));
    odometry.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    writer.write(1, "SIM_TRUTH", bytes.data(), bytes.size());
    writer.write(2, "SIM_TRUTH", bytes.data(), bytes.size() - 10);  // cut short
    bytes.push_back(0);
    writer.write(3, "SIM_TRUTH", bytes.data(), bytes.size());  // one byte too many
  }
  const auto summary = summarizeLog(path);
  ASSERT_TRUE(summary) << summary.error();
  const ChannelSummary& truth = summary->channels.at(0);
  EXPECT_EQ(truth.count, 3);
  EXPECT_EQ(truth.typeText(), "thicket.odometry_t");
  EXPECT_EQ(truth.decode_failures, 2);
  EXPECT_NE(truth.first_decode_error.find(
                "event 1: malformed thicket.odometry_t (704 bytes): quality: truncated"),
            std::string::npos)
      << truth.first_decode_error;
  ASSERT_EQ(summary->warnings.size(), 1u);
  EXPECT_NE(summary->warnings[0].find("SIM_TRUTH: 2 of 3 messages do not decode"),
            std::string::npos)
      << summary->warnings[0];
  EXPECT_EQ(summary->error, "");
}

TEST_F(LogSummary, ATornLogIsSummarizedUpToWhereItBreaks) {
  const std::string path = tempPath("torn.lcm");
  writeMixedLog(path);
  const auto whole = fs::file_size(path);
  fs::resize_file(path, whole - 20);  // the logger was killed mid-write
  const auto summary = summarizeLog(path);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->events, 16);
  EXPECT_EQ(channel(*summary, "SIM_TRUTH").count, 10);
  EXPECT_NE(summary->error.find("event 16 at byte"), std::string::npos) << summary->error;
  EXPECT_NE(summary->error.find("torn or corrupt event"), std::string::npos) << summary->error;

  // Something was read: the summary is printed, the damage named on stderr, exit status 0.
  const CliResult result = run("summary '" + path + "'");
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("read 16 events, then stopped"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("SIM_TRUTH"), std::string::npos) << result.output;
}

// Overwrites the 4 bytes at `offset` with a big-endian value.
void patch(const std::string& path, std::streamoff offset, uint32_t value) {
  std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
  file.seekp(offset);
  const char bytes[4] = {static_cast<char>(value >> 24), static_cast<char>(value >> 16),
                         static_cast<char>(value >> 8), static_cast<char>(value)};
  file.write(bytes, 4);
}

TEST_F(LogSummary, CorruptHeadersEndTheReadingWithoutACrash) {
  // Three events of 28 + 4 + 100 bytes each: header (sync, number, time, lengths), "CHAN", data.
  const std::string original = tempPath("original.lcm");
  {
    LogWriter writer(original);
    const std::vector<uint8_t> data(100, 7);
    for (int i = 0; i < 3; ++i) writer.write(1000 * i, "CHAN", data.data(), data.size());
  }
  const std::streamoff second = 132;
  struct Case {
    std::streamoff offset;
    uint32_t value;
    std::string error;
  };
  const std::vector<Case> cases = {
      {second + 24, 0x7fffffff, "claims"},  // data length (lcm::LogFile crashes on it)
      {second + 20, 5000, "impossible channel name length 5000"},
      {second + 24, 0xffffff00, "negative data length -256"},
      {second, 0x12345678, "no sync word"},
  };
  for (const Case& c : cases) {
    const std::string path = tempPath("corrupt.lcm");
    fs::copy_file(original, path, fs::copy_options::overwrite_existing);
    patch(path, c.offset, c.value);
    const auto summary = summarizeLog(path);
    ASSERT_TRUE(summary) << summary.error();
    EXPECT_EQ(summary->events, 1) << c.error;
    EXPECT_NE(summary->error.find("event 1 at byte 132"), std::string::npos) << summary->error;
    EXPECT_NE(summary->error.find(c.error), std::string::npos) << summary->error;
  }
}

TEST_F(LogSummary, NothingReadableExitsWithStatusOne) {
  const std::string path = tempPath("garbage.lcm");
  std::ofstream(path) << "this is not an LCM log at all, just text\n";
  const CliResult result = run("summary '" + path + "'");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("read 0 events, then stopped"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("no sync word"), std::string::npos) << result.output;
}

TEST_F(LogSummary, AnEmptyLogIsFine) {
  const std::string path = tempPath("empty.lcm");
  { LogWriter writer(path); }
  const auto summary = summarizeLog(path);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->events, 0);
  EXPECT_EQ(summary->error, "");
  const CliResult result = run("summary '" + path + "'");
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("0 events on 0 channels"), std::string::npos) << result.output;
}

TEST_F(LogSummary, AMissingFileIsAClearErrorWithStatusTwo) {
  const std::string path = tempPath("does_not_exist.lcm");
  const CliResult result = run("summary '" + path + "'");
  EXPECT_EQ(result.status, 2) << result.output;
  EXPECT_EQ(result.output,
            "thicket-log: cannot open log '" + path + "': No such file or directory\n");
  EXPECT_FALSE(summarizeLog(path));
}

TEST_F(LogSummary, BadArgumentsExitWithStatusTwoAndAHint) {
  for (const std::string args :
       {"", "summary", "summary a.lcm --bogus", "frobnicate x.lcm", "summary a.lcm b.lcm"}) {
    const CliResult result = run(args);
    EXPECT_EQ(result.status, 2) << args << "\n" << result.output;
    EXPECT_NE(result.output.find("Run with --help"), std::string::npos) << result.output;
  }
  const CliResult help = run("--help");
  EXPECT_EQ(help.status, 0);
  for (const char* command : {"summary", "plot", "mission", "record"}) {
    EXPECT_NE(help.output.find(command), std::string::npos) << help.output;
  }
  const CliResult summary_help = run("summary --help");
  EXPECT_EQ(summary_help.status, 0);
  EXPECT_NE(summary_help.output.find("--json"), std::string::npos) << summary_help.output;
}

TEST_F(LogSummary, TheTablePrintsOneRowPerChannelAndTotals) {
  const std::string path = tempPath("table.lcm");
  writeMixedLog(path);
  const CliResult result = run("summary '" + path + "'");
  ASSERT_EQ(result.status, 0) << result.output;
  std::vector<std::string> lines;
  std::istringstream stream(result.output);
  for (std::string line; std::getline(stream, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 8u) << result.output;  // 2 header lines, column names, 4 rows, total
  EXPECT_NE(lines[0].find("17 events on 4 channels"), std::string::npos) << lines[0];
  EXPECT_NE(lines[1].find("1.000 s from 1970-01-01 00:00:01.000000 UTC"), std::string::npos)
      << lines[1];
  const auto words = [](const std::string& line) {
    std::istringstream in(line);
    return std::vector<std::string>(std::istream_iterator<std::string>(in), {});
  };
  EXPECT_EQ(words(lines[3]),
            (std::vector<std::string>{"ALIEN", "unknown", "0x0123456789abcdef", "3", "0.100",
                                      "0.900", "0.800", "2.50", "12.0", "12"}));
  const std::string size = std::to_string(encodedSize(makeOdometry(0)));
  EXPECT_EQ(words(lines[6]),
            (std::vector<std::string>{"SIM_TRUTH", "thicket.odometry_t", "11", "0.000", "1.000",
                                      "1.000", "10.00", size + ".0", size}));
  EXPECT_EQ(words(lines[5])[6], "-");  // PM_INFO: one message has no rate
  EXPECT_EQ(words(lines[7])[0], "total");
  EXPECT_EQ(words(lines[7])[1], "17");
}

TEST_F(LogSummary, JsonHasTheSameNumbers) {
  const std::string path = tempPath("json.lcm");
  writeMixedLog(path);
  const CliResult result = run("summary '" + path + "' --json");
  ASSERT_EQ(result.status, 0) << result.output;
  const YAML::Node json = YAML::Load(result.output);  // JSON is YAML
  EXPECT_EQ(json["events"].as<int64_t>(), 17);
  EXPECT_EQ(json["first_utime"].as<int64_t>(), 1'000'000);
  EXPECT_DOUBLE_EQ(json["span_s"].as<double>(), 1.0);
  EXPECT_TRUE(json["complete"].as<bool>());
  EXPECT_TRUE(json["error"].IsNull());
  ASSERT_EQ(json["channels"].size(), 4u);
  const YAML::Node alien = json["channels"][0];
  EXPECT_EQ(alien["channel"].as<std::string>(), "ALIEN");
  EXPECT_EQ(alien["type"].as<std::string>(), "unknown 0x0123456789abcdef");
  EXPECT_EQ(alien["count"].as<int64_t>(), 3);
  EXPECT_DOUBLE_EQ(alien["rate_hz"].as<double>(), 2.5);
  EXPECT_EQ(alien["first_utime"].as<int64_t>(), 1'100'000);
  EXPECT_EQ(alien["max_bytes"].as<int64_t>(), 12);
  EXPECT_TRUE(json["channels"][2]["rate_hz"].IsNull());  // PM_INFO
  EXPECT_EQ(json["channels"][3]["types"][0]["type"].as<std::string>(), "thicket.odometry_t");
  EXPECT_EQ(json["channels"][3]["types"][0]["count"].as<int64_t>(), 11);

  // A torn log says so in the JSON too.
  fs::resize_file(path, fs::file_size(path) - 20);
  const CliResult torn =
      runCommand("(" + std::string(THICKET_LOG) + " summary '" + path + "' --json 2>/dev/null)");
  const YAML::Node damaged = YAML::Load(torn.output);
  EXPECT_FALSE(damaged["complete"].as<bool>());
  EXPECT_NE(damaged["error"].as<std::string>().find("torn or corrupt event"), std::string::npos);
}

// Whatever the file holds, --json prints JSON: a channel name that is not UTF-8 (the hand-made
// writer copied its bytes) and times at the ends of int64 (whose difference overflowed).
TEST_F(LogSummary, JsonIsValidForAnyFile) {
  const std::string path = tempPath("odd.lcm");
  {
    LogWriter writer(path);
    const std::vector<uint8_t> alien = alienMessage(4);
    writer.write(INT64_MIN + 1, "BAD\xff\xfe", alien.data(), alien.size());
    writer.write(INT64_MAX, "BAD\xff\xfe", alien.data(), alien.size());
  }
  const CliResult result = run("summary '" + path + "' --json");
  ASSERT_EQ(result.status, 0) << result.output;
  nlohmann::json json;
  ASSERT_NO_THROW(json = nlohmann::json::parse(result.output)) << result.output;
  ASSERT_TRUE(json["span_s"].is_number());
  EXPECT_GT(json["span_s"].get<double>(), 1.8e13);  // 2^64 us, not a wrapped difference
  ASSERT_EQ(json["channels"].size(), 1u);
  EXPECT_EQ(json["channels"][0]["count"].get<int64_t>(), 2);
}

}  // namespace
}  // namespace thicket::log

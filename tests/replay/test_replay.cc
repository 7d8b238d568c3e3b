// Replay regression: every reference log in logs/ replays exactly into the real VIO bridge,
// mapper, explorer and local planner; the references together exercise what they claim; a
// changed planner option or an altered recorded message shows in the diff by channel, message and
// field; incomplete and damaged logs are reported, never crashed on.
//
// When a reference fails because behaviour changed on purpose: thicket-replay record-references.
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <thicket/goal_t.hpp>
#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>
#include <thicket/sim_event_t.hpp>

#include "commands.h"
#include "temp_dir_test.h"
#include "thicket/local_planner/local_planner.h"

namespace thicket::replay {

// Test names and failure messages show the reference's name, not its bytes.
void PrintTo(const ReferenceFlight& reference, std::ostream* out) {
  *out << reference.name;
}

namespace {

const std::string kRegenerate =
    "\n(if the change is intended: build/tools/replay/thicket-replay record-references)";

std::string referenceLog(const std::string& name) {
  for (const ReferenceFlight& reference : referenceFlights()) {
    if (reference.name == name) return referencePath(defaultLogsDir(), reference);
  }
  throw std::runtime_error("no reference " + name);
}

std::vector<LogEvent> readEvents(const std::string& path) {
  LogReader reader(path);
  std::vector<LogEvent> events = reader.readAll();
  if (!reader.error().empty()) throw std::runtime_error(reader.error());
  return events;
}

const LcmTypeSet& types() {
  static const Expected<LcmTypeSet> types = LcmTypeSet::loadDirectory(defaultLcmTypesDir());
  if (!types) throw std::runtime_error(types.error());
  return *types;
}

CheckOptions checkOptions(const std::string& log, const std::string& method = "") {
  CheckOptions options;
  options.log = log;
  options.method = method;
  options.lcmtypes_dir = defaultLcmTypesDir();
  return options;
}

// ---- the references ----

class ReferenceLog : public ::testing::TestWithParam<ReferenceFlight> {};

TEST_P(ReferenceLog, ReplaysExactly) {
  const std::string path = referencePath(defaultLogsDir(), GetParam());
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " is missing" << kRegenerate;
  EXPECT_LT(static_cast<int64_t>(std::filesystem::file_size(path)), kMaxReferenceBytes);
  const auto result = checkLog(checkOptions(path));
  ASSERT_TRUE(result) << result.error();
  EXPECT_TRUE(result->equal) << result->text << kRegenerate;
  // Every replayed module had outputs to compare.
  auto recorded = [&](const std::string& channel) {
    const auto it = result->replay.recorded.find(channel);
    return it == result->replay.recorded.end() ? size_t{0} : it->second.size();
  };
  for (const char* channel : {"STATE_ESTIMATE", "MAP_TSDF", "MAP_ESDF", "MAPPER_STATUS",
                              "PLANNER_TRAJECTORY", "PLANNER_STATUS", "MODULE_TIMING"}) {
    EXPECT_GT(recorded(channel), 0u) << channel;
  }
  if (GetParam().flight.method != "none") {
    EXPECT_GT(recorded("EXPLORER_GOAL"), 0u);
  }
  EXPECT_TRUE(result->replay.notes.empty()) << result->text;
}

INSTANTIATE_TEST_SUITE_P(References, ReferenceLog, ::testing::ValuesIn(referenceFlights()),
                         [](const ::testing::TestParamInfo<ReferenceFlight>& info) {
                           return info.param.name;
                         });

TEST(ReferenceLogs, TogetherExerciseThePlannerAndTheExplorer) {
  int64_t total_bytes = 0;
  std::map<std::string, int> seen;
  for (const ReferenceFlight& reference : referenceFlights()) {
    const std::string path = referencePath(defaultLogsDir(), reference);
    ASSERT_TRUE(std::filesystem::exists(path)) << path << kRegenerate;
    total_bytes += static_cast<int64_t>(std::filesystem::file_size(path));
    for (const LogEvent& event : readEvents(path)) {
      if (event.channel == "PLANNER_STATUS") {
        planner_status_t status;
        ASSERT_EQ(event.decode(status), "");
        if (!status.is_final && status.state == planner_status_t::STATE_STUCK) ++seen["asks"];
        if (status.is_final &&
            status.reason.rfind(local_planner::kBlockedTrajectoryReason, 0) == 0) {
          ++seen["committed trajectory blocked"];
        }
        if (status.is_final && status.state == planner_status_t::STATE_STUCK) ++seen["stuck"];
        if (status.is_final && status.state == planner_status_t::STATE_HOLDING) ++seen["holding"];
        if (status.is_final && status.state == planner_status_t::STATE_PLANNED &&
            status.goal_source == goal_t::SOURCE_EXPLORER) {
          ++seen["flies an intermediate goal"];
        }
      } else if (event.channel == "EXPLORER_GOAL") {
        goal_t goal;
        ASSERT_EQ(event.decode(goal), "");
        if (goal.status == goal_t::STATUS_OK) ++seen["intermediate goals"];
        if (goal.status == goal_t::STATUS_NO_CANDIDATE) ++seen["no candidate"];
      } else if (event.channel == "SIM_EVENT") {
        sim_event_t sim;
        ASSERT_EQ(event.decode(sim), "");
        if (sim.outcome == sim_event_t::OUTCOME_GOAL_REACHED) ++seen["goal reached"];
      } else if (event.channel == "MAP_REQUEST") {
        ++seen["snapshots requested"];
      }
    }
  }
  EXPECT_LE(total_bytes, kMaxReferencesBytes);
  EXPECT_GE(seen["asks"], 10);
  EXPECT_GE(seen["stuck"], 5);
  EXPECT_GE(seen["holding"], 5);
  EXPECT_GE(seen["flies an intermediate goal"], 2);
  EXPECT_GE(seen["intermediate goals"], 10);
  EXPECT_GE(seen["no candidate"], 1);
  EXPECT_GE(seen["committed trajectory blocked"], 1);
  EXPECT_GE(seen["goal reached"], 1);
  EXPECT_GE(seen["snapshots requested"], 3);
}

// ---- changes show in the diff ----

class ReplayDiff : public testing::TempDirTest {
 protected:
  static const std::vector<LogEvent>& events() {
    static const std::vector<LogEvent> events =
        readEvents(referenceLog("paper_short_local_exploration"));
    return events;
  }
  static GraphOptions options() {
    return *trialGraphOptions(*simWorld(events()), "local_exploration");
  }
  std::string writeLog(const std::vector<LogEvent>& events) {
    const std::string path = tempPath("altered.lcm");
    LogWriter writer(path);
    for (const LogEvent& e : events)
      writer.write(e.timestamp, e.channel, e.data.data(), e.data.size());
    return path;
  }
  static std::vector<LogEvent> without(const std::string& channel) {
    std::vector<LogEvent> kept;
    for (const LogEvent& e : events()) {
      if (e.channel != channel) kept.push_back(e);
    }
    return kept;
  }
};

TEST_F(ReplayDiff, AChangedPlannerOptionShowsByChannelMessageAndField) {
  GraphOptions changed = options();
  changed.planner.planner.loco.w_g *= 1.01;
  const CheckResult result = checkEvents(events(), changed, types(), 1000);
  EXPECT_FALSE(result.equal);
  // The map does not depend on the planner: only what the planner (and the explorer answering
  // it) publishes differs.
  for (const ChannelComparison& channel : result.comparison.channels) {
    if (channel.channel.rfind("MAP", 0) == 0 || channel.channel == "STATE_ESTIMATE") {
      EXPECT_TRUE(channel.equal()) << result.text;
    }
  }
  const std::regex line(
      "PLANNER_(STATUS|TRAJECTORY) message [0-9]+ of [0-9]+ \\(utime [0-9]+\\): "
      "[a-z_]+(\\[[0-9]+\\])*: recorded \\S+ replayed \\S+");
  bool named = false;
  for (const std::string& l : result.comparison.lines) named = named || std::regex_match(l, line);
  EXPECT_TRUE(named) << result.text;
}

TEST_F(ReplayDiff, AnAlteredRecordedMessageIsNamedWithBothValues) {
  std::vector<LogEvent> altered = events();
  size_t seen = 0, total = 0;
  std::string original, changed;
  int64_t utime = 0;
  for (const LogEvent& e : altered) total += e.channel == "PLANNER_TRAJECTORY";
  for (LogEvent& e : altered) {
    if (e.channel != "PLANNER_TRAJECTORY" || ++seen != 6) continue;
    polynomial_trajectory_t trajectory;
    ASSERT_EQ(e.decode(trajectory), "");
    double& c = trajectory.coefficients.at(2).at(1).at(4);
    char text[64];
    original.assign(text, std::to_chars(text, text + sizeof text, c).ptr);
    c = std::nextafter(c, 1e9);  // one bit
    changed.assign(text, std::to_chars(text, text + sizeof text, c).ptr);
    utime = trajectory.utime;
    e.data.resize(static_cast<size_t>(trajectory.getEncodedSize()));
    trajectory.encode(e.data.data(), 0, static_cast<int>(e.data.size()));
  }
  ASSERT_GE(seen, 6u);
  const auto result = checkLog(checkOptions(writeLog(altered), "local_exploration"));
  ASSERT_TRUE(result) << result.error();
  EXPECT_FALSE(result->equal);
  // Recorded outputs never feed the replay: nothing downstream of the altered message differs.
  ASSERT_EQ(result->comparison.lines.size(), 1u) << result->text;
  EXPECT_EQ(result->comparison.lines[0],
            "PLANNER_TRAJECTORY message 6 of " + std::to_string(total) + " (utime " +
                std::to_string(utime) + "): coefficients[2][1][4]: recorded " + changed +
                " replayed " + original);
  EXPECT_NE(result->text.find("PLANNER_TRAJECTORY: recorded " + std::to_string(total) +
                              " messages, replayed " + std::to_string(total) + ", 1 differs\n"),
            std::string::npos)
      << result->text;
  EXPECT_NE(result->text.find("differs: 1 of "), std::string::npos) << result->text;
}

TEST_F(ReplayDiff, AMissingInputChannelIsReported) {
  const auto result =
      checkLog(checkOptions(writeLog(without("CAMERA_DEPTH")), "local_exploration"));
  ASSERT_TRUE(result) << result.error();
  EXPECT_FALSE(result->equal);
  EXPECT_NE(result->text.find("note: the log has no CAMERA_DEPTH (an input of mapper)"),
            std::string::npos)
      << result->text;
  EXPECT_NE(result->text.find("\nMAP_ESDF: recorded "), std::string::npos) << result->text;
}

TEST_F(ReplayDiff, AMissingOutputChannelIsReported) {
  const std::vector<LogEvent> events = without("PLANNER_TRAJECTORY");
  const auto result = checkLog(checkOptions(writeLog(events), "local_exploration"));
  ASSERT_TRUE(result) << result.error();
  EXPECT_FALSE(result->equal);
  EXPECT_NE(
      result->text.find("note: the log has no PLANNER_TRAJECTORY, which the replay published"),
      std::string::npos)
      << result->text;
  EXPECT_NE(result->text.find("PLANNER_TRAJECTORY: recorded 0 messages, replayed "),
            std::string::npos)
      << result->text;
  EXPECT_NE(result->text.find("differs: 1 of "), std::string::npos) << result->text;
}

TEST_F(ReplayDiff, ATornLogIsReportedAndFails) {
  const std::string whole = referenceLog("paper_short_local_exploration");
  const std::string torn = tempPath("torn.lcm");
  std::filesystem::copy_file(whole, torn);
  // The last event, cut in the middle.
  std::filesystem::resize_file(torn, std::filesystem::file_size(whole) - 40);
  const auto result = checkLog(checkOptions(torn, "local_exploration"));
  ASSERT_TRUE(result) << result.error();
  EXPECT_FALSE(result->equal);
  EXPECT_NE(result->text.find("damaged log: " + torn + ": "), std::string::npos) << result->text;
  EXPECT_NE(result->text.find("torn or corrupt log"), std::string::npos) << result->text;
}

TEST_F(ReplayDiff, LogsThatCannotBeReplayedSayWhy) {
  auto error = [](const CheckOptions& options) {
    const auto result = checkLog(options);
    return result ? std::string("checked") : result.error();
  };
  EXPECT_NE(error(checkOptions(writeLog(without("SIM_WORLD")), "none")).find("no SIM_WORLD"),
            std::string::npos);
  EXPECT_NE(error(checkOptions(writeLog(events()))).find("give the method it was flown with"),
            std::string::npos);
  EXPECT_NE(error(checkOptions(writeLog(events()), "bogus")).find("unknown method 'bogus'"),
            std::string::npos);
  EXPECT_NE(error(checkOptions(tempPath("nothing.lcm"), "none")).find("cannot open log"),
            std::string::npos);
  const std::string garbage = tempPath("garbage.lcm");
  std::ofstream(garbage) << std::string(5000, '\xed') << "not a log";
  EXPECT_NE(error(checkOptions(garbage, "none")).find("no SIM_WORLD"), std::string::npos);
  CheckOptions no_types = checkOptions(referenceLog("paper_none"));
  no_types.lcmtypes_dir = tempPath("empty");
  std::filesystem::create_directory(no_types.lcmtypes_dir);
  EXPECT_NE(error(no_types).find("no .lcm files"), std::string::npos);
}

}  // namespace
}  // namespace thicket::replay

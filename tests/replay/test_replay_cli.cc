// thicket-replay as a user runs it: check's exit status (0 equal, 1 a difference or a damaged
// log, 2 cannot check), record flying a short trial that then checks equal, and clear messages
// for wrong arguments.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "cli.h"
#include "commands.h"
#include "temp_dir_test.h"

namespace thicket::replay {
namespace {

using thicket::testing::runCommand;

const std::string kReplay = THICKET_REPLAY;

std::string reference(const std::string& name) {
  for (const ReferenceFlight& r : referenceFlights()) {
    if (r.name == name) return referencePath(defaultLogsDir(), r);
  }
  throw std::runtime_error("no reference " + name);
}

class ReplayCli : public testing::TempDirTest {};

TEST_F(ReplayCli, CheckSaysEqualForAReference) {
  const auto result = runCommand(kReplay + " check " + reference("paper_none"));
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("equal: "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("replayed into vio_bridge, mapper, local_planner in "),
            std::string::npos)
      << result.output;
}

TEST_F(ReplayCli, CheckFailsOnADamagedLog) {
  const std::string torn = tempPath("torn.lcm");
  std::filesystem::copy_file(reference("paper_none"), torn);
  std::filesystem::resize_file(torn, std::filesystem::file_size(torn) - 1000);
  const auto result = runCommand(kReplay + " check " + torn + " --method none --max-diffs 2");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("damaged log: "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("differs: "), std::string::npos) << result.output;
}

TEST_F(ReplayCli, CheckWithTheWrongMethodShowsTheDifferences) {
  const auto result = runCommand(kReplay + " check " + reference("paper_rrt_star_conservative") +
                                 " --method random --max-diffs 3");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("EXPLORER_GOAL message 1 of "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("strategy: recorded \"rrt_star_conservative\" replayed \"random\""),
            std::string::npos)
      << result.output;
  EXPECT_NE(result.output.find(" more differences"), std::string::npos) << result.output;
}

TEST_F(ReplayCli, RecordFliesATrialThatReplaysExactly) {
  const std::string log = tempPath("short.lcm");
  const auto recorded = runCommand(kReplay + " record --out " + log +
                                   " --scenario paper --density 0.1 --seed 1 --method none "
                                   "--replans 3");
  ASSERT_EQ(recorded.status, 0) << recorded.output;
  EXPECT_NE(recorded.output.find("wrote " + log + ": "), std::string::npos) << recorded.output;
  EXPECT_NE(recorded.output.find("3 replans"), std::string::npos) << recorded.output;
  EXPECT_NE(recorded.output.find("replays exactly in "), std::string::npos) << recorded.output;
  EXPECT_FALSE(std::filesystem::exists(log + ".partial"));
  const auto checked = runCommand(kReplay + " check " + log + " --method none");
  EXPECT_EQ(checked.status, 0) << checked.output;
  // Not a reference: the method must be given.
  const auto unnamed = runCommand(kReplay + " check " + log);
  EXPECT_EQ(unnamed.status, 2) << unnamed.output;
  EXPECT_NE(unnamed.output.find("--method M"), std::string::npos) << unnamed.output;
}

TEST_F(ReplayCli, WrongArgumentsSayWhatIsWrong) {
  struct Case {
    std::string args;
    std::string message;
  };
  const std::string out = " --out " + tempPath("x.lcm");
  const Case cases[] = {
      {"", "A subcommand is required"},
      {"replay", "unexpected argument 'replay'"},
      {"check", "LOG is required"},
      {"check a.lcm b.lcm", "not expected: b.lcm"},
      {"check a.lcm --max-diffs many", "--max-diffs: must be an integer >= 0, not 'many'"},
      {"check a.lcm --speed 2", "--speed"},
      {"check " + tempPath("missing.lcm") + " --method none", "cannot open log"},
      {"record" + out + " --scenario paper --density 0.1 --method none", "--seed is required"},
      {"record" + out + " --scenario paper --density 0.1 --seed -3 --method none",
       "--seed: must be an integer >= 0, not '-3'"},
      {"record" + out + " --scenario paper --density x --seed 1 --method none",
       "--density: must be a number >= 0, not 'x'"},
      {"record" + out + " --scenario paper --density 0.1 --seed 1 --method best",
       "--method: best not in {none,"},
      {"record" + out + " --scenario moon --density 0.1 --seed 1 --method none", "moon"},
      {"record" + out + " --scenario paper --density 0.1 --seed 1 --method none --replans 0",
       "--replans: must be an integer in [1, 100000], not '0'"},
      {"record" + out + " --scenario paper --density 0.1 --seed 1 --method none" +
           " --dynamic-obstacle yes",
       "--dynamic-obstacle: must be on or off, not 'yes'"},
      {"record-references --logs", "--logs: 1 required TEXT missing"},
  };
  for (const Case& c : cases) {
    const auto result = runCommand(kReplay + " " + c.args);
    EXPECT_EQ(result.status, 2) << c.args << "\n" << result.output;
    EXPECT_NE(result.output.find(c.message), std::string::npos) << c.args << "\n" << result.output;
  }
  EXPECT_FALSE(std::filesystem::exists(tempPath("x.lcm")));
  const auto help = runCommand(kReplay + " --help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.output.find("record-references"), std::string::npos);
}

}  // namespace
}  // namespace thicket::replay

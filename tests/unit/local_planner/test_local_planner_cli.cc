// thicket-local-planner as a user runs it: the shipped parameter file is current, and bad
// configurations stop it at start with a message.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "cli.h"
#include "local_planner_node.h"

namespace thicket::local_planner {
namespace {

using thicket::testing::CliResult;

CliResult planner(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_LOCAL_PLANNER) + " " + args);
}

// config/params/local_planner.yaml documents every option; it must load and must not fall behind.
TEST(LocalPlannerCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<LocalPlannerNodeOptions>(
      THICKET_LOCAL_PLANNER, "thicket-local-planner",
      std::string(THICKET_SOURCE_DIR) + "/config/params/local_planner.yaml");
}

TEST(LocalPlannerCli, RefusesBadConfigurationsWithAMessage) {
  const std::string config =
      ::testing::TempDir() + "/local_planner_cli_" + std::to_string(::getpid()) + ".yaml";
  const auto run_with = [&](const std::string& yaml) {
    std::ofstream(config) << yaml;
    return planner("--lcm-url memq:// --config " + config);
  };
  CliResult result = planner("--config /nonexistent.yaml");
  EXPECT_EQ(result.status, 2);
  result = run_with("planner:\n  loco:\n    w_c: .nan\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("w_c"), std::string::npos) << result.output;
  result = run_with("planner:\n  goal_finder:\n    method: sideways\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("method"), std::string::npos) << result.output;
  // Each corner is in range on its own; together they are an empty volume.
  result = run_with("planner:\n  flight_volume_min: [0, 0, 5]\n  flight_volume_max: [10, 10, 1]\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("LocalPlanner"), std::string::npos) << result.output;
  result = planner("--bogus");
  EXPECT_EQ(result.status, 2);
  std::remove(config.c_str());
}

}  // namespace
}  // namespace thicket::local_planner

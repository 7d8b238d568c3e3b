// thicket-explorer as a user runs it: the shipped parameter file is current, and bad
// configurations stop it at start with a message.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "cli.h"
#include "explorer_node.h"

namespace thicket::explorer {
namespace {

using thicket::testing::CliResult;

CliResult explorer(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_EXPLORER) + " " + args);
}

// config/params/explorer.yaml documents every option; it must load and must not fall behind.
TEST(ExplorerCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<ExplorerNodeOptions>(
      THICKET_EXPLORER, "thicket-explorer",
      std::string(THICKET_SOURCE_DIR) + "/config/params/explorer.yaml");
}

TEST(ExplorerCli, RefusesBadConfigurationsWithAMessage) {
  const std::string config =
      ::testing::TempDir() + "/explorer_cli_" + std::to_string(::getpid()) + ".yaml";
  const auto run_with = [&](const std::string& yaml) {
    std::ofstream(config) << yaml;
    return explorer("--lcm-url memq:// --config " + config);
  };
  CliResult result = explorer("--config /nonexistent.yaml");
  EXPECT_EQ(result.status, 2);
  result = run_with("explorer:\n  strategy: teleport\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("strategy"), std::string::npos) << result.output;
  result = run_with("explorer:\n  p_goal: 1.5\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("p_goal"), std::string::npos) << result.output;
  result = run_with("explorer:\n  rrt_star:\n    range: .nan\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("range"), std::string::npos) << result.output;
  // Each bound is in range on its own; together they are inconsistent.
  result = run_with("explorer:\n  nbvp:\n    initial_nodes: 50\n    max_nodes: 10\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("explorer"), std::string::npos) << result.output;
  result = explorer("--bogus");
  EXPECT_EQ(result.status, 2);
  std::remove(config.c_str());
}

}  // namespace
}  // namespace thicket::explorer

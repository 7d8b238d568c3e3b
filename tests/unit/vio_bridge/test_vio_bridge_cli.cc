// thicket-vio-bridge as a user runs it: the shipped parameter file is current, and bad
// configurations stop it at start with a message.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "cli.h"
#include "vio_bridge_node.h"

namespace thicket::vio_bridge {
namespace {

using thicket::testing::CliResult;

CliResult bridge(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_VIO_BRIDGE) + " " + args);
}

// config/params/vio_bridge.yaml documents every option; it must load and must not fall behind.
TEST(VioBridgeCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<VioBridgeNodeOptions>(
      THICKET_VIO_BRIDGE, "thicket-vio-bridge",
      std::string(THICKET_SOURCE_DIR) + "/config/params/vio_bridge.yaml");
}

TEST(VioBridgeCli, RefusesBadConfigurationsWithAMessage) {
  const std::string config =
      ::testing::TempDir() + "/vio_bridge_cli_" + std::to_string(::getpid()) + ".yaml";
  const auto run_with = [&](const std::string& yaml) {
    std::ofstream(config) << yaml;
    return bridge("--lcm-url memq:// --config " + config);
  };
  const auto expect_refused = [](const CliResult& result, const std::string& mention) {
    EXPECT_EQ(result.status, 2) << result.output;
    EXPECT_NE(result.output.find(mention), std::string::npos) << result.output;
  };
  expect_refused(bridge("--config /nonexistent.yaml"), "nonexistent");
  expect_refused(run_with("bridge:\n  max_speed: -1\n"), "max_speed");
  expect_refused(run_with("bridge:\n  on_stale: ignore\n"), "on_stale");
  expect_refused(run_with("bridge:\n  max_gap: .nan\n"), "max_gap");
  expect_refused(run_with("bridge:\n  body_in_vio_body:\n    orientation: [1, 0, 0]\n"),
                 "orientation");
  expect_refused(run_with("bridge:\n  vio_world_in_world:\n    orientation: [0.5, 0, 0, 0]\n"),
                 "unit quaternion");
  // Each bound is in range on its own; together they are inconsistent.
  expect_refused(run_with("bridge:\n  quaternion_tolerance: 0.1\n  quaternion_max_error: 0.01\n"),
                 "quaternion_max_error");
  expect_refused(run_with("input_channel: STATE_ESTIMATE\n"), "differ");
  expect_refused(run_with("bridge:\n  max_sped: 3\n"), "max_sped");
  EXPECT_EQ(bridge("--bogus").status, 2);
  std::remove(config.c_str());
}

}  // namespace
}  // namespace thicket::vio_bridge

// thicket-sim's offline commands as a user runs them: the printed world and the written PNG
// match the core library's answers exactly, and bad arguments fail with a message.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "cli.h"
#include "png.h"
#include "sim_node.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"

namespace thicket::sim {
namespace {

using thicket::testing::CliResult;

CliResult run(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_SIM) + " " + args);
}

// A parameter file for one test, removed when the test ends.
struct TempConfig {
  std::string path;
  explicit TempConfig(const std::string& text)
      : path(::testing::TempDir() + "/sim_cli_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
             std::to_string(::getpid()) + ".yaml") {
    std::ofstream(path) << text;
  }
  ~TempConfig() { std::remove(path.c_str()); }
};

World paperWorld(double density, uint64_t seed) {
  auto spec = loadScenario("paper", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  return *generateWorld(*spec, density, seed);
}

TEST(SimCli, WorldPrintsTheGeneratedWorldAsJson) {
  const CliResult result = run("world --scenario paper --density 0.3 --seed 42 --json");
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_EQ(result.output, worldToJson(paperWorld(0.3, 42)) + "\n");
}

TEST(SimCli, RenderWritesMillimetreDepthOfTheCore) {
  const std::string path =
      ::testing::TempDir() + "/sim_cli_depth_" + std::to_string(::getpid()) + ".png";
  const CliResult result =
      run("render --scenario paper --density 0.3 --seed 42 --pose 1,5,1.5,0.3 --out " + path);
  ASSERT_EQ(result.status, 0) << result.output;
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(image.type(), CV_16UC1);
  ASSERT_EQ(image.cols, 320);
  ASSERT_EQ(image.rows, 240);

  const DepthRenderer renderer(paperWorld(0.3, 42), {});
  std::vector<float> depth;
  renderer.render(Pose::fromYaw(Eigen::Vector3d(1, 5, 1.5), 0.3), depth);
  int returns = 0;
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      const double mm = std::round(static_cast<double>(depth[v * image.cols + u]) * 1000.0);
      const int expected = mm > 65535 ? 0 : static_cast<int>(mm);
      ASSERT_EQ(image.at<uint16_t>(v, u), expected) << u << "," << v;
      returns += expected > 0;
    }
  }
  EXPECT_GT(returns, 320 * 240 / 2);
  std::remove(path.c_str());
}

TEST(SimCli, BadArgumentsFailWithAMessage) {
  CliResult result = run("world --scenario paper --density -1 --seed 1 --json");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("--density"), std::string::npos) << result.output;
  result = run("world --scenario atlantis --density 0.1 --seed 1 --json");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("atlantis"), std::string::npos) << result.output;
  result = run("render --scenario paper --density 0.1 --seed 1 --pose 1,2,3 --out /tmp/x.png");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("--pose"), std::string::npos) << result.output;
  result = run("render --scenario paper --density 0.1 --seed 010 --pose 1,2,3,0 --out /tmp/x.png");
  EXPECT_EQ(result.status, 2);  // not octal 8
  EXPECT_NE(result.output.find("--seed"), std::string::npos) << result.output;
  result = run("render --scenario paper --density 0.1 --seed 1 --bogus 3");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("unexpected argument '--bogus'"), std::string::npos)
      << result.output;
  result = run("fly");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("unexpected argument 'fly'"), std::string::npos) << result.output;
}

// config/params/sim.yaml documents every option; it must load and must not fall behind the code.
TEST(SimCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<SimOptions>(
      THICKET_SIM, "thicket-sim", std::string(THICKET_SOURCE_DIR) + "/config/params/sim.yaml");
}

// Without lockstep the simulator steps on its own clock; with no planner the vehicle hovers
// until the replan limit.
TEST(SimCli, RunFreelyHoversToTheReplanLimitWithoutAPlanner) {
  const TempConfig config(
      "rate: 200\nvehicle: {replan_limit: 3}\ndepth_camera: {width: 32, height: 24}\n");
  const CliResult result = run("run --lcm-url memq:// --config " + config.path + " --seed 3");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("replan limit reached after 3 cycles, path 0.00 m"),
            std::string::npos)
      << result.output;
}

// Without a planner there is no committed path to block: the obstacle never appears, and the
// run says so.
TEST(SimCli, RunReportsADynamicObstacleThatNeverAppeared) {
  const TempConfig config(
      "rate: 200\nvehicle: {replan_limit: 3}\ndepth_camera: {width: 32, height: 24}\n"
      "dynamic_obstacle: {enabled: true, appear_time: 0}\n");
  const CliResult result = run("run --lcm-url memq:// --config " + config.path + " --seed 3");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("the dynamic obstacle never appeared"), std::string::npos)
      << result.output;
}

TEST(SimCli, RunRefusesADynamicObstacleThatWouldStartInsideTheRobot) {
  const TempConfig config("dynamic_obstacle: {enabled: true, distance_ahead_min: 0.9}\n");
  const CliResult result = run("run --lcm-url memq:// --config " + config.path + " --seed 3");
  EXPECT_EQ(result.status, 2) << result.output;
  EXPECT_NE(result.output.find("dynamic_obstacle: distance_ahead_min (0.9 m) must exceed radius "
                               "(0.5 m) + the robot radius (0.5 m)"),
            std::string::npos)
      << result.output;
}

TEST(SimCli, RunWithoutAPlannerAbortsInLockstep) {
  const TempConfig config(
      "lockstep: true\nlockstep_timeout: 0.2\ndepth_camera: {width: 32, height: 24}\n");
  const CliResult result =
      run("run --lcm-url memq:// --config " + config.path + " --density 0.1 --seed 3");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("aborted: no final planner status for 0.2"), std::string::npos)
      << result.output;
}

// The PNG writers refuse pixels that do not fill the image instead of reading past them.
TEST(SimPng, PixelsThatDoNotFillTheImageAreRefused) {
  const std::string path = ::testing::TempDir() + "/sim_png_" + std::to_string(::getpid()) + ".png";
  EXPECT_NE(writeDepthPng(path, 4, 3, std::vector<float>(11, 1.0f)).find("11 pixels for a 4 x 3"),
            std::string::npos);
  EXPECT_NE(writeGrayPng(path, 4, 3, std::vector<uint8_t>(13, 7)).find("13 pixels"),
            std::string::npos);
  EXPECT_NE(writeDepthPng(path, 0, 3, {}).find("for a 0 x 3"), std::string::npos);
  ASSERT_EQ(writeDepthPng(path, 4, 3, std::vector<float>(12, 1.5f)), "");
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(image.type(), CV_16UC1);
  EXPECT_EQ(image.at<uint16_t>(2, 3), 1500);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace thicket::sim

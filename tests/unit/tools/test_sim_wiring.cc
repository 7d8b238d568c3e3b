// One wiring: the benchmark's in-process graph and the shipped simulation sheets run every module
// with the same options. Each sheet's commands are split as the deputy splits them, their
// --config files loaded as the executables load them, and the result compared option by option
// (describeParams) with what trialGraphOptions builds for the world the sheet flies.
#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "stereo_depth_node.h"
#include "thicket/common/params.h"
#include "thicket/procman/command_line.h"
#include "thicket/procman/sheet.h"
#include "thicket/sim/render.h"
#include "trials.h"

namespace thicket::bench {
namespace {

const std::string kSource = THICKET_SOURCE_DIR;

// A sheet command's program (the file name), its --config file relative to the repository root,
// where sheets run (empty when it passes none), and its other flags with their values.
struct Launch {
  std::string program;
  std::string config;
  std::map<std::string, std::string> flags;
};

std::map<std::string, Launch> launches(const std::string& sheet_path) {
  const auto sheet = procman::loadSheet(kSource + "/" + sheet_path);
  EXPECT_TRUE(sheet) << (sheet ? "" : sheet.error());
  std::map<std::string, Launch> result;
  if (!sheet) return result;
  for (const procman::SheetCommand& command : sheet->commands) {
    const auto split = procman::splitCommandLine(command.exec, {});
    EXPECT_TRUE(split) << command.exec;
    if (!split) continue;
    Launch launch{std::filesystem::path(split->argv.front()).filename().string(), "", {}};
    for (size_t i = 1; i + 1 < split->argv.size(); ++i) {
      if (split->argv[i].rfind("--", 0) == 0) launch.flags[split->argv[i]] = split->argv[i + 1];
    }
    if (launch.flags.count("--config")) launch.config = launch.flags.at("--config");
    result[launch.program] = launch;
  }
  return result;
}

// The options an executable started by `launch` runs with.
template <class Options>
Options optionsOf(const Launch& launch) {
  return launch.config.empty() ? Options{} : loadParams<Options>(kSource + "/" + launch.config);
}

// The world a sheet's thicket-sim command flies (--scenario, --density, --seed); the simulation
// sheets all fly one, the replay sheet none (its logs come from sim.pmd).
sim::World sheetWorld(const std::string& sheet_path) {
  std::map<std::string, Launch> sheet = launches(sheet_path);
  if (!sheet.count("thicket-sim")) sheet = launches("config/sim.pmd");
  const std::map<std::string, std::string>& flags = sheet.at("thicket-sim").flags;
  auto spec = sim::loadScenario(flags.at("--scenario"), kSource + "/config/worlds");
  EXPECT_TRUE(spec);
  return *sim::generateWorld(*spec, std::stod(flags.at("--density")),
                             std::stoull(flags.at("--seed")));
}

void expectSheetMatchesTrials(const std::string& sheet_path) {
  SCOPED_TRACE(sheet_path);
  const std::map<std::string, Launch> sheet = launches(sheet_path);
  const sim::World world = sheetWorld(sheet_path);
  ASSERT_TRUE(sheet.count("thicket-explorer"));
  // The sheet runs the explorer's configured strategy: the benchmark method of the same name.
  const std::string method =
      optionsOf<explorer::ExplorerNodeOptions>(sheet.at("thicket-explorer")).explorer.strategy;
  const TrialGraphOptions trial = trialGraphOptions(method, "soft", world.seed, world.bounds_min,
                                                    world.bounds_max, world.robot_radius);
  ASSERT_TRUE(trial.explorer);
  EXPECT_EQ(describeParams(optionsOf<explorer::ExplorerNodeOptions>(sheet.at("thicket-explorer"))),
            describeParams(*trial.explorer));
  ASSERT_TRUE(sheet.count("thicket-local-planner"));
  EXPECT_EQ(describeParams(optionsOf<local_planner::LocalPlannerNodeOptions>(
                sheet.at("thicket-local-planner"))),
            describeParams(trial.planner));
  ASSERT_TRUE(sheet.count("thicket-mapper"));
  // The checkpoint is the process's crash recovery, which a trial (one process) does without.
  auto sheet_mapper = optionsOf<mapper::MapperNodeOptions>(sheet.at("thicket-mapper"));
  sheet_mapper.checkpoint.clear();
  EXPECT_EQ(describeParams(sheet_mapper), describeParams(trial.mapper));
  if (sheet.count("thicket-vio-bridge")) {
    EXPECT_EQ(
        describeParams(optionsOf<vio_bridge::VioBridgeNodeOptions>(sheet.at("thicket-vio-bridge"))),
        describeParams(trial.bridge));
  }
}

TEST(SimWiring, TheSimulationSheetRunsTheBenchmarksOptions) {
  expectSheetMatchesTrials("config/sim.pmd");
}

TEST(SimWiring, TheStereoSheetRunsTheBenchmarksOptions) {
  expectSheetMatchesTrials("config/sim_stereo.pmd");
  // Its depth node takes the file the benchmark's stereo trials load, and that file describes the
  // pairs the simulator renders.
  const std::map<std::string, Launch> sheet = launches("config/sim_stereo.pmd");
  ASSERT_TRUE(sheet.count("thicket-stereo-depth"));
  EXPECT_EQ(sheet.at("thicket-stereo-depth").config, "config/sim/stereo_depth.yaml");
  const auto node =
      optionsOf<stereo_depth::StereoDepthNodeOptions>(sheet.at("thicket-stereo-depth"));
  const sim::StereoCameraOptions camera;
  const sim::StereoRenderer renderer(sheetWorld("config/sim_stereo.pmd"), camera);
  const PinholeCamera rendered = renderer.camera();
  const stereo_depth::RectifiedCameraOptions& rectified = node.stereo.rectified;
  EXPECT_EQ(rectified.width, rendered.width);
  EXPECT_EQ(rectified.height, rendered.height);
  EXPECT_DOUBLE_EQ(rectified.fx, rendered.fx);
  EXPECT_DOUBLE_EQ(rectified.fy, rendered.fy);
  EXPECT_DOUBLE_EQ(rectified.cx, rendered.cx);
  EXPECT_DOUBLE_EQ(rectified.cy, rendered.cy);
  EXPECT_DOUBLE_EQ(rectified.baseline, renderer.baseline());
  EXPECT_EQ(node.camera_position_in_body, camera.position_in_body);
  EXPECT_DOUBLE_EQ(node.camera_pitch_down_deg, camera.pitch_down_deg);
}

TEST(SimWiring, TheReplaySheetRunsTheBenchmarksOptions) {
  expectSheetMatchesTrials("config/replay.pmd");
}

// The comparison itself tells options apart: one changed option in a file the benchmark loads
// makes the texts differ.
TEST(SimWiring, OneChangedOptionShows) {
  const sim::World world = sheetWorld("config/sim.pmd");
  TrialGraphOptions trial =
      trialGraphOptions("local_exploration", "soft", world.seed, world.bounds_min, world.bounds_max,
                        world.robot_radius);
  const std::string before = describeParams(trial.planner);
  trial.planner.planner.loco.clearance_margin += 0.01;
  EXPECT_NE(describeParams(trial.planner), before);
}

}  // namespace
}  // namespace thicket::bench

// thicket-log plot: a hand-made mission log (two cylinders, a path, goals, a collision and an ESDF
// built from a snapshot and deltas logged out of revision order): the scene read from it checked
// exactly (map columns by class, points, notes), the JSON plot_mission.py draws, and the PNG it
// writes; missing channels, nothing to draw, bad arguments.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/sim_event_t.hpp>
#include <thicket/sim_world_t.hpp>

#include "cli.h"
#include "plot.h"
#include "temp_dir_test.h"
#include "thicket/common/lcm_log.h"
#include "thicket/common/map_update.h"

namespace thicket::log {
namespace {

namespace fs = std::filesystem;
using thicket::testing::CliResult;
using thicket::testing::runCommand;

CliResult run(const std::string& args) {
  return runCommand(std::string(THICKET_LOG) + " " + args);
}

constexpr double kVoxel = 0.2;
constexpr double kHeight = 1.5;  // flown height: the map band is 1.0 .. 2.0 m

sim_world_t makeWorld() {
  sim_world_t world{};
  world.scenario = "hand-made";
  world.bounds_max[0] = 10;
  world.bounds_max[1] = 8;
  world.bounds_max[2] = 4;
  world.start[0] = 1, world.start[1] = 4, world.start[2] = kHeight;
  world.goal[0] = 9, world.goal[1] = 4, world.goal[2] = kHeight;
  world.robot_radius = 0.5;
  world.num_cylinders = 2;
  world.cylinder_x = {3.0, 7.0};
  world.cylinder_y = {4.0, 2.0};
  world.cylinder_radius = {0.5, 0.4};
  world.cylinder_height = {4.0, 4.0};
  return world;
}

// The flown path: (1, 4) → (2, 6) → (8, 6) → (9, 4), sampled every 0.1 m.
std::vector<Eigen::Vector3d> flownPath() {
  const std::vector<Eigen::Vector3d> corners = {
      {1, 4, kHeight}, {2, 6, kHeight}, {8, 6, kHeight}, {9, 4, kHeight}};
  std::vector<Eigen::Vector3d> path;
  for (size_t i = 0; i + 1 < corners.size(); ++i) {
    const int steps = static_cast<int>(std::ceil((corners[i + 1] - corners[i]).norm() / 0.1));
    for (int s = 0; s < steps; ++s) {
      path.push_back(corners[i] + (corners[i + 1] - corners[i]) * s / steps);
    }
  }
  path.push_back(corners.back());
  return path;
}

goal_t makeGoal(const Eigen::Vector3d& p, int8_t source) {
  goal_t goal{};
  goal.source = source;
  goal.status = goal_t::STATUS_OK;
  goal.num_waypoints = 1;
  goal.waypoints = {{p.x(), p.y(), p.z()}};
  goal.yaws = {0};
  return goal;
}

// Every voxel of block (bx, by, 0) observed free, 1 m from anything.
void addFreeBlock(EsdfLayer& layer, int bx, int by) {
  Block<EsdfVoxel>& block = layer.allocateBlock(BlockIndex(bx, by, 0));
  for (EsdfVoxel& v : block.voxels) v = EsdfVoxel{1.0f, true, false};
}

// A vertical run of observed voxels at distance 0 through the band, at the voxel holding (x, y).
void addOccupiedColumn(EsdfLayer& layer, double x, double y) {
  for (double z = 1.1; z < 2.0; z += kVoxel) {
    *layer.voxel(layer.voxelIndex({x, y, z})) = EsdfVoxel{0.0f, true, true};
  }
}

// Where the ESDF ends up (in revision order), with voxel centres as the probe points:
//  - (1.1, 5.1) occupied at revision 1, free again at revision 2;
//  - (2.1, 3.5) occupied from revision 2;
//  - (2.5, 4.5) occupied only at z = 0.1, below the band: drawn free;
//  - block (2, 0, 0) (x 6.4 .. 9.6, y 0 .. 3.2) free at revision 0, removed at revision 2.
// Revision 2 is logged before revision 1: drawing in file order would get the first two wrong.
void writeMap(LogWriter& writer, int64_t t) {
  EsdfLayer layer(kVoxel);
  addFreeBlock(layer, 0, 1);
  addFreeBlock(layer, 2, 0);
  const auto snapshot = encodeMapUpdate(layer, {t, 7, 0, true}, {}, {});

  addOccupiedColumn(layer, 1.1, 5.1);
  const auto revision1 = encodeMapUpdate(layer, {t + 1, 7, 1, false}, {BlockIndex(0, 1, 0)}, {});

  addFreeBlock(layer, 0, 1);
  addOccupiedColumn(layer, 2.1, 3.5);
  *layer.voxel(layer.voxelIndex({2.5, 4.5, 0.1})) = EsdfVoxel{0.0f, true, true};
  layer.removeBlock(BlockIndex(2, 0, 0));
  const auto revision2 =
      encodeMapUpdate(layer, {t + 2, 7, 2, false}, {BlockIndex(0, 1, 0)}, {BlockIndex(2, 0, 0)});
  for (const auto* messages : {&snapshot, &revision2, &revision1}) {
    for (const map_update_t& msg : *messages) writer.write(t, "MAP_ESDF", msg);
  }
}

struct Channels {
  bool world = true, truth = true, goal = true, explorer = true, event = true, map = true;
  bool dynamic_obstacle = false;  // SIM_WORLD again at the end, with a third cylinder at (5, 3)
};

void writeMission(const std::string& path, const Channels& channels = {}) {
  LogWriter writer(path);
  int64_t t = 1'000'000;
  if (channels.world) writer.write(t, "SIM_WORLD", makeWorld());
  if (channels.goal) {
    writer.write(t, "MISSION_GOAL", makeGoal({9, 4, kHeight}, goal_t::SOURCE_OPERATOR));
  }
  if (channels.explorer) {
    writer.write(t, "EXPLORER_GOAL", makeGoal({5, 6.5, kHeight}, goal_t::SOURCE_EXPLORER));
  }
  if (channels.truth) {
    int64_t sequence = 0;
    for (const Eigen::Vector3d& p : flownPath()) {
      odometry_t odometry{};
      odometry.utime = t += 100'000;
      odometry.sequence = sequence++;
      odometry.position[0] = p.x(), odometry.position[1] = p.y(), odometry.position[2] = p.z();
      odometry.orientation[0] = 1;
      writer.write(t, "SIM_TRUTH", odometry);
    }
  }
  if (channels.event) {
    sim_event_t event{};
    event.utime = t;
    event.type = sim_event_t::TYPE_COLLISION;
    event.position[0] = 6, event.position[1] = 1, event.position[2] = kHeight;
    writer.write(t, "SIM_EVENT", event);
    event.type = sim_event_t::TYPE_TRIAL_END;  // not a collision: not drawn
    event.position[0] = 4;
    writer.write(t, "SIM_EVENT", event);
  }
  if (channels.map) writeMap(writer, t);
  if (channels.dynamic_obstacle) {
    sim_world_t world = makeWorld();
    world.num_cylinders = 3;
    world.cylinder_x.push_back(5.0);
    world.cylinder_y.push_back(3.0);
    world.cylinder_radius.push_back(0.5);
    world.cylinder_height.push_back(4.0);
    writer.write(t, "SIM_WORLD", world);
  }
}

std::string cellName(Cell cell) {
  return cell == Cell::kOccupied ? "occupied" : cell == Cell::kFree ? "free" : "unknown";
}

bool near(const std::optional<PlotPoint>& p, double x, double y) {
  return p && std::hypot(p->x - x, p->y - y) < 1e-9;
}

// Each test writes into a fresh directory of its own, removed when it ends.
class LogPlot : public thicket::testing::TempDirTest {};

TEST_F(LogPlot, ReadsWorldMapPathGoalsAndCollisions) {
  const std::string log_path = tempPath("mission.lcm");
  writeMission(log_path);
  PlotOptions options;
  options.out = tempPath("top.png");
  const auto scene = readPlotScene(log_path, options);
  ASSERT_TRUE(scene) << scene.error();
  EXPECT_EQ(scene->map_layer, "MAP_ESDF");
  ASSERT_TRUE(scene->map);
  EXPECT_EQ(scene->map->revision, 2);
  EXPECT_DOUBLE_EQ(scene->z_min, kHeight - 0.5);
  EXPECT_DOUBLE_EQ(scene->z_max, kHeight + 0.5);
  EXPECT_EQ(scene->subtitle, "MAP_ESDF rev 2, max over z 1.0..2.0 m");
  EXPECT_TRUE(scene->notes.empty()) << scene->notes.front();

  ASSERT_TRUE(scene->world);
  EXPECT_EQ(scene->world->cylinder_x, (std::vector<double>{3.0, 7.0}));
  EXPECT_EQ(scene->path.size(), flownPath().size());
  EXPECT_TRUE(near(scene->start, 1, 4));
  EXPECT_TRUE(near(scene->goal, 9, 4));
  ASSERT_EQ(scene->explorer_goals.size(), 1u);
  EXPECT_TRUE(near(scene->explorer_goals[0], 5, 6.5));
  ASSERT_EQ(scene->collisions.size(), 1u);  // the trial end is no collision
  EXPECT_TRUE(near(scene->collisions[0], 6, 1));

  const auto at = [&](double x, double y) { return cellName(scene->map->at(x, y)); };
  EXPECT_EQ(at(1.1, 5.1), "free");      // revision 2 cleared it, though logged first
  EXPECT_EQ(at(2.1, 3.5), "occupied");  // revision 2's obstacle
  EXPECT_EQ(at(2.5, 4.5), "free");      // occupied only below the band
  EXPECT_EQ(at(0.5, 3.5), "free");      // the snapshot's free block
  EXPECT_EQ(at(8.0, 1.0), "unknown");   // a block removed at revision 2
  EXPECT_EQ(at(5.0, 7.5), "unknown");   // never observed

  // What the script is given: the same, in metres and voxel columns.
  const nlohmann::json json = nlohmann::json::parse(sceneJson(*scene, 640));
  EXPECT_EQ(json["size"], 640);
  EXPECT_EQ(json["title"], "mission.lcm");
  EXPECT_EQ(json["world"]["cylinders"].size(), 2u);
  EXPECT_EQ(json["world"]["cylinders"][1], nlohmann::json({7.0, 2.0, 0.4}));
  EXPECT_EQ(json["goal"], nlohmann::json({9.0, 4.0}));
  EXPECT_EQ(json["collisions"], nlohmann::json({{6.0, 1.0}}));
  EXPECT_EQ(json["map"]["name"], "ESDF");
  const nlohmann::json occupied = json["map"]["occupied"];
  EXPECT_NE(std::find(occupied.begin(), occupied.end(), nlohmann::json({10, 17})), occupied.end())
      << occupied;  // (2.1, 3.5) at 0.2 m voxels
  EXPECT_EQ(json["map"]["free"].size() + occupied.size(), scene->map->columns.size());
}

TEST_F(LogPlot, DrawsAPngOfTheAskedSize) {
  const std::string log_path = tempPath("mission.lcm");
  writeMission(log_path);
  const std::string png = tempPath("top.png");
  const CliResult result = run("plot '" + log_path + "' --out '" + png + "' --size 640");
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("wrote " + png + " (640x640 px)"), std::string::npos)
      << result.output;
  const cv::Mat image = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 640);
  // The path's colour (#1450e6) is drawn somewhere; the scene's JSON is not left behind.
  cv::Mat path;
  cv::inRange(image, cv::Scalar(210, 70, 10), cv::Scalar(250, 90, 30), path);
  EXPECT_GT(cv::countNonZero(path), 100);
  EXPECT_EQ(std::distance(fs::directory_iterator(tempPath("")), fs::directory_iterator()), 2)
      << "only the log and the PNG";
}

// The simulator publishes the world again when a dynamic obstacle appears: the last one is drawn.
TEST_F(LogPlot, TheLastSimWorldIsDrawn) {
  const std::string log_path = tempPath("mission.lcm");
  PlotOptions options;
  options.out = tempPath("top.png");
  for (const bool dynamic_obstacle : {false, true}) {
    Channels channels;
    channels.dynamic_obstacle = dynamic_obstacle;
    writeMission(log_path, channels);
    const auto scene = readPlotScene(log_path, options);
    ASSERT_TRUE(scene) << scene.error();
    ASSERT_TRUE(scene->world);
    EXPECT_EQ(scene->world->cylinder_x.size(), dynamic_obstacle ? 3u : 2u);
  }
}

TEST_F(LogPlot, TheZBandSelectsWhatTheMapShows) {
  const std::string log_path = tempPath("mission.lcm");
  writeMission(log_path);
  PlotOptions options;
  options.out = tempPath("low.png");
  options.z_min = 0.0;
  options.z_max = 0.2;  // only the ground-level voxels
  const auto scene = readPlotScene(log_path, options);
  ASSERT_TRUE(scene) << scene.error();
  ASSERT_TRUE(scene->map);
  EXPECT_EQ(cellName(scene->map->at(2.5, 4.5)), "occupied");
  EXPECT_EQ(cellName(scene->map->at(2.1, 3.5)), "free");
}

TEST_F(LogPlot, MissingChannelsAreNamedAndTheRestIsDrawn) {
  const std::string log_path = tempPath("world_only.lcm");
  writeMission(log_path, {.world = true,
                          .truth = false,
                          .goal = false,
                          .explorer = false,
                          .event = false,
                          .map = false});
  const std::string png = tempPath("world_only.png");
  const CliResult result = run("plot '" + log_path + "' --out '" + png + "' --size 400");
  EXPECT_EQ(result.status, 0) << result.output;
  for (const std::string note :
       {"no SIM_TRUTH or STATE_ESTIMATE: no path drawn", "no MAP_ESDF or MAP_TSDF: no map drawn",
        "no SIM_EVENT", "no EXPLORER_GOAL", "no MISSION_GOAL: the goal is SIM_WORLD's"}) {
    EXPECT_NE(result.output.find(note), std::string::npos) << note << "\n" << result.output;
  }
  const cv::Mat image = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 400);
  EXPECT_EQ(image.rows, 400);
}

TEST_F(LogPlot, ATsdfIsReadWhenThereIsNoEsdf) {
  const std::string log_path = tempPath("tsdf.lcm");
  {
    LogWriter writer(log_path);
    TsdfLayer layer(kVoxel);
    Block<TsdfVoxel>& block = layer.allocateBlock(BlockIndex(0, 0, 0));
    for (TsdfVoxel& v : block.voxels) v = TsdfVoxel{0.8f, 1.0f};
    for (double z = 1.1; z < 2.0; z += kVoxel) *layer.voxel(layer.voxelIndex({1.5, 1.5, z})) = {};
    *layer.voxel(layer.voxelIndex({2.1, 2.1, 1.5})) = TsdfVoxel{-0.1f, 2.0f};  // behind a surface
    for (const map_update_t& msg : encodeMapUpdate(layer, {1, 3, 0, true}, {}, {})) {
      writer.write(1, "MAP_TSDF", msg);
    }
    odometry_t odometry{};
    odometry.position[0] = 0.5, odometry.position[1] = 0.5, odometry.position[2] = kHeight;
    writer.write(2, "STATE_ESTIMATE", odometry);
    odometry.position[0] = std::numeric_limits<double>::quiet_NaN();  // a diverged estimate
    writer.write(3, "STATE_ESTIMATE", odometry);
    odometry.position[0] = 2.5;
    writer.write(4, "STATE_ESTIMATE", odometry);
  }
  PlotOptions options;
  options.out = tempPath("tsdf.png");
  const auto scene = readPlotScene(log_path, options);
  ASSERT_TRUE(scene) << scene.error();
  EXPECT_EQ(scene->map_layer, "MAP_TSDF");
  EXPECT_TRUE(scene->path_is_estimate);
  EXPECT_EQ(scene->path.size(), 2u);  // the NaN left out
  const std::string notes = [&] {
    std::string all;
    for (const std::string& note : scene->notes) all += note + "\n";
    return all;
  }();
  EXPECT_NE(notes.find("no SIM_TRUTH: the path is the STATE_ESTIMATE"), std::string::npos) << notes;
  ASSERT_TRUE(scene->map);
  EXPECT_EQ(cellName(scene->map->at(2.1, 2.1)), "occupied");
  EXPECT_EQ(cellName(scene->map->at(1.5, 1.5)), "unknown");  // weight 0
  EXPECT_EQ(cellName(scene->map->at(1.0, 2.9)), "free");
  EXPECT_TRUE(plotLog(log_path, options)) << "a path through NaN still draws";

  options.layer = "esdf";  // asked for explicitly, and absent
  const auto esdf = readPlotScene(log_path, options);
  ASSERT_TRUE(esdf) << esdf.error();
  EXPECT_EQ(esdf->map_layer, "");
}

TEST_F(LogPlot, NothingToDrawIsAnErrorWithStatusOne) {
  const std::string log_path = tempPath("procman_only.lcm");
  {
    LogWriter writer(log_path);
    procman_lcm::deputy_info_t info{};
    writer.write(1, "PM_INFO", info);
  }
  const std::string png = tempPath("nothing.png");
  const CliResult result = run("plot '" + log_path + "' --out '" + png + "'");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("nothing to draw"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(png));
}

TEST_F(LogPlot, AMissingLogOrBadArgumentsExitWithStatusTwo) {
  const std::string png = tempPath("never.png");
  const std::string missing = tempPath("missing.lcm");
  CliResult result = run("plot '" + missing + "' --out '" + png + "'");
  EXPECT_EQ(result.status, 2) << result.output;
  EXPECT_NE(result.output.find("cannot open log '" + missing + "': No such file or directory"),
            std::string::npos)
      << result.output;

  const std::string log_path = tempPath("mission.lcm");
  writeMission(log_path);
  for (const std::string args :
       {"", "--size 1000", "--out x.png --size 300", "--out x.png --size 12.5",
        "--out x.png --layer octomap", "--out x.png --z-band 2,1", "--out x.png --z-band 1"}) {
    result = run("plot '" + log_path + "' " + args);
    EXPECT_EQ(result.status, 2) << args << "\n" << result.output;
    EXPECT_NE(result.output.find("Run with --help"), std::string::npos) << result.output;
  }
  EXPECT_FALSE(fs::exists(png));

  result = run("plot '" + log_path + "' --out /nonexistent_dir/top.png");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_NE(result.output.find("cannot write '/nonexistent_dir/top.png'"), std::string::npos)
      << result.output;
}

}  // namespace
}  // namespace thicket::log

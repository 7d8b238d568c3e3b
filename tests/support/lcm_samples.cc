// Writes one encoded, fully populated sample of every LCM type to OUT_DIR/<package>.<type>.bin.
// The Java check (tests/java/LcmTypesCheck.java) decodes each with the jar, as lcm-spy does, and
// requires the re-encoded bytes to be identical. Adding a .lcm file without a sample here fails
// that check. With --log FILE it also writes them as an LCM log, one channel per type
// (SAMPLE_<PACKAGE>_<TYPE>), to replay into lcm-spy with lcm-logplayer.
#include <cctype>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/discovery_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>
#include <thicket/depth_image_t.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/map_request_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/mapper_status_t.hpp>
#include <thicket/module_timing_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/planner_status_t.hpp>
#include <thicket/polynomial_trajectory_t.hpp>
#include <thicket/setpoint_t.hpp>
#include <thicket/sim_event_t.hpp>
#include <thicket/sim_world_t.hpp>
#include <thicket/stereo_image_t.hpp>

#include "thicket/common/lcm_log.h"

namespace {

std::string g_out_dir;
std::unique_ptr<thicket::LogWriter> g_log;
int g_written = 0;

template <class Msg>
void save(const std::string& package, const Msg& msg) {
  std::vector<char> bytes(static_cast<size_t>(msg.getEncodedSize()));
  if (msg.encode(bytes.data(), 0, static_cast<int>(bytes.size())) !=
      static_cast<int>(bytes.size())) {
    std::fprintf(stderr, "cannot encode %s\n", Msg::getTypeName());
    std::exit(1);
  }
  std::ofstream(g_out_dir + "/" + package + "." + Msg::getTypeName() + ".bin", std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (g_log) {
    std::string channel = "SAMPLE_" + package + "_" + Msg::getTypeName();
    for (char& c : channel) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    g_log->write(1'000'000 + 1000 * g_written, channel, bytes.data(), bytes.size());
  }
  ++g_written;
}

template <size_t N>
void fill(double (&array)[N], double first) {
  for (size_t i = 0; i < N; ++i) array[i] = first + 0.5 * static_cast<double>(i);
}

thicket::image_t sampleImage(const std::string& camera, uint8_t shade) {
  thicket::image_t image{};
  image.utime = 1'700'000'000'000'000;
  image.camera_id = camera;
  image.width = 4;
  image.height = 2;
  image.row_stride = 4;
  image.pixel_format = thicket::image_t::PIXEL_GRAY8;
  image.encoding = thicket::image_t::ENCODING_RAW;
  image.data = {shade, 1, 2, 3, 4, 5, 6, 255};
  image.size = static_cast<int32_t>(image.data.size());
  return image;
}

procman_lcm::cmd_t sampleCmd(const std::string& id) {
  procman_lcm::cmd_t cmd{};
  cmd.command_id = id;
  cmd.exec_str = "thicket-mapper --config \"config/params/mapper.yaml\"";
  cmd.group = "mapping/core";
  cmd.auto_respawn = true;
  cmd.stop_signal = 15;
  cmd.stop_time_allowed = 7.5f;
  return cmd;
}

void thicketSamples() {
  thicket::odometry_t odometry{};
  odometry.utime = 1'000'001;
  odometry.sequence = 17;
  fill(odometry.position, 1.0);
  odometry.orientation[0] = 0.5;
  odometry.orientation[1] = -0.5;
  odometry.orientation[2] = 0.5;
  odometry.orientation[3] = -0.5;
  fill(odometry.linear_velocity, -0.25);
  fill(odometry.angular_velocity, 0.125);
  fill(odometry.pose_covariance, 0.01);
  fill(odometry.twist_covariance, 0.02);
  odometry.quality = thicket::odometry_t::QUALITY_DEGRADED;
  odometry.flags = static_cast<int32_t>(thicket::odometry_t::FLAG_POSITION_JUMP) |
                   static_cast<int32_t>(thicket::odometry_t::FLAG_STALE);
  odometry.reason = "position jumped 2.1 m in 0.05 s";
  save("thicket", odometry);

  save("thicket", sampleImage("left", 9));

  thicket::stereo_image_t stereo{};
  stereo.utime = 2'000'000;
  stereo.calibration_id = "vi-sensor-sim";
  stereo.rectified = true;
  stereo.left = sampleImage("left", 10);
  stereo.right = sampleImage("right", 11);
  save("thicket", stereo);

  thicket::depth_image_t depth{};
  depth.utime = 3'000'000;
  depth.camera_id = "depth";
  depth.width = 2;
  depth.height = 1;
  depth.fx = depth.fy = 160.0;
  depth.cx = 0.5;
  depth.cy = 0.0;
  fill(depth.camera_in_body_position, 0.1);
  depth.camera_in_body_orientation[0] = 0.5;
  depth.camera_in_body_orientation[1] = -0.5;
  depth.camera_in_body_orientation[2] = 0.5;
  depth.camera_in_body_orientation[3] = -0.5;
  depth.min_range = 0.1;
  depth.max_range = 20.0;
  depth.depth_encoding = thicket::depth_image_t::DEPTH_UINT16_MM;
  depth.compression = thicket::depth_image_t::COMPRESSION_NONE;
  depth.data = {0x10, 0x27, 0x00, 0x00};  // 10 m, no return
  depth.size = static_cast<int32_t>(depth.data.size());
  save("thicket", depth);

  thicket::map_block_t block{};
  block.index[0] = -3;
  block.index[1] = 7;
  block.index[2] = 0;
  block.compression = thicket::map_block_t::COMPRESSION_NONE;
  block.data = {1, 2, 3, 4, 5, 6, 7, 8};
  block.raw_size = block.size = static_cast<int32_t>(block.data.size());
  save("thicket", block);

  thicket::map_update_t update{};
  update.utime = 4'000'000;
  update.map_id = 123456789;
  update.layer = thicket::map_update_t::LAYER_ESDF;
  update.voxel_format = thicket::map_update_t::FORMAT_ESDF_F32_U8;
  update.voxel_size = 0.2;
  update.voxels_per_side = 16;
  update.revision = 42;
  update.full_snapshot = false;
  update.part_index = 1;
  update.num_parts = 3;
  update.blocks = {block, block};
  update.blocks[1].index[2] = 1;
  update.num_blocks = 2;
  update.removed = {{1, 2, 3}, {-4, -5, -6}};
  update.num_removed = 2;
  save("thicket", update);

  thicket::map_request_t request{};
  request.utime = 4'100'000;
  request.requester = "local_planner";
  request.layer = thicket::map_update_t::LAYER_TSDF;
  request.map_id = 123456789;
  request.last_revision = 40;
  request.reason = "gap after revision 40";
  save("thicket", request);

  thicket::goal_t goal{};
  goal.utime = 5'000'000;
  goal.goal_id = 9;
  goal.source = thicket::goal_t::SOURCE_EXPLORER;
  goal.strategy = "local_exploration";
  goal.cycle = 31;
  goal.status = thicket::goal_t::STATUS_OK;
  goal.reason = "best of 15 candidates";
  goal.yaw_policy = thicket::goal_t::YAW_FIXED;
  goal.tolerance = 0.3;
  goal.score = 0.75;
  goal.waypoints = {{1.0, 2.0, 1.5}, {3.0, 4.0, 1.5}};
  goal.yaws = {0.0, 1.5};
  goal.num_waypoints = 2;
  save("thicket", goal);

  thicket::polynomial_trajectory_t trajectory{};
  trajectory.utime = 6'000'000;
  trajectory.cycle = 31;
  trajectory.goal_id = 9;
  trajectory.yaw_policy = thicket::polynomial_trajectory_t::YAW_ALONG_VELOCITY;
  trajectory.num_segments = 2;
  trajectory.num_coefficients = 3;
  trajectory.durations = {1.2, 0.8};
  trajectory.coefficients = {{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}},
                             {{-1, -2, -3}, {0, 0, 0}, {1.5, 0, 0}}};
  save("thicket", trajectory);

  thicket::planner_status_t status{};
  status.utime = 6'000'000;
  status.cycle = 31;
  status.is_final = true;
  status.state = thicket::planner_status_t::STATE_STUCK;
  status.reason = "every restart collides";
  status.map_revision = 42;
  status.goal_id = 9;
  status.goal_source = thicket::goal_t::SOURCE_OPERATOR;
  fill(status.goal, 14.0);
  fill(status.horizon_goal, 4.0);
  fill(status.start_position, 1.0);
  fill(status.start_velocity, 0.1);
  fill(status.start_acceleration, -0.1);
  status.cost_total = 12.5;
  status.cost_derivative = 0.5;
  status.cost_collision = 10.0;
  status.cost_goal = 2.0;
  status.min_distance = 0.3;
  status.iterations = 120;
  status.restarts = 5;
  status.solve_time_ms = 1.75;
  save("thicket", status);

  thicket::setpoint_t setpoint{};
  setpoint.utime = 6'010'000;
  setpoint.cycle = 31;
  fill(setpoint.position, 1.0);
  fill(setpoint.velocity, 0.2);
  fill(setpoint.acceleration, 0.0);
  setpoint.yaw = 0.3;
  setpoint.yaw_rate = -0.1;
  save("thicket", setpoint);

  thicket::module_timing_t timing{};
  timing.utime = 4'000'000;
  timing.module = "mapper";
  timing.sequence = 42;
  timing.stages = {"tsdf_insert", "esdf_update"};
  timing.durations_ms = {1.25, 0.75};
  timing.num_stages = 2;
  save("thicket", timing);

  thicket::mapper_status_t mapper{};
  mapper.utime = 4'000'000;
  mapper.result = thicket::mapper_status_t::RESULT_REFUSED;
  mapper.reason = "depth has 12 NaN pixels";
  mapper.map_id = 123456789;
  mapper.revision = 42;
  mapper.num_tsdf_blocks = 300;
  mapper.num_esdf_blocks = 280;
  mapper.memory_bytes = 9'000'000;
  mapper.frames_integrated = 42;
  mapper.frames_refused = 1;
  mapper.frames_pending = 2;
  save("thicket", mapper);

  thicket::sim_world_t world{};
  world.utime = 0;
  world.scenario = "paper";
  world.density = 0.3;
  world.seed = 7;
  fill(world.bounds_min, 0.0);
  fill(world.bounds_max, 10.0);
  fill(world.start, 1.0);
  fill(world.goal, 14.0);
  world.robot_radius = 0.5;
  world.cylinder_x = {3.0, 4.5};
  world.cylinder_y = {5.0, 2.5};
  world.cylinder_radius = {0.25, 0.4};
  world.cylinder_height = {4.0, 2.5};
  world.num_cylinders = 2;
  save("thicket", world);

  thicket::sim_event_t event{};
  event.utime = 60'000'000;
  event.type = thicket::sim_event_t::TYPE_TRIAL_END;
  event.outcome = thicket::sim_event_t::OUTCOME_GOAL_REACHED;
  event.cycle = 60;
  fill(event.position, 13.9);
  event.clearance = 1.2;
  event.message = "goal reached";
  event.num_replans = 60;
  event.path_length = 14.2;
  event.path_time = 59.0;
  event.min_clearance = 0.61;
  event.distance_to_goal = 0.1;
  save("thicket", event);
}

void procmanSamples() {
  save("procman_lcm", sampleCmd("mapper"));

  procman_lcm::cmd_desired_t desired{};
  desired.cmd = sampleCmd("planner");
  desired.desired_runid = 3;
  desired.force_quit = true;
  save("procman_lcm", desired);

  procman_lcm::cmd_status_t status{};
  status.cmd = sampleCmd("explorer");
  status.pid = 4242;
  status.actual_runid = 3;
  status.exit_code = -1;
  status.cpu_usage = 0.25f;
  status.mem_vsize_bytes = 1'000'000'000;
  status.mem_rss_bytes = 50'000'000;
  save("procman_lcm", status);

  procman_lcm::orders_t orders{};
  orders.utime = 1'700'000'000'000'000;
  orders.deputy_id = "vehicle";
  orders.sheriff_id = "ground:1234:1700000000000000";
  orders.cmds = {desired, desired};
  orders.cmds[1].cmd.command_id = "mapper";
  orders.ncmds = 2;
  save("procman_lcm", orders);

  procman_lcm::deputy_info_t info{};
  info.utime = 1'700'000'000'000'000;
  info.deputy_id = "vehicle";
  info.cpu_load = 0.5f;
  info.phys_mem_total_bytes = 24'000'000'000;
  info.phys_mem_free_bytes = 12'000'000'000;
  info.swap_total_bytes = 0;
  info.swap_free_bytes = 0;
  info.cmds = {status};
  info.ncmds = 1;
  save("procman_lcm", info);

  procman_lcm::output_t output{};
  output.utime = 1'700'000'000'000'000;
  output.deputy_id = "vehicle";
  output.command_ids = {"mapper", ""};
  output.text = {"integrated frame 42\n", "deputy started\n"};
  output.num_commands = 2;
  save("procman_lcm", output);

  procman_lcm::discovery_t discovery{};
  discovery.utime = 1'700'000'000'000'000;
  discovery.transmitter_id = "vehicle";
  discovery.nonce = 4242;
  save("procman_lcm", discovery);
}

}  // namespace

int main(int argc, char** argv) {
  const bool with_log = argc == 4 && std::string(argv[2]) == "--log";
  if (argc != 2 && !with_log) {
    std::fprintf(stderr, "usage: %s OUT_DIR [--log FILE]\n", argv[0]);
    return 2;
  }
  g_out_dir = argv[1];
  if (with_log) g_log = std::make_unique<thicket::LogWriter>(argv[3]);
  thicketSamples();
  procmanSamples();
  std::printf("wrote %d samples to %s\n", g_written, g_out_dir.c_str());
  return 0;
}

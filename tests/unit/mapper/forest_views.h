// Depth frames of forest50 (density 0.2, seed 1) seen along its start-goal diagonal, for the
// mapper tests that check maps against the simulator's ground truth.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "thicket/common/depth_image.h"
#include "thicket/common/geometry.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"

namespace thicket::mapper {

/// A depth frame (its utime and camera_in_body set) and the poses it was seen from.
struct Frame {
  DepthImage image;
  Pose world_T_body;
  Pose world_T_camera;
};

/// The frame the renderer sees from world_T_body at utime.
inline Frame renderFrame(const sim::DepthRenderer& renderer, const Pose& world_T_body,
                         int64_t utime = 0) {
  Frame frame;
  frame.image = renderer.renderImage(world_T_body, utime);
  frame.world_T_body = world_T_body;
  frame.world_T_camera = world_T_body * renderer.cameraInBody();
  return frame;
}

/// The benchmark's world of `scenario` (config/worlds) at `density` and `seed`.
inline sim::World benchmarkWorld(const std::string& scenario, double density, uint64_t seed) {
  const auto spec = sim::loadScenario(scenario, std::string(THICKET_SOURCE_DIR) + "/config/worlds");
  if (!spec) throw std::runtime_error(spec.error());
  return *sim::generateWorld(*spec, density, seed);
}

/// Built once.
inline const sim::World& forest() {
  static const sim::World world = benchmarkWorld("forest50", 0.2, 1);
  return world;
}

/// Views along the forest's start-goal diagonal at the start's height, every metre from 2 m on,
/// facing the goal, clear of the trees; a second apart (utime 1 s, 2 s, ...).
inline std::vector<Frame> forestFrames(int count) {
  const sim::World& world = forest();
  const sim::GroundTruth truth(world);
  const sim::DepthRenderer renderer(world, sim::DepthCameraOptions{});
  const Eigen::Vector3d direction = (world.goal - world.start).normalized();
  std::vector<Frame> frames;
  for (double s = 2.0; static_cast<int>(frames.size()) < count; s += 1.0) {
    const Eigen::Vector3d p = world.start + s * direction;
    if (truth.distance(p) > world.robot_radius) {
      frames.push_back(renderFrame(renderer,
                                   Pose::fromYaw(p, std::atan2(direction.y(), direction.x())),
                                   static_cast<int64_t>(frames.size() + 1) * 1'000'000));
    }
  }
  return frames;
}

}  // namespace thicket::mapper

// Rendering speed on the forest50 world at density 0.2 (BENCHMARK.md), from poses a vehicle
// could fly: a depth frame should take under 2 ms and a stereo pair under 10 ms on one core.
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include <benchmark/benchmark.h>

#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

constexpr int kPoses = 16;

const World& forest() {
  static const World world = [] {
    auto spec = loadScenario("forest50", std::string(THICKET_SOURCE_DIR) + "/config/worlds");
    if (!spec) throw std::runtime_error(spec.error());
    return *generateWorld(*spec, 0.2, 1);
  }();
  return world;
}

// Poses along the start-goal diagonal at 1.5 m, facing the goal, clear of every tree.
Pose benchPose(int i) {
  static const std::vector<Pose> poses = [] {
    const World& world = forest();
    const GroundTruth truth(world);
    const Eigen::Vector3d direction = (world.goal - world.start).normalized();
    std::vector<Pose> result;
    for (double s = 2.0; result.size() < kPoses; s += 2.0) {
      const Eigen::Vector3d p = world.start + s * direction;
      if (truth.distance(p) > world.robot_radius) {
        result.push_back(Pose::fromYaw(p, std::atan2(direction.y(), direction.x())));
      }
    }
    return result;
  }();
  return poses[static_cast<size_t>(i % kPoses)];
}

void BM_DepthFrame(benchmark::State& state) {
  const DepthRenderer renderer(forest(), DepthCameraOptions{});
  std::vector<float> depth;
  int i = 0;
  for (auto _ : state) {
    renderer.render(benchPose(i++ % kPoses), depth);
    benchmark::DoNotOptimize(depth.data());
  }
}
BENCHMARK(BM_DepthFrame)->Unit(benchmark::kMillisecond);

void BM_DepthFrameNoisy(benchmark::State& state) {
  DepthCameraOptions options;
  options.noise_stddev_at_1m = 0.005;
  const DepthRenderer renderer(forest(), options);
  std::vector<float> depth;
  int i = 0;
  for (auto _ : state) {
    renderer.render(benchPose(i % kPoses), depth, i);
    ++i;
    benchmark::DoNotOptimize(depth.data());
  }
}
BENCHMARK(BM_DepthFrameNoisy)->Unit(benchmark::kMillisecond);

void BM_StereoPair(benchmark::State& state) {
  const StereoRenderer renderer(forest(), StereoCameraOptions{});
  std::vector<uint8_t> left, right;
  int i = 0;
  for (auto _ : state) {
    renderer.render(benchPose(i++ % kPoses), left, right);
    benchmark::DoNotOptimize(left.data());
    benchmark::DoNotOptimize(right.data());
  }
}
BENCHMARK(BM_StereoPair)->Unit(benchmark::kMillisecond);

// The per-frame set-up alone: binning the cylinders by azimuth around the eye.
void BM_PrepareView(benchmark::State& state) {
  const RayCaster caster(forest());
  int i = 0;
  for (auto _ : state) {
    const RayCaster::View view = caster.view(benchPose(i++ % kPoses).position, 20.0);
    benchmark::DoNotOptimize(&view);
  }
}
BENCHMARK(BM_PrepareView)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace thicket::sim

// Rendering speed on a forest50-like world at density 0.2 (BENCHMARK.md): a depth frame should
// take under 2 ms and a stereo pair under 10 ms on one core.
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

constexpr int kPoses = 16;

// The eye positions the benchmarks cycle through: a ring in the middle of the forest at 1.5 m.
Pose benchPose(int i) {
  const double angle = 2 * 3.14159265358979 * i / kPoses;
  const Eigen::Vector3d position(25 + 12 * std::cos(angle), 25 + 12 * std::sin(angle), 1.5);
  return Pose::fromYaw(position, 0.7 * i);
}

// 420 cylinders (density 0.2 on 50 x 50 m minus 2 m margins) drawn with a fixed seed, none within
// 0.3 m of an eye.
const World& forest() {
  static const World world = [] {
    World w;
    w.bounds_min = Eigen::Vector3d::Zero();
    w.bounds_max = Eigen::Vector3d(50, 50, 5);
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> xy(2, 48), radius(0.1, 0.5), height(2, 5);
    while (w.cylinders.size() < 420) {
      const Cylinder c{xy(rng), xy(rng), radius(rng), height(rng)};
      bool clear = true;
      for (int i = 0; i < kPoses; ++i) {
        const Eigen::Vector3d eye = benchPose(i).position;
        clear = clear && std::hypot(c.x - eye.x(), c.y - eye.y()) > c.radius + 0.3;
      }
      if (clear) w.cylinders.push_back(c);
    }
    return w;
  }();
  return world;
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

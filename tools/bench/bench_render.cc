// Rendering speed on the forest50 world at density 0.2 (docs/benchmark.md), from poses a vehicle
// could fly: a depth frame should take under 2 ms and a stereo pair under 10 ms, its two cameras
// on two threads (measured on the 2-core machine, idle: 8.4 ms; 15.9 ms on one core).
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_worlds.h"
#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

constexpr int kPoses = 16;

using bench::forest;

Pose benchPose(int i) {
  static const std::vector<Pose> poses = bench::flightPoses(2.0, kPoses);
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

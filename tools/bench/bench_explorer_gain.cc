// Exploration gain (docs/design.md §1, local exploration): the fraction of unknown voxels in the
// 320x240, 90°, 0.5-5 m camera frustum, checking every stride-th frustum point, on the map of the
// benchmark flight (bench_worlds.h: 80 frames through forest50 at density 0.2, 0.20 m voxels). Each
// run evaluates 200 seeded poses near the flight path (up to 1 m to the side, 0.5 m up or down, any
// heading), one per iteration. Counters: median_ms and p95_ms per evaluation; mean_abs_error and
// max_abs_error against the exact (stride 1) fraction at the same poses; speedup, the median
// stride-1 time (measured in the same run, before the timed loop) over the median time; fraction,
// the share of frustum points checked (1 / stride). The paper's claim (docs/design.md §1): 5 % of
// the points (stride 20) give ~1 % error at ~3x the speed. BM_ExplorationGainVisible does the same
// for the occlusion-aware variant (NBVP's gain), against its own stride-1 values.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_worlds.h"
#include "thicket/common/statistics.h"
#include "thicket/explorer/gain.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::bench {

namespace {

constexpr double kVoxel = 0.2;
constexpr int kGainPoses = 200;

// The TSDF of the whole benchmark flight: built once.
const TsdfLayer& flownMap() {
  static const TsdfLayer layer = [] {
    TsdfLayer tsdf(kVoxel);
    const mapper::TsdfIntegrator integrator{mapper::TsdfIntegratorOptions{}};
    for (const FlightFrame& frame : flightFrames()) {
      integrator.integrate(frame.image, frame.world_T_camera, tsdf);
    }
    return tsdf;
  }();
  return layer;
}

// kGainPoses camera poses near the flight path (seeded): a random frame's position moved up to
// 1 m sideways and 0.5 m up or down, facing any way.
const std::vector<Pose>& gainPoses() {
  static const std::vector<Pose> poses = [] {
    const std::vector<FlightFrame>& frames = flightFrames();
    std::mt19937 rng(1);
    std::uniform_int_distribution<size_t> frame(0, frames.size() - 1);
    std::uniform_real_distribution<double> lateral(-1.0, 1.0), vertical(-0.5, 0.5),
        yaw(-std::numbers::pi, std::numbers::pi);
    std::vector<Pose> result;
    for (int n = 0; n < kGainPoses; ++n) {
      const Pose& body = frames[frame(rng)].world_T_body;
      const Eigen::Vector3d side = body.orientation * Eigen::Vector3d::UnitY();
      const Eigen::Vector3d p =
          body.position + lateral(rng) * side + vertical(rng) * Eigen::Vector3d::UnitZ();
      result.push_back(explorer::ExplorationGain::cameraAt(p, yaw(rng)));
    }
    return result;
  }();
  return poses;
}

// Arg: the stride. One pose per iteration; visible selects visibleUnknownFraction.
void gainBenchmark(benchmark::State& state, bool visible) {
  const int stride = static_cast<int>(state.range(0));
  const explorer::ExplorationGain gain(explorer::GainOptions{}, kVoxel);
  const TsdfLayer& tsdf = flownMap();
  const std::vector<Pose>& poses = gainPoses();
  const auto evaluate = [&](const Pose& pose, int s) {
    return visible ? gain.visibleUnknownFraction(tsdf, pose, s)
                   : gain.unknownFraction(tsdf, pose, s);
  };

  // The exact fractions and their times, for this run's error and speedup counters.
  std::vector<double> exact;
  std::vector<double> exact_ms;
  for (const Pose& pose : poses) {
    explorer::Gain g;
    exact_ms.push_back(timeMs([&] { g = evaluate(pose, 1); }));
    exact.push_back(g.unknown_fraction);
  }

  std::vector<double> ms;
  double error_sum = 0;
  double error_max = 0;
  size_t i = 0;
  for (auto _ : state) {
    const size_t n = i++ % poses.size();
    explorer::Gain g;
    ms.push_back(timeMs([&] {
      g = evaluate(poses[n], stride);
      benchmark::DoNotOptimize(g);
    }));
    state.SetIterationTime(ms.back() * 1e-3);
    const double error = std::abs(g.unknown_fraction - exact[n]);
    error_sum += error;
    error_max = std::max(error_max, error);
  }
  if (ms.empty()) return;
  state.counters["median_ms"] = median(ms);
  state.counters["p95_ms"] = quantile(ms, 0.95);
  state.counters["mean_abs_error"] = error_sum / static_cast<double>(ms.size());
  state.counters["max_abs_error"] = error_max;
  state.counters["speedup"] = median(exact_ms) / median(ms);
  state.counters["fraction"] = 1.0 / stride;
}

void BM_ExplorationGain(benchmark::State& state) {
  gainBenchmark(state, false);
}
BENCHMARK(BM_ExplorationGain)
    ->Arg(1)
    ->Arg(2)
    ->Arg(5)
    ->Arg(10)
    ->Arg(20)
    ->Arg(50)
    ->Arg(100)
    ->Iterations(kGainPoses)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

void BM_ExplorationGainVisible(benchmark::State& state) {
  gainBenchmark(state, true);
}
BENCHMARK(BM_ExplorationGainVisible)
    ->Arg(1)
    ->Arg(5)
    ->Arg(20)
    ->Iterations(kGainPoses)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace thicket::bench

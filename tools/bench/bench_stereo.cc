// Stereo depth per 752x480 pair (the simulator's default camera, a VI-Sensor-like pair) on
// forest50 at density 0.2: rectification, semi-global matching and disparity to depth, as
// thicket-stereo-depth runs them on every STEREO pair. The pairs are rendered beforehand.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_worlds.h"
#include "thicket/common/loop.h"
#include "thicket/sim/render.h"
#include "thicket/stereo_depth/stereo_depth.h"

namespace thicket::stereo_depth {
namespace {

constexpr int kPairs = 16;

// kPairs rendered pairs along the diagonal, and the calibration of the camera: built once.
struct Pairs {
  StereoCalibration calibration;
  std::vector<StereoPair> pairs;
};

const Pairs& renderedPairs() {
  static const Pairs pairs = [] {
    const sim::StereoRenderer renderer(bench::forest(), sim::StereoCameraOptions{});
    Pairs out;
    auto calibration = parseStereoCalibration(renderer.calibrationYaml("bench"), "bench");
    if (!calibration) throw std::runtime_error(calibration.error());
    out.calibration = *calibration;
    for (const Pose& body : bench::flightPoses(2.0, kPairs)) {
      StereoPair pair;
      pair.calibration_id = "bench";
      pair.left = {renderer.camera().width, renderer.camera().height, {}};
      pair.right = pair.left;
      renderer.render(body, pair.left.pixels, pair.right.pixels);
      out.pairs.push_back(std::move(pair));
    }
    return out;
  }();
  return pairs;
}

// One pair per iteration: rectify + match + depth (+ outliers when enabled) [ms per pair].
void runPairs(benchmark::State& state, const StereoDepthOptions& options) {
  const Pairs& input = renderedPairs();
  auto pipeline = StereoDepth::create(options, input.calibration);
  if (!pipeline) throw std::runtime_error(pipeline.error());
  std::vector<double> ms, rectify_ms, match_ms;
  double valid = 0;
  size_t i = 0;
  for (auto _ : state) {
    const StereoPair& pair = input.pairs[i++ % input.pairs.size()];
    Expected<StereoFrame> frame = unexpected("not run");
    ms.push_back(bench::timeMs([&] { frame = pipeline->process(pair, steadyClockMillis); }));
    if (!frame) throw std::runtime_error(frame.error());
    rectify_ms.push_back(frame->rectify_ms);
    match_ms.push_back(frame->match_ms);
    valid += frame->validFraction();
    state.SetIterationTime(ms.back() * 1e-3);
  }
  if (ms.empty()) return;
  state.counters["median_ms"] = median(ms);
  state.counters["p95_ms"] = quantile(ms, 0.95);
  state.counters["rectify_ms"] = median(rectify_ms);
  state.counters["match_ms"] = median(match_ms);
  state.counters["valid"] = valid / static_cast<double>(ms.size());
}

void BM_StereoDepthPair(benchmark::State& state) {
  runPairs(state, StereoDepthOptions{});
}
BENCHMARK(BM_StereoDepthPair)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(kPairs);

// OpenCV's 5-direction SGBM: the same depth within 5 m as the default 3-way, twice the time.
void BM_StereoDepthPairSgbm(benchmark::State& state) {
  StereoDepthOptions options;
  options.matcher.mode = "sgbm";
  runPairs(state, options);
}
BENCHMARK(BM_StereoDepthPairSgbm)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime()
    ->Iterations(kPairs);

// Matching at half resolution (376x240, 32 disparities: the same depth range): depth at the size
// a mapper at 0.1 m voxels uses. Its accuracy: DepthAccuracy.HalfResolutionAgainstTheTrueDepth.
void BM_StereoDepthPairHalf(benchmark::State& state) {
  StereoDepthOptions options;
  options.downscale = 2;
  options.matcher.num_disparities = 32;
  runPairs(state, options);
}
BENCHMARK(BM_StereoDepthPairHalf)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime()
    ->Iterations(kPairs);

void BM_StereoDepthPairOutliers(benchmark::State& state) {
  StereoDepthOptions options;
  options.outliers.enabled = true;
  runPairs(state, options);
}
BENCHMARK(BM_StereoDepthPairOutliers)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime()
    ->Iterations(kPairs);

}  // namespace
}  // namespace thicket::stereo_depth

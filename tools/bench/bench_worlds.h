// The benchmark world of docs/benchmark.md, forest50 at density 0.2, and poses a vehicle could fly
// through it: shared by the benchmarks so they measure on the same frames.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "forest_flight.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/geometry.h"
#include "thicket/common/statistics.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"

namespace thicket::bench {

/// A depth frame of a flight and where its camera was.
struct FlightFrame {
  DepthImage image;
  Pose world_T_body;
  Pose world_T_camera;
};

/// Frames in a flight, and the distance between two: one mapping cycle of docs/design.md §1 (4 Hz)
/// at v_max (1 m/s).
constexpr int kFlightFrames = 80;
constexpr double kFlightStep = 0.25;  // [m]

/// The frames the default depth camera (320x240, 90°) sees every kFlightStep along the first 20 m
/// of the diagonal: the mapping benchmark's input, the same for thicket and its peers.
inline const std::vector<FlightFrame>& flightFrames() {
  static const std::vector<FlightFrame> frames = [] {
    const sim::DepthRenderer renderer(forest(), sim::DepthCameraOptions{});
    std::vector<FlightFrame> result;
    int64_t utime = 0;
    for (const Pose& body : flightPoses(kFlightStep, kFlightFrames)) {
      FlightFrame frame;
      frame.image = renderer.renderImage(body, utime += 250'000);
      frame.world_T_body = body;
      frame.world_T_camera = body * renderer.cameraInBody();
      result.push_back(std::move(frame));
    }
    return result;
  }();
  return frames;
}

/// How long fn takes [ms].
template <class Fn>
double timeMs(Fn&& fn) {
  const auto start = std::chrono::steady_clock::now();
  fn();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

/// One flight frame per benchmark iteration, in order, every `stride`-th (a flight `stride` times
/// as fast): step(frame) does the frame's work and returns the part of it that counts [ms]
/// (untimed preparation stays out). The per-frame times. Run kFlightFrames / stride iterations.
template <class Step>
std::vector<double> flyFlight(benchmark::State& state, Step&& step, size_t stride = 1) {
  const std::vector<FlightFrame>& frames = flightFrames();
  std::vector<double> ms;
  size_t i = 0;
  for (auto _ : state) {
    ms.push_back(step(frames[(i++ * stride) % frames.size()]));
    state.SetIterationTime(ms.back() * 1e-3);
  }
  return ms;
}

/// Median and 95th percentile of per-frame times [ms] as counters, and memory [MiB] (0: the
/// library does not say).
inline void reportFrameTimes(benchmark::State& state, std::vector<double> ms, size_t memory_bytes) {
  if (ms.empty()) return;
  state.counters["median_ms"] = median(ms);
  state.counters["p95_ms"] = quantile(ms, 0.95);
  state.counters["MiB"] = static_cast<double>(memory_bytes) / (1 << 20);
}

}  // namespace thicket::bench

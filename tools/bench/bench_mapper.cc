// Mapping speed on the frames of a flight through forest50 at density 0.2 (bench_worlds.h): TSDF
// insert and ESDF update per frame, at 0.20, 0.10 and 0.05 m voxels. Each run maps the whole
// flight once from an empty map; the reported time is the mean per frame, with the median and
// the 95th percentile as counters (ms), and the map's memory at the end (MiB). Targets at 0.20 m:
// TSDF insert <= 2 ms and ESDF update <= 2 ms median (the paper: 27.0 ms and 14.5 ms).
#include <algorithm>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_worlds.h"
#include "thicket/mapper/esdf_integrator.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::bench {

namespace {

// Method 0 projective, 1 raycast, 2 projective with Open3D's ScalableTSDFVolume's per-voxel work
// (bench_mapper_peers.cc: line-of-sight distances, no new-surface detection or shadow reset) but
// carving free space, 3 that without carving: only the blocks near returns, Open3D's work.
mapper::TsdfIntegratorOptions tsdfOptions(int64_t method) {
  mapper::TsdfIntegratorOptions options;
  options.method = method == 1 ? mapper::TsdfIntegratorOptions::Method::kRaycast
                               : mapper::TsdfIntegratorOptions::Method::kProjective;
  if (method >= 2) {
    options.normal_distances = false;
    options.new_surfaces_replace = false;
    options.new_surface_shadow = 0;
  }
  options.carve_free_space = method != 3;
  return options;
}

// Args: voxel size in mm, method (see tsdfOptions).
void BM_TsdfInsert(benchmark::State& state) {
  const double voxel = state.range(0) * 1e-3;
  const mapper::TsdfIntegrator integrator(tsdfOptions(state.range(1)));
  TsdfLayer tsdf(voxel);
  const std::vector<double> ms = flyFlight(state, [&](const FlightFrame& frame) {
    return timeMs([&] {
      benchmark::DoNotOptimize(integrator.integrate(frame.image, frame.world_T_camera, tsdf));
    });
  });
  reportFrameTimes(state, ms, tsdf.memoryBytes());
}
BENCHMARK(BM_TsdfInsert)
    ->ArgsProduct({{200, 100, 50}, {0, 2, 3}})
    ->Args({200, 1})
    ->Iterations(kFlightFrames)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// Maps the flight with every stride-th frame; the TSDF insert of each frame runs untimed before
// its ESDF update.
void esdfFlight(benchmark::State& state, double voxel, size_t stride,
                const mapper::EsdfIntegratorOptions& options = {}) {
  const mapper::TsdfIntegrator tsdf_integrator(tsdfOptions(0));
  mapper::EsdfIntegrator esdf_integrator{options};
  esdf_integrator.setInitialPosition(flightFrames().front().world_T_body.position);
  TsdfLayer tsdf(voxel);
  EsdfLayer esdf(voxel);
  const std::vector<double> ms = flyFlight(
      state,
      [&](const FlightFrame& frame) {
        const auto changed = tsdf_integrator.integrate(frame.image, frame.world_T_camera, tsdf);
        return timeMs([&] {
          benchmark::DoNotOptimize(
              esdf_integrator.update(tsdf, changed, frame.world_T_body.position, esdf));
        });
      },
      stride);
  reportFrameTimes(state, ms, tsdf.memoryBytes() + esdf.memoryBytes());
  // The ESDF layer, and the integrator's wavefront state beside it (docs: at most twice it).
  state.counters["esdf_MiB"] = static_cast<double>(esdf.memoryBytes()) / (1 << 20);
  state.counters["state_MiB"] = static_cast<double>(esdf_integrator.memoryBytes()) / (1 << 20);
}

// Arg: voxel size in mm. A frame per mapping cycle at v_max (docs/design.md §1: 4 Hz, 1 m/s).
void BM_EsdfUpdate(benchmark::State& state) {
  esdfFlight(state, state.range(0) * 1e-3, 1);
}
BENCHMARK(BM_EsdfUpdate)
    ->Arg(200)
    ->Arg(100)
    ->Arg(50)
    ->Iterations(kFlightFrames)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// Args: voxel size in mm, stride. The same flight `stride` times as fast (every stride-th frame,
// stride x 0.25 m apart): that many times the change per frame. Stride 4, 1 m per frame, is the
// pace of the benchmark's trials (a frame per simulated second at up to 1 m/s), whose ESDF
// timings (T1) this matches.
void BM_EsdfUpdateFaster(benchmark::State& state) {
  esdfFlight(state, state.range(0) * 1e-3, static_cast<size_t>(state.range(1)));
}
BENCHMARK(BM_EsdfUpdateFaster)
    ->Args({200, 2})
    ->Iterations(kFlightFrames / 2)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EsdfUpdateFaster)
    ->Args({200, 4})
    ->Iterations(kFlightFrames / 4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// Args: voxel size in mm, stride. BM_EsdfUpdate(Faster) with the paper's occupied sphere
// (occupied_everywhere off): unobserved voxels are occupied only within r_o of the vehicle, a
// sphere that moves with it.
void BM_EsdfUpdateSphere(benchmark::State& state) {
  mapper::EsdfIntegratorOptions options;
  options.occupied_everywhere = false;
  esdfFlight(state, state.range(0) * 1e-3, static_cast<size_t>(state.range(1)), options);
}
BENCHMARK(BM_EsdfUpdateSphere)
    ->Args({200, 4})
    ->Iterations(kFlightFrames / 4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EsdfUpdateSphere)
    ->Args({100, 1})
    ->Args({50, 1})
    ->Iterations(kFlightFrames)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace thicket::bench

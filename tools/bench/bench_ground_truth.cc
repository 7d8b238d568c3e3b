// Ground-truth queries on forest50 at density 0.2: the distance every executed sample is checked
// with, and the solvability oracle run twice per benchmark trial (planning and collision radius).
#include <stdexcept>

#include <benchmark/benchmark.h>

#include "bench_worlds.h"
#include "thicket/sim/oracle.h"

namespace thicket::sim {
namespace {

using bench::forest50;

void BM_GroundTruthDistance(benchmark::State& state) {
  const World world = forest50(1);
  const GroundTruth truth(world);
  // A fixed walk over the whole world, so queries hit every part of the acceleration grid.
  uint64_t k = 0;
  for (auto _ : state) {
    ++k;
    const Eigen::Vector3d p(0.5 + static_cast<double>((k * 7919) % 4900) / 100.0,
                            0.5 + static_cast<double>((k * 104729) % 4900) / 100.0,
                            0.5 + static_cast<double>(k % 40) / 10.0);
    benchmark::DoNotOptimize(truth.distance(p));
  }
}
BENCHMARK(BM_GroundTruthDistance);

void BM_SolvabilityOracle(benchmark::State& state) {
  uint64_t seed = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const World world = forest50(seed++ % 8);
    const GroundTruth truth(world);
    state.ResumeTiming();
    benchmark::DoNotOptimize(checkSolvable(truth).solvable);
  }
}
BENCHMARK(BM_SolvabilityOracle)->Unit(benchmark::kMillisecond);

// The part of the oracle that does not depend on the radius tested (in BM_SolvabilityOracle too).
void BM_OracleBottleneck(benchmark::State& state) {
  uint64_t seed = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const World world = forest50(seed++ % 8);
    state.ResumeTiming();
    benchmark::DoNotOptimize(bottleneckClearance(world));
  }
}
BENCHMARK(BM_OracleBottleneck)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace thicket::sim

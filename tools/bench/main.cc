// thicket-bench: the benchmark driver and the module cores' micro-benchmarks.
//
//   thicket-bench run --density D --trials N --out DIR [...]   trials of one configuration
//   thicket-bench [--benchmark_filter=REGEX ...]              Google Benchmark (bench_*.cc)
#include <string>
#include <string_view>
#include <vector>

#include <benchmark/benchmark.h>

#include "trials.h"

int main(int argc, char** argv) {
  if (argc > 1 && std::string_view(argv[1]) == "run") {
    return thicket::bench::runCommand(std::vector<std::string>(argv + 2, argv + argc));
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

// thicket-bench: the benchmark driver and the module cores' micro-benchmarks.
//
//   thicket-bench run --density D --trials N --out DIR [...]   trials of one configuration
//   thicket-bench experiment --out DIR [...]                   the benchmark's experiments
//   thicket-bench merge --out DIR IN_DIR...                    gathers shards' output folders
//   thicket-bench subsampling --out DIR [...]                  experiment E5 alone
//   thicket-bench clearance --out DIR [...]                    the ESDF's clearance error
//   thicket-bench [--benchmark_filter=REGEX ...]              Google Benchmark (bench_*.cc)
#include <string>
#include <string_view>
#include <vector>

#include <benchmark/benchmark.h>

#include "clearance.h"
#include "experiments.h"
#include "subsampling.h"
#include "trials.h"

int main(int argc, char** argv) {
  if (argc > 1) {
    const std::string_view command = argv[1];
    const std::vector<std::string> args(argv + 2, argv + argc);
    if (command == "run") return thicket::bench::runCommand(args);
    if (command == "experiment") return thicket::bench::experimentCommand(args);
    if (command == "merge") return thicket::bench::mergeCommand(args);
    if (command == "subsampling") return thicket::bench::subsamplingCommand(args);
    if (command == "clearance") return thicket::bench::clearanceCommand(args);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

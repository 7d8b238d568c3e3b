// thicket-bench: the benchmark driver and the module cores' micro-benchmarks.
//
//   thicket-bench run --density D --trials N --out DIR [...]   trials of one configuration
//   thicket-bench experiment --out DIR [...]                   the benchmark's experiments
//   thicket-bench merge --out DIR IN_DIR...                    gathers shards' output folders
//   thicket-bench report DIR                                   the report of DIR again
//   thicket-bench subsampling --out DIR [...]                  experiment E5 alone
//   thicket-bench clearance --out DIR [...]                    the ESDF's clearance error
//   thicket-bench [--benchmark_filter=REGEX ...]              Google Benchmark (bench_*.cc)
#include <malloc.h>

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <benchmark/benchmark.h>

#include "clearance.h"
#include "experiments.h"
#include "report.h"
#include "subsampling.h"
#include "thicket/common/cli.h"
#include "trials.h"

namespace {

int microBenchmarks(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

// The trials' graph runs in this process on memq://, which copies every message into a buffer it
// mallocs and frees once the message is handled: map updates of hundreds of kilobytes, every frame.
// glibc by default maps such buffers afresh, or returns the top of its heap to the system after
// they are freed, so the next message faults its pages in and zeroes them again: a sixth of the
// process's page faults on E2, 5 % of its time. The heap keeps its peak instead.
void keepHeapPages() {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest: buffers below it come from the heap
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

}  // namespace

int main(int argc, char** argv) {
  keepHeapPages();
  if (argc == 1 || std::string_view(argv[1]).rfind("--benchmark", 0) == 0) {
    return microBenchmarks(argc, argv);
  }
  struct Command {
    const char* name;
    const char* summary;
    std::function<int(const std::vector<std::string>&)> run;
  };
  namespace bench = thicket::bench;
  const Command commands[] = {
      {"run", "trials of one configuration", bench::runCommand},
      {"experiment", "the benchmark's experiments (resumable, shardable)",
       bench::experimentCommand},
      {"merge", "gathers shards' output folders", bench::mergeCommand},
      {"report", "writes an output folder's report again", bench::reportCommand},
      {"subsampling", "experiment E5 alone", bench::subsamplingCommand},
      {"clearance", "the ESDF's clearance error", bench::clearanceCommand},
  };
  CLI::App app(
      "thicket-bench: the benchmark driver (docs/benchmark.md) and the module cores'\n"
      "micro-benchmarks. `thicket-bench COMMAND --help` describes a command's flags.",
      "thicket-bench");
  app.footer(
      "Without a command, or with --benchmark_* flags (e.g. --benchmark_filter=REGEX), it runs\n"
      "the Google Benchmark micro-benchmarks.");
  app.require_subcommand(1);
  std::vector<CLI::App*> apps;
  for (const Command& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.summary);
    sub->prefix_command();  // its arguments, --help included, go to the command's own parser
    sub->set_help_flag();
    apps.push_back(sub);
  }
  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  for (size_t i = 0; i < apps.size(); ++i) {
    if (apps[i]->parsed()) return commands[i].run(apps[i]->remaining());
  }
  return 2;  // require_subcommand(1) leaves no other case
}

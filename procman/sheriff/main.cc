// thicket-sheriff: runs a process sheet through procman_lcm deputies (docs/procman.md).
// Headless: prints a status table and the commands' output to stdout, takes commands on stdin
// (one per line; EOF does not quit), quits on `quit`, SIGINT or SIGTERM after stopping what it
// ordered. `thicket-sheriff --help` lists the options.
#include <cstdio>
#include <exception>
#include <utility>

#include "args.h"
#include "sheriff_program.h"
#include "thicket/procman/sheet.h"

using namespace thicket::procman;
using namespace thicket::sheriff;

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  Args args;
  if (auto exit_code = parseArgs(argc, argv, args)) return *exit_code;
  Sheet sheet;
  if (!args.sheet_path.empty()) {
    auto loaded = loadSheet(args.sheet_path);
    if (!loaded) {
      std::fprintf(stderr, "%s: %s\n", kProgram, loaded.error().c_str());
      return 2;
    }
    sheet = std::move(*loaded);
  }
  try {
    return runSheriffProgram(args, std::move(sheet));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 1;
  }
}

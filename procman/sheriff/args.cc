// thicket-sheriff's command line parsed with CLI11, and the combinations it refuses.
#include "args.h"

#include "thicket/common/cli.h"

namespace thicket::sheriff {

std::optional<int> parseArgs(int argc, char** argv, Args& args) {
  CLI::App app(
      "thicket-sheriff: runs the commands of a procman sheet through thicket-deputy (or any\n"
      "procman_lcm deputy). Prints a status table and the commands' output; reads commands on\n"
      "stdin ('help').\n"
      "  thicket-sheriff [options] sheet.pmd [script]\n"
      "  thicket-sheriff -o [options] [sheet.pmd]",
      kProgram);
  app.footer(
      "Exit status: 0 on quit or a completed script, 1 on a failed script or a runtime error,\n"
      "2 on a bad command line, sheet or script name.");
  app.add_option("sheet", args.sheet_path, "the process sheet (.pmd)")->check(cli::nonEmpty());
  app.add_option("script", args.script, "a script of the sheet to run")->check(cli::nonEmpty());
  CLI::Option* lone_ranger =
      app.add_flag("-l,--lone-ranger", args.lone_ranger,
                   "spawn a local thicket-deputy for the sheet's deputy id (one per id when the "
                   "sheet names several); it dies with the sheriff")
          ->disable_flag_override();
  app.add_flag("-o,--observer", args.observer,
               "send no orders: only show what deputies and sheriffs say")
      ->disable_flag_override()
      ->excludes(lone_ranger);
  cli::addLcmUrl(app, args.lcm_url, true);
  app.add_flag("--exit-after-script", args.exit_after_script,
               "exit when the script ends: 0 if it completed, 1 if it failed or timed out "
               "(commands keep running on their deputies; with -l the local deputy stops them "
               "as it exits)")
      ->disable_flag_override();
  app.add_option("--wait-timeout", args.wait_timeout_s,
                 "fail a script whose status wait lasts more than S seconds (0: wait forever)")
      ->check(cli::number(0, 1e6))
      ->capture_default_str();
  app.add_option("--status-period", args.status_period_s,
                 "reprint the status table on changes at most every S seconds (0: only on "
                 "'status')")
      ->check(cli::number(0, 1e6))
      ->capture_default_str();
  if (auto exit_code = cli::parse(app, argc, argv)) return exit_code;
  std::string problem;
  if (args.sheet_path.empty() && !args.observer) {
    problem = "no sheet given";
  } else if (args.observer && !args.script.empty()) {
    problem = "an observer sends no orders, so it cannot run a script";
  } else if (args.exit_after_script && args.script.empty()) {
    problem = "--exit-after-script needs a script";
  }
  if (!problem.empty()) return cli::usageError(kProgram, problem);
  return std::nullopt;
}

}  // namespace thicket::sheriff

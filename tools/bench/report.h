// The benchmark report (docs/benchmark.md, Outputs): reads an output folder's trials.csv (and
// run_log.csv and e5_subsampling.csv when present) and writes summary.md and figures/*.png. The
// numbers are computed here; tools/bench/figures.py only draws the tables this code writes to
// figures/*.csv, so every statistic has one implementation and is unit-tested.
#pragma once

#include <string>
#include <vector>

namespace thicket::bench {

/// A 95 % confidence interval of a proportion.
struct Interval {
  double low = 0;
  double high = 1;
};

/// The Wilson score interval (z = 1.959964) of `successes` out of `trials`; [0, 1] when there
/// were no trials (nothing is known).
Interval wilsonInterval(int successes, int trials);

struct ReportOptions {
  std::string python = "/usr/bin/python3";  ///< the interpreter with matplotlib
  std::string figures_script;               ///< empty: tools/bench/figures.py of the source tree
  std::string worlds_dir;                   ///< empty: config/worlds of the source tree
};

/// Writes out_dir/summary.md and out_dir/figures/ (the figures' data as CSV, and the PNGs that
/// figures.py draws from it) from out_dir/trials.csv, out_dir/run_log.csv and
/// out_dir/e5_subsampling.csv. Returns an error text, empty on success. When trials.csv cannot be
/// read nothing is written; when only the figures fail the summary is still written and the error
/// returned.
std::string writeReport(const std::string& out_dir, const ReportOptions& options = {});

/// `thicket-bench report DIR`: writeReport(DIR) for the user; exit status 0 when the report was
/// written, 1 when it (or a figure) could not be, 2 for bad arguments.
int reportCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

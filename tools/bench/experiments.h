// thicket-bench experiment / merge: the benchmark's experiments (docs/benchmark.md: E1, E2, E4 fly
// trials; E3 and T1 are computed from E2's and E4's rows; E5 is its own program; E6 flies trials
// with the simulator's dynamic obstacle), run as one deterministic list of trials that can be
// resumed after a kill, split across machines (--shard i/N) and merged back.
//
// Output folder DIR:
//   rows/shard-<i>-of-<N>.csv  one line per finished trial, appended and flushed at once (the
//                              resume state). Columns: the fixed columns of trials.csv (up to
//                              blocked_cycles), then `timings`: "<stage>=<median>/<p95>/<max>;..."
//                              in milliseconds, sorted by stage, since the stages differ from
//                              trial to trial. merge writes rows/merged.csv.
//   trials.csv                 every trial of rows/*.csv once (a row that could not run is
//                              replaced by a later one that did), sorted; the timings spread
//                              into <stage>_ms_median, _ms_p95, _ms_max columns.
//   paths/<key, '/' -> '-'>.csv  the executed path of every trial (t, x, y, z, yaw).
//   logs/<key, '/' -> '-'>.lcm   the LCM log of the trials --record selects.
//   run_log.csv                one line per run or merge.
#pragma once

#include <string>
#include <vector>

#include "plans.h"
#include "thicket/common/expected.h"

namespace thicket::bench {

/// Parses the flags after "experiment"; the error is a message for the user naming the flag
/// (exit status 2).
Expected<ExperimentOptions> parseExperimentOptions(const std::vector<std::string>& args);

/// `thicket-bench experiment ARGS` and `thicket-bench merge ARGS`: exit status 0 when every
/// trial ran and the output was written, 1 when a trial could not run or output could not be
/// written (or read), 2 for bad flags.
int experimentCommand(const std::vector<std::string>& args);
int mergeCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

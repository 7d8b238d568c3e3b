// The report's figures: figures.py run on the figures' data, and the files a report replaces.
#pragma once

#include <string>

namespace thicket::bench::report_internal {

// Runs `python script out_dir` (no shell), its output going to figures/figures.log; the error
// text, empty when it exited with status 0 (the log is then removed).
std::string drawFigures(const std::string& python, const std::string& script,
                        const std::string& out_dir, const std::string& log);

// Whether figures/<name> is a file a report writes (and the next one replaces): the figures and
// their data, figures.log, and E2's of every scenario (e2Figure).
bool reportFigureFile(const std::string& name);

}  // namespace thicket::bench::report_internal

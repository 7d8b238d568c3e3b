// The files of the report's figures that a report replaces.
#pragma once

#include <string>

namespace thicket::bench::report_internal {

// Whether figures/<name> is a file a report writes (and the next one replaces): the figures and
// their data, figures.log, and E2's of every scenario (e2Figure).
bool reportFigureFile(const std::string& name);

}  // namespace thicket::bench::report_internal

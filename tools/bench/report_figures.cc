// The files a report's figures are drawn from and into (figures.py, run by writeReport).
#include "report_figures.h"

#include <algorithm>
#include <iterator>
#include <regex>

namespace thicket::bench::report_internal {
namespace {

const char* const kFigureFiles[] = {
    "e1_success.png",      "e1_success.csv",     "e3_path_length.png", "e3_path_length.csv",
    "e4_success.png",      "e4_success.csv",     "e4_forest.png",      "e4_forest_world.csv",
    "e4_forest_paths.csv", "e5_subsampling.png", "e5_subsampling.csv", "figures.log"};

}  // namespace

bool reportFigureFile(const std::string& name) {
  if (std::find(std::begin(kFigureFiles), std::end(kFigureFiles), name) != std::end(kFigureFiles)) {
    return true;
  }
  static const std::regex e2(R"(e2_success(_.+)?\.(png|csv))");
  return std::regex_match(name, e2);
}

}  // namespace thicket::bench::report_internal

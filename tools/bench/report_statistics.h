// The report's statistics: success tallies, the trials of an experiment, by scenario.
#pragma once

#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "plans.h"
#include "report_inputs.h"

namespace thicket::bench::report_internal {

struct Tally {
  int successes = 0;
  int trials = 0;
  void add(bool success) {
    ++trials;
    successes += success;
  }
};

// Variant (method or goal finding) -> density -> tally.
using SuccessTable = std::map<std::string, std::map<double, Tally>>;

// The known names first in the order the paper lists them, then any others alphabetically.
std::vector<std::string> ordered(const std::set<std::string>& names,
                                 const std::vector<std::string>& known);

template <class Map>
std::set<std::string> keysOf(const Map& map) {
  std::set<std::string> keys;
  for (const auto& [key, value] : map) keys.insert(key);
  return keys;
}

std::vector<const Trial*> select(const std::vector<Trial>& trials, const std::string& experiment);

// The scenario of the paper's own world: listed first, its E2 figure named without a scenario
// (e2_success.png), and E3's claim (path lengths) is about it.
inline constexpr const char* kPaperScenario = "paper";

// `trials` by scenario, kPaperScenario first, then the others alphabetically: the sections of an
// experiment flown on several scenarios show each on its own.
std::vector<std::pair<std::string, std::vector<const Trial*>>> byScenario(
    const std::vector<const Trial*>& trials);

// "E2/paper": how the tables over every experiment name a row, one per experiment and scenario.
std::string experimentScenario(const TrialSpec& spec);

}  // namespace thicket::bench::report_internal

// The report's statistics: the Wilson interval, success tallies, trials by experiment and scenario.
#include "report_statistics.h"

#include <algorithm>
#include <cmath>

#include "report.h"

namespace thicket::bench {

Interval wilsonInterval(int successes, int trials) {
  if (trials <= 0) return {0, 1};
  constexpr double z = 1.959963984540054;  // the standard normal's 97.5 % quantile
  const double n = trials, p = successes / n, z2 = z * z;
  const double denominator = 1 + z2 / n;
  const double center = (p + z2 / (2 * n)) / denominator;
  const double half = z * std::sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denominator;
  return {std::max(0.0, center - half), std::min(1.0, center + half)};
}

}  // namespace thicket::bench

namespace thicket::bench::report_internal {

std::vector<std::string> ordered(const std::set<std::string>& names,
                                 const std::vector<std::string>& known) {
  std::vector<std::string> result;
  for (const std::string& name : known) {
    if (names.count(name)) result.push_back(name);
  }
  for (const std::string& name : names) {
    if (std::find(known.begin(), known.end(), name) == known.end()) result.push_back(name);
  }
  return result;
}

std::vector<const Trial*> select(const std::vector<Trial>& trials, const std::string& experiment) {
  std::vector<const Trial*> selected;
  for (const Trial& t : trials) {
    if (t.spec.experiment == experiment && t.ran()) selected.push_back(&t);
  }
  return selected;
}

std::vector<std::pair<std::string, std::vector<const Trial*>>> byScenario(
    const std::vector<const Trial*>& trials) {
  std::map<std::string, std::vector<const Trial*>> groups;
  for (const Trial* t : trials) groups[t->spec.scenario].push_back(t);
  std::vector<std::pair<std::string, std::vector<const Trial*>>> ordered_groups;
  for (const std::string& scenario : ordered(keysOf(groups), {kPaperScenario})) {
    ordered_groups.emplace_back(scenario, groups[scenario]);
  }
  return ordered_groups;
}

std::string experimentScenario(const TrialSpec& spec) {
  return spec.experiment + "/" + spec.scenario;
}

}  // namespace thicket::bench::report_internal

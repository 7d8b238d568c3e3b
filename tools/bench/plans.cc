// The experiments' plans, the trial list they make, and the key and files of a trial.
#include "plans.h"

#include <algorithm>
#include <cmath>

#include "trials.h"

namespace thicket::bench {

std::string TrialSpec::key() const {
  return experiment + "/" + scenario + "/d" + formatNumber("%g", density) + "/" + method + "/" +
         goal_finding + "/" + sensor + "/s" + std::to_string(seed);
}

std::string keyFileName(const std::string& key) {
  std::string name = key;
  std::replace(name.begin(), name.end(), '/', '-');
  return name;
}

std::string trialPathFile(const std::string& key) {
  return "paths/" + keyFileName(key) + ".csv";
}

std::string trialLogFile(const std::string& key) {
  return "logs/" + keyFileName(key) + ".lcm";
}

namespace {

// What each --experiment name selects: the plan whose trials it needs (E3 is computed from E2's
// rows, T1 from E4's), or none for E5, which is its own program.
struct ExperimentName {
  const char* name;
  const char* plan;  // nullptr: E5
};
const ExperimentName kExperimentNames[] = {{"E1", "E1"}, {"E2", "E2"},    {"E3", "E2"},
                                           {"E4", "E4"}, {"E5", nullptr}, {"E6", "E6"},
                                           {"T1", "E4"}};

bool sameDensity(double a, double b) {
  return std::abs(a - b) < 1e-9;
}

}  // namespace

const std::vector<Plan>& plans() {
  static const std::vector<Plan> table = [] {
    // 0.05 ... 0.50: k / 20 is the double nearest each decimal, as "0.15" parses.
    std::vector<double> paper;
    for (int k = 1; k <= 10; ++k) paper.push_back(k / 20.0);
    return std::vector<Plan>{
        {"E1", {"paper"}, paper, {"none"}, goalFindingNames(), 100, 60},
        {"E2", {"paper", "eth"}, paper, methodNames(), {"soft"}, 50, 120},
        {"E4", {"forest50"}, {0.1, 0.2}, methodNames(false), {"soft"}, 20, 500},
        // A path blocked in flight: a cylinder appears on the committed trajectory.
        {"E6", {"paper"}, {0.2}, methodNames(false), {"soft"}, 20, 60, true},
    };
  }();
  return table;
}

std::vector<std::string> experimentNames() {
  std::vector<std::string> names;
  for (const ExperimentName& e : kExperimentNames) names.emplace_back(e.name);
  return names;
}

bool selects(const std::vector<std::string>& filter, const std::string& item) {
  return filter.empty() || std::find(filter.begin(), filter.end(), item) != filter.end();
}

bool selectsDensity(const std::vector<double>& filter, double density) {
  return filter.empty() || std::any_of(filter.begin(), filter.end(),
                                       [&](double d) { return sameDensity(d, density); });
}

std::vector<const Plan*> selectedPlans(const ExperimentOptions& options) {
  std::vector<const Plan*> selected;
  for (const Plan& plan : plans()) {
    for (const ExperimentName& e : kExperimentNames) {
      if (e.plan != nullptr && e.plan == std::string(plan.id) &&
          selects(options.experiments, e.name)) {
        selected.push_back(&plan);
        break;
      }
    }
  }
  return selected;
}

std::vector<TrialSpec> trialList(const ExperimentOptions& options) {
  std::vector<TrialSpec> list;
  for (const Plan* plan : selectedPlans(options)) {
    TrialSpec spec;
    spec.experiment = plan->id;
    spec.dynamic_obstacle = plan->dynamic_obstacle;
    spec.replans = options.replans.value_or(plan->replans);
    const int trials = options.trials.value_or(plan->trials);
    for (int t = 0; t < trials; ++t) {
      spec.trial = t;
      spec.seed = static_cast<uint64_t>(options.seed_base) + static_cast<uint64_t>(t);
      for (const std::string& scenario : plan->scenarios) {
        if (!selects(options.scenarios, scenario)) continue;
        spec.scenario = scenario;
        for (double density : plan->densities) {
          if (!selectsDensity(options.densities, density)) continue;
          spec.density = density;
          for (const std::string& method : plan->methods) {
            if (!selects(options.methods, method)) continue;
            spec.method = method;
            for (const std::string& goal_finding : plan->goal_findings) {
              if (!selects(options.goal_findings, goal_finding)) continue;
              spec.goal_finding = goal_finding;
              list.push_back(spec);
            }
          }
        }
      }
    }
  }
  return list;
}

}  // namespace thicket::bench

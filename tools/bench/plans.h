// The benchmark's experiments as plans of trials (E1, E2, E4, E6), and what a selection flies.
#pragma once

#include <string>
#include <vector>

#include "experiments.h"

namespace thicket::bench {

// An experiment that flies trials: the cross product of its lists, `trials` worlds each.
struct Plan {
  const char* id;
  std::vector<std::string> scenarios;
  std::vector<double> densities;
  std::vector<std::string> methods;
  std::vector<std::string> goal_findings;
  int trials;
  int replans;
  bool dynamic_obstacle = false;  // the simulator's dynamic obstacle, with its default options
};

// The experiments that fly trials, in the order they run.
const std::vector<Plan>& plans();

// The names --experiment takes.
std::vector<std::string> experimentNames();

// Whether `filter` (a selection flag's list; empty selects everything) selects `item`.
bool selects(const std::vector<std::string>& filter, const std::string& item);
bool selectsDensity(const std::vector<double>& filter, double density);

// The plans the experiments select, in the plans' order.
std::vector<const Plan*> selectedPlans(const ExperimentOptions& options);

}  // namespace thicket::bench

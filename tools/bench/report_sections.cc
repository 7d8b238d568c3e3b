// The sections of summary.md: contents, throughput, safety, worlds, E1 to E6 and T1.
#include "report_sections.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <optional>
#include <set>
#include <tuple>
#include <utility>

#include "csv.h"
#include "report.h"
#include "report_markdown.h"
#include "report_statistics.h"
#include "thicket/common/statistics.h"
#include "thicket/sim/dynamic_obstacle.h"
#include "thicket/sim/world.h"

namespace thicket::bench::report_internal {
namespace {

// figures/<name>.csv: variant,density,successes,trials,rate,low,high.
std::string successCsv(const SuccessTable& table, const std::vector<std::string>& order) {
  std::string text = "variant,density,successes,trials,rate,low,high\n";
  for (const std::string& variant : order) {
    for (const auto& [density, tally] : table.at(variant)) {
      const Interval ci = wilsonInterval(tally.successes, tally.trials);
      text += csvCell(variant) + "," + densityText(density) + "," +
              std::to_string(tally.successes) + "," + std::to_string(tally.trials) + "," +
              print("%.6f,%.6f,%.6f\n", static_cast<double>(tally.successes) / tally.trials, ci.low,
                    ci.high);
    }
  }
  return text;
}

}  // namespace

std::string overviewSection(const std::vector<Trial>& trials, const std::vector<RunLogRow>& runs,
                            bool has_e5, size_t e5_rows) {
  std::map<std::string, std::pair<int, int>> by_experiment;  // E2/paper -> trials, ran
  std::set<std::string> experiments;
  for (const Trial& t : trials) {
    auto& [count, ran] = by_experiment[experimentScenario(t.spec)];
    ++count;
    ran += t.ran();
    experiments.insert(t.spec.experiment);
  }
  std::string text = "## Contents\n\n";
  std::vector<std::vector<std::string>> rows;
  for (const auto& [experiment, counts] : by_experiment) {
    rows.push_back({experiment, std::to_string(counts.first), std::to_string(counts.second),
                    std::to_string(counts.first - counts.second)});
  }
  text += markdownTable({"experiment/scenario", "trials", "ran", "could not run"}, rows);
  std::vector<std::string> derived;
  if (experiments.count("E2")) derived.push_back("E3 from the E2 trials");
  if (experiments.count("E4")) derived.push_back("T1 from the E4 trials");
  if (has_e5)
    derived.push_back("E5 from e5_subsampling.csv (" + std::to_string(e5_rows) + " rows)");
  if (!derived.empty()) {
    text += "Also: ";
    for (size_t i = 0; i < derived.size(); ++i) text += (i ? "; " : "") + derived[i];
    text += ".\n\n";
  }
  text +=
      "Trials that could not run are left out of every rate, length and timing below; success "
      "intervals are Wilson 95 % score intervals.\n\n";

  std::string failed;
  for (const Trial& t : trials) {
    if (!t.ran()) {
      failed += "- `" + t.key + "` (trials.csv line " + std::to_string(t.line) +
                "): " + escapeCell(t.end_reason) + "\n";
    }
  }
  if (!failed.empty()) text += "### Trials that could not run\n\n" + failed + "\n";

  if (!runs.empty()) {
    text += "### Invocations (run_log.csv)\n\n";
    std::vector<std::vector<std::string>> log_rows;
    for (const RunLogRow& r : runs) {
      log_rows.push_back({r.started_utc, duration(r.wall_s), "`" + r.command + "`",
                          std::to_string(r.jobs), r.shard, std::to_string(r.trials_run),
                          std::to_string(r.trials_skipped), r.cpu, std::to_string(r.cores)});
    }
    text += markdownTable({"started (UTC)", "wall time", "command", "jobs", "shard", "trials run",
                           "trials skipped", "cpu", "cores"},
                          log_rows);
  }
  return text;
}

std::string throughputSection(const std::vector<Trial>& trials,
                              const std::vector<RunLogRow>& runs) {
  std::map<std::string, std::pair<double, double>> by_experiment;  // simulated s, wall s
  double simulated = 0, wall = 0;
  int count = 0;
  for (const Trial& t : trials) {
    if (!t.ran()) continue;
    by_experiment[experimentScenario(t.spec)].first += t.path_time_s;
    by_experiment[experimentScenario(t.spec)].second += t.wall_time_s;
    simulated += t.path_time_s;
    wall += t.wall_time_s;
    ++count;
  }
  if (count == 0) return "";
  auto ratio = [](double a, double b) { return b > 0 ? print("%.2f", a / b) : std::string("–"); };
  std::vector<std::vector<std::string>> rows;
  for (const auto& [experiment, sums] : by_experiment) {
    rows.push_back({experiment, print("%.0f", sums.first), print("%.0f", sums.second),
                    ratio(sums.first, sums.second)});
  }
  rows.push_back({"all", print("%.0f", simulated), print("%.0f", wall), ratio(simulated, wall)});
  std::string text =
      "## Throughput\n\nSimulated seconds flown per wall-clock second: the sum of path_time_s "
      "over the sum of wall_time_s of the trials, i.e. per thread (each trial runs on one "
      "thread).\n\n";
  text += markdownTable({"experiment/scenario", "simulated [s]", "trial wall time [s]",
                         "simulated s per wall s, per thread"},
                        rows);
  double run_wall = 0;
  int invocations = 0;
  for (const RunLogRow& r : runs) {
    if (r.trials_run > 0) {
      run_wall += r.wall_s;
      ++invocations;
    }
  }
  if (invocations > 0 && run_wall > 0) {
    text +=
        print("Whole run: %.0f simulated s in %.0f s of wall time over the ", simulated, run_wall) +
        std::to_string(invocations) + (invocations == 1 ? " invocation" : " invocations") +
        print(" that ran trials (run_log.csv): %.2f simulated s per wall s (",
              simulated / run_wall) +
        "shards run on separate machines at once make this an underestimate).\n\n";
  }
  return text;
}

std::string safetySection(const std::vector<Trial>& trials) {
  std::map<std::string, Tally> tallies;  // E2/paper -> collisions (as successes) / trials
  std::map<std::string, double> closest;
  std::vector<const Trial*> collided;
  for (const Trial& t : trials) {
    if (!t.ran() || !conservativeMethod(t.spec.method)) continue;
    const std::string experiment = experimentScenario(t.spec);
    tallies[experiment].add(t.collision);
    const auto [it, inserted] = closest.emplace(experiment, t.min_clearance_m);
    if (!inserted) it->second = std::min(it->second, t.min_clearance_m);
    if (t.collision) collided.push_back(&t);
  }
  if (tallies.empty()) return "";
  std::vector<std::vector<std::string>> rows;
  Tally all;
  for (const auto& [experiment, tally] : tallies) {
    rows.push_back({experiment, std::to_string(tally.trials), std::to_string(tally.successes),
                    print("%.4f", closest[experiment])});
    all.trials += tally.trials;
    all.successes += tally.successes;
  }
  rows.push_back({"all", std::to_string(all.trials), std::to_string(all.successes), "-"});
  std::string text =
      "## Safety: collisions of the conservative methods\n\n"
      "Every method but rrt_star_optimistic must never collide (target: zero). A collision is "
      "an executed path closer to an obstacle than the robot radius; in E6 the dynamic obstacle "
      "is one from its appearance on.\n\n" +
      markdownTable({"experiment/scenario", "conservative trials", "collisions",
                     "smallest executed clearance [m]"},
                    rows);
  if (!collided.empty()) {
    text += "Trials that collided (executed clearance):\n\n";
    for (const Trial* t : collided) {
      text += "- `" + t->key + "` (" + print("%.4f", t->min_clearance_m) + " m)\n";
    }
    text += "\n";
  }
  return text;
}

std::string e1Section(Report& report, const std::vector<Trial>& trials) {
  SuccessTable table;
  for (const Trial* t : select(trials, "E1"))
    table[t->spec.goal_finding][t->spec.density].add(t->success);
  if (table.empty()) return "";
  const auto order = ordered(keysOf(table), goalFindingNames());
  report.figureData("e1_success.png", "e1_success.csv", successCsv(table, order));
  return "## E1: optimization only, success per goal finding and density\n\n"
         "line = straight-line goal finding, gradient = ESDF gradient goal finding, soft = "
         "gradient + soft goal cost. Cells: successes/trials = rate [95 % interval].\n\n" +
         successMatrix(table, order, "density") +
         report.image("e1_success.png", "E1: success rate vs density");
}

namespace {

// The paragraph that stands where a trials.csv predates the planning radius's oracle columns.
std::string noPlanningOracle() {
  return "Unknown here: this trials.csv has no column solvable_collision_radius. It was written "
         "before the oracle tested the planning radius; its solvable is the oracle at the "
         "collision radius, and needs_overflight and bottleneck_m are missing.\n\n";
}

}  // namespace

std::string worldsSection(const std::vector<Trial>& trials) {
  std::map<std::tuple<std::string, double, uint64_t>, const Trial*> worlds;
  for (const Trial& t : trials) {
    if (t.ran()) worlds.emplace(std::tuple{t.spec.scenario, t.spec.density, t.spec.seed}, &t);
  }
  if (worlds.empty()) return "";
  struct Counts {
    int worlds = 0, solvable = 0, solvable_collision = 0, overflight = 0;
    std::vector<double> bottlenecks;
  };
  std::map<std::pair<std::string, double>, Counts> by_density;
  bool known = true;
  for (const auto& [world, t] : worlds) {
    Counts& counts = by_density[{std::get<0>(world), std::get<1>(world)}];
    ++counts.worlds;
    counts.solvable_collision += t->solvable_collision_radius;
    if (!t->solvable) {
      known = false;
      continue;
    }
    counts.solvable += *t->solvable;
    counts.overflight += *t->needs_overflight;
    counts.bottlenecks.push_back(*t->bottleneck_m);
  }
  std::vector<std::vector<std::string>> rows;
  for (const auto& [scenario_density, counts] : by_density) {
    const auto ifKnown = [known](int count) { return known ? std::to_string(count) : "–"; };
    rows.push_back({scenario_density.first, densityText(scenario_density.second),
                    std::to_string(counts.worlds), ifKnown(counts.solvable),
                    std::to_string(counts.solvable_collision), ifKnown(counts.overflight),
                    counts.bottlenecks.empty() ? "–" : print("%.3f", median(counts.bottlenecks))});
  }
  return std::string(
             "## Worlds: what the oracle says\n\n"
             "Every world (scenario, density, seed) some trial flew, once. Solvable: the "
             "ground-truth oracle finds a path for a sphere of the planning radius (robot radius "
             "+ the planner's acceptance margin, the clearance the planner demands) or of the "
             "collision radius (robot radius), flying over cylinders low enough. Need overflight: "
             "solvable at the planning radius, but only over some cylinder. Bottleneck: the "
             "largest radius of a disc that gets from start to goal in the plane with every "
             "cylinder blocking, whatever its height.\n\n") +
         (known ? "" : noPlanningOracle()) +
         markdownTable({"scenario", "density", "worlds", "solvable at planning radius",
                        "solvable at collision radius", "need overflight", "median bottleneck [m]"},
                       rows);
}

namespace {

// E2's figure of one scenario: e2_success.png for kPaperScenario, e2_success_<scenario>.png for
// the others; `extension` ".png" or ".csv" (its data).
std::string e2Figure(const std::string& scenario, const std::string& extension) {
  return std::string("e2_success") + (scenario == kPaperScenario ? "" : "_" + scenario) + extension;
}

// How a failed trial failed, from where it ended and what it flew (the classes of the failure
// analysis behind frontier_memory): a collision; near the goal (it ended within kNearGoalM of
// it); else by its executed path against the straight line from start to goal: a stall (shorter
// than the line: it mostly hovered), slow (up to twice the line), a wander (longer).
enum class FailureClass { kStall, kSlow, kWander, kNearGoal, kCollision };
constexpr double kNearGoalM = 2.0;
const char* const kFailureClassNames[] = {"stall", "slow", "wander", "near goal", "collision"};

FailureClass failureClass(const Trial& t) {
  if (t.collision) return FailureClass::kCollision;
  if (t.distance_to_goal_m < kNearGoalM) return FailureClass::kNearGoal;
  if (t.path_length_m < t.straight_line_m) return FailureClass::kStall;
  return t.path_length_m <= 2 * t.straight_line_m ? FailureClass::kSlow : FailureClass::kWander;
}

// The failure classes of one scenario's E2 trials: per method over every density (with the
// median executed path of the failures), and per density and method.
std::string failureSection(const std::string& scenario, const std::vector<const Trial*>& e2,
                           const std::vector<std::string>& order) {
  using Counts = std::array<int, std::size(kFailureClassNames)>;
  std::map<std::string, Counts> overall;
  std::map<double, std::map<std::string, Counts>> by_density;
  std::map<std::string, std::vector<double>> failed_lengths;
  for (const Trial* t : e2) {
    by_density[t->spec.density][t->spec.method];  // a cell for every flown configuration
    if (t->success) continue;
    const auto k = static_cast<size_t>(failureClass(*t));
    ++overall[t->spec.method][k];
    ++by_density[t->spec.density][t->spec.method][k];
    failed_lengths[t->spec.method].push_back(t->path_length_m);
  }
  std::vector<std::string> header = {"method", "failures"};
  header.insert(header.end(), std::begin(kFailureClassNames), std::end(kFailureClassNames));
  header.push_back("median failed path [m]");
  std::vector<std::vector<std::string>> rows;
  for (const std::string& method : order) {
    const Counts& counts = overall[method];
    std::vector<std::string> row = {method, std::to_string(failed_lengths[method].size())};
    for (int count : counts) row.push_back(std::to_string(count));
    row.push_back(medianOrDash(failed_lengths[method]));
    rows.push_back(row);
  }
  std::vector<std::string> matrix_header = {"density"};
  matrix_header.insert(matrix_header.end(), order.begin(), order.end());
  std::vector<std::vector<std::string>> matrix;
  for (const auto& [density, methods] : by_density) {
    std::vector<std::string> row = {densityText(density)};
    for (const std::string& method : order) {
      const auto found = methods.find(method);
      std::string cell = "–";
      if (found != methods.end()) {
        cell.clear();
        for (int count : found->second) cell += (cell.empty() ? "" : "/") + std::to_string(count);
      }
      row.push_back(cell);
    }
    matrix.push_back(row);
  }
  return "### How the failures failed (" + scenario +
         ")\n\n"
         "Every failed trial in one class: a collision; near the goal (ended less than " +
         print("%g", kNearGoalM) +
         " m from it); else by its executed path against the straight line from start to goal: "
         "stall (shorter: it mostly hovered), slow (up to twice the line), wander (longer).\n\n" +
         markdownTable(header, rows) +
         "Per density, cells stall/slow/wander/near goal/collision:\n\n" +
         markdownTable(matrix_header, matrix);
}

// E2 on one scenario: success per method and density, per method over every density, on the
// worlds solvable at either oracle radius.
std::string e2ScenarioSection(Report& report, const std::string& scenario,
                              const std::vector<const Trial*>& e2) {
  // Success over the worlds solvable at the planning radius and at the collision radius.
  SuccessTable all, on_planning, on_collision;
  std::map<std::string, int> collisions;
  std::map<std::string, std::vector<double>> lengths;
  std::map<std::string, Tally> overall, overall_planning, overall_collision;
  bool planning_known = true;
  for (const Trial* t : e2) {
    const std::string& method = t->spec.method;
    all[method][t->spec.density].add(t->success);
    overall[method].add(t->success);
    on_planning[method];  // every method gets a column
    on_collision[method];
    planning_known = planning_known && t->solvable.has_value();
    if (t->solvable.value_or(false)) {
      on_planning[method][t->spec.density].add(t->success);
      overall_planning[method].add(t->success);
    }
    if (t->solvable_collision_radius) {
      on_collision[method][t->spec.density].add(t->success);
      overall_collision[method].add(t->success);
    }
    collisions[method] += t->collision;
    if (t->success) lengths[method].push_back(t->path_length_m);
  }
  const auto order = ordered(keysOf(all), methodNames());
  const std::string figure = e2Figure(scenario, ".png");
  report.figureData(figure, e2Figure(scenario, ".csv"), successCsv(all, order));

  std::string text =
      "## E2: goal-selection strategies on " + scenario +
      ", success per method and density\n\n"
      "Cells: successes/trials = rate [95 % interval].\n\n" +
      successMatrix(all, order, "density") +
      report.image(figure, "E2 on " + scenario + ": success rate vs density per method");

  std::vector<std::vector<std::string>> rows;
  for (const std::string& method : order) {
    std::string target = "not required (plans through unknown space)";
    if (conservativeMethod(method)) target = collisions[method] == 0 ? "met" : "MISSED";
    const Tally& planning = overall_planning[method];
    const Tally& collision = overall_collision[method];
    rows.push_back({method, successCell(overall[method]),
                    planning_known ? std::to_string(planning.trials) : "–",
                    planning_known ? successCell(planning) : "–", std::to_string(collision.trials),
                    successCell(collision), std::to_string(collisions[method]), target,
                    medianOrDash(lengths[method])});
  }
  const std::string on = " (" + scenario + ")\n\n";
  text += "### Per method, all densities" + on +
          "A world is solvable when the ground-truth oracle finds "
          "a path for a sphere of the planning radius (robot radius + the planner's acceptance "
          "margin) or of the collision radius (robot radius); solvable worlds are counted in "
          "trials. Target: zero collisions for every conservative method (all but "
          "rrt_star_optimistic). Path length: median over the successful trials.\n\n" +
          (planning_known ? "" : noPlanningOracle()) +
          markdownTable({"method", "success", "solvable at planning radius",
                         "success on solvable at planning radius", "solvable at collision radius",
                         "success on solvable at collision radius", "collisions",
                         "zero-collision target", "median path length [m]"},
                        rows);
  text += "### Success on worlds solvable at the planning radius" + on +
          (planning_known ? successMatrix(on_planning, order, "density") : noPlanningOracle());
  text += "### Success on worlds solvable at the collision radius" + on +
          successMatrix(on_collision, order, "density");
  text += failureSection(scenario, e2, order);
  return text;
}

}  // namespace

std::string e2Section(Report& report, const std::vector<Trial>& trials) {
  std::string text;
  for (const auto& [scenario, e2] : byScenario(select(trials, "E2"))) {
    text += e2ScenarioSection(report, scenario, e2);
  }
  return text;
}

namespace {

// E3 on one scenario's E2 trials: the table of mean path lengths of method `a` and method `b` on
// the worlds both solved, and the figure's data (density, pairs, the two means); empty when either
// method flew none of its worlds.
struct E3Table {
  std::string text, csv;
};
std::optional<E3Table> e3Table(const std::vector<const Trial*>& e2, const std::string& a,
                               const std::string& b) {
  // A world is (density, seed) flown with the same goal finding and sensor.
  std::map<std::string, std::pair<const Trial*, const Trial*>> worlds;  // a, b
  Tally a_success, b_success;
  for (const Trial* t : e2) {
    const std::string world = densityText(t->spec.density) + "/" + t->spec.goal_finding + "/" +
                              t->spec.sensor + "/" + std::to_string(t->spec.seed);
    if (t->spec.method == a) {
      worlds[world].first = t;
      a_success.add(t->success);
    } else if (t->spec.method == b) {
      worlds[world].second = t;
      b_success.add(t->success);
    }
  }
  if (a_success.trials == 0 || b_success.trials == 0) return std::nullopt;

  struct Sums {
    int pairs = 0;
    double a = 0, b = 0;
  };
  std::map<double, Sums> by_density;
  Sums total;
  for (const auto& [world, pair] : worlds) {
    const auto [ta, tb] = pair;
    if (!ta || !tb || !ta->success || !tb->success) continue;
    for (Sums* s : {&by_density[ta->spec.density], &total}) {
      ++s->pairs;
      s->a += ta->path_length_m;
      s->b += tb->path_length_m;
    }
  }
  E3Table table;
  table.text = "Success over every E2 world of the scenario: " + a + " " + successCell(a_success) +
               ", " + b + " " + successCell(b_success) + ".\n\n";
  if (total.pairs == 0) {
    table.text += "No world was solved by both methods.\n\n";
    return table;
  }
  auto row = [](const std::string& label, const Sums& s) {
    const double mean_a = s.a / s.pairs, mean_b = s.b / s.pairs;
    return std::vector<std::string>{label,
                                    std::to_string(s.pairs),
                                    meters(mean_a),
                                    meters(mean_b),
                                    print("%.3f", mean_b / mean_a),
                                    print("%.1f %%", 100 * (1 - mean_b / mean_a))};
  };
  std::vector<std::vector<std::string>> rows;
  table.csv = "density,pairs," + a + "_mean_m," + b + "_mean_m\n";
  for (const auto& [density, s] : by_density) {
    rows.push_back(row(densityText(density), s));
    table.csv += densityText(density) + "," + std::to_string(s.pairs) +
                 print(",%.6f,%.6f\n", s.a / s.pairs, s.b / s.pairs);
  }
  rows.push_back(row("all", total));
  table.text += markdownTable({"density", "worlds both solved", a + " mean [m]", b + " mean [m]",
                               "ratio (" + b + " / " + a + ")", b + " shorter by"},
                              rows);
  return table;
}

}  // namespace

std::string e3Section(Report& report, const std::vector<Trial>& trials) {
  std::string text;
  const auto scenarios = byScenario(select(trials, "E2"));
  for (const auto& [scenario, e2] : scenarios) {
    const std::optional<E3Table> table = e3Table(e2, "random", "local_exploration");
    if (!table) continue;
    if (text.empty()) {
      text =
          "## E3: path length, random vs local_exploration\n\n"
          "On the E2 worlds that both random and local_exploration solved. Paper: local "
          "exploration is on par with random in success and its paths are up to 35 % shorter "
          "(on its own world, " +
          std::string(kPaperScenario) + ").\n\n";
    }
    text += "### E3 on " + scenario + "\n\n" + table->text;
    if (scenario == kPaperScenario && !table->csv.empty()) {
      report.figureData("e3_path_length.png", "e3_path_length.csv", table->csv);
      text += report.image("e3_path_length.png",
                           "E3: mean path length per density on " + std::string(kPaperScenario));
    }
  }
  for (const auto& [scenario, e2] : scenarios) {
    for (const char* other : {"random", "local_exploration"}) {
      const std::optional<E3Table> table = e3Table(e2, other, "frontier_memory");
      if (!table) continue;
      text += "### E3 on " + scenario + ": frontier_memory against " + other + "\n\n" +
              "On the E2 worlds both solved.\n\n" + table->text;
    }
  }
  return text;
}

namespace {

// The E4 top-down figure's data: the world of the lowest seed at density 0.2 (else the highest
// E4 density) that the most methods flew (every method, when one did), and its paths.
std::string forestFigure(Report& report, const std::vector<const Trial*>& e4,
                         const std::string& worlds_dir) {
  std::set<double> densities;
  for (const Trial* t : e4) densities.insert(t->spec.density);
  const double density = densities.count(0.2) ? 0.2 : *densities.rbegin();
  std::map<uint64_t, std::vector<const Trial*>> flown;  // seed -> the trials with a path file
  for (const Trial* t : e4) {
    if (t->spec.density == density &&
        std::filesystem::exists(report.out_dir + "/" + trialPathFile(t->key))) {
      flown[t->spec.seed].push_back(t);
    }
  }
  if (flown.empty())
    return "No E4 trial at density " + densityText(density) +
           " has its path file, so there is no top-down figure.\n\n";
  auto best = flown.begin();
  for (auto it = flown.begin(); it != flown.end(); ++it) {
    if (it->second.size() > best->second.size()) best = it;
  }
  const Trial& first = *best->second.front();
  auto spec = sim::loadScenario(first.spec.scenario, worlds_dir);
  if (!spec) {
    report.problems.push_back("E4 top-down figure: " + spec.error());
    return "";
  }
  auto world = sim::generateWorld(*spec, density, best->first);
  if (!world) {
    report.problems.push_back("E4 top-down figure: " + world.error());
    return "";
  }
  std::string world_csv = "kind,x,y,z,radius,height\n";
  auto point = [&](const char* kind, const Eigen::Vector3d& p) {
    world_csv += print("%s,%.6f,%.6f,%.6f,,\n", kind, p.x(), p.y(), p.z());
  };
  point("bounds_min", world->bounds_min);
  point("bounds_max", world->bounds_max);
  point("start", world->start);
  point("goal", world->goal);
  for (const sim::Cylinder& c : world->cylinders) {
    world_csv += print("cylinder,%.6f,%.6f,0,%.6f,%.6f\n", c.x, c.y, c.radius, c.height);
  }
  std::map<std::string, const Trial*> by_method;
  for (const Trial* t : best->second) by_method[t->spec.method] = t;
  std::string paths_csv = "method,density,seed,path\n";
  std::string methods;
  for (const std::string& method : ordered(keysOf(by_method), methodNames())) {
    paths_csv += csvCell(method) + "," + densityText(density) + "," + std::to_string(best->first) +
                 "," + csvCell(trialPathFile(by_method[method]->key)) + "\n";
    methods += (methods.empty() ? "" : ", ") + method;
  }
  report.figureData("e4_forest.png", "e4_forest_world.csv", world_csv);
  report.figureData("e4_forest.png", "e4_forest_paths.csv", paths_csv);
  return "Top-down: " + first.spec.scenario + " at density " + densityText(density) + ", seed " +
         std::to_string(best->first) + " (" + std::to_string(world->cylinders.size()) +
         " cylinders), flown by " + methods + ".\n\n" +
         report.image("e4_forest.png", "E4: every method on one forest");
}

}  // namespace

std::string e4Section(Report& report, const std::vector<Trial>& trials,
                      const std::string& worlds_dir) {
  const auto e4 = select(trials, "E4");
  if (e4.empty()) return "";
  SuccessTable table;
  std::map<std::string, int> collisions;
  std::map<std::string, std::map<double, std::vector<double>>> lengths;
  std::set<double> densities;
  for (const Trial* t : e4) {
    table[t->spec.method][t->spec.density].add(t->success);
    collisions[t->spec.method] += t->collision;
    if (t->success) lengths[t->spec.method][t->spec.density].push_back(t->path_length_m);
    densities.insert(t->spec.density);
  }
  const auto order = ordered(keysOf(table), methodNames());
  std::vector<std::string> header = {"method"};
  for (double d : densities) header.push_back("success d=" + densityText(d));
  header.push_back("collisions");
  for (double d : densities) header.push_back("median path length d=" + densityText(d) + " [m]");
  std::vector<std::vector<std::string>> rows;
  std::string csv = "method,density,successes,trials,rate,low,high\n";
  for (const std::string& method : order) {
    std::vector<std::string> row = {method};
    for (double d : densities) {
      const auto found = table[method].find(d);
      row.push_back(found == table[method].end() ? "–" : successCell(found->second));
    }
    row.push_back(std::to_string(collisions[method]));
    for (double d : densities) row.push_back(medianOrDash(lengths[method][d]));
    rows.push_back(row);
  }
  report.figureData("e4_success.png", "e4_success.csv", successCsv(table, order));
  std::string text =
      "## E4: long forest, success per method\n\nCells: successes/trials = rate [95 % "
      "interval]; path length over the successful trials.\n\n" +
      markdownTable(header, rows) + report.image("e4_success.png", "E4: success per method");
  return text + forestFigure(report, e4, worlds_dir);
}

std::string e6Section(Report& report, const std::vector<Trial>& trials,
                      const std::string& worlds_dir) {
  const auto e6 = select(trials, "E6");
  if (e6.empty()) return "";
  std::map<std::pair<std::string, double>, std::vector<const Trial*>> groups;
  for (const Trial* t : e6) groups[{t->spec.scenario, t->spec.density}].push_back(t);
  const sim::DynamicObstacleOptions obstacle;  // the trials fly its defaults
  std::string text =
      "## E6: a path blocked in flight\n\n" +
      print(
          "The simulator's dynamic obstacle: a cylinder of radius %g m, as tall as the height "
          "limit, appears on the vehicle's committed trajectory %g-%g m ahead ",
          obstacle.radius, obstacle.distance_ahead_min, obstacle.distance_ahead_max) +
      print(
          "at the first frame at or after %g s with that much committed path left (it may "
          "never appear). ",
          obstacle.appear_time) +
      "Touched: the vehicle came closer to it than the robot radius (a collision). Clearance: the "
      "smallest over the trials in which it appeared. Blocked cycles: planner cycles that found "
      "their committed trajectory blocked by a new map; the median over the trials in which it "
      "appeared.\n\n";
  for (const auto& [where, group] : groups) {
    const auto& [scenario, density] = where;
    std::optional<double> robot_radius;
    if (auto spec = sim::loadScenario(scenario, worlds_dir)) {
      robot_radius = spec->robot_radius;
    } else {
      report.problems.push_back("E6: " + spec.error());
    }
    struct Counts {
      Tally success;
      int appeared = 0, touched = 0, collisions = 0, blocked = 0;
      std::optional<double> closest;
      std::vector<double> blocked_cycles;
    };
    std::map<std::string, Counts> by_method;
    bool known = true;
    for (const Trial* t : group) {
      Counts& c = by_method[t->spec.method];
      c.success.add(t->success);
      c.collisions += t->collision;
      known = known && t->blocked_cycles.has_value();
      if (!t->obstacle_clearance_m) continue;
      const double clearance = *t->obstacle_clearance_m;
      ++c.appeared;
      c.touched += robot_radius && clearance < *robot_radius;
      c.closest = std::min(c.closest.value_or(clearance), clearance);
      c.blocked += t->blocked_cycles.value_or(0) > 0;
      c.blocked_cycles.push_back(static_cast<double>(t->blocked_cycles.value_or(0)));
    }
    std::vector<std::vector<std::string>> rows;
    for (const std::string& method : ordered(keysOf(by_method), methodNames())) {
      const Counts& c = by_method[method];
      const auto ifKnown = [known](const std::string& cell) { return known ? cell : "–"; };
      rows.push_back(
          {method, std::to_string(c.success.trials), ifKnown(std::to_string(c.appeared)),
           robot_radius ? ifKnown(std::to_string(c.touched)) : "–", std::to_string(c.collisions),
           successCell(c.success), c.closest ? print("%.4f", *c.closest) : "–",
           ifKnown(std::to_string(c.blocked)),
           c.blocked_cycles.empty() ? "–" : ifKnown(print("%g", median(c.blocked_cycles)))});
    }
    text += "### E6 on " + scenario + ", density " + densityText(density) + "\n\n" +
            (known ? ""
                   : "Unknown here: this trials.csv has no column blocked_cycles (written "
                     "before the dynamic obstacle's columns).\n\n") +
            markdownTable({"method", "trials", "obstacle appeared", "touched it", "collisions",
                           "success", "smallest clearance to the obstacle [m]",
                           "with a blocked cycle", "median blocked cycles"},
                          rows);
  }
  return text;
}

std::string t1Section(const std::vector<Trial>& trials) {
  struct Samples {
    std::vector<double> medians, p95s;
    double max = 0;
  };
  std::map<std::string, Samples> stages;
  for (const Trial* t : select(trials, "E4")) {
    for (const auto& [stage, timing] : t->timings) {
      Samples& s = stages[stage];
      s.medians.push_back(timing.median_ms);
      s.p95s.push_back(timing.p95_ms);
      s.max = std::max(s.max, timing.max_ms);
    }
  }
  if (stages.empty()) return "";
  struct PaperStage {
    const char* stage;
    const char* name;
    double ms;
  };
  const PaperStage paper[] = {
      {"mapper_tsdf_insert", "TSDF insert", 27.0},
      {"mapper_esdf_update", "ESDF update", 14.5},
      {"local_planner_trajectory_optimization", "trajectory optimization", 19.3},
      {"explorer_goal_selection", "intermediate goal selection", 5.9}};
  std::vector<std::vector<std::string>> rows;
  auto row = [&](const std::string& stage, const std::string& paper_ms,
                 const std::string& paper_ratio) {
    const Samples& s = stages.at(stage);
    rows.push_back({stage, std::to_string(s.medians.size()), milliseconds(median(s.medians)),
                    milliseconds(median(s.p95s)), milliseconds(s.max), paper_ms, paper_ratio});
  };
  std::set<std::string> shown;
  for (const PaperStage& p : paper) {
    if (!stages.count(p.stage)) continue;
    const double ours = median(stages.at(p.stage).medians);
    row(p.stage, print("%.1f (", p.ms) + p.name + ")",
        ours > 0 ? print(p.ms / ours < 10 ? "%.1f×" : "%.0f×", p.ms / ours) : std::string("–"));
    shown.insert(p.stage);
  }
  for (const auto& [stage, samples] : stages) {
    if (!shown.count(stage)) row(stage, "–", "–");
  }
  return "## T1: per-stage timings on the E4 trials\n\n"
         "Each trial reports the median, p95 and maximum of a stage's durations; over the trials "
         "this table gives the median of the per-trial medians, the median of the per-trial p95s "
         "and the maximum of the per-trial maxima. Paper: 2.4 GHz dual-core i7, on board (one "
         "figure per stage); its ratio to our median.\n\n" +
         markdownTable({"stage", "trials", "median [ms]", "p95 [ms]", "max [ms]", "paper [ms]",
                        "paper / median"},
                       rows);
}

std::string e5Section(Report& report, const std::vector<E5Row>& rows) {
  if (rows.empty()) return "";
  std::vector<std::vector<std::string>> cells;
  std::string csv =
      "fraction,stride,poses,mean_abs_error,p95_abs_error,max_abs_error,median_us,speedup\n";
  for (const E5Row& r : rows) {
    cells.push_back({print("%g", r.fraction), std::to_string(r.stride), std::to_string(r.poses),
                     print("%.4f", r.mean_abs_error), print("%.4f", r.p95_abs_error),
                     print("%.4f", r.max_abs_error), print("%.1f", r.median_us),
                     print("%.2f×", r.speedup)});
    csv += print("%.9g,", r.fraction) + std::to_string(r.stride) + "," + std::to_string(r.poses) +
           print(",%.9g,%.9g,%.9g,%.9g,%.9g\n", r.mean_abs_error, r.p95_abs_error, r.max_abs_error,
                 r.median_us, r.speedup);
  }
  report.figureData("e5_subsampling.png", "e5_subsampling.csv", csv);
  return "## E5: exploration-gain subsampling\n\n"
         "Error of the gain (fraction of unknown frustum voxels) when checking every stride-th "
         "frustum voxel, against stride 1; time of one gain evaluation. Paper: 5 % of the voxels "
         "give about 1 % error at about 3× the speed.\n\n" +
         markdownTable({"fraction", "stride", "poses", "mean abs error", "p95 abs error",
                        "max abs error", "median [µs]", "speed-up"},
                       cells) +
         report.image("e5_subsampling.png", "E5: gain error and speed-up vs fraction");
}

}  // namespace thicket::bench::report_internal

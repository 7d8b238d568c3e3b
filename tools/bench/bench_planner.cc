// Trajectory optimization speed on recorded planning problems: the planning cycles of real flights
// (the paper scenario at densities 0.1, 0.2 and 0.3, seeds 0-2, the default planner: gradient goal
// finding + soft goal), each with the ESDF the planner saw, its start state and horizon goal.
// Every benchmark iteration solves the next problem; the reported counters are the median and 95th
// percentile per solve (ms), the median L-BFGS iterations per solve and the fraction accepted.
// Target: median <= 2 ms (the paper: 19.3 ms per optimization).
#include <algorithm>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>
#include <thicket/map_update_t.hpp>
#include <thicket/planner_status_t.hpp>

#include "bench_worlds.h"
#include "thicket/common/map_update.h"
#include "thicket/common/statistics.h"
#include "thicket/local_planner/loco.h"
#include "trials.h"

namespace thicket::bench {

namespace {

struct PlanningProblem {
  std::shared_ptr<const EsdfLayer> esdf;
  local_planner::SplineEnds ends;
  int64_t cycle = 0;
};

// Watches a trial: mirrors the ESDF like the planner and, at every cycle that ran an
// optimization, keeps a copy of the map with the cycle's start state and horizon goal.
class ProblemRecorder : public Node {
 public:
  ProblemRecorder(lcm::LCM& lcm, std::vector<PlanningProblem>& problems, size_t max_problems)
      : Node("problem_recorder", lcm), problems_(problems), max_problems_(max_problems) {
    subscribe<map_update_t>(
        "MAP_ESDF", [this](const map_update_t& msg, const MessageInfo&) { mirror_.apply(msg); },
        1000);
    subscribe<planner_status_t>("PLANNER_STATUS", [this](const planner_status_t& msg,
                                                         const MessageInfo&) {
      if (!msg.is_final || msg.iterations == 0 || mirror_.layer() == nullptr ||
          problems_.size() >= max_problems_) {
        return;
      }
      PlanningProblem problem;
      problem.esdf = std::make_shared<const EsdfLayer>(*mirror_.layer());
      problem.ends.start_position = Eigen::Map<const Eigen::Vector3d>(msg.start_position);
      problem.ends.start_velocity = Eigen::Map<const Eigen::Vector3d>(msg.start_velocity);
      problem.ends.start_acceleration = Eigen::Map<const Eigen::Vector3d>(msg.start_acceleration);
      problem.ends.end_position = Eigen::Map<const Eigen::Vector3d>(msg.horizon_goal);
      problem.cycle = msg.cycle;
      problems_.push_back(std::move(problem));
    });
  }

 private:
  MapMirror<EsdfVoxel> mirror_;
  std::vector<PlanningProblem>& problems_;
  size_t max_problems_;
};

constexpr size_t kProblemsPerTrial = 15;

const std::vector<PlanningProblem>& recordedProblems() {
  static const std::vector<PlanningProblem> problems = [] {
    std::vector<PlanningProblem> all;
    for (double density : {0.1, 0.2, 0.3}) {
      RunOptions options;
      options.density = density;
      options.replans = static_cast<int>(kProblemsPerTrial);
      for (int trial = 0; trial < 3; ++trial) {
        std::vector<PlanningProblem> trial_problems;
        runTrial(options, trialWorld(options, trial), trial, [&](lcm::LCM& lcm) {
          return std::make_unique<ProblemRecorder>(lcm, trial_problems, kProblemsPerTrial);
        });
        all.insert(all.end(), trial_problems.begin(), trial_problems.end());
      }
    }
    return all;
  }();
  return problems;
}

// Arg: random restarts allowed (0: one L-BFGS run per problem, the paper's "optimization").
void BM_LocoSolve(benchmark::State& state) {
  const std::vector<PlanningProblem>& problems = recordedProblems();
  local_planner::LocoOptions options;
  options.restarts = static_cast<int>(state.range(0));
  const local_planner::Loco loco(options);
  std::vector<double> ms, iterations;
  int accepted = 0;
  size_t i = 0;
  for (auto _ : state) {
    const PlanningProblem& problem = problems[i++ % problems.size()];
    const local_planner::DistanceField field = local_planner::esdfField(*problem.esdf);
    local_planner::LocoResult result;
    ms.push_back(timeMs([&] {
      result = loco.solve(problem.ends, true, field, static_cast<uint64_t>(problem.cycle));
    }));
    state.SetIterationTime(ms.back() * 1e-3);
    iterations.push_back(result.iterations);
    accepted += result.accepted;
  }
  state.counters["problems"] = static_cast<double>(problems.size());
  state.counters["median_ms"] = median(ms);
  state.counters["p95_ms"] = quantile(ms, 0.95);
  state.counters["median_iterations"] = median(iterations);
  state.counters["p95_iterations"] = quantile(iterations, 0.95);
  state.counters["accepted"] = static_cast<double>(accepted) / static_cast<double>(ms.size());
}
BENCHMARK(BM_LocoSolve)
    ->Arg(0)
    ->Arg(5)
    ->Iterations(3 * 3 * kProblemsPerTrial)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

}  // namespace thicket::bench

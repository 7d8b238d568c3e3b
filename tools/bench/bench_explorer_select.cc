// Intermediate goal selection speed on recorded requests: the stuck cycles of real flights (the
// paper scenario at density 0.3, seeds 0-4, optimization only, so the planner gets stuck where the
// forest blocks it), each with the TSDF and ESDF the explorer would have seen and the cycle's start
// and goal. BM_GoalSelection/<k> runs strategy k of explorer::strategyNames() (the order of the
// docs/benchmark.md table), one request per iteration. Counters: median_ms and p95_ms per
// selection, found (the share of requests answered with a goal), median_gain_evaluations.
// local_exploration runs with P_g = 0, so every selection samples and scores its N candidates (with
// the default P_g = 0.5 half the answers are the global goal at no cost). Target for
// local_exploration: median
// <= 1 ms (the paper: 5.9 ms).
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>
#include <thicket/map_update_t.hpp>
#include <thicket/planner_status_t.hpp>

#include "bench_worlds.h"
#include "thicket/common/map_update.h"
#include "thicket/common/statistics.h"
#include "thicket/explorer/goal_selector.h"
#include "trials.h"

namespace thicket::bench {

namespace {

struct RecordedRequest {
  std::shared_ptr<const TsdfLayer> tsdf;
  std::shared_ptr<const EsdfLayer> esdf;
  explorer::ExplorationRequest request;
  sim::World world;  // for the flight volume
};

// Watches a trial: mirrors both maps like the explorer and, at every stuck cycle, keeps a copy of
// them with the cycle's start and goal.
class RequestRecorder : public Node {
 public:
  RequestRecorder(lcm::LCM& lcm, const sim::World& world, std::vector<RecordedRequest>& requests,
                  size_t max_requests)
      : Node("request_recorder", lcm),
        world_(world),
        requests_(requests),
        max_requests_(max_requests) {
    subscribe<map_update_t>(
        "MAP_TSDF", [this](const map_update_t& msg, const MessageInfo&) { mirror(tsdf_, msg); },
        1000);
    subscribe<map_update_t>(
        "MAP_ESDF", [this](const map_update_t& msg, const MessageInfo&) { mirror(esdf_, msg); },
        1000);
    subscribe<planner_status_t>(
        "PLANNER_STATUS", [this](const planner_status_t& msg, const MessageInfo&) {
          if (msg.state != planner_status_t::STATE_STUCK || tsdf_.layer() == nullptr ||
              esdf_.layer() == nullptr || requests_.size() >= max_requests_) {
            return;
          }
          RecordedRequest recorded;
          recorded.tsdf = std::make_shared<const TsdfLayer>(*tsdf_.layer());
          recorded.esdf = std::make_shared<const EsdfLayer>(*esdf_.layer());
          recorded.request.utime = msg.utime;
          recorded.request.cycle = msg.cycle;
          recorded.request.start = Eigen::Map<const Eigen::Vector3d>(msg.start_position);
          recorded.request.goal = Eigen::Map<const Eigen::Vector3d>(msg.goal);
          recorded.world = world_;
          requests_.push_back(std::move(recorded));
        });
  }

 private:
  // Without an explorer in the graph nobody else asks for TSDF snapshots.
  template <class Voxel>
  void mirror(MapMirror<Voxel>& mirror, const map_update_t& msg) {
    if (mirror.apply(msg).outcome == MapMirror<Voxel>::Outcome::kNeedSnapshot) {
      publish("MAP_REQUEST", mirror.request(msg.utime, name()));
    }
  }

  const sim::World& world_;
  MapMirror<TsdfVoxel> tsdf_;
  MapMirror<EsdfVoxel> esdf_;
  std::vector<RecordedRequest>& requests_;
  size_t max_requests_;
};

constexpr size_t kRequestsPerTrial = 8;
constexpr int kTrials = 5;

const std::vector<RecordedRequest>& recordedRequests() {
  static const std::vector<RecordedRequest> requests = [] {
    std::vector<RecordedRequest> all;
    RunOptions options;
    options.density = 0.3;
    options.replans = 60;
    for (int trial = 0; trial < kTrials; ++trial) {
      const sim::World world = trialWorld(options, trial);
      std::vector<RecordedRequest> trial_requests;
      runTrial(options, world, trial, [&](lcm::LCM& lcm) {
        return std::make_unique<RequestRecorder>(lcm, world, trial_requests, kRequestsPerTrial);
      });
      all.insert(all.end(), trial_requests.begin(), trial_requests.end());
    }
    return all;
  }();
  return requests;
}

// Arg: the index of the strategy in explorer::strategyNames().
void BM_GoalSelection(benchmark::State& state) {
  const std::vector<RecordedRequest>& requests = recordedRequests();
  const std::string& strategy = explorer::strategyNames().at(static_cast<size_t>(state.range(0)));
  state.SetLabel(strategy);
  if (requests.empty()) {
    state.SkipWithError("no stuck cycle was recorded");
    return;
  }
  // One selector per world, as one explorer node per trial.
  std::vector<std::unique_ptr<explorer::GoalSelector>> selectors;
  for (const RecordedRequest& recorded : requests) {
    explorer::ExplorerOptions options;
    options.strategy = strategy;
    options.seed = static_cast<int64_t>(recorded.world.seed);
    options.flight_volume_min = recorded.world.bounds_min;
    options.flight_volume_max = recorded.world.bounds_max;
    options.p_goal = 0;
    selectors.push_back(explorer::makeGoalSelector(options));
  }
  std::vector<double> ms, evaluations;
  int found = 0;
  size_t i = 0;
  for (auto _ : state) {
    const size_t k = i++ % requests.size();
    const RecordedRequest& recorded = requests[k];
    explorer::Proposal proposal;
    ms.push_back(timeMs([&] {
      proposal = selectors[k]->select(recorded.request, {recorded.tsdf.get(), recorded.esdf.get()});
    }));
    state.SetIterationTime(ms.back() * 1e-3);
    evaluations.push_back(static_cast<double>(proposal.gain_evaluations));
    found += proposal.found;
  }
  state.counters["requests"] = static_cast<double>(requests.size());
  state.counters["median_ms"] = median(ms);
  state.counters["p95_ms"] = quantile(ms, 0.95);
  state.counters["found"] = static_cast<double>(found) / static_cast<double>(ms.size());
  state.counters["median_gain_evaluations"] = median(evaluations);
}
BENCHMARK(BM_GoalSelection)
    ->DenseRange(1, static_cast<int>(explorer::strategyNames().size()) - 1)
    ->Iterations(3 * kTrials * kRequestsPerTrial)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

}  // namespace thicket::bench

// The RRT* baselines (rrt_star_optimistic, rrt_star_conservative): OMPL's RRT* grown from the
// stuck start toward the global goal, in the bounding box of the two grown by box_margin and cut to
// the flight volume (a goal outside the flight volume is clamped into it).
//
// Validity. optimistic reads the TSDF: a point is free when the voxel holding it is unknown
// (unallocated, or weight below gain.min_weight) or its distance is at least the clearance; unknown
// space is free. conservative reads the ESDF through esdfFree: unknown space is occupied. Edges are
// checked every rrt_star.check_step (the states OMPL's discrete motion validator checks, the
// resolution given as a fraction of the space's extent; EdgeValidator checks them in order along
// the edge, without OMPL's per-edge queue and std::function, rrt_edges.h), and priced by their
// length (EdgeLengthObjective, the same bits as OMPL's path length). A new node connects to its
// cheapest neighbour with a free edge; OMPL's default sorts the neighbourhood (hundreds of nodes,
// k-nearest RRT*) by cost to find it, which took most of a request's time, so each neighbour
// cheaper than the best so far is checked in neighbour order instead
// (rrt_star.delay_collision_checks: false). Both pick the cheapest neighbour with a free edge, so
// the trees agree (the tests and the benchmark find them identical).
//
// Clearance. Both use treeClearance's policy: min_clearance, relaxed to the start's own clearance
// down to half of it, so a vehicle stuck near an obstacle can still leave; OMPL assumes the start
// valid, and the relaxed clearance is what makes it so. optimistic takes the start's TSDF distance
// (an unknown start counts as min_clearance). A start below half the clearance (or unknown, for
// conservative) gets no tree: we never hand OMPL an invalid start.
//
// Determinism. OMPL seeds every RNG it constructs from a process-global generator, so nothing of
// OMPL's randomness is used: the space's sampler draws uniformly in the bounds from its own
// std::mt19937_64, RRT*'s goal-bias RNG (rng_) is reseeded, both from mixSeed(seed, cycle) and a
// salt; nearest neighbours are an exact linear scan with ties broken by insertion order (GNAT,
// OMPL's default, picks random pivots); informed, rejection and ordered sampling and tree pruning
// stay off (their samplers would not be ours). The space, problem and planner are built fresh per
// request, and the budget is an iteration count, so a request gives bit-identical proposals in any
// process, call order or thread.
//
// Result. RRT* keeps the path to the goal or, failing that, to the tree node closest to it: the
// proposal is that path's states after the start (yaw along velocity). optimistic's path is tracked
// waypoint by waypoint and replanned (a new request) when the planner gets stuck on it;
// conservative proposes the branch toward the tree node closest to the goal.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <ompl/base/PlannerTerminationCondition.h>
#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/ScopedState.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/StateSampler.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/base/terminationconditions/IterationTerminationCondition.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/planners/rrt/RRTstar.h>
#include <ompl/util/Console.h>

#include "motion_neighbors.h"
#include "rrt_edges.h"
#include "strategies.h"
#include "thicket/common/esdf_query.h"
#include "thicket/common/random.h"

namespace thicket::explorer::detail {
namespace {

namespace ob = ompl::base;
namespace og = ompl::geometric;

// Salts of the two streams drawn per request.
constexpr int64_t kSamplerSalt = 1;
constexpr int64_t kGoalBiasSalt = 2;

using RealState = ob::RealVectorStateSpace::StateType;

void fromVector(const Eigen::Vector3d& p, ob::State* state) {
  auto* s = state->as<RealState>();
  for (int i = 0; i < 3; ++i) s->values[i] = p[i];
}

// Uniform in the box [lo, hi] from its own generator. Every sampler the space allocates starts the
// same stream, so it does not matter how many OMPL allocates or in which order.
class SeededBoxSampler final : public ob::StateSampler {
 public:
  SeededBoxSampler(const ob::StateSpace* space, const Eigen::Vector3d& lo,
                   const Eigen::Vector3d& hi, uint64_t seed)
      : ob::StateSampler(space), lo_(lo), hi_(hi), generator_(seed) {}

  void sampleUniform(ob::State* state) override {
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) p[i] = lo_[i] + (hi_[i] - lo_[i]) * unit();
    fromVector(p, state);
  }

  // RRT* does not use these; they draw from the same generator all the same.
  void sampleUniformNear(ob::State* state, const ob::State* near, double distance) override {
    const Eigen::Vector3d c = statePosition(near);
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) p[i] = c[i] + distance * (2 * unit() - 1);
    fromVector(p.cwiseMax(lo_).cwiseMin(hi_), state);
  }
  void sampleGaussian(ob::State* state, const ob::State* mean, double std_dev) override {
    const Eigen::Vector3d c = statePosition(mean);
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) {
      // Box-Muller; 1 - unit() is in (0, 1].
      const double r = std::sqrt(-2 * std::log(1 - unit()));
      p[i] = c[i] + std_dev * r * std::cos(2 * std::numbers::pi * unit());
    }
    fromVector(p.cwiseMax(lo_).cwiseMin(hi_), state);
  }

 private:
  // [0, 1) from the top 53 bits: the same in every standard library, unlike the distributions.
  double unit() { return static_cast<double>(generator_() >> 11) * 0x1.0p-53; }

  Eigen::Vector3d lo_, hi_;
  std::mt19937_64 generator_;
};

// RRT*'s nearest neighbours: an exact linear scan over the motions' positions, ties broken by
// insertion order (motion_neighbors.h).
struct MotionPosition {
  template <typename Motion>
  Eigen::Vector3d operator()(const Motion* motion) const {
    return statePosition(motion->state);
  }
};
template <typename T>
using MotionNeighbors = PointNearestNeighbors<T, MotionPosition>;

// RRT* with its goal-bias RNG seeded, and the tree's size exposed for the reason.
class SeededRrtStar final : public og::RRTstar {
 public:
  SeededRrtStar(const ob::SpaceInformationPtr& si, uint64_t seed) : og::RRTstar(si) {
    rng_.setLocalSeed(static_cast<std::uint_fast32_t>(seed));
  }
  size_t treeSize() const { return nn_ ? nn_->size() : 0; }
};

// OMPL logs each solve at INFO; warnings and errors still show.
void silenceOmplInfo() {
  static std::once_flag once;
  std::call_once(once, [] { ompl::msg::setLogLevel(ompl::msg::LOG_WARN); });
}

std::string format(const char* fmt, auto... args) {
  char text[256];
  std::snprintf(text, sizeof(text), fmt, args...);
  return text;
}

class RrtStarSelector final : public GoalSelector {
 public:
  RrtStarSelector(const ExplorerOptions& options, bool optimistic)
      : options_(options), optimistic_(optimistic) {
    silenceOmplInfo();
  }

  const char* name() const override {
    return optimistic_ ? "rrt_star_optimistic" : "rrt_star_conservative";
  }

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    Proposal proposal;
    if (optimistic_ ? maps.tsdf == nullptr : maps.esdf == nullptr) {
      proposal.reason = "no map";
      proposal.map_missing = true;
      return proposal;
    }
    const RrtStarOptions& o = options_.rrt_star;
    const Eigen::Vector3d& start = request.start;
    if (!start.allFinite() || !inFlightVolume(options_, start)) {
      proposal.reason = "the start is outside the flight volume";
      return proposal;
    }
    if (!request.goal.allFinite()) {
      proposal.reason = "the goal is not finite";
      return proposal;
    }
    const Eigen::Vector3d goal =
        request.goal.cwiseMax(options_.flight_volume_min).cwiseMin(options_.flight_volume_max);
    const std::string clamped = goal != request.goal ? "goal clamped into the flight volume; " : "";

    // The tree's TSDF lookups, mostly in a few blocks along its edges.
    std::optional<VoxelLookup<TsdfVoxel>> tsdf;
    if (optimistic_) tsdf.emplace(*maps.tsdf);
    const std::optional<double> clearance =
        optimistic_ ? tsdfTreeClearance(*tsdf, start) : treeClearance(options_, *maps.esdf, start);
    if (!clearance) {
      proposal.reason = optimistic_
                            ? "the start is inside or too close to an obstacle in the TSDF"
                            : "the start is unknown or too close to an obstacle in the ESDF";
      return proposal;
    }
    const auto free = [&](const Eigen::Vector3d& p) {
      return optimistic_ ? tsdfFree(*tsdf, p, *clearance)
                         : esdfFree(options_, *maps.esdf, p, *clearance);
    };
    if (!free(start)) {  // not expected after the clearance policy, but OMPL must not see it
      proposal.reason = "the start is not free at the tree's clearance";
      return proposal;
    }

    // The box of start and goal grown by the margin, in the flight volume (which holds both).
    const Eigen::Vector3d lo =
        (start.cwiseMin(goal).array() - o.box_margin).matrix().cwiseMax(options_.flight_volume_min);
    const Eigen::Vector3d hi =
        (start.cwiseMax(goal).array() + o.box_margin).matrix().cwiseMin(options_.flight_volume_max);
    auto space = std::make_shared<ob::RealVectorStateSpace>(3);
    ob::RealVectorBounds bounds(3);
    for (int i = 0; i < 3; ++i) {
      bounds.setLow(i, lo[i]);
      bounds.setHigh(i, hi[i]);
    }
    space->setBounds(bounds);
    const double extent = space->getMaximumExtent();
    if (!(extent > 0)) {
      proposal.reason = "no room to grow a tree (the start is the goal and box_margin is 0)";
      return proposal;
    }
    const uint64_t seed = mixSeed(options_.seed, request.cycle);
    const uint64_t sampler_seed = mixSeed(static_cast<int64_t>(seed), kSamplerSalt);
    space->setStateSamplerAllocator([lo, hi, sampler_seed](const ob::StateSpace* s) {
      return std::make_shared<SeededBoxSampler>(s, lo, hi, sampler_seed);
    });

    auto si = std::make_shared<ob::SpaceInformation>(space);
    si->setStateValidityChecker([&](const ob::State* s) { return free(statePosition(s)); });
    si->setMotionValidator(std::make_shared<EdgeValidator<decltype(free)>>(si, free));
    // OMPL wants a fraction in (0, 1); a finer step than asked is only safer.
    si->setStateValidityCheckingResolution(std::clamp(o.check_step / extent, 1e-12, 0.5));
    si->setup();

    auto pdef = std::make_shared<ob::ProblemDefinition>(si);
    ob::ScopedState<> start_state(space), goal_state(space);
    fromVector(start, start_state.get());
    fromVector(goal, goal_state.get());
    pdef->addStartState(start_state);
    pdef->setGoalState(goal_state, o.goal_tolerance);
    pdef->setOptimizationObjective(std::make_shared<EdgeLengthObjective>(si));

    auto planner =
        std::make_shared<SeededRrtStar>(si, mixSeed(static_cast<int64_t>(seed), kGoalBiasSalt));
    planner->setProblemDefinition(pdef);
    planner->setRange(o.range);
    planner->setGoalBias(o.goal_bias);
    // The defaults, stated: these would sample through samplers and RNGs that are not ours.
    planner->setInformedSampling(false);
    planner->setSampleRejection(false);
    planner->setNewStateRejection(false);
    planner->setTreePruning(false);
    planner->setDelayCC(o.delay_collision_checks);
    planner->setNearestNeighbors<MotionNeighbors>();  // sets the planner up
    ob::IterationTerminationCondition iterations(static_cast<unsigned int>(o.iterations));
    planner->solve(iterations);

    const std::string budget =
        format("RRT* %u iterations, %zu nodes", planner->numIterations(), planner->treeSize());
    const auto path = pdef->getSolutionPath();
    if (!path) {
      proposal.reason = clamped + "the tree did not grow from the start (" + budget + ")";
      return proposal;
    }
    const auto& states = path->as<og::PathGeometric>()->getStates();
    const bool exact = pdef->hasExactSolution();
    const Eigen::Vector3d end = statePosition(states.back());
    if (states.size() < 2 || (!exact && !((end - goal).norm() < (start - goal).norm()))) {
      proposal.reason =
          clamped + "no tree node is closer to the goal than the start (" + budget + ")";
      return proposal;
    }
    for (size_t i = 1; i < states.size(); ++i)
      proposal.waypoints.push_back(statePosition(states[i]));
    proposal.found = true;
    proposal.score = path->as<og::PathGeometric>()->length();
    const int n = static_cast<int>(proposal.waypoints.size());
    if (exact) {
      proposal.reason = clamped +
                        format("path to the goal, %d waypoints, %.2f m (", n, proposal.score) +
                        budget + ")";
    } else {
      proposal.reason = clamped +
                        format(
                            "branch to the tree node closest to the goal (%.2f m from it), %d "
                            "waypoints, %.2f m (",
                            (end - goal).norm(), n, proposal.score) +
                        budget + ")";
    }
    return proposal;
  }

 private:
  // The TSDF voxel holding p, or nullptr when it is unknown.
  const TsdfVoxel* knownTsdf(VoxelLookup<TsdfVoxel>& tsdf, const Eigen::Vector3d& p) const {
    const TsdfVoxel* voxel = tsdf.voxelAt(p);
    return voxel != nullptr && voxel->weight >= options_.gain.min_weight ? voxel : nullptr;
  }

  // In the flight volume, and unknown or at least `clearance` from surfaces in the TSDF.
  bool tsdfFree(VoxelLookup<TsdfVoxel>& tsdf, const Eigen::Vector3d& p, double clearance) const {
    if (!inFlightVolume(options_, p)) return false;
    const TsdfVoxel* voxel = knownTsdf(tsdf, p);
    return voxel == nullptr || voxel->distance >= clearance;
  }

  // treeClearance's policy on the TSDF: an unknown start has min_clearance.
  std::optional<double> tsdfTreeClearance(VoxelLookup<TsdfVoxel>& tsdf,
                                          const Eigen::Vector3d& start) const {
    const TsdfVoxel* voxel = knownTsdf(tsdf, start);
    const double distance = voxel == nullptr ? options_.min_clearance : voxel->distance;
    if (!(distance >= 0.5 * options_.min_clearance)) return std::nullopt;
    return std::min(options_.min_clearance, distance);
  }

  ExplorerOptions options_;
  bool optimistic_;
};

}  // namespace

std::unique_ptr<GoalSelector> makeRrtStar(const ExplorerOptions& options, bool optimistic) {
  return std::make_unique<RrtStarSelector>(options, optimistic);
}

}  // namespace thicket::explorer::detail

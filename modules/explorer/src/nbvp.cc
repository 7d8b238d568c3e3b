// nbvp: the receding-horizon next-best-view planner of Bircher et al. (ICRA 2016) as a baseline.
//
// Each request grows an RRT in position and yaw rooted at the start. A new node is drawn uniformly
// in the ball of radius r around the start (drawInBall: one attempt per iteration, max_draws in
// all), steered from the nearest node (by position) to at most nbvp.range, and kept only when the
// edge from that node is free in the ESDF (unknown space occupied) with the tree clearance
// (treeClearance); it gets a uniform random yaw in [-pi, pi). Its gain g is the visible unknown
// fraction of its view (occlusion by ray shooting, every s-th frustum point), and its value is
//   value(node) = value(parent) + g * exp(-lambda * (branch length from the root to the node)),
// the value of the root being 0: the root is the current view, already integrated in the map, and
// its yaw (toward the goal) only closes the tree. The tree grows until it holds initial_nodes
// nodes and its best value beats zero_gain, or max_nodes nodes, or max_draws draws are spent;
// budgets are counts, so answers do not depend on the machine. The answer is the first edge of the
// branch to the best node: the root's child on it, with that child's yaw. The local planner flies
// it and then returns to the global goal by itself (NBVP "alternates with the goal"), so the goal
// is never proposed here.
//
// Our choices:
// - The gain is the visible unknown fraction rather than Bircher's visible unknown volume: every
//   view checks the same number of frustum points (the same grid at the same stride), so the
//   fraction is the count times a constant and ranks branches exactly as the volume would; it keeps
//   zero_gain and the scores on the same [0, 1]-per-node scale as local_exploration's gain.
// - The branch length is the length along the tree (the sum of the edges from the root), as in
//   Bircher's implementation, not the straight-line distance.
// - The tree lives in the ball of radius r around the start (Bircher: a box around the vehicle),
//   in observed free space with the clearance the other ESDF strategies keep.
// - Re-seeding (Bircher: the remainder of the previous best branch is reinserted in the new tree):
//   after each request the selector remembers the best branch past its first edge (nothing when
//   nothing was found). The next request inserts those nodes first, in order from the root, each
//   steered from its nearest tree node to at most nbvp.range, kept only when the edge is free and
//   the node lies within r of the new start, with its remembered yaw and a freshly computed gain;
//   they count as nodes and gain evaluations but not as draws. The memory is used only by a request
//   of a later cycle than the one that made it, so asking the same cycle again gives the same
//   answer, and a selector that starts over (a replay, a new trial) forgets the old branch. The
//   answers are therefore deterministic given the sequence of requests and maps the selector has
//   answered; a fresh selector answers a request as if it were the first.
// - Draws are seeded from mixSeed(seed, cycle), like the other strategies.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "strategies.h"
#include "thicket/common/random.h"

namespace thicket::explorer::detail {

namespace {

// A node of the tree: a view (position and yaw) with its branch from the root.
struct TreeNode {
  Eigen::Vector3d position;
  double yaw = 0;
  int parent = -1;    // index in the tree; -1 for the root
  double length = 0;  // branch length from the root [m]
  double value = 0;   // accumulated discounted gain of the branch from the root
  int depth = 0;      // edges from the root
};

// A node of a previous best branch, to be reinserted.
struct Remembered {
  Eigen::Vector3d position;
  double yaw = 0;
};

class NbvpSelector final : public GoalSelector {
 public:
  explicit NbvpSelector(const ExplorerOptions& options) : options_(options) {}
  const char* name() const override { return "nbvp"; }
  void prepare(double voxel_size) override { gains_.forVoxelSize(voxel_size); }

  Proposal select(const ExplorationRequest& request, const MapView& maps) override {
    // The memory of the previous request, if it may be used, and forgotten in any case: this
    // request leaves its own.
    std::vector<Remembered> seeds;
    if (memory_cycle_ && request.cycle > *memory_cycle_) seeds = std::move(memory_);
    memory_.clear();
    memory_cycle_ = request.cycle;

    Proposal proposal;
    if (maps.tsdf == nullptr || maps.esdf == nullptr) {
      proposal.reason = "no map";
      proposal.map_missing = true;
      return proposal;
    }
    const std::optional<double> clearance = treeClearance(options_, *maps.esdf, request.start);
    if (!clearance) {
      proposal.reason =
          "the start is unknown in the ESDF, outside the flight volume or too close to an "
          "obstacle";
      return proposal;
    }
    Tree tree(options_, maps, gains_.forVoxelSize(maps.tsdf->voxelSize()), request, *clearance);

    const NbvpOptions& o = options_.nbvp;
    int reseeded = 0;
    for (const Remembered& seed : seeds) {
      if (tree.nodes() >= o.max_nodes) break;
      reseeded += tree.extend(seed.position, seed.yaw);
    }

    Rng rng(mixSeed(options_.seed, request.cycle));
    std::uniform_real_distribution<double> yaw_draw(-std::numbers::pi, std::numbers::pi);
    int draws = 0;
    while (draws < options_.max_draws && tree.nodes() < o.max_nodes &&
           !(tree.nodes() >= o.initial_nodes && tree.bestValue() > o.zero_gain)) {
      ++draws;
      const auto target = drawInBall(rng, request.start, options_.radius, options_, 1);
      if (!target) continue;
      // The yaw is drawn for every point in the ball, kept or not, so that the stream of draws
      // does not depend on which edges are free.
      tree.extend(*target, yaw_draw(rng));
    }
    proposal.gain_evaluations = tree.nodes();

    char text[200];
    if (!(tree.bestValue() > o.zero_gain)) {
      std::snprintf(text, sizeof(text),
                    "nothing to explore: best branch value %.4f after %d nodes (%d re-seeded) "
                    "in %d draws",
                    tree.bestValue(), tree.nodes(), reseeded, draws);
      proposal.reason = text;
      return proposal;
    }
    const std::vector<int> branch = tree.branchToBest();  // root's child first
    const TreeNode& first = tree.node(branch.front());
    const TreeNode& best = tree.node(branch.back());
    proposal.found = true;
    proposal.waypoints = {first.position};
    proposal.yaws = {first.yaw};
    proposal.score = best.value;
    std::snprintf(text, sizeof(text),
                  "first edge (%.2f m) of the best of %d nodes (%d re-seeded): value %.4f, "
                  "branch of %d edges, %.2f m",
                  first.length, tree.nodes(), reseeded, best.value, best.depth, best.length);
    proposal.reason = text;
    for (size_t i = 1; i < branch.size(); ++i) {
      const TreeNode& n = tree.node(branch[i]);
      memory_.push_back({n.position, n.yaw});
    }
    return proposal;
  }

 private:
  // One request's tree.
  class Tree {
   public:
    Tree(const ExplorerOptions& options, const MapView& maps, const ExplorationGain& gain,
         const ExplorationRequest& request, double clearance)
        : options_(options), maps_(maps), gain_(gain), clearance_(clearance) {
      const Eigen::Vector3d to_goal = request.goal - request.start;
      TreeNode root;
      root.position = request.start;
      root.yaw = to_goal.head<2>().norm() > 0 ? std::atan2(to_goal.y(), to_goal.x()) : 0.0;
      nodes_.push_back(root);
    }

    // Nodes, the root excluded.
    int nodes() const { return static_cast<int>(nodes_.size()) - 1; }
    const TreeNode& node(int i) const { return nodes_[static_cast<size_t>(i)]; }
    double bestValue() const { return nodes_[static_cast<size_t>(best_)].value; }

    // Steers from the node nearest `target` toward it and adds the node with `yaw` when the edge
    // is free and the node lies within r of the root. Whether a node was added.
    bool extend(const Eigen::Vector3d& target, double yaw) {
      const TreeNode& parent = nodes_[static_cast<size_t>(nearest(target))];
      const Eigen::Vector3d step = target - parent.position;
      const double distance = step.norm();
      if (!(distance > 0)) return false;
      const double range = options_.nbvp.range;
      const Eigen::Vector3d position =
          distance > range ? Eigen::Vector3d(parent.position + step * (range / distance)) : target;
      if ((position - nodes_.front().position).norm() > options_.radius) return false;
      if (!esdfSegmentFree(options_, *maps_.esdf, parent.position, position, clearance_,
                           options_.nbvp.check_step)) {
        return false;
      }
      const Gain g = gain_.visibleUnknownFraction(
          *maps_.tsdf, ExplorationGain::cameraAt(position, yaw), options_.subsample);
      TreeNode n;
      n.position = position;
      n.yaw = yaw;
      n.parent = static_cast<int>(&parent - nodes_.data());
      n.length = parent.length + std::min(distance, range);
      n.depth = parent.depth + 1;
      n.value = parent.value + g.unknown_fraction * std::exp(-options_.nbvp.lambda * n.length);
      nodes_.push_back(n);  // `parent` dangles from here on
      if (nodes_.back().value > bestValue()) best_ = static_cast<int>(nodes_.size()) - 1;
      return true;
    }

    // The nodes from the root's child to the best node (empty when the root is best).
    std::vector<int> branchToBest() const {
      std::vector<int> branch;
      for (int i = best_; i > 0; i = nodes_[static_cast<size_t>(i)].parent) branch.push_back(i);
      std::reverse(branch.begin(), branch.end());
      return branch;
    }

   private:
    // The first of the nodes nearest to p.
    int nearest(const Eigen::Vector3d& p) const {
      int best = 0;
      double best_d2 = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < nodes_.size(); ++i) {
        const double d2 = (nodes_[i].position - p).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best = static_cast<int>(i);
        }
      }
      return best;
    }

    const ExplorerOptions& options_;
    const MapView& maps_;
    const ExplorationGain& gain_;
    double clearance_;
    std::vector<TreeNode> nodes_;
    int best_ = 0;  // the root until a node beats its value 0
  };

  ExplorerOptions options_;
  GainCache gains_{options_.gain};
  // The remainder of the previous request's best branch past its first edge, and that request's
  // cycle.
  std::vector<Remembered> memory_;
  std::optional<int64_t> memory_cycle_;
};

}  // namespace

std::unique_ptr<GoalSelector> makeNbvp(const ExplorerOptions& options) {
  return std::make_unique<NbvpSelector>(options);
}

}  // namespace thicket::explorer::detail

// Intermediate goal selection (docs/design.md §1, exploration): when the local planner is stuck, a
// strategy proposes where to go next. Strategies are selected by name and seeded from the
// configuration and the planner cycle they answer, so the same request gives the same proposal in
// any process layout (nbvp also re-seeds its tree from its previous answer, so its answers follow
// from the sequence of requests, as in a replay).
//
//   none                   proposes nothing (the optimization-only baseline)
//   random                 a uniformly random point in the sphere of radius r around the start
//   rrt_star_optimistic    OMPL RRT* toward the global goal on the TSDF, unknown space free: the
//                          path (to the goal, or to the tree node closest to it), waypoint by
//                          waypoint
//   rrt_star_conservative  OMPL RRT* toward the global goal on the ESDF, unknown space occupied:
//                          the branch to the tree node closest to the goal
//   nbvp                   receding-horizon next-best-view (Bircher et al. 2016): an RRT in
//                          position and yaw in observed free space, each node's gain the visible
//                          unknown fraction decayed by exp(-lambda * branch length), summed along
//                          the branch; the first edge of the best branch
//   local_exploration  the paper's method: with probability P_g the global goal; otherwise N points
//                      sampled in observed free space within r of the start, each facing away from
//                      the start, scored R = w_e l + w_g (d_g - ||g - x||) / d_g with l the unknown
//                      fraction of its view (every s-th frustum voxel) and d_g = ||g - x_s|| + r
//   frontier_memory    beyond the paper: the goal along a verified path when it is near and
//                      reachable, else the best frontier viewpoint (facing its cluster) along a
//                      verified path, else back home to a place with frontiers; it remembers the
//                      places flown and the targets that failed (frontier_memory.cc)
//
// look_around (any strategy, with fixed_yaw) answers the first stuck request at each place with a
// turn in place toward the heading that sees the most unknown space (weighted toward the goal),
// before the strategy is asked, and looks elsewhere when the strategy then finds nothing there.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/params.h"
#include "thicket/common/voxel_layer.h"
#include "thicket/explorer/gain.h"

namespace thicket::explorer {

/// What the stuck planner asks.
struct ExplorationRequest {
  int64_t utime = 0;                                ///< the stuck cycle's time [µs]
  int64_t cycle = 0;                                ///< the stuck cycle
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  ///< where the vehicle plans from [m]
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();   ///< the goal it is stuck on [m]
};

/// The maps a strategy reads; either may be null before the first snapshot.
struct MapView {
  const TsdfLayer* tsdf = nullptr;
  const EsdfLayer* esdf = nullptr;
};

/// A strategy's answer.
struct Proposal {
  bool found = false;
  std::vector<Eigen::Vector3d> waypoints;  ///< tracked in order
  std::vector<double> yaws;                ///< one per waypoint [rad]; empty: along velocity
  double score = 0;                        ///< the strategy's score (debugging)
  std::string reason;                      ///< why nothing was found, or how it was chosen
  bool map_missing = false;                ///< nothing found because the strategy has no map
  int64_t gain_evaluations = 0;
};

/// Look-around: the first stuck request at each place is answered with a look, a waypoint at the
/// start with the heading whose view has the most visible unknown space (times 1 toward the goal
/// down to 1/3 away from it); later requests there go to the strategy, and when it finds nothing
/// the best heading not yet looked at from there is looked at. Needs fixed_yaw (a look without a
/// yaw is no goal).
struct LookAroundOptions {
  bool enabled = false;
  double radius = 1.0;    ///< a place is where a look was answered, within this [m]
  int headings = 8;       ///< headings compared, evenly spaced
  double min_gain = 0.1;  ///< a view with less visible unknown is not worth a look
  /// The look's gains check every subsample-th frustum voxel: a ranking of a few headings needs
  /// far fewer than the strategies' gains (E5: stride 100 is within 1.3 % at p95).
  int subsample = 100;

  void declare(Params& p);
};

/// The RRT* baselines. Budgets are iterations, so answers are deterministic.
struct RrtStarOptions {
  int iterations = 1500;        ///< RRT* iterations per request
  double range = 1.5;           ///< longest tree edge [m]
  double goal_bias = 0.05;      ///< probability of sampling the goal
  double goal_tolerance = 0.3;  ///< a node this close to the goal reaches it [m]
  double check_step = 0.1;      ///< edges are checked for collisions every this [m]
  /// The tree grows in the bounding box of start and goal grown by this, inside the flight volume.
  double box_margin = 5.0;
  /// OMPL's delayCC: a new node sorts its neighbours by cost and checks their edges in that order
  /// until one is free; without, it checks, in neighbour order, each neighbour cheaper than the
  /// best free one so far. Both connect it to its cheapest neighbour with a free edge (they could
  /// differ only on exactly equal costs); without is faster where edges are cheap to check, as
  /// here, since sorting a neighbourhood of hundreds (k-nearest RRT*) then dominates a request.
  bool delay_collision_checks = false;

  void declare(Params& p);
};

/// The next-best-view baseline. Budgets are node counts, so answers are deterministic.
struct NbvpOptions {
  int initial_nodes = 15;   ///< N_T: the tree grows at least this many nodes ...
  int max_nodes = 200;      ///< ... and at most this many, until a branch's value beats zero_gain
  double range = 1.0;       ///< longest tree edge [m]
  double lambda = 0.5;      ///< the gain of a node decays as exp(-lambda * branch length) [1/m]
  double zero_gain = 0.0;   ///< a best branch worth no more than this: nothing left to explore
  double check_step = 0.1;  ///< edges are checked for collisions every this [m]

  void declare(Params& p);
};

/// frontier_memory (frontier_memory.cc): frontier viewpoints reached along verified paths, with a
/// memory of the places flown and of the targets that failed.
struct FrontierMemoryOptions {
  double radius = 6.0;        ///< frontiers and paths in a box of this half-width [m]
  double grid = 0.4;          ///< the path search's cell [m]
  double cluster_size = 1.0;  ///< frontier voxels are clustered in cells of this [m]
  int min_frontier = 8;       ///< a cluster has at least this many frontier voxels
  bool layers = true;         ///< search and look up to `climb` above and below the start
  double climb = 3.0;         ///< [m]
  bool memory = true;         ///< remember places, failed targets and the committed one
  double progress = 2.0;      ///< a path toward the goal must end this much nearer it [m]
  double w_goal = 2.0;        ///< weight of the cluster's distance to the goal
  double w_climb = 1.0;       ///< extra cost per metre climbed
  /// Paths prefer this much clearance above min_clearance [m]: a step into a cell with less costs
  /// up to 1 + w_comfort times its length, and shortcuts keep the clearance of what they replace.
  double comfort = 0.2;
  double w_comfort = 1.0;
  double w_altitude = 0.3;  ///< weight of the viewpoint's height difference to the goal
  double w_size = 1.0;      ///< weight of the cluster's size
  double hysteresis = 1.0;  ///< the committed target stands unless another scores this better
  /// With layers: when no verified path makes progress, first climb to the reached cell (0.8 m or
  /// more above the start, within 3 m of it) whose view toward the goal holds the most unknown
  /// space, if at least this fraction; 0: never.
  double climb_look = 0.3;
  int tabu_attempts = 2;     ///< a target asked again from its request's place this often ...
  double tabu_radius = 1.5;  ///< ... is not proposed again within this [m]

  void declare(Params& p);
};

struct ExplorerOptions {
  /// One of strategyNames().
  std::string strategy = "local_exploration";
  int64_t seed = 0;     ///< draws are seeded from this and the cycle
  double radius = 5.0;  ///< r: candidates lie within this of the start [m]
  int candidates = 15;  ///< N
  int subsample = 20;   ///< s: the gain checks every s-th frustum voxel
  double w_e = 1.0;     ///< weight of the exploration gain
  double w_g = 0.5;     ///< weight of the progress toward the goal
  double p_goal = 0.5;  ///< P_g: probability of proposing the global goal
  /// Candidates must be this far from obstacles in the ESDF, so the planner can end there, and
  /// the RRT* and NBVP trees keep it: the planner's acceptance, robot radius + clearance margin
  /// (local_planner's LocoOptions) [m].
  double min_clearance = 0.62;
  /// local_exploration: candidates must be reachable from the start along a straight line that
  /// keeps the clearance RRT* and NBVP trees keep (treeClearance).
  bool reachable = false;
  /// Send each proposal's yaws (YAW_FIXED): the planner flies the vehicle to each waypoint facing
  /// its yaw and turns there. Off: the vehicle faces along its velocity (the paper).
  bool fixed_yaw = false;
  int max_draws = 1000;  ///< random draws per request before giving up on finding N candidates
  Eigen::Vector3d flight_volume_min = Eigen::Vector3d(-1000, -1000, 0.5);
  Eigen::Vector3d flight_volume_max = Eigen::Vector3d(1000, 1000, 100);
  GainOptions gain;
  LookAroundOptions look_around;
  RrtStarOptions rrt_star;
  NbvpOptions nbvp;
  FrontierMemoryOptions frontier_memory;

  void declare(Params& p);
};

/// A goal-selection strategy.
class GoalSelector {
 public:
  virtual ~GoalSelector() = default;
  virtual const char* name() const = 0;
  virtual Proposal select(const ExplorationRequest& request, const MapView& maps) = 0;
  /// Builds what selection needs for maps of this voxel size (the gain's frustum tables), so that
  /// the first request does not pay for it. Optional: select builds it when it is missing.
  virtual void prepare(double /*voxel_size*/) {}
};

/// The strategy options.strategy names. Throws std::invalid_argument on an unknown name or bad
/// options.
std::unique_ptr<GoalSelector> makeGoalSelector(const ExplorerOptions& options);

/// The strategies makeGoalSelector knows.
const std::vector<std::string>& strategyNames();

}  // namespace thicket::explorer

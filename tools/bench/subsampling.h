// Experiment E5 of the benchmark (docs/benchmark.md): the error and the speed-up of the exploration
// gain (explorer/gain.h, the unknown fraction of the camera frustum) when only every stride-th
// frustum point is checked, on maps the real graph flew. The real graph (local_exploration) flies
// `maps` trials with a passive observer that mirrors the mapper's TSDF; camera poses are then
// drawn near the flown paths and each pose's gain is evaluated at every stride, stride 1 (the
// exact gain) always among them. Writes e5_subsampling.csv:
//   fraction,stride,poses,mean_abs_error,p95_abs_error,max_abs_error,median_us,speedup
// one row per fraction (fraction = 1/stride, the share of frustum points checked; the error of a
// pose is |gain(stride) - gain(1)|; median_us the median wall time of one evaluation [µs];
// speedup = median_us at stride 1 / median_us at this stride). Everything but the two time
// columns is the same at any --jobs.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/expected.h"
#include "thicket/common/geometry.h"
#include "thicket/common/voxel_layer.h"
#include "thicket/sim/vehicle.h"
#include "thicket/sim/world.h"

namespace thicket::bench {

/// What `thicket-bench subsampling` was asked for.
struct SubsamplingOptions {
  int maps = 4;      ///< trials flown for their maps, trial i on the world of seed_base + i
  int poses = 1000;  ///< camera poses, spread evenly over the maps
  std::vector<double> fractions = {0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0};
  std::string scenario = "forest50";
  double density = 0.2;
  int64_t seed_base = 0;   ///< also seeds the poses
  int replans = 120;       ///< the replan limit of each flight
  int jobs = 1;            ///< flights run on this many threads
  std::string worlds_dir;  ///< empty: the source tree's config/worlds
  std::string out_dir;     ///< where e5_subsampling.csv goes
  std::string help;        ///< the --help text, when it was asked
};

/// One row of e5_subsampling.csv.
struct SubsamplingRow {
  double fraction = 0;  ///< 1 / stride
  int stride = 1;
  int poses = 0;
  double mean_abs_error = 0;
  double p95_abs_error = 0;
  double max_abs_error = 0;
  double median_us = 0;  ///< wall time of one evaluation (measured, not deterministic)
  double speedup = 0;    ///< median_us at stride 1 / median_us (measured)
};

/// The stride that checks `fraction` of the frustum points: round(1 / fraction).
int strideOfFraction(double fraction);

/// Why `options` cannot run (a message for the user), or nothing.
std::optional<std::string> checkSubsamplingOptions(const SubsamplingOptions& options);

/// Parses the flags after "subsampling"; the error is a message for the user (exit status 2).
Expected<SubsamplingOptions> parseSubsamplingOptions(const std::vector<std::string>& args);

/// A map the real graph flew: the mapper's TSDF at the end of the trial and the executed path.
struct FlownMap {
  uint64_t seed = 0;
  std::string end_reason;  ///< the simulator's
  std::shared_ptr<const TsdfLayer> tsdf;
  std::vector<sim::PathSample> path;
  Eigen::Vector3d bounds_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d bounds_max = Eigen::Vector3d::Zero();
};

/// Flies trial `map` of `options` (method local_exploration, world seed seed_base + map) and
/// keeps the TSDF its mapper published on MAP_TSDF. The error says why there is no map.
Expected<FlownMap> flyMap(const SubsamplingOptions& options, int map);

/// A camera pose (optical frame) on one of the maps.
struct GainPose {
  int map = 0;
  Pose world_T_camera;
};

/// `count` camera poses drawn with a generator seeded from `seed`: pose n on map n % maps.size(),
/// at a random sample of that map's path moved up to 1 m sideways (across the flown heading) and
/// 0.5 m up or down, facing any way, redrawn until inside the world bounds.
std::vector<GainPose> drawGainPoses(const std::vector<FlownMap>& maps, int count, uint64_t seed);

/// The rows of `fractions` (sorted by fraction) over `poses` on `maps` (indexed by
/// GainPose::map); stride 1 is evaluated whether it is listed or not. Each pose is evaluated at
/// every stride in turn, starting at a different stride for each pose, so that machine load and
/// warm caches affect every stride alike. The error names a bad fraction or pose.
Expected<std::vector<SubsamplingRow>> measureSubsampling(const std::vector<const TsdfLayer*>& maps,
                                                         const std::vector<GainPose>& poses,
                                                         const std::vector<double>& fractions);

/// E5 as configured: flies the maps, draws the poses, measures and writes
/// out_dir/e5_subsampling.csv. Progress goes to stderr. The error says what failed.
Expected<std::vector<SubsamplingRow>> runSubsampling(const SubsamplingOptions& options);

/// `thicket-bench subsampling ARGS`: runs E5 and prints the table. Returns the exit status: 0 on
/// success, 1 when a flight or the output failed, 2 for bad flags.
int subsamplingCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

// thicket-bench clearance: how much clearance the mapper's ESDF promises that the world does not
// have, on maps built along flown paths. The planner accepts a trajectory when every sample's
// interpolated ESDF distance is at least robot radius + clearance margin; the margin is only safe
// if it covers the worst overestimate (ESDF distance − true distance) the map ever makes where the
// planner reads it. This measures that overestimate, so the margin can be derived from it.
//
// The real graph (local_exploration, the shipped options) flies each world once; the frames it saw
// (the vehicle's pose at every replan period) are then rendered again and mapped afresh by the
// mapper core under every configuration: voxel size × depth noise × mapping variant. After each
// frame, within the planning horizon of the vehicle and the flight volume (the world's bounds
// shrunk by the robot radius), where the true distance (the analytic ground truth) is at most robot
// radius + band:
//   - voxels: every voxel in free space observed by the TSDF (weight > 0) and flagged observed in
//     the ESDF: the error is its ESDF distance − the true distance at its centre;
//   - points: seeded random points in free space (the same for every configuration) where the
//     interpolated ESDF is known and the 8 voxels around them were observed by the TSDF (the
//     take-off sphere's free space is assumed, not mapped): the error is the interpolated distance
//     − the true distance, what the planner's acceptance test reads. Its maximum B bounds the
//     overestimate: a sample in collision (true distance < robot radius) reads less than robot
//     radius + B;
//   - margin: of those points, the ones in collision: interpolated distance − robot radius. Its
//     maximum M <= B is the smallest acceptance margin that refuses every one of them;
//   - under: points up to 0.3 m beyond the robot radius: true distance − interpolated distance,
//     how much narrower the map makes the passages the planner has to find.
// Writes DIR/clearance.csv (one row per configuration) and prints the table; the worst point of
// each configuration is named (world, frame, position) so that it can be looked at.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/expected.h"
#include "thicket/mapper/mapper.h"

namespace thicket::bench {

/// A mapping variant: a name and what it changes in the mapper's options.
struct MappingVariant {
  std::string name;
  std::string description;
  std::function<void(mapper::MapperOptions&)> apply;
};
/// The variants `--variants` accepts, in their fixed order.
const std::vector<MappingVariant>& mappingVariants();

/// What `thicket-bench clearance` was asked for.
struct ClearanceOptions {
  /// Flights as "scenario:density"; each flies `worlds` worlds (seeds seed_base + i).
  std::vector<std::string> flights = {"paper:0.3", "eth:0.3", "forest50:0.2"};
  int worlds = 2;
  int64_t seed_base = 0;
  int replans = 60;  ///< the replan limit of each flight
  std::vector<double> voxel_sizes = {0.2, 0.1};
  /// Depth noise sigma at 1 m of the re-rendered frames (sigma = this · z²) [1/m]; 0: ideal.
  std::vector<double> noises = {0.0, 0.005};
  std::vector<std::string> variants;  ///< empty: every variant
  double horizon = 3.0;               ///< r_p: voxels and points this close to the vehicle [m]
  double robot_radius = 0.5;          ///< [m]
  /// Only voxels and points at most robot_radius + band from an obstacle count. With band 0 that
  /// is where a sample is in collision, which is what the margin must refuse; farther out the
  /// ESDF's overestimate grows with the distance (its paths between sites) but cannot make the
  /// planner accept a collision [m].
  double band = 0.0;
  int points_per_frame = 2000;
  int jobs = 1;
  std::string worlds_dir;  ///< empty: the source tree's config/worlds
  std::string out_dir;
  std::string help;  ///< the --help text, when it was asked
};

/// The distribution of one kind of error of one configuration [m].
struct ErrorSummary {
  int64_t count = 0;
  double mean = 0;
  double p99 = 0;
  double p999 = 0;
  double max = 0;
  std::string worst;  ///< where the maximum is: "paper d0.3 s1 frame 12 (x, y, z): esdf E true T"
};

/// One row of clearance.csv.
struct ClearanceRow {
  std::string scenario;
  double density = 0;
  double voxel_size = 0;
  double noise = 0;
  std::string variant;
  int flights = 0;
  int frames = 0;
  ErrorSummary voxels;
  ErrorSummary points;
  /// The points in collision (true distance < robot_radius): interpolated ESDF − robot_radius. Its
  /// maximum is the smallest clearance margin that refuses every one of them.
  ErrorSummary margin;
  /// Points in free space up to 0.3 m beyond the robot radius, where passages are decided: true
  /// distance − interpolated ESDF. What the map reads too low there narrows every gap.
  ErrorSummary under;
};

Expected<ClearanceOptions> parseClearanceOptions(const std::vector<std::string>& args);

/// Flies, maps and measures; one row per (flight scenario, voxel size, noise, variant) in that
/// order. Deterministic at any --jobs. Throws std::runtime_error when a flight cannot run.
std::vector<ClearanceRow> measureClearance(const ClearanceOptions& options);

/// `thicket-bench clearance ARGS`: exit status 0, 1 when something could not run or be written,
/// 2 for bad flags.
int clearanceCommand(const std::vector<std::string>& args);

}  // namespace thicket::bench

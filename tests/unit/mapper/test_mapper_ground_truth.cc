// The whole mapping pipeline against the simulator's ground truth: depth frames rendered along a
// flight through forest50 go through the Mapper (pose pairing, TSDF, incremental ESDF); the ESDF
// in observed space is compared with the true distance to the nearest obstacle.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "forest_views.h"
#include "thicket/mapper/mapper.h"

namespace thicket::mapper {
namespace {

double mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

double percentile(std::vector<double> values, double fraction) {
  const auto nth = values.begin() + static_cast<ptrdiff_t>(fraction * (values.size() - 1));
  std::nth_element(values.begin(), nth, values.end());
  return *nth;
}

// The ESDF as the planner uses it: after each frame of a flight, the voxels the TSDF observed
// within the planning horizon (3 m) of the vehicle, compared with the true distance (clamped to
// max_distance, where the ESDF saturates). Errors in voxels.
struct EsdfErrors {
  std::vector<double> error;  // esdf - truth, every voxel
  std::vector<double> near;   // |esdf - truth| where the true distance is within 0.5 m
};

EsdfErrors flyAndCompare(int views, bool normal_distances = false) {
  const sim::GroundTruth truth(forest());
  MapperOptions options;
  options.tsdf.normal_distances = normal_distances;
  Mapper mapper{options};
  const double vs = mapper.options().voxel_size;
  const double max_distance = mapper.options().esdf.max_distance;
  const double horizon = 3.0;
  EsdfErrors errors;
  std::vector<MapRevisionUpdate> updates;
  for (const Frame& frame : forestFrames(views)) {
    EXPECT_FALSE(mapper.addPose(frame.image.utime, frame.world_T_body).has_value());
    EXPECT_EQ(mapper.addFrame(frame.image).status, FrameOutcome::Status::kPending);
    for (const FrameOutcome& outcome : mapper.integrateReady(updates)) {
      EXPECT_EQ(outcome.status, FrameOutcome::Status::kIntegrated) << outcome.reason;
    }
    const Eigen::Vector3d& position = frame.world_T_body.position;
    const EsdfLayer& esdf = mapper.esdf();
    for (const BlockIndex& b : esdf.blockIndices()) {
      const auto& voxels = esdf.block(b)->voxels;
      for (int i = 0; i < kVoxelsPerBlock; ++i) {
        const VoxelIndex v = voxelOfBlock(b, i);
        const Eigen::Vector3d c = esdf.voxelCenter(v);
        if ((c - position).norm() > horizon) continue;
        const TsdfVoxel* observed = mapper.tsdf().voxel(v);
        if (observed == nullptr || observed->weight <= 0) continue;
        EXPECT_TRUE(voxels[i].observed);
        const double d = std::clamp(truth.distance(c), -max_distance, max_distance);
        const double error = (voxels[i].distance - d) / vs;
        errors.error.push_back(error);
        if (std::abs(d) <= 0.5) errors.near.push_back(std::abs(error));
      }
    }
  }
  EXPECT_EQ(mapper.revision(), views);
  return errors;
}

// Near surfaces the error is that of the TSDF and of distances along the 26-neighbour graph.
// Elsewhere the ESDF may be smaller than the truth (unknown space near the vehicle is occupied),
// but never much larger: that would promise clearance that is not there.
TEST(MapperGroundTruth, EsdfWithinThePlanningHorizonMatchesTrueDistances) {
  const EsdfErrors errors = flyAndCompare(15);
  std::vector<double> magnitude;
  for (double e : errors.error) magnitude.push_back(std::abs(e));
  const double near_mean = mean(errors.near);
  const double near_p95 = percentile(errors.near, 0.95);
  const double excess_p95 = percentile(errors.error, 0.95);
  const double excess_max = percentile(errors.error, 1.0);
  std::printf(
      "ESDF within 3 m of the vehicle over 15 views, %zu voxel samples: |error| mean %.3f, p95 "
      "%.3f voxels; within 0.5 m of a surface (%zu): mean %.3f, p95 %.3f; esdf - truth: p95 "
      "%.3f, max %.3f voxels\n",
      errors.error.size(), mean(magnitude), percentile(magnitude, 0.95), errors.near.size(),
      near_mean, near_p95, excess_p95, excess_max);
  EXPECT_GT(errors.near.size(), 20000u);
  EXPECT_LT(near_mean, 0.75);
  EXPECT_LT(near_p95, 2.0);
  EXPECT_LT(excess_p95, 1.0);
  EXPECT_LT(excess_max, 2.0);
}

// Distances along the surface normal instead of the line of sight: the ESDF overstates the true
// distance less (the slant of cylinder flanks no longer inflates it), near surfaces it is closer
// to the truth, and it stays as bounded as before.
TEST(MapperGroundTruth, NormalDistancesOverstateLessThanLineOfSightDistances) {
  const EsdfErrors line_of_sight = flyAndCompare(15, false);
  const EsdfErrors normal = flyAndCompare(15, true);
  const double excess_los = percentile(line_of_sight.error, 0.95);
  const double excess_normal = percentile(normal.error, 0.95);
  std::printf(
      "esdf - truth p95: line of sight %.3f, normal %.3f voxels; near-surface |error| "
      "mean: %.3f, %.3f voxels\n",
      excess_los, excess_normal, mean(line_of_sight.near), mean(normal.near));
  EXPECT_LT(excess_normal, excess_los - 0.1);
  EXPECT_LT(mean(normal.near), mean(line_of_sight.near));
  EXPECT_LT(percentile(normal.error, 1.0), 2.0);
}

}  // namespace
}  // namespace thicket::mapper

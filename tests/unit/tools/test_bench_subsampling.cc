// Experiment E5 (tools/bench/subsampling.h): the mirrored TSDF follows the flown mission, the
// poses lie near the flown path, the subsampled gain matches the analytic unknown fraction of a
// hand-built map, the rows aggregate the per-pose errors exactly and do not depend on --jobs,
// and `thicket-bench subsampling` writes the contract's CSV and refuses bad flags.
#include "subsampling.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli.h"
#include "temp_dir_test.h"
#include "thicket/common/statistics.h"
#include "thicket/explorer/gain.h"
#include "thicket/mapper/mapper.h"
#include "trials.h"

namespace thicket::bench {
namespace {

using std::numbers::pi;

// The voxel size of the synthetic maps below.
constexpr double kVoxel = 0.2;
const char* const kHeader =
    "fraction,stride,poses,mean_abs_error,p95_abs_error,max_abs_error,median_us,speedup";

// A short forest50 flight: enough to map some forest, quick enough for a unit test.
SubsamplingOptions shortFlights(int maps, int poses) {
  SubsamplingOptions options;
  options.maps = maps;
  options.poses = poses;
  options.replans = 12;
  options.fractions = {0.02, 0.05, 0.25, 1.0};
  return options;
}

const FlownMap& flownMap() {
  static const FlownMap map = [] {
    Expected<FlownMap> flown = flyMap(shortFlights(1, 60), 0);
    if (!flown) throw std::runtime_error(flown.error());
    return std::move(*flown);
  }();
  return map;
}

bool observed(const TsdfLayer& tsdf, const Eigen::Vector3d& p) {
  const TsdfVoxel* voxel = tsdf.voxel(tsdf.voxelIndex(p));
  return voxel != nullptr && voxel->weight >= explorer::GainOptions{}.min_weight;
}

// The mirror holds what the mapper integrated during the whole flight, not just its start: the
// vehicle plans only through observed space beyond the start's clear radius (docs/design.md §1), so
// nearly every voxel it flew through, far along the path too, is observed.
TEST(Subsampling, MirroredMapCoversTheWholeFlight) {
  const FlownMap& map = flownMap();
  ASSERT_NE(map.tsdf, nullptr);
  ASSERT_FALSE(map.path.empty());
  EXPECT_EQ(map.tsdf->voxelSize(), mapper::MapperOptions{}.voxel_size);  // what the graph flies
  const Eigen::Vector3d start = map.path.front().position;
  int beyond = 0, seen = 0;
  double farthest = 0;
  for (const sim::PathSample& s : map.path) {
    const double from_start = (s.position - start).norm();
    farthest = std::max(farthest, from_start);
    if (from_start < 1.5) continue;
    ++beyond;
    seen += observed(*map.tsdf, s.position);
  }
  std::printf(
      "flight to %.1f m from the start, %d of %d samples beyond 1.5 m observed, %zu blocks\n",
      farthest, seen, beyond, map.tsdf->numBlocks());
  ASSERT_GT(farthest, 4.0) << map.end_reason;
  EXPECT_GE(seen, 0.95 * beyond);
  // ... and the last position in particular.
  EXPECT_TRUE(observed(*map.tsdf, map.path.back().position));
}

// The recorder only listens: the trial flies as `thicket-bench run` flies it without one.
TEST(Subsampling, RecorderLeavesTheFlightAsItIs) {
  const SubsamplingOptions options = shortFlights(1, 60);
  RunOptions run;
  run.scenario = options.scenario;
  run.density = options.density;
  run.method = "local_exploration";
  run.replans = options.replans;
  const TrialResult plain = runTrial(run, trialWorld(run, 0), 0);
  const FlownMap& map = flownMap();
  EXPECT_EQ(map.end_reason, plain.end_reason);
  ASSERT_EQ(map.path.size(), plain.path.size());
  for (size_t i = 0; i < plain.path.size(); ++i) {
    ASSERT_EQ(map.path[i].position, plain.path[i].position) << "sample " << i;
  }
}

TEST(Subsampling, PosesLieNearTheFlownPathsInsideTheBounds) {
  const std::vector<FlownMap> maps = {flownMap(), flownMap()};
  const std::vector<GainPose> poses = drawGainPoses(maps, 101, 5);
  ASSERT_EQ(poses.size(), 101u);
  int quadrants[4] = {0, 0, 0, 0};
  for (size_t n = 0; n < poses.size(); ++n) {
    SCOPED_TRACE("pose " + std::to_string(n));
    EXPECT_EQ(poses[n].map, static_cast<int>(n % 2));
    const Pose& pose = poses[n].world_T_camera;
    const Eigen::Vector3d p = pose.position;
    EXPECT_TRUE((p.array() >= maps[0].bounds_min.array()).all()) << p.transpose();
    EXPECT_TRUE((p.array() <= maps[0].bounds_max.array()).all()) << p.transpose();
    // Within 1 m sideways and 0.5 m vertically of some path sample.
    const bool near =
        std::any_of(maps[0].path.begin(), maps[0].path.end(), [&](const sim::PathSample& s) {
          return (s.position - p).head<2>().norm() <= 1.0 + 1e-9 &&
                 std::abs(s.position.z() - p.z()) <= 0.5 + 1e-9;
        });
    EXPECT_TRUE(near) << p.transpose();
    // A level forward camera: the optical z axis is horizontal.
    const Eigen::Vector3d forward = pose.orientation * Eigen::Vector3d::UnitZ();
    EXPECT_NEAR(forward.z(), 0.0, 1e-9);
    const double heading = std::atan2(forward.y(), forward.x());
    ++quadrants[static_cast<int>(std::floor((heading + pi) / (pi / 2))) % 4];
  }
  for (int q : quadrants) EXPECT_GT(q, 10) << "headings are not spread over every direction";
  // Seeded: the same seed gives the same poses, another seed others.
  const std::vector<GainPose> again = drawGainPoses(maps, 101, 5);
  const std::vector<GainPose> other = drawGainPoses(maps, 101, 6);
  for (size_t n = 0; n < poses.size(); ++n) {
    EXPECT_EQ(again[n].world_T_camera.position, poses[n].world_T_camera.position);
  }
  EXPECT_NE(other[0].world_T_camera.position, poses[0].world_T_camera.position);
}

// The documented error of a subsampled estimate: three standard deviations of the fraction of a
// simple random sample of the same size (the Z-order sample is stratified and does better),
// plus the voxelization of the frustum's sides that the exact grid itself has.
double expectedError(double fraction, int64_t points, int stride) {
  const double samples = static_cast<double>((points + stride - 1) / stride);
  return 3.0 * std::sqrt(fraction * (1.0 - fraction) / samples) + 0.006;
}

// The unknown fraction of the continuous frustum of a level camera at height h when the
// horizontal slab zlo <= z < zhi is observed and everything else unknown: at depth d the
// cross-section is (2 tan(hfov/2) d) wide and spans optical y in [-tan(vfov/2) d,
// tan(vfov/2) d], y pointing down (world z = h - y). Midpoint rule over the depth.
double slabUnknownFraction(const PinholeCamera& camera, double h, double zlo, double zhi) {
  const double th = std::tan(camera.horizontalFov() / 2), tv = std::tan(camera.verticalFov() / 2);
  const int steps = 100000;
  const double d0 = 0.5, d1 = 5.0, dd = (d1 - d0) / steps;
  double total = 0, known = 0;
  for (int i = 0; i < steps; ++i) {
    const double d = d0 + (i + 0.5) * dd;
    const double width = 2 * th * d;
    const double lo = std::max(-tv * d, h - zhi), hi = std::min(tv * d, h - zlo);
    total += width * 2 * tv * d;
    known += width * std::max(0.0, hi - lo);
  }
  return 1.0 - known / total;
}

// Observed free voxels for 0.4 <= z < 4.0 over x, y in [-9.6, 9.6), unknown elsewhere.
TsdfLayer slabMap() {
  TsdfLayer tsdf(kVoxel);
  for (int x = -48; x < 48; ++x) {
    for (int y = -48; y < 48; ++y) {
      for (int z = 2; z < 20; ++z) tsdf.allocateVoxel({x, y, z}) = TsdfVoxel{1.0f, 1.0f};
    }
  }
  return tsdf;
}

// Ground truth: on the slab map the gain at every stride matches the analytic unknown fraction
// within the subsampling's expected error, and the rows' errors stay within those bounds.
TEST(Subsampling, SubsampledGainMatchesTheAnalyticFractionOfASlab) {
  const TsdfLayer tsdf = slabMap();
  const explorer::ExplorationGain gain(explorer::GainOptions{}, kVoxel);
  const int64_t points = gain.frustumPoints();
  const std::vector<int> strides = {1, 2, 5, 20, 50, 100};
  // Heights on voxel faces put every frustum grid layer on voxel centres (no rounding at the
  // slab's faces); the slab fills the upper part of the view, the middle, the lower part.
  std::vector<GainPose> poses;
  std::vector<double> analytic;
  for (double h : {0.2, 1.0, 2.2, 4.4, 6.6}) {
    for (double yaw : {0.0, 0.7, 2.0, -2.9}) {
      poses.push_back({0, explorer::ExplorationGain::cameraAt(Eigen::Vector3d(0.3, -0.2, h), yaw)});
      analytic.push_back(slabUnknownFraction(gain.camera(), h, 0.4, 4.0));
    }
  }
  std::vector<double> worst(strides.size(), 0.0);
  for (size_t n = 0; n < poses.size(); ++n) {
    for (size_t s = 0; s < strides.size(); ++s) {
      const double value =
          gain.unknownFraction(tsdf, poses[n].world_T_camera, strides[s]).unknown_fraction;
      const double tolerance = expectedError(analytic[n], points, strides[s]);
      EXPECT_NEAR(value, analytic[n], tolerance) << "pose " << n << ", stride " << strides[s];
      worst[s] = std::max(worst[s], std::abs(value - analytic[n]));
    }
  }
  for (size_t s = 0; s < strides.size(); ++s) {
    std::printf("slab: stride %3d, worst |gain - analytic| %.4f\n", strides[s], worst[s]);
  }
  std::printf("slab: analytic unknown fractions %.3f .. %.3f\n",
              *std::min_element(analytic.begin(), analytic.end()),
              *std::max_element(analytic.begin(), analytic.end()));
  // The views must differ for the comparison to mean something.
  EXPECT_LT(*std::min_element(analytic.begin(), analytic.end()), 0.4);
  EXPECT_GT(*std::max_element(analytic.begin(), analytic.end()), 0.9);

  const auto rows = measureSubsampling({&tsdf}, poses, {0.01, 0.05, 0.5, 1.0});
  ASSERT_TRUE(rows) << rows.error();
  ASSERT_EQ(rows->size(), 4u);
  for (const SubsamplingRow& row : *rows) {
    // |gain(s) - gain(1)| <= |gain(s) - analytic| + |analytic - gain(1)|.
    double bound = 0;
    for (double a : analytic) {
      bound = std::max(bound, expectedError(a, points, row.stride) + expectedError(a, points, 1));
    }
    EXPECT_LE(row.max_abs_error, bound) << "stride " << row.stride;
  }
  EXPECT_EQ(rows->back().stride, 1);
  EXPECT_EQ(rows->back().max_abs_error, 0.0);
}

// On the flown map: the fraction 1 row is exact, and every row is the mean, p95 and max of the
// per-pose |gain(stride) - gain(1)| computed here directly.
TEST(Subsampling, RowsAggregateThePerPoseErrorsOnAFlownMap) {
  const std::vector<GainPose> poses = drawGainPoses({flownMap()}, 50, 3);
  const std::vector<double> fractions = {1.0, 0.05, 0.2, 0.01};
  const auto rows = measureSubsampling({flownMap().tsdf.get()}, poses, fractions);
  ASSERT_TRUE(rows) << rows.error();
  ASSERT_EQ(rows->size(), fractions.size());
  const explorer::ExplorationGain gain(explorer::GainOptions{}, flownMap().tsdf->voxelSize());
  std::vector<double> exact;
  for (const GainPose& p : poses) {
    exact.push_back(gain.unknownFraction(*flownMap().tsdf, p.world_T_camera).unknown_fraction);
  }
  // The poses see known and unknown space.
  EXPECT_LT(*std::min_element(exact.begin(), exact.end()), 0.7);
  EXPECT_GT(*std::max_element(exact.begin(), exact.end()), 0.9);
  const std::vector<int> expected_strides = {100, 20, 5, 1};
  for (size_t r = 0; r < rows->size(); ++r) {
    const SubsamplingRow& row = (*rows)[r];
    SCOPED_TRACE("stride " + std::to_string(row.stride));
    EXPECT_EQ(row.stride, expected_strides[r]);
    EXPECT_EQ(row.fraction, 1.0 / row.stride);
    EXPECT_EQ(row.poses, 50);
    std::vector<double> errors;
    for (size_t n = 0; n < poses.size(); ++n) {
      errors.push_back(
          std::abs(gain.unknownFraction(*flownMap().tsdf, poses[n].world_T_camera, row.stride)
                       .unknown_fraction -
                   exact[n]));
    }
    double sum = 0;
    for (double e : errors) sum += e;
    EXPECT_EQ(row.mean_abs_error, sum / static_cast<double>(errors.size()));
    EXPECT_EQ(row.p95_abs_error, quantile(errors, 0.95));
    EXPECT_EQ(row.max_abs_error, *std::max_element(errors.begin(), errors.end()));
    for (double value : {row.mean_abs_error, row.p95_abs_error, row.max_abs_error}) {
      EXPECT_TRUE(std::isfinite(value));
      EXPECT_GE(value, 0.0);
      EXPECT_LE(value, 1.0);
    }
    EXPECT_LE(row.mean_abs_error, row.max_abs_error);
    EXPECT_LE(row.p95_abs_error, row.max_abs_error);
    EXPECT_GT(row.median_us, 0.0);
    EXPECT_GT(row.speedup, 0.0);
  }
  const SubsamplingRow& whole = rows->back();
  EXPECT_EQ(whole.mean_abs_error, 0.0);
  EXPECT_EQ(whole.p95_abs_error, 0.0);
  EXPECT_EQ(whole.max_abs_error, 0.0);
  EXPECT_EQ(whole.speedup, 1.0);  // its own time over itself
  // Checking 1 % of the points does make errors on a real map.
  EXPECT_GT(rows->front().max_abs_error, 0.0);
}

TEST(Subsampling, MeasureRefusesBadInput) {
  const TsdfLayer tsdf(kVoxel);
  const std::vector<GainPose> poses = {{0, explorer::ExplorationGain::cameraAt({0, 0, 1}, 0)}};
  EXPECT_FALSE(measureSubsampling({&tsdf}, {}, {1.0}));
  EXPECT_FALSE(measureSubsampling({}, poses, {1.0}));
  EXPECT_FALSE(measureSubsampling({&tsdf}, poses, {}));
  EXPECT_FALSE(measureSubsampling({&tsdf}, poses, {0.0}));
  EXPECT_FALSE(measureSubsampling({&tsdf}, poses, {std::nan("")}));
  EXPECT_FALSE(measureSubsampling({&tsdf}, {{1, poses[0].world_T_camera}}, {1.0}));
  GainPose nan_pose = poses[0];
  nan_pose.world_T_camera.position.x() = std::nan("");
  const auto refused = measureSubsampling({&tsdf}, {nan_pose}, {1.0});
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().find("finite"), std::string::npos) << refused.error();
  // An empty map is all unknown: no error at any stride.
  const auto rows = measureSubsampling({&tsdf}, poses, {0.1, 1.0});
  ASSERT_TRUE(rows) << rows.error();
  EXPECT_EQ((*rows)[0].max_abs_error, 0.0);
}

using Table = std::vector<std::vector<std::string>>;

Table readCsv(const std::string& path) {
  std::ifstream file(path);
  Table rows;
  for (std::string line; std::getline(file, line);) {
    std::vector<std::string> cells;
    std::stringstream stream(line);
    for (std::string cell; std::getline(stream, cell, ',');) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

class SubsamplingRun : public thicket::testing::TempDirTest {};

// Two maps flown on one thread and on two: the same rows apart from the times, and the CSV of the
// contract.
TEST_F(SubsamplingRun, WritesTheSameRowsAtAnyJobs) {
  SubsamplingOptions options = shortFlights(2, 40);
  options.replans = 8;
  options.out_dir = tempPath("jobs1");
  const auto one = runSubsampling(options);
  ASSERT_TRUE(one) << one.error();
  options.jobs = 2;
  options.out_dir = tempPath("jobs2");
  const auto two = runSubsampling(options);
  ASSERT_TRUE(two) << two.error();

  ASSERT_EQ(one->size(), options.fractions.size());
  ASSERT_EQ(two->size(), one->size());
  for (size_t r = 0; r < one->size(); ++r) {
    EXPECT_EQ((*one)[r].stride, (*two)[r].stride);
    EXPECT_EQ((*one)[r].poses, 40);
    EXPECT_EQ((*one)[r].mean_abs_error, (*two)[r].mean_abs_error);
    EXPECT_EQ((*one)[r].p95_abs_error, (*two)[r].p95_abs_error);
    EXPECT_EQ((*one)[r].max_abs_error, (*two)[r].max_abs_error);
  }
  const Table a = readCsv(tempPath("jobs1") + "/e5_subsampling.csv");
  const Table b = readCsv(tempPath("jobs2") + "/e5_subsampling.csv");
  ASSERT_EQ(a.size(), options.fractions.size() + 1);
  ASSERT_EQ(b.size(), a.size());
  std::string header;
  for (const std::string& cell : a[0]) header += (header.empty() ? "" : ",") + cell;
  EXPECT_EQ(header, kHeader);
  const std::vector<std::string> fractions = {"0.02", "0.05", "0.25", "1"};
  for (size_t r = 1; r < a.size(); ++r) {
    ASSERT_EQ(a[r].size(), 8u);
    EXPECT_EQ(a[r][0], fractions[r - 1]);
    // fraction, stride, poses and the errors; median_us and speedup are measured times.
    for (size_t c = 0; c < 6; ++c) EXPECT_EQ(a[r][c], b[r][c]) << "row " << r << " column " << c;
    for (size_t c = 3; c < 8; ++c) EXPECT_TRUE(std::isfinite(std::stod(a[r][c])));
  }
  EXPECT_EQ(a.back()[3], "0.000000");
  EXPECT_EQ(a.back()[5], "0.000000");
}

using thicket::testing::CliResult;

CliResult bench(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_BENCH) + " subsampling " + args);
}

TEST_F(SubsamplingRun, CommandPrintsTheTableAndWritesTheCsv) {
  const std::string out = tempPath("cli");
  const CliResult result =
      bench("--out " + out + " --maps 1 --poses 30 --replans 6 --fractions 0.1,1 --seed-base 2");
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("map 0/1: seed 2:"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("median us"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("wrote " + out + "/e5_subsampling.csv"), std::string::npos)
      << result.output;
  const Table table = readCsv(out + "/e5_subsampling.csv");
  ASSERT_EQ(table.size(), 3u);
  EXPECT_EQ(table[1][1], "10");
  EXPECT_EQ(table[2][1], "1");
  EXPECT_EQ(table[2][2], "30");

  const CliResult help = bench("--help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.output.find("Usage: thicket-bench subsampling"), std::string::npos);
}

TEST_F(SubsamplingRun, CommandRefusesBadFlags) {
  const std::string out = " --out " + tempPath("bad");
  struct Case {
    std::string args;
    std::string message;
  };
  const Case cases[] = {
      {"--maps 1", "--out is required"},
      {"--fractions 0" + out, "fraction 0 is not in"},
      {"--fractions 1.5" + out, "fraction 1.5 is not in"},
      {"--fractions 0.1,nan" + out, "--fractions: must be a number, not 'nan'"},
      {"--fractions 0.3,0.33" + out, "fractions 0.3 and 0.33 both give stride 3"},
      {"--fractions a" + out, "--fractions: must be a number, not 'a'"},
      {"--maps 0" + out, "--maps: must be an integer >= 1, not '0'"},
      {"--poses 1.5" + out, "--poses: must be an integer >= 1, not '1.5'"},
      {"--jobs 0" + out, "--jobs: must be an integer in [1, 1024], not '0'"},
      {"--replans" + out, "--replans: must be an integer >= 1, not '--out'"},
      {"--density -1" + out, "the density must be a non-negative number"},
      {"--density x" + out, "--density: must be a number, not 'x'"},
      {"--seed-base -3" + out, "--seed-base: must be an integer >= 0"},
      {"--scenario nowhere" + out, "nowhere"},
      {"--bogus 1" + out, "not expected: 1 --bogus"},
      {"stray" + out, "not expected: stray"},
      {out + " --poses", "--poses: 1 required INT:>= 1 missing"},
  };
  for (const Case& c : cases) {
    const CliResult result = bench(c.args);
    EXPECT_EQ(result.status, 2) << c.args << "\n" << result.output;
    EXPECT_NE(result.output.find(c.message), std::string::npos) << c.args << "\n" << result.output;
    EXPECT_FALSE(std::filesystem::exists(tempPath("bad") + "/e5_subsampling.csv")) << c.args;
  }
  // An output folder that cannot be made fails the run before any flight.
  std::ofstream(tempPath("file")) << "not a folder";
  const CliResult unwritable = bench("--maps 1 --out " + tempPath("file") + "/sub");
  EXPECT_EQ(unwritable.status, 1) << unwritable.output;
  EXPECT_NE(unwritable.output.find("cannot create"), std::string::npos) << unwritable.output;
  EXPECT_EQ(unwritable.output.find("map 0/1"), std::string::npos) << unwritable.output;
}

}  // namespace
}  // namespace thicket::bench

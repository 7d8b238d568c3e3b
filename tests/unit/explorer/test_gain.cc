#include "thicket/explorer/gain.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "../mapper/forest_views.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::explorer {
namespace {

using std::numbers::pi;

constexpr double kVoxel = 0.2;

// A TSDF whose blocks cover the cube [-half, half)^3 (rounded out to whole blocks), every voxel
// set to f(index) when that gives a value and left unobserved (weight 0) otherwise.
template <class F>
TsdfLayer makeLayer(double voxel_size, double half, F f) {
  TsdfLayer layer(voxel_size);
  const int blocks = static_cast<int>(std::ceil(half / layer.blockSize()));
  for (int a = -blocks; a < blocks; ++a) {
    for (int b = -blocks; b < blocks; ++b) {
      for (int c = -blocks; c < blocks; ++c) {
        auto& block = layer.allocateBlock(BlockIndex(a, b, c));
        for (int i = 0; i < kVoxelsPerBlock; ++i) {
          const std::optional<TsdfVoxel> voxel = f(voxelOfBlock(block.index, i));
          if (voxel) block.voxels[i] = *voxel;
        }
      }
    }
  }
  return layer;
}

constexpr TsdfVoxel kFree{1.0f, 1.0f};
constexpr TsdfVoxel kSurface{-0.05f, 1.0f};

// The optical-frame frustum volume between two depths: the cross-section at depth z is
// z^2 * 4 tan(hfov / 2) tan(vfov / 2).
double frustumVolume(const PinholeCamera& camera, double z0, double z1) {
  return 4.0 * std::tan(camera.horizontalFov() / 2) * std::tan(camera.verticalFov() / 2) *
         (z1 * z1 * z1 - z0 * z0 * z0) / 3.0;
}

// The exact (stride 1) count of frustum points whose TSDF voxel is unknown, from the documented
// grid enumerated here independently of the class: points (i + 0.5, j + 0.5, k + 0.5) * voxel
// size of the optical frame inside the frustum of the ideal default camera (f = 160 exactly, so
// that points on the side planes x = +-z fall on the image's half-open edges exactly), looked up
// with the layer's own uncached voxel().
Gain bruteForceUnknown(double voxel_size, const TsdfLayer& tsdf, const Pose& world_T_camera) {
  const PinholeCamera ideal{320, 240, 160.0, 160.0, 159.5, 119.5};
  const int n = static_cast<int>(std::ceil(5.0 / voxel_size)) + 2;
  Gain result;
  for (int k = -n; k <= n; ++k) {
    for (int j = -n; j <= n; ++j) {
      for (int i = -n; i <= n; ++i) {
        const Eigen::Vector3d p((i + 0.5) * voxel_size, (j + 0.5) * voxel_size,
                                (k + 0.5) * voxel_size);
        if (!ideal.inFrustum(p, 0.5, 5.0)) continue;
        // As the class stores the point.
        const Eigen::Vector3d world = world_T_camera.transform(p.cast<float>().cast<double>());
        const TsdfVoxel* voxel = tsdf.voxel(tsdf.voxelIndex(world));
        ++result.checked;
        if (voxel == nullptr || voxel->weight < GainOptions{}.min_weight) ++result.unknown;
      }
    }
  }
  result.unknown_fraction = static_cast<double>(result.unknown) / result.checked;
  return result;
}

// A TSDF mapped from ten forest50 views along the start-goal diagonal: built once.
const TsdfLayer& flownMap() {
  static const TsdfLayer layer = [] {
    TsdfLayer tsdf(kVoxel);
    const mapper::TsdfIntegrator integrator{mapper::TsdfIntegratorOptions{}};
    for (const mapper::Frame& frame : mapper::forestFrames(10)) {
      integrator.integrate(frame.image, frame.world_T_camera, tsdf);
    }
    return tsdf;
  }();
  return layer;
}

// 200 seeded camera poses near that flight: along the first 12 m of the diagonal, up to 1 m to
// either side and 0.5 m up or down, heading up to 2 rad away from the goal's.
std::vector<Pose> posesNearFlight() {
  const sim::World& world = mapper::forest();
  const Eigen::Vector3d direction = (world.goal - world.start).normalized();
  const Eigen::Vector3d side = Eigen::Vector3d::UnitZ().cross(direction).normalized();
  const double heading = std::atan2(direction.y(), direction.x());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> along(1.0, 12.0), lateral(-1.0, 1.0), vertical(-0.5, 0.5),
      turn(-2.0, 2.0);
  std::vector<Pose> poses;
  for (int n = 0; n < 200; ++n) {
    const Eigen::Vector3d p = world.start + along(rng) * direction + lateral(rng) * side +
                              vertical(rng) * Eigen::Vector3d::UnitZ();
    poses.push_back(ExplorationGain::cameraAt(p, heading + turn(rng)));
  }
  return poses;
}

void expectSameGain(const Gain& a, const Gain& b) {
  EXPECT_EQ(a.checked, b.checked);
  EXPECT_EQ(a.unknown, b.unknown);
  EXPECT_EQ(a.unknown_fraction, b.unknown_fraction);
}

TEST(ExplorationGain, FrustumGridFillsTheFrustumVolume) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  const double expected = frustumVolume(gain.camera(), 0.5, 5.0) / std::pow(kVoxel, 3);
  std::printf("frustum grid: %lld points, frustum volume / voxel volume = %.0f\n",
              static_cast<long long>(gain.frustumPoints()), expected);
  EXPECT_NEAR(static_cast<double>(gain.frustumPoints()), expected, 0.005 * expected);
  const ExplorationGain fine(GainOptions{}, 0.1);
  EXPECT_NEAR(static_cast<double>(fine.frustumPoints()), 8 * expected, 0.005 * 8 * expected);
  EXPECT_EQ(gain.camera().width, 320);
  EXPECT_EQ(gain.camera().height, 240);
  EXPECT_NEAR(gain.camera().horizontalFov(), pi / 2, 1e-12);
}

TEST(ExplorationGain, EmptyMapIsAllUnknown) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  const TsdfLayer empty(kVoxel);
  // Allocated but never observed: every voxel has weight 0.
  const TsdfLayer unobserved =
      makeLayer(kVoxel, 6.4, [](const VoxelIndex&) { return std::optional<TsdfVoxel>(); });
  const int64_t n = gain.frustumPoints();
  ASSERT_GT(n, 0);
  for (const TsdfLayer* tsdf : {&empty, &unobserved}) {
    for (const Pose& pose : {ExplorationGain::cameraAt(Eigen::Vector3d(0.3, -0.1, 1.0), 0.4),
                             ExplorationGain::cameraAt(Eigen::Vector3d::Zero(), -2.0)}) {
      for (int stride : {1, 2, 7, 20, 100, static_cast<int>(n), static_cast<int>(n) + 5}) {
        for (const Gain& g : {gain.unknownFraction(*tsdf, pose, stride),
                              gain.visibleUnknownFraction(*tsdf, pose, stride)}) {
          EXPECT_EQ(g.checked, (n + stride - 1) / stride) << "stride " << stride;
          EXPECT_EQ(g.unknown, g.checked);
          EXPECT_EQ(g.unknown_fraction, 1.0);
        }
      }
    }
  }
}

TEST(ExplorationGain, ObservedFreeBoxIsAllKnown) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  // Frustum corners reach sqrt(5^2 + 5^2 + 3.75^2) = 8 m from the camera.
  const TsdfLayer free = makeLayer(kVoxel, 9.6, [](const VoxelIndex&) { return kFree; });
  for (double yaw : {0.0, 1.0, pi, -2.5}) {
    const Pose pose = ExplorationGain::cameraAt(Eigen::Vector3d(0.1, 0.2, -0.3), yaw);
    for (int stride : {1, 20}) {
      const Gain g = gain.unknownFraction(free, pose, stride);
      EXPECT_EQ(g.unknown, 0);
      EXPECT_EQ(g.unknown_fraction, 0.0);
      EXPECT_EQ(g.checked, (gain.frustumPoints() + stride - 1) / stride);
      EXPECT_EQ(gain.visibleUnknownFraction(free, pose, stride).unknown, 0);
    }
  }
  // Weights below min_weight are unknown.
  const TsdfLayer faint = makeLayer(kVoxel, 6.4, [](const VoxelIndex&) {
    return TsdfVoxel{1.0f, 1e-7f};
  });
  const Pose pose = ExplorationGain::cameraAt(Eigen::Vector3d::Zero(), 0.0);
  EXPECT_EQ(gain.unknownFraction(faint, pose).unknown_fraction, 1.0);
  GainOptions lenient;
  lenient.min_weight = 1e-8;
  EXPECT_EQ(ExplorationGain(lenient, kVoxel).unknownFraction(faint, pose).unknown_fraction, 0.0);
}

// Observed free for world x < x0, unknown beyond: the fraction is the frustum's volume beyond
// x0 over its whole volume, up to the voxelization.
TEST(ExplorationGain, HalfSpaceMatchesTheFrustumVolumeBeyondTheBoundary) {
  struct Case {
    double voxel_size;
    double x0;  // on a voxel boundary
  };
  for (const Case c : {Case{0.1, 2.5}, Case{0.2, 2.6}, Case{0.2, 1.0}}) {
    const int boundary = static_cast<int>(std::lround(c.x0 / c.voxel_size));
    const TsdfLayer tsdf = makeLayer(c.voxel_size, 6.4, [&](const VoxelIndex& v) {
      return v.x() < boundary ? std::optional<TsdfVoxel>(kFree) : std::nullopt;
    });
    const ExplorationGain gain(GainOptions{}, c.voxel_size);
    const double expected =
        frustumVolume(gain.camera(), c.x0, 5.0) / frustumVolume(gain.camera(), 0.5, 5.0);
    const Gain ahead = gain.unknownFraction(tsdf, ExplorationGain::cameraAt({0, 0, 0}, 0.0));
    std::printf("half space at x = %.1f, voxel %.1f: fraction %.4f, frustum volume %.4f\n", c.x0,
                c.voxel_size, ahead.unknown_fraction, expected);
    EXPECT_NEAR(ahead.unknown_fraction, expected, 0.005) << "x0 " << c.x0;
    // Nothing occludes: the visible fraction is the same.
    expectSameGain(gain.visibleUnknownFraction(tsdf, ExplorationGain::cameraAt({0, 0, 0}, 0.0)),
                   ahead);
    // Looking back along -x: all observed.
    const Gain behind = gain.unknownFraction(tsdf, ExplorationGain::cameraAt({0, 0, 0}, pi));
    EXPECT_EQ(behind.unknown, 0);
    EXPECT_EQ(behind.checked, gain.frustumPoints());
  }
}

TEST(ExplorationGain, CountsEqualABruteForceLookupOfTheDocumentedGrid) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  const std::vector<Pose> poses = posesNearFlight();
  for (size_t n = 0; n < poses.size(); n += 20) {
    const Gain fast = gain.unknownFraction(flownMap(), poses[n]);
    const Gain brute = bruteForceUnknown(kVoxel, flownMap(), poses[n]);
    EXPECT_EQ(fast.checked, brute.checked);
    // Rounding in the two transforms may put a point on the other side of a voxel face.
    EXPECT_NEAR(static_cast<double>(fast.unknown), static_cast<double>(brute.unknown), 2.0)
        << "pose " << n;
    EXPECT_GT(brute.unknown, 0);
    EXPECT_LT(brute.unknown, brute.checked);
  }
}

TEST(ExplorationGain, SubsampledEstimateIsCloseToTheExactFractionOnAFlownMap) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  double sum = 0, worst = 0, lowest = 1, highest = 0;
  const std::vector<Pose> poses = posesNearFlight();
  for (const Pose& pose : poses) {
    const double exact = gain.unknownFraction(flownMap(), pose, 1).unknown_fraction;
    const double estimate = gain.unknownFraction(flownMap(), pose, 20).unknown_fraction;
    sum += std::abs(estimate - exact);
    worst = std::max(worst, std::abs(estimate - exact));
    lowest = std::min(lowest, exact);
    highest = std::max(highest, exact);
  }
  const double mean = sum / poses.size();
  std::printf(
      "stride 20 vs 1 on a flown map, %zu poses: mean |error| %.4f, max %.4f (exact fractions "
      "%.3f .. %.3f)\n",
      poses.size(), mean, worst, lowest, highest);
  // The poses must see both known and unknown space for the comparison to mean something.
  EXPECT_LT(lowest, 0.5);
  EXPECT_GT(highest, 0.9);
  EXPECT_LT(mean, 0.02);
  EXPECT_LT(worst, 0.06);
}

// A surface slab at x in [2, 2.2) across the whole view, observed free space in front, unknown
// behind.
TEST(ExplorationGain, SurfacesHideWhatIsBehindThem) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  const Pose pose = ExplorationGain::cameraAt({0, 0, 0}, 0.0);
  const auto scene = [](bool wall_where_y_below_0, bool wall_where_y_above_0,
                        bool behind_observed_above_0) {
    return makeLayer(kVoxel, 6.4, [=](const VoxelIndex& v) -> std::optional<TsdfVoxel> {
      const bool above = v.y() >= 0;
      if (v.x() < 10) return kFree;  // x < 2
      if (v.x() == 10 && (above ? wall_where_y_above_0 : wall_where_y_below_0)) return kSurface;
      if (above && behind_observed_above_0) return kFree;
      return std::nullopt;
    });
  };

  const TsdfLayer wall = scene(true, true, false);
  const Gain plain = gain.unknownFraction(wall, pose);
  const Gain visible = gain.visibleUnknownFraction(wall, pose);
  EXPECT_GT(plain.unknown_fraction, 0.85);  // the frustum beyond x = 2.2
  EXPECT_EQ(visible.unknown, 0);
  EXPECT_EQ(visible.checked, plain.checked);

  // Without the wall the unknown space is in plain view.
  const TsdfLayer open = scene(false, false, false);
  expectSameGain(gain.visibleUnknownFraction(open, pose), gain.unknownFraction(open, pose));
  // The wall's own points are unknown without it.
  EXPECT_GT(gain.unknownFraction(open, pose).unknown, plain.unknown);

  // A wall over world y >= 0 only: rays from the camera (at y = 0) to points at y < 0 never
  // enter y >= 0, and rays to points beyond the wall at y >= 0 cross it. What stays visible is
  // the unknown space at y < 0, which the plain fraction counts alone when y >= 0 is observed.
  const Gain half_visible = gain.visibleUnknownFraction(scene(false, true, false), pose);
  const Gain unknown_below_0 = gain.unknownFraction(scene(false, true, true), pose);
  expectSameGain(half_visible, unknown_below_0);
  EXPECT_GT(half_visible.unknown_fraction, 0.4);
  EXPECT_LT(half_visible.unknown_fraction, 0.6);

  // Looking back from behind the wall (x = 4, facing -x): the points in front of the wall are
  // observed, those behind the camera's side are unknown and in view.
  const Pose back = ExplorationGain::cameraAt({4.1, 0.1, 0.1}, pi);
  expectSameGain(gain.visibleUnknownFraction(wall, back), gain.unknownFraction(wall, back));
}

TEST(ExplorationGain, OcclusionOnAFlownMapOnlyRemovesUnknownPoints) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  int hidden_somewhere = 0;
  for (const Pose& pose : posesNearFlight()) {
    const Gain plain = gain.unknownFraction(flownMap(), pose, 5);
    const Gain visible = gain.visibleUnknownFraction(flownMap(), pose, 5);
    EXPECT_EQ(visible.checked, plain.checked);
    EXPECT_LE(visible.unknown, plain.unknown);
    if (visible.unknown < plain.unknown) ++hidden_somewhere;
  }
  // The trees hide unknown space from most of these poses.
  EXPECT_GT(hidden_somewhere, 100);
}

// The early-stopping walk gives the whole gain exactly when the fraction passes both bounds, and
// nothing when it misses either by the smallest step (one point in `checked`).
TEST(ExplorationGain, TheWalkIfAboveGivesTheGainOnlyWhenItPassesBothBounds) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  int passed = 0;
  const std::vector<Pose> poses = posesNearFlight();
  for (size_t n = 0; n < poses.size(); n += 10) {
    const Gain full = gain.visibleUnknownFraction(flownMap(), poses[n], 5);
    const double f = full.unknown_fraction, below = f - 0.5 / static_cast<double>(full.checked);
    const double above = f + 0.5 / static_cast<double>(full.checked);
    const std::optional<Gain> both =
        gain.visibleUnknownFractionIfAbove(flownMap(), poses[n], 5, f, below);
    ASSERT_TRUE(both) << "pose " << n;
    expectSameGain(*both, full);
    EXPECT_FALSE(gain.visibleUnknownFractionIfAbove(flownMap(), poses[n], 5, above, -1));
    EXPECT_FALSE(gain.visibleUnknownFractionIfAbove(flownMap(), poses[n], 5, 0, f));
    passed += f > 0;
  }
  EXPECT_GT(passed, 10);  // views that do see unknown space were among them
}

TEST(ExplorationGain, IsDeterministic) {
  const ExplorationGain a(GainOptions{}, kVoxel);
  const ExplorationGain b(GainOptions{}, kVoxel);
  EXPECT_EQ(a.frustumPoints(), b.frustumPoints());
  const std::vector<Pose> poses = posesNearFlight();
  for (size_t n = 0; n < poses.size(); n += 25) {
    for (int stride : {1, 20}) {
      expectSameGain(a.unknownFraction(flownMap(), poses[n], stride),
                     b.unknownFraction(flownMap(), poses[n], stride));
      expectSameGain(a.unknownFraction(flownMap(), poses[n], stride),
                     a.unknownFraction(flownMap(), poses[n], stride));
      expectSameGain(a.visibleUnknownFraction(flownMap(), poses[n], stride),
                     b.visibleUnknownFraction(flownMap(), poses[n], stride));
    }
  }
}

TEST(ExplorationGain, CameraAtLooksAlongItsYaw) {
  for (double yaw : {0.0, 0.7, pi / 2, -2.0, pi}) {
    const Eigen::Vector3d position(1.0, -2.0, 1.5);
    const Pose pose = ExplorationGain::cameraAt(position, yaw);
    EXPECT_EQ(pose.position, position);
    const Eigen::Matrix3d r = pose.orientation.toRotationMatrix();
    EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0), 1e-12))
        << "optical z at yaw " << yaw << ": " << r.col(2).transpose();
    // Image right is the vehicle's right, image down is world down.
    EXPECT_TRUE(r.col(0).isApprox(Eigen::Vector3d(std::sin(yaw), -std::cos(yaw), 0), 1e-12));
    EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
    EXPECT_NEAR(pose.orientation.norm(), 1.0, 1e-12);
  }
}

TEST(ExplorationGain, RefusesBadInput) {
  const ExplorationGain gain(GainOptions{}, kVoxel);
  const TsdfLayer tsdf(kVoxel);
  const Pose pose = ExplorationGain::cameraAt({0, 0, 0}, 0.0);
  EXPECT_THROW(gain.unknownFraction(tsdf, pose, 0), std::invalid_argument);
  EXPECT_THROW(gain.unknownFraction(tsdf, pose, -3), std::invalid_argument);
  EXPECT_THROW(gain.visibleUnknownFraction(tsdf, pose, 0), std::invalid_argument);
  EXPECT_THROW(gain.unknownFraction(TsdfLayer(0.1), pose), std::invalid_argument);
  EXPECT_THROW(gain.visibleUnknownFraction(TsdfLayer(0.25), pose), std::invalid_argument);
  Pose nan_pose = pose;
  nan_pose.position.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(gain.unknownFraction(tsdf, nan_pose), std::invalid_argument);
  Pose scaled = pose;
  scaled.orientation.coeffs() *= 2.0;
  EXPECT_THROW(gain.visibleUnknownFraction(tsdf, scaled), std::invalid_argument);
  Pose far = pose;
  far.position.x() = 1e12;
  EXPECT_THROW(gain.unknownFraction(tsdf, far), std::invalid_argument);
  EXPECT_NO_THROW(gain.unknownFraction(tsdf, pose, 1));

  const auto refused = [](auto change, double voxel_size = kVoxel) {
    GainOptions options;
    change(options);
    EXPECT_THROW(ExplorationGain(options, voxel_size), std::invalid_argument);
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  refused([](GainOptions& o) { o.width = 0; });
  refused([](GainOptions& o) { o.height = -1; });
  refused([&](GainOptions& o) { o.hfov_deg = nan; });
  refused([](GainOptions& o) { o.hfov_deg = 0; });
  refused([](GainOptions& o) { o.hfov_deg = 180; });
  refused([](GainOptions& o) { o.hfov_deg = 0.5; });  // its YAML's [1, 179]; it used to pass
  refused([](GainOptions& o) { o.min_range = o.max_range; });
  refused([](GainOptions& o) { o.min_range = 6; });
  refused([](GainOptions& o) { o.min_range = -1; });
  refused([&](GainOptions& o) { o.max_range = nan; });
  refused([](GainOptions& o) { o.max_range = std::numeric_limits<double>::infinity(); });
  refused([](GainOptions& o) { o.min_weight = 0; });
  refused([](GainOptions&) {}, 0.0);
  refused([](GainOptions&) {}, -0.2);
  refused([&](GainOptions&) {}, nan);
  refused([](GainOptions&) {}, 1e-4);  // a grid of billions of points
}

TEST(GainOptions, LoadsAndRefusesFromYaml) {
  const auto options = loadParamsFromString<GainOptions>(
      "width: 640\nheight: 480\nhfov_deg: 60\nmin_range: 0.2\nmax_range: 4\nmin_weight: 0.01\n",
      "test");
  EXPECT_EQ(options.width, 640);
  EXPECT_EQ(options.height, 480);
  EXPECT_EQ(options.hfov_deg, 60);
  EXPECT_EQ(options.min_range, 0.2);
  EXPECT_EQ(options.max_range, 4);
  EXPECT_EQ(options.min_weight, 0.01);
  EXPECT_NO_THROW(ExplorationGain(options, kVoxel));
  EXPECT_THROW(loadParamsFromString<GainOptions>("width: 0\n", "test"), ParamError);
  EXPECT_THROW(loadParamsFromString<GainOptions>("hfov_deg: 200\n", "test"), ParamError);
  EXPECT_THROW(loadParamsFromString<GainOptions>("min_weight: 0\n", "test"), ParamError);
  EXPECT_THROW(loadParamsFromString<GainOptions>("fov: 90\n", "test"), ParamError);
  // The documented defaults load back as the defaults.
  const auto defaults = loadParamsFromString<GainOptions>(describeParams<GainOptions>(), "doc");
  EXPECT_EQ(defaults.width, GainOptions{}.width);
  EXPECT_EQ(defaults.max_range, GainOptions{}.max_range);
}

}  // namespace
}  // namespace thicket::explorer

#include "thicket/mapper/tsdf_integrator.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "forest_views.h"
#include "thicket/sim/ground_truth.h"

namespace thicket::mapper {
namespace {

using Method = TsdfIntegratorOptions::Method;
using std::numbers::pi;

// An image of the default camera that sees nothing.
Frame emptyFrame(const Pose& world_T_camera) {
  Frame frame;
  frame.image.camera = PinholeCamera::fromHorizontalFov(320, 240, pi / 2);
  frame.image.min_range = 0.05;
  frame.image.max_range = 20;
  frame.image.depth.assign(320 * 240, 0.0f);
  frame.world_T_camera = world_T_camera;
  return frame;
}

TsdfIntegrator makeIntegrator(Method method) {
  TsdfIntegratorOptions options;
  options.method = method;
  return TsdfIntegrator(options);
}

// Calls f(centre, voxel) for every observed voxel (weight > 0).
template <class F>
void forEachObserved(const TsdfLayer& layer, F f) {
  for (const BlockIndex& b : layer.blockIndices()) {
    const auto& voxels = layer.block(b)->voxels;
    for (int i = 0; i < kVoxelsPerBlock; ++i) {
      if (voxels[i].weight > 0) f(layer.voxelCenter(voxelOfBlock(b, i)), voxels[i]);
    }
  }
}

double mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return values.empty() ? std::numeric_limits<double>::quiet_NaN() : sum / values.size();
}

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto nth = values.begin() + static_cast<ptrdiff_t>(fraction * (values.size() - 1));
  std::nth_element(values.begin(), nth, values.end());
  return *nth;
}

using Snapshot = std::map<std::tuple<int, int, int>, TsdfLayer::BlockType>;

Snapshot snapshot(const TsdfLayer& layer) {
  Snapshot copy;
  for (const BlockIndex& b : layer.blockIndices()) {
    copy.emplace(std::tuple{b.x(), b.y(), b.z()}, *layer.block(b));
  }
  return copy;
}

bool sameVoxels(const TsdfLayer::BlockType& a, const TsdfLayer::BlockType& b) {
  return std::memcmp(a.voxels.data(), b.voxels.data(), sizeof(a.voxels)) == 0;
}

std::string methodName(Method method) {
  return method == Method::kProjective ? "Projective" : "Raycast";
}

class TsdfIntegratorTest : public ::testing::TestWithParam<std::tuple<Method, double>> {
 protected:
  Method method() const { return std::get<0>(GetParam()); }
  double voxelSize() const { return std::get<1>(GetParam()); }
  double truncation() const { return 4 * voxelSize(); }
};

std::string paramName(const ::testing::TestParamInfo<std::tuple<Method, double>>& info) {
  return methodName(std::get<0>(info.param)) + "_" +
         std::to_string(static_cast<int>(std::round(std::get<1>(info.param) * 100))) + "cm";
}

INSTANTIATE_TEST_SUITE_P(Tsdf, TsdfIntegratorTest,
                         ::testing::Combine(::testing::Values(Method::kProjective,
                                                              Method::kRaycast),
                                            ::testing::Values(0.2, 0.1)),
                         paramName);

// The update rule, exactly: a one-pixel camera looking along world z through a column of voxel
// centres sees a plane at 3 m, then at 3.1 m. Along its axis both methods measure z.
TEST_P(TsdfIntegratorTest, OnAxisVoxelsFollowTheUpdateRule) {
  const double vs = voxelSize();
  TsdfIntegratorOptions options;
  options.method = method();
  options.max_weight = 0.2;  // the second frame saturates voxels in front of the surface
  const TsdfIntegrator integrator(options);
  Frame frame;
  frame.image.camera = PinholeCamera{1, 1, 1.0, 1.0, 0.0, 0.0};
  frame.image.min_range = 0.05;
  frame.image.max_range = 20;
  frame.world_T_camera.position = Eigen::Vector3d(0.5 * vs, 0.5 * vs, 0);
  TsdfLayer layer(vs);
  std::vector<TsdfVoxel> expected(static_cast<size_t>(std::round(5 / vs)));
  for (const double depth : {3.0, 3.1}) {
    frame.image.depth = {static_cast<float>(depth)};
    integrator.integrate(frame.image, frame.world_T_camera, layer);
    for (size_t k = 0; k < expected.size(); ++k) {
      const double sdf = depth - (k + 0.5) * vs;
      if (sdf <= -truncation()) continue;
      double weight = 1 / (depth * depth);
      if (sdf < -vs) weight *= (truncation() + sdf) / (truncation() - vs);
      TsdfVoxel& e = expected[k];
      e.distance = static_cast<float>(
          (e.weight * e.distance + weight * std::min(sdf, truncation())) / (e.weight + weight));
      e.weight = static_cast<float>(std::min(e.weight + weight, options.max_weight));
    }
  }
  for (size_t k = 0; k < expected.size(); ++k) {
    const TsdfVoxel* voxel = layer.voxel(VoxelIndex(0, 0, static_cast<int>(k)));
    const TsdfVoxel actual = voxel ? *voxel : TsdfVoxel{};
    EXPECT_NEAR(actual.distance, expected[k].distance, 1e-6) << "voxel " << k;
    EXPECT_NEAR(actual.weight, expected[k].weight, 1e-6) << "voxel " << k;
  }
  // The expectations cover the whole rule: saturated free space in front, reduced weight deep
  // behind the surface, nothing beyond the truncation.
  EXPECT_EQ(expected[0].weight, 0.2f);
  EXPECT_EQ(expected[0].distance, static_cast<float>(truncation()));
  EXPECT_LT(expected[static_cast<size_t>(std::round(3.1 / vs)) + 2].weight, 1 / 9.0 + 1 / 9.61);
  EXPECT_EQ(expected.back().weight, 0);
}

// A wall seen head-on: in the middle of the image the distance along the rays is (close to) the
// Euclidean distance, so the TSDF must match the true signed distance near the wall.
TEST_P(TsdfIntegratorTest, WallSeenHeadOnMatchesTrueDistance) {
  sim::World world;
  world.bounds_min = Eigen::Vector3d(0, 0, 0);
  world.bounds_max = Eigen::Vector3d(20, 20, 6);
  const sim::GroundTruth truth(world);
  const sim::DepthRenderer renderer(world, sim::DepthCameraOptions{});
  const TsdfIntegrator integrator = makeIntegrator(method());
  TsdfLayer layer(voxelSize());
  for (const Eigen::Vector3d& position :
       {Eigen::Vector3d(16, 10, 3), Eigen::Vector3d(16.5, 9.7, 3.2),
        Eigen::Vector3d(15.6, 10.3, 2.9)}) {
    const Frame frame = renderFrame(renderer, Pose::fromYaw(position, 0));
    integrator.integrate(frame.image, frame.world_T_camera, layer);
  }
  // Wall x = 20, within 1 m of the image centres: no ground, no corners, rays within 20° of the
  // normal.
  const auto in_region = [&](const Eigen::Vector3d& c) {
    return c.y() > 9 && c.y() < 11 && c.z() > 2 && c.z() < 4 && std::abs(c.x() - 20) < 2;
  };
  int checked = 0;
  double worst = 0;
  forEachObserved(layer, [&](const Eigen::Vector3d& c, const TsdfVoxel& v) {
    if (!in_region(c) || std::abs(v.distance) >= truncation()) return;
    const double error = std::abs(v.distance - truth.distance(c));
    worst = std::max(worst, error);
    EXPECT_LT(error, 0.5 * voxelSize()) << "at " << c.transpose() << ": " << v.distance;
    ++checked;
  });
  // The region holds 2 m x 2 m of wall, so (2 / voxel)^2 columns of voxels; each has about
  // 2 * truncation / voxel = 8 voxels within the truncation, of which the deepest one behind the
  // wall has (almost) no weight.
  const int columns = static_cast<int>(std::round(4 / (voxelSize() * voxelSize())));
  EXPECT_GE(checked, 7 * columns);
  std::printf("wall: %d voxels within truncation, worst |d - true| = %.4f m (%.2f voxels)\n",
              checked, worst, worst / voxelSize());
}

// The forest from several views: where the TSDF crosses zero between neighbouring voxels, the true
// surface must be close; what the TSDF says is free must be free.
//
// Only crossings between values at most kMaxCrossingJump voxels apart count as surfaces. A distance
// field changes by at most one voxel between neighbours; projective and ray distances stretch that
// by 1 / cos(incidence), three voxels allowing incidences up to about 70 degrees. Larger jumps are
// occlusion edges: a voxel in the shadow of a thin trunk (the TSDF puts it behind the surface, up
// to the truncation) next to one seen past the trunk. They are an inherent TSDF artefact, not a
// surface (and on the safe side: the shadow reads as occupied), so they are counted and printed
// only.
TEST_P(TsdfIntegratorTest, ForestSurfaceMatchesGroundTruth) {
  constexpr double kMaxCrossingJump = 3;
  const sim::GroundTruth truth(forest());
  const std::vector<Frame> frames = forestFrames(5);
  const TsdfIntegrator integrator = makeIntegrator(method());
  TsdfLayer layer(voxelSize());
  for (const Frame& frame : frames) integrator.integrate(frame.image, frame.world_T_camera, layer);

  const auto tau = static_cast<float>(truncation());
  std::vector<double> surface_errors;  // at crossings that can be surfaces
  std::vector<double> all_errors;      // at every crossing, occlusion edges included
  double min_free_truth = std::numeric_limits<double>::infinity();
  double deepest_observed = 0;
  int free_voxels = 0;
  forEachObserved(layer, [&](const Eigen::Vector3d& c, const TsdfVoxel& v) {
    EXPECT_LE(std::abs(v.distance), tau);
    const double true_distance = truth.distance(c);
    deepest_observed = std::min(deepest_observed, true_distance);
    // Well inside an obstacle, every view saw a surface in front of the voxel.
    if (true_distance < -voxelSize()) {
      EXPECT_LT(v.distance, 0) << "at " << c.transpose() << ", true distance " << true_distance;
    }
    if (v.distance >= tau - 1e-6f) {
      ++free_voxels;
      min_free_truth = std::min(min_free_truth, true_distance);
    }
    if (std::abs(v.distance) >= tau) return;
    for (int axis = 0; axis < 3; ++axis) {
      const Eigen::Vector3d n = c + voxelSize() * Eigen::Vector3d::Unit(axis);
      const TsdfVoxel* neighbour = layer.voxel(layer.voxelIndex(n));
      if (!neighbour || neighbour->weight <= 0 || std::abs(neighbour->distance) >= tau) continue;
      if ((v.distance < 0) == (neighbour->distance < 0)) continue;
      const double alpha = v.distance / (v.distance - neighbour->distance);
      const double error = std::abs(truth.distance(c + alpha * (n - c)));
      all_errors.push_back(error);
      if (std::abs(v.distance - neighbour->distance) <= kMaxCrossingJump * voxelSize()) {
        surface_errors.push_back(error);
      }
    }
  });
  const double mean_error = mean(surface_errors) / voxelSize();
  const double p95_error = percentile(surface_errors, 0.95) / voxelSize();
  std::printf(
      "forest: %zu surface crossings, error mean %.3f voxels, p95 %.3f voxels (all %zu crossings: "
      "mean %.3f, p95 %.3f); %d free voxels, nearest true distance %.4f m; deepest observed "
      "voxel %.3f m inside\n",
      surface_errors.size(), mean_error, p95_error, all_errors.size(),
      mean(all_errors) / voxelSize(), percentile(all_errors, 0.95) / voxelSize(), free_voxels,
      min_free_truth, -deepest_observed);
  EXPECT_GT(surface_errors.size(), 0.5 * all_errors.size());
  EXPECT_GT(surface_errors.size(), 1000u);
  EXPECT_LT(mean_error, 0.5);
  EXPECT_LT(p95_error, 1.0);
  EXPECT_GT(free_voxels, 10000);
  EXPECT_GT(min_free_truth, 0);
  // Voxels deeper than the truncation (as measured along a ray up to the image corner, 1.6 times
  // the optical z) plus half a voxel diagonal behind every surface are never observed.
  EXPECT_GT(deepest_observed, -(1.6 * truncation() + std::sqrt(3.0) / 2 * voxelSize()));
}

// A view into empty space marks the space along every ray as free up to the integration range,
// and nothing beyond it.
TEST_P(TsdfIntegratorTest, NoReturnClearsUpToIntegrationRange) {
  const Pose world_T_camera{Eigen::Vector3d(1.3, -2.1, 0.7),
                            Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()) *
                                               Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()))};
  const Frame frame = emptyFrame(world_T_camera);
  const TsdfIntegrator integrator = makeIntegrator(method());
  const double range = integrator.options().max_integration_range;
  TsdfLayer layer(voxelSize());
  const TsdfIntegrationResult result = integrator.integrate(frame.image, world_T_camera, layer);
  EXPECT_GT(result.voxels_updated, 0);
  EXPECT_EQ(result.changed_blocks, layer.blockIndices());

  const Pose camera_T_world = world_T_camera.inverse();
  const auto clearing_weight = static_cast<float>(1 / (range * range));
  int observed = 0;
  forEachObserved(layer, [&](const Eigen::Vector3d& c, const TsdfVoxel& v) {
    ++observed;
    ASSERT_EQ(v.distance, static_cast<float>(truncation()));
    // The projective method measures range as optical z and updates a voxel once per image; the
    // ray caster measures along the ray and updates a voxel once per ray through it.
    const Eigen::Vector3d c_camera = camera_T_world.transform(c);
    if (method() == Method::kProjective) {
      ASSERT_EQ(v.weight, clearing_weight);
      ASSERT_LE(c_camera.z(), range + 1e-9);
    } else {
      ASSERT_GE(v.weight, clearing_weight);
      ASSERT_LE(c_camera.norm(), range + voxelSize());
    }
  });
  EXPECT_GT(observed, 1000);

  // Points along the rays of the inner pixels, from where voxels are small in the image to a voxel
  // short of the range.
  const PinholeCamera& camera = frame.image.camera;
  for (int v = 40; v <= camera.height - 40; v += 20) {
    for (int u = 40; u <= camera.width - 40; u += 20) {
      const Eigen::Vector3d dir = camera.backProject(u, v, 1).normalized();
      for (double t = 1.5; t <= range - voxelSize(); t += 0.25) {
        const Eigen::Vector3d p = world_T_camera.transform(t * dir);
        const TsdfVoxel* voxel = layer.voxel(layer.voxelIndex(p));
        ASSERT_NE(voxel, nullptr) << "pixel (" << u << ", " << v << ") at " << t << " m";
        EXPECT_GT(voxel->weight, 0);
        EXPECT_EQ(voxel->distance, static_cast<float>(truncation()));
      }
    }
  }
}

// An obstacle appears where the map saw free space many times: a wall at 4.8 m, then a patch in
// the middle of the image at 1.5 m. Along the optical axis (through voxel centres, where both
// methods measure optical z) every voxel is checked against where it lies behind the patch: at
// the surface the measurement replaces the free-space history (new_surfaces_replace); from one
// voxel behind it to the truncation the voxel holds the frame's measurement alone (inside, not
// free); from there to new_surface_shadow deeper it is unobserved; beyond, still free. Beside the
// patch nothing changes. With the shadow off the stale free space stays. A second view of the
// patch is no new surface and resets nothing.
TEST_P(TsdfIntegratorTest, NewSurfacesEnterAtOnceAndTheirShadowBecomesUnobserved) {
  const double vs = voxelSize();
  const double t = truncation();
  constexpr double kWall = 4.8;
  constexpr double kPatch = 1.5;
  constexpr double kShadow = 1.0;
  const Pose world_T_camera{Eigen::Vector3d(0.5 * vs, 0.5 * vs, 0), Eigen::Quaterniond::Identity()};
  Frame wall = emptyFrame(world_T_camera);
  std::fill(wall.image.depth.begin(), wall.image.depth.end(), static_cast<float>(kWall));
  Frame patch = wall;
  const PinholeCamera& camera = wall.image.camera;
  for (int v = 80; v < 160; ++v) {
    for (int u = 110; u < 210; ++u) patch.image.depth[v * camera.width + u] = kPatch;
  }
  const auto axis = [&](TsdfLayer& layer, int k) -> TsdfVoxel& {
    return layer.allocateVoxel(VoxelIndex(0, 0, k));
  };
  // The voxel beside the patch (pixel column 40) at about optical z.
  const auto beside = [&](const TsdfLayer& layer, double z) {
    const TsdfVoxel* voxel = layer.voxel(layer.voxelIndex(camera.backProject(40, 120, z)));
    return voxel ? *voxel : TsdfVoxel{};
  };
  constexpr double kEps = 1e-6;  // voxel centres this close to an interval's end are not judged

  for (const double shadow : {kShadow, 0.0}) {
    SCOPED_TRACE("new_surface_shadow " + std::to_string(shadow));
    TsdfIntegratorOptions options;
    options.method = method();
    options.new_surface_shadow = shadow;
    const TsdfIntegrator integrator(options);
    TsdfLayer layer(vs);
    for (int i = 0; i < 5; ++i) integrator.integrate(wall.image, world_T_camera, layer);
    const Snapshot before = snapshot(layer);
    const TsdfIntegrationResult result = integrator.integrate(patch.image, world_T_camera, layer);

    int surface = 0, inside = 0, unobserved = 0, beyond = 0;
    for (int k = 0; (k + 0.5) * vs < kWall - t; ++k) {
      const double depth = (k + 0.5) * vs - kPatch;  // behind the patch, along the axis
      const TsdfVoxel voxel = axis(layer, k);
      SCOPED_TRACE("voxel " + std::to_string(k) + ", " + std::to_string(depth) + " m behind");
      if (std::abs(depth) <= vs - kEps) {
        EXPECT_LE(std::abs(voxel.distance), vs);  // replaced, not averaged with free space
        ++surface;
      } else if (depth > vs + kEps && depth < t - kEps) {
        if (shadow > 0) {
          EXPECT_LT(voxel.distance, 0);  // the frame's measurement alone: inside
        } else {
          EXPECT_GT(voxel.distance, 0);  // stale free space outweighs it
        }
        ++inside;
      } else if (depth > t + kEps && depth < t + kShadow - kEps) {
        if (shadow > 0) {
          EXPECT_EQ(voxel.weight, 0);
        } else {
          EXPECT_GT(voxel.weight, 0);
          EXPECT_EQ(voxel.distance, static_cast<float>(t));
        }
        ++unobserved;
      } else if (depth > t + kShadow + kEps) {
        EXPECT_GT(voxel.weight, 0);
        EXPECT_EQ(voxel.distance, static_cast<float>(t));
        ++beyond;
      }
      // Beside the patch the same depths are still seen free.
      if (depth > vs && depth < t + kShadow) {
        EXPECT_GT(beside(layer, (k + 0.5) * vs).weight, 0);
        EXPECT_EQ(beside(layer, (k + 0.5) * vs).distance, static_cast<float>(t));
      }
    }
    // Every interval was judged.
    EXPECT_GE(surface, 1);
    EXPECT_GE(inside, 1);
    EXPECT_GE(unobserved, static_cast<int>(kShadow / vs) - 2);
    EXPECT_GE(beyond, 2);
    // Every block whose voxels the frame changed, the shadow's included, is reported changed.
    for (const auto& [key, block] : snapshot(layer)) {
      if (sameVoxels(block, before.at(key))) continue;
      const BlockIndex b(std::get<0>(key), std::get<1>(key), std::get<2>(key));
      EXPECT_TRUE(std::binary_search(result.changed_blocks.begin(), result.changed_blocks.end(), b,
                                     indexLess));
    }

    // Seen again, the patch is no new surface: free space in its shadow (as if a view had shown
    // it since) is not reset again.
    const int k_shadow = static_cast<int>(std::floor((kPatch + t + 0.5 * kShadow) / vs));
    axis(layer, k_shadow) = TsdfVoxel{static_cast<float>(t), 1.0f};
    integrator.integrate(patch.image, world_T_camera, layer);
    EXPECT_EQ(axis(layer, k_shadow).weight, 1.0f);
  }
}

// The shadow is for obstacles that appear: a flight through a static forest keeps the free space
// it observed. At trunk silhouettes rays that passed beside a trunk leave the voxels its surface
// cuts clearly free, and a later view that hits the trunk there would count as a new surface
// without the probes behind the return and the cosine gate.
TEST(TsdfIntegrator, AStaticForestFlightKeepsItsFreeSpace) {
  const std::vector<Frame> frames = forestFrames(20);
  TsdfIntegratorOptions off;
  off.new_surface_shadow = 0;
  const TsdfIntegrator with(TsdfIntegratorOptions{}), without(off);
  TsdfLayer a(0.1), b(0.1);
  for (const Frame& frame : frames) {
    with.integrate(frame.image, frame.world_T_camera, a);
    without.integrate(frame.image, frame.world_T_camera, b);
  }
  int free_without = 0, lost = 0;
  forEachObserved(b, [&](const Eigen::Vector3d& c, const TsdfVoxel& v) {
    if (!(v.distance > 0)) return;
    ++free_without;
    const TsdfVoxel* voxel = a.voxel(a.voxelIndex(c));
    if (voxel == nullptr || voxel->weight == 0) ++lost;
  });
  std::printf("static forest flight: %d of %d observed free voxels lost to shadows\n", lost,
              free_without);
  EXPECT_GT(free_without, 100000);
  // 3 are lost; without the probes and the cosine gate, 698.
  EXPECT_LE(lost, free_without / 20000);
}

// The projective integrator skips each voxel row's stretch outside the image analytically; in
// empty space it must still update exactly the voxels whose centres project into the image at
// optical z in (0, range], found here by brute force, from cameras at random poses.
TEST(TsdfIntegrator, ProjectiveUpdatesEveryVoxelInTheFrustum) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<> unit(-1, 1);
  const double vs = 0.2;
  const TsdfIntegrator integrator = makeIntegrator(Method::kProjective);
  const double range = integrator.options().max_integration_range;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(unit(rng), unit(rng), unit(rng), unit(rng)).normalized();
    const Pose world_T_camera{Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 3, q};
    const Frame frame = emptyFrame(world_T_camera);
    const PinholeCamera& camera = frame.image.camera;
    TsdfLayer layer(vs);
    const TsdfIntegrationResult result = integrator.integrate(frame.image, world_T_camera, layer);

    const Pose camera_T_world = world_T_camera.inverse();
    // The frustum's far corners are sqrt(1 + 1 + 0.75^2) ranges away.
    const VoxelIndex lo = layer.voxelIndex(world_T_camera.position.array() - 1.6 * range);
    const VoxelIndex hi = layer.voxelIndex(world_T_camera.position.array() + 1.6 * range);
    int64_t inside = 0;
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const Eigen::Vector3d p =
              camera_T_world.transform(layer.voxelCenter(VoxelIndex(x, y, z)));
          if (!(p.z() > 0 && p.z() <= range)) continue;
          const double column = camera.fx * p.x() / p.z() + camera.cx + 0.5;
          const double row = camera.fy * p.y() / p.z() + camera.cy + 0.5;
          if (column >= 0 && column < camera.width && row >= 0 && row < camera.height) ++inside;
        }
      }
    }
    EXPECT_GT(inside, 10000) << "trial " << trial;
    EXPECT_EQ(result.voxels_updated, inside) << "trial " << trial;
  }
}

// Without carving, the integrator visits only the blocks near returns: from an empty map, every
// voxel it observes holds what the carving integrator gives it, and every voxel the carving one
// puts within the truncation of a return in range is among them (the block cover misses none);
// pixels without a return change nothing.
TEST(TsdfIntegrator, WithoutCarvingOnlyTheVoxelsNearReturnsChange) {
  TsdfIntegratorOptions options;
  const TsdfIntegrator carving(options);
  options.carve_free_space = false;
  const TsdfIntegrator surfaces(options);
  const double range = options.max_integration_range;
  for (const double vs : {0.2, 0.1, 0.05}) {
    const double truncation = options.truncation_voxels * vs;
    for (const Frame& frame : forestFrames(4)) {
      TsdfLayer all(vs), near(vs);
      carving.integrate(frame.image, frame.world_T_camera, all);
      const TsdfIntegrationResult result =
          surfaces.integrate(frame.image, frame.world_T_camera, near);
      const Pose camera_T_world = frame.world_T_camera.inverse();
      int64_t observed_all = 0, in_band = 0, observed_near = 0, differ = 0, missed = 0;
      forEachObserved(all, [&](const Eigen::Vector3d& c, const TsdfVoxel& v) {
        ++observed_all;
        const TsdfVoxel* other = near.voxel(near.voxelIndex(c));
        const bool seen = other != nullptr && other->weight > 0;
        if (seen && (other->distance != v.distance || other->weight != v.weight)) ++differ;
        if (std::abs(v.distance) < truncation &&
            camera_T_world.transform(c).z() <= range - truncation) {
          ++in_band;
          missed += !seen;
        }
      });
      forEachObserved(near, [&](const Eigen::Vector3d&, const TsdfVoxel&) { ++observed_near; });
      EXPECT_GT(in_band, 1000) << vs;
      EXPECT_EQ(missed, 0) << vs;
      EXPECT_EQ(differ, 0) << vs;
      EXPECT_GE(observed_near, in_band) << vs;
      EXPECT_LT(observed_near, observed_all / 2) << vs;
      EXPECT_EQ(result.voxels_updated, observed_near) << vs;
    }
  }
  // Nothing seen: nothing changes.
  TsdfLayer layer(0.1);
  const Frame empty = emptyFrame(Pose{});
  const TsdfIntegrationResult result = surfaces.integrate(empty.image, empty.world_T_camera, layer);
  EXPECT_EQ(result.voxels_updated, 0);
  EXPECT_TRUE(result.changed_blocks.empty());
  EXPECT_EQ(layer.numBlocks(), 0u);
  // The ray caster has no such mode.
  options.method = Method::kRaycast;
  EXPECT_THROW(TsdfIntegrator{options}, std::invalid_argument);
}

// Depths below the image's min_range are not measurements: they neither mark surfaces nor clear.
TEST_P(TsdfIntegratorTest, IgnoresReturnsBelowMinRange) {
  Frame frame = emptyFrame(Pose{});
  frame.image.min_range = 0.5;
  std::fill(frame.image.depth.begin(), frame.image.depth.end(), 0.4f);
  TsdfLayer layer(voxelSize());
  const TsdfIntegrationResult result =
      makeIntegrator(method()).integrate(frame.image, frame.world_T_camera, layer);
  EXPECT_EQ(result.voxels_updated, 0);
  EXPECT_TRUE(result.changed_blocks.empty());
  EXPECT_EQ(layer.numBlocks(), 0u);
}

// The same frames give the same voxels bit for bit, and changed_blocks lists exactly the blocks
// whose content changed; no block is left allocated without an observed voxel.
TEST_P(TsdfIntegratorTest, DeterministicWithExactChangedBlocks) {
  const std::vector<Frame> frames = forestFrames(3);
  const TsdfIntegrator integrator = makeIntegrator(method());
  TsdfLayer first(voxelSize());
  for (const Frame& frame : frames) {
    const Snapshot before = snapshot(first);
    const TsdfIntegrationResult result =
        integrator.integrate(frame.image, frame.world_T_camera, first);
    std::vector<BlockIndex> expected;
    for (const BlockIndex& b : first.blockIndices()) {
      const auto old = before.find(std::tuple{b.x(), b.y(), b.z()});
      if (old == before.end() || !sameVoxels(old->second, *first.block(b))) expected.push_back(b);
    }
    EXPECT_EQ(result.changed_blocks, expected);
    EXPECT_FALSE(expected.empty());
    EXPECT_GE(result.voxels_updated, static_cast<int64_t>(expected.size()));
  }
  for (const BlockIndex& b : first.blockIndices()) {
    const auto& voxels = first.block(b)->voxels;
    EXPECT_TRUE(
        std::any_of(voxels.begin(), voxels.end(), [](const TsdfVoxel& v) { return v.weight > 0; }))
        << "empty block " << b.transpose();
  }

  TsdfLayer second(voxelSize());
  for (const Frame& frame : frames) integrator.integrate(frame.image, frame.world_T_camera, second);
  ASSERT_EQ(first.blockIndices(), second.blockIndices());
  for (const BlockIndex& b : first.blockIndices()) {
    EXPECT_TRUE(sameVoxels(*first.block(b), *second.block(b))) << "block " << b.transpose();
  }
}

// Each thread keeps the last camera's pixel rays: a frame of another camera of the same size
// (another focal length) after it maps as in a thread that never saw the first.
TEST_P(TsdfIntegratorTest, AnotherCameraOfTheSameSizeIsMappedWithItsOwnRays) {
  const std::vector<Frame> frames = forestFrames(2);
  Frame narrow = frames[1];
  narrow.image.camera = PinholeCamera::fromHorizontalFov(320, 240, pi / 3);
  const TsdfIntegrator integrator = makeIntegrator(method());
  TsdfLayer after_other(voxelSize());
  integrator.integrate(frames[0].image, frames[0].world_T_camera, after_other);
  after_other = TsdfLayer(voxelSize());
  integrator.integrate(narrow.image, narrow.world_T_camera, after_other);
  TsdfLayer alone(voxelSize());
  std::thread([&] { integrator.integrate(narrow.image, narrow.world_T_camera, alone); }).join();
  ASSERT_EQ(after_other.blockIndices(), alone.blockIndices());
  ASSERT_FALSE(alone.blockIndices().empty());
  for (const BlockIndex& b : alone.blockIndices()) {
    EXPECT_TRUE(sameVoxels(*after_other.block(b), *alone.block(b))) << "block " << b.transpose();
  }
}

// changed_voxels names, per changed block, exactly the voxels whose distance changed bit for bit
// or whose weight crossed observed_weight (here one that voxels seen from beyond 3.2 m cross on
// their second or third frame): what the ESDF classifies again. With and without carving.
TEST_P(TsdfIntegratorTest, ReportsTheVoxelsWhoseDistanceOrObservednessChanged) {
  const std::vector<Frame> frames = forestFrames(4);
  for (const bool carve : {true, false}) {
    if (!carve && method() == Method::kRaycast) continue;
    TsdfIntegratorOptions options;
    options.method = method();
    options.carve_free_space = carve;
    options.observed_weight = 0.1;
    const TsdfIntegrator integrator(options);
    TsdfLayer layer(voxelSize());
    int64_t crossings = 0;
    int64_t reported = 0;
    for (const Frame& frame : frames) {
      const Snapshot before = snapshot(layer);
      const TsdfIntegrationResult result =
          integrator.integrate(frame.image, frame.world_T_camera, layer);
      EXPECT_EQ(result.observed_weight, 0.1f);
      ASSERT_EQ(result.changed_voxels.size(), result.changed_blocks.size());
      for (size_t k = 0; k < result.changed_blocks.size(); ++k) {
        const BlockIndex& b = result.changed_blocks[k];
        const auto old = before.find(std::tuple{b.x(), b.y(), b.z()});
        const TsdfLayer::BlockType empty(b);
        const auto& was = old != before.end() ? old->second.voxels : empty.voxels;
        const auto& is = layer.block(b)->voxels;
        BlockVoxels expected;
        for (int i = 0; i < kVoxelsPerBlock; ++i) {
          const bool crossed = (was[i].weight >= 0.1f) != (is[i].weight >= 0.1f);
          crossings += crossed && std::bit_cast<uint32_t>(was[i].distance) ==
                                      std::bit_cast<uint32_t>(is[i].distance);
          if (crossed ||
              std::bit_cast<uint32_t>(was[i].distance) != std::bit_cast<uint32_t>(is[i].distance)) {
            expected.insert(i);
            ++reported;
          }
        }
        EXPECT_TRUE(result.changed_voxels[k] == expected)
            << "block " << b.transpose() << (carve ? "" : " without carving");
      }
    }
    EXPECT_GT(reported, 0);
    // Some voxels are reported for their weight alone (free space at the truncation).
    EXPECT_GT(crossings, 0) << (carve ? "" : "without carving");
  }
}

// Saturated voxels that a measurement leaves as they were are updated but not changed.
TEST_P(TsdfIntegratorTest, SaturatedRepeatsChangeNothing) {
  TsdfIntegratorOptions options;
  options.method = method();
  options.max_weight = 0.01;  // below the clearing weight 1/25: saturated after one frame
  const TsdfIntegrator integrator(options);
  const Frame frame = emptyFrame(Pose{});
  TsdfLayer layer(voxelSize());
  const TsdfIntegrationResult first =
      integrator.integrate(frame.image, frame.world_T_camera, layer);
  const Snapshot before = snapshot(layer);
  const TsdfIntegrationResult second =
      integrator.integrate(frame.image, frame.world_T_camera, layer);
  EXPECT_FALSE(first.changed_blocks.empty());
  EXPECT_TRUE(second.changed_blocks.empty());
  EXPECT_EQ(second.voxels_updated, first.voxels_updated);
  ASSERT_EQ(snapshot(layer).size(), before.size());
  forEachObserved(layer,
                  [&](const Eigen::Vector3d&, const TsdfVoxel& v) { ASSERT_EQ(v.weight, 0.01f); });
}

// Where both methods observe the surface, they agree. They differ by design away from the
// image centre: the projective distance is the ray distance times the cosine of the ray's angle.
TEST(TsdfIntegrator, ProjectiveAndRaycastAgreeNearSurfaces) {
  const std::vector<Frame> frames = forestFrames(3);
  for (const double voxel_size : {0.2, 0.1}) {
    TsdfLayer projective(voxel_size), raycast(voxel_size);
    for (const Frame& frame : frames) {
      makeIntegrator(Method::kProjective).integrate(frame.image, frame.world_T_camera, projective);
      makeIntegrator(Method::kRaycast).integrate(frame.image, frame.world_T_camera, raycast);
    }
    std::vector<double> differences;
    forEachObserved(projective, [&](const Eigen::Vector3d& c, const TsdfVoxel& p) {
      const TsdfVoxel* r = raycast.voxel(raycast.voxelIndex(c));
      if (!r || r->weight <= 0) return;
      if (std::abs(p.distance) < voxel_size && std::abs(r->distance) < voxel_size) {
        differences.push_back(std::abs(p.distance - r->distance));
      }
    });
    const double mean_difference = mean(differences);
    std::printf("voxel %.1f m: %zu voxels near surfaces, mean |projective - raycast| %.4f m\n",
                voxel_size, differences.size(), mean_difference);
    // Hundreds of voxels at 0.2 m, four times as many at 0.1 m (surfaces are areas).
    EXPECT_GT(static_cast<double>(differences.size()), 300 * std::pow(0.2 / voxel_size, 2));
    EXPECT_LT(mean_difference, 0.25 * voxel_size);
  }
}

TEST(TsdfIntegrator, RefusesBadInput) {
  const TsdfIntegrator integrator = makeIntegrator(Method::kProjective);
  const Frame good = emptyFrame(Pose{});
  TsdfLayer layer(0.2);
  const auto refuses = [&](const DepthImage& image, const Pose& pose) {
    EXPECT_THROW(integrator.integrate(image, pose, layer), std::invalid_argument);
  };

  Frame frame = good;
  frame.image.depth.pop_back();
  refuses(frame.image, frame.world_T_camera);
  frame = good;
  frame.image.camera.fx = 0;
  refuses(frame.image, frame.world_T_camera);
  frame = good;
  frame.image.max_range = frame.image.min_range;
  refuses(frame.image, frame.world_T_camera);
  for (const float depth :
       {-1.0f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    frame = good;
    frame.image.depth.back() = depth;
    refuses(frame.image, frame.world_T_camera);
  }
  Pose pose;
  pose.position.y() = std::numeric_limits<double>::quiet_NaN();
  refuses(good.image, pose);
  pose = Pose{};
  pose.orientation.w() = std::numeric_limits<double>::quiet_NaN();
  refuses(good.image, pose);
  pose = Pose{};
  pose.orientation.coeffs() *= 2;
  refuses(good.image, pose);
  // Refused input leaves the layer alone, even when only the last pixel is bad.
  EXPECT_EQ(layer.numBlocks(), 0u);

  // The good frame itself is accepted.
  EXPECT_NO_THROW(integrator.integrate(good.image, good.world_T_camera, layer));

  for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    TsdfIntegratorOptions options;
    options.truncation_voxels = bad;
    EXPECT_THROW(TsdfIntegrator{options}, std::invalid_argument);
    options = {};
    options.max_integration_range = bad;
    EXPECT_THROW(TsdfIntegrator{options}, std::invalid_argument);
    options = {};
    options.max_weight = bad;
    EXPECT_THROW(TsdfIntegrator{options}, std::invalid_argument);
    if (bad != 0) {  // 0 turns the shadow off
      options = {};
      options.new_surface_shadow = bad;
      EXPECT_THROW(TsdfIntegrator{options}, std::invalid_argument);
    }
  }
  TsdfIntegratorOptions off;
  off.new_surface_shadow = 0;
  EXPECT_NO_THROW(TsdfIntegrator{off});
  // A parameter file sets the shadow, but cannot ask for a negative one either.
  EXPECT_EQ(loadParamsFromString<TsdfIntegratorOptions>("new_surface_shadow: 0.5\n", "test")
                .new_surface_shadow,
            0.5);
  EXPECT_THROW(loadParamsFromString<TsdfIntegratorOptions>("new_surface_shadow: -0.5\n", "test"),
               std::exception);
}

TEST(TsdfIntegrator, OptionsLoadFromYaml) {
  const auto options = loadParamsFromString<TsdfIntegratorOptions>(
      "method: raycast\ntruncation_voxels: 3\nmax_integration_range: 4.5\n", "test");
  EXPECT_EQ(options.method, Method::kRaycast);
  EXPECT_EQ(options.truncation_voxels, 3);
  EXPECT_EQ(options.max_integration_range, 4.5);
  EXPECT_EQ(options.max_weight, 1e4);
  EXPECT_EQ(loadParamsFromString<TsdfIntegratorOptions>("", "test").method, Method::kProjective);
  EXPECT_NE(describeParams<TsdfIntegratorOptions>().find("method: projective"), std::string::npos);
  EXPECT_THROW(loadParamsFromString<TsdfIntegratorOptions>("method: merged\n", "test"), ParamError);
  EXPECT_THROW(loadParamsFromString<TsdfIntegratorOptions>("truncation_voxels: 0\n", "test"),
               ParamError);
}

}  // namespace
}  // namespace thicket::mapper

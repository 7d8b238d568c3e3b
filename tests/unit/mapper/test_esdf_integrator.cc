#include "thicket/mapper/esdf_integrator.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "forest_flight.h"
#include "thicket/common/params.h"
#include "thicket/mapper/tsdf_integrator.h"
#include "thicket/sim/render.h"

namespace {

using thicket::BlockIndex;
using thicket::BlockVoxels;
using thicket::EsdfLayer;
using thicket::EsdfVoxel;
using thicket::indexLess;
using thicket::kVoxelsPerBlock;
using thicket::TsdfLayer;
using thicket::TsdfVoxel;
using thicket::VoxelIndex;
using thicket::mapper::EsdfIntegrator;
using thicket::mapper::EsdfIntegratorOptions;
using thicket::mapper::EsdfUpdateResult;

// No TSDF block changed (a bare {} would be ambiguous: update() takes blocks or an integration).
const std::vector<BlockIndex> kNoChange;

// Far from every test world: the unknown-space spheres stay out of the way there.
const Eigen::Vector3d kFarAway(-100, -100, 50);

// Vertical cylinders of unbounded height and the ground plane z = 0.
struct Cylinder {
  double x, y, radius;
};
struct World {
  std::vector<Cylinder> cylinders;

  double signedDistance(const Eigen::Vector3d& p) const {
    double d = p.z();
    for (const Cylinder& c : cylinders) {
      d = std::min(d, std::hypot(p.x() - c.x, p.y() - c.y) - c.radius);
    }
    return d;
  }
  // How many of the objects (ground included) contain p.
  int containing(const Eigen::Vector3d& p) const {
    int n = p.z() < 0;
    for (const Cylinder& c : cylinders) n += std::hypot(p.x() - c.x, p.y() - c.y) < c.radius;
    return n;
  }
};

struct Box {
  Eigen::Vector3d lo, hi;
};

template <class F>
void forEachVoxel(const TsdfLayer& layer, const Box& box, F&& f) {
  const VoxelIndex lo = layer.voxelIndex(box.lo);
  const VoxelIndex hi = layer.voxelIndex(box.hi);
  for (int z = lo.z(); z < hi.z(); ++z) {
    for (int y = lo.y(); y < hi.y(); ++y) {
      for (int x = lo.x(); x < hi.x(); ++x) f(VoxelIndex(x, y, z));
    }
  }
}

// Observes every voxel of the box as a perfect sensor would: weight 1, the true signed distance
// clamped to +-truncation. With see_deep false, voxels deeper than the truncation behind a
// surface stay as they were (a real TSDF never sees them). Adds the blocks it changed.
void observe(TsdfLayer& tsdf, const World& world, const Box& box, double truncation, bool see_deep,
             std::vector<BlockIndex>& changed) {
  forEachVoxel(tsdf, box, [&](const VoxelIndex& v) {
    const double d = world.signedDistance(tsdf.voxelCenter(v));
    if (!see_deep && d < -truncation) return;
    TsdfVoxel& voxel = tsdf.allocateVoxel(v);
    voxel.distance = static_cast<float>(std::clamp(d, -truncation, truncation));
    voxel.weight = 1;
    changed.push_back(thicket::blockOfVoxel(v));
  });
}

// Whole-layer equality: the same blocks, flags, and distances within tolerance.
::testing::AssertionResult sameEsdf(const EsdfLayer& a, const EsdfLayer& b, double tolerance) {
  const std::vector<BlockIndex> blocks = a.blockIndices();
  if (blocks != b.blockIndices()) {
    return ::testing::AssertionFailure()
           << "block sets differ: " << a.numBlocks() << " vs " << b.numBlocks() << " blocks";
  }
  int64_t mismatches = 0;
  int64_t farther = 0;  // larger magnitude in a, among those that differ only in distance
  double largest = 0;
  std::string first;
  for (const BlockIndex& index : blocks) {
    const auto& va = a.block(index)->voxels;
    const auto& vb = b.block(index)->voxels;
    for (int i = 0; i < kVoxelsPerBlock; ++i) {
      if (va[i].observed == vb[i].observed && va[i].fixed == vb[i].fixed &&
          std::abs(va[i].distance - vb[i].distance) <= tolerance) {
        continue;
      }
      if (va[i].observed == vb[i].observed && va[i].fixed == vb[i].fixed) {
        farther += std::abs(va[i].distance) > std::abs(vb[i].distance);
        largest = std::max(largest, static_cast<double>(std::abs(va[i].distance - vb[i].distance)));
      }
      if (mismatches++ == 0) {
        const VoxelIndex v = thicket::voxelOfBlock(index, i);
        first = "voxel (" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " +
                std::to_string(v.z()) + "): " + std::to_string(va[i].distance) + " obs " +
                std::to_string(va[i].observed) + " fixed " + std::to_string(va[i].fixed) + " vs " +
                std::to_string(vb[i].distance) + " obs " + std::to_string(vb[i].observed) +
                " fixed " + std::to_string(vb[i].fixed);
      }
    }
  }
  if (mismatches == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << mismatches << " voxels differ (" << farther
                                       << " farther from the surface in the first layer, largest "
                                       << "difference " << largest << " m), first " << first;
}

// A byte copy of a layer, to see exactly which blocks a call changed.
using Snapshot = std::map<std::array<int, 3>, std::vector<uint64_t>>;

uint64_t snapshot(const EsdfVoxel& v) {
  return uint64_t{std::bit_cast<uint32_t>(v.distance)} << 2 | uint64_t{v.observed} << 1 |
         uint64_t{v.fixed};
}

Snapshot snapshot(const EsdfLayer& layer) {
  Snapshot s;
  for (const BlockIndex& index : layer.blockIndices()) {
    std::vector<uint64_t>& bytes = s[{index.x(), index.y(), index.z()}];
    for (const EsdfVoxel& v : layer.block(index)->voxels) bytes.push_back(snapshot(v));
  }
  return s;
}

std::vector<BlockIndex> toIndices(const std::vector<std::array<int, 3>>& keys) {
  std::vector<BlockIndex> out;
  for (const auto& k : keys) out.emplace_back(k[0], k[1], k[2]);
  std::sort(out.begin(), out.end(), indexLess);
  return out;
}

// The report of an incremental update names exactly the blocks that changed or went, and in each
// changed block exactly the voxels that differ from before (from the zero voxel in a new block),
// which is all the map's deltas carry.
void expectReportMatches(const Snapshot& before, const Snapshot& after,
                         const EsdfUpdateResult& result) {
  std::vector<std::array<int, 3>> changed, removed;
  std::vector<BlockVoxels> changed_voxels;
  for (const auto& [key, bytes] : after) {
    const auto it = before.find(key);
    if (it != before.end() && it->second == bytes) continue;
    changed.push_back(key);
    BlockVoxels& voxels = changed_voxels.emplace_back();
    for (int i = 0; i < kVoxelsPerBlock; ++i) {
      if (bytes[i] != (it != before.end() ? it->second[i] : snapshot(EsdfVoxel{}))) {
        voxels.insert(i);
      }
    }
  }
  for (const auto& [key, bytes] : before) {
    if (!after.count(key)) removed.push_back(key);
  }
  EXPECT_EQ(result.changed_blocks, toIndices(changed));
  EXPECT_TRUE(result.changed_voxels == changed_voxels);
  EXPECT_EQ(result.removed_blocks, toIndices(removed));
  EXPECT_EQ(result.voxels_updated > 0, !changed.empty() || !removed.empty());
}

// The ESDF distance at p; NaN where no block is allocated.
float distanceAt(const EsdfLayer& esdf, const Eigen::Vector3d& p) {
  const EsdfVoxel* v = esdf.voxel(esdf.voxelIndex(p));
  return v != nullptr ? v->distance : std::numeric_limits<float>::quiet_NaN();
}

// The length of the shortest 26-connected path along offset d in free space [voxels].
double octile(const VoxelIndex& d) {
  std::array<int, 3> a{std::abs(d.x()), std::abs(d.y()), std::abs(d.z())};
  std::sort(a.begin(), a.end());
  return a[0] * std::sqrt(3.0) + (a[1] - a[0]) * std::sqrt(2.0) + (a[2] - a[1]);
}

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return values[static_cast<size_t>(q * (values.size() - 1))];
}

double mean(const std::vector<double>& values) {
  double sum = 0;
  for (const double v : values) sum += v;
  return sum / values.size();
}

double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// ---------------------------------------------------------------------------------------------

// How far the nearest voxel of `tsdf` that `options` call unobserved is from v (capped beyond
// max_distance), where the observed voxels are a box of the grid: straight across the nearest
// face, a whole number of voxels.
double unobservedDistance(const TsdfLayer& tsdf, const VoxelIndex& v,
                          const EsdfIntegratorOptions& options) {
  const int max_steps = static_cast<int>(std::ceil(options.max_distance / tsdf.voxelSize())) + 1;
  int nearest = max_steps;
  for (int axis = 0; axis < 3; ++axis) {
    for (const int direction : {-1, 1}) {
      VoxelIndex u = v;
      for (int step = 1; step < nearest; ++step) {
        u[axis] += direction;
        const TsdfVoxel* voxel = tsdf.voxel(u);
        if (voxel == nullptr || voxel->weight < options.min_weight) {
          nearest = step;
          break;
        }
      }
    }
  }
  return nearest * tsdf.voxelSize();
}

// The ESDF of a fully observed analytic world against its true signed distance. With the paper's
// sphere, the vehicle is far away and the world alone decides; with every unobserved voxel
// occupied, the truth is the nearer of the world's surface and the unobserved space around the
// observed box.
void checkGroundTruth(double voxel_size, bool occupied_everywhere) {
  const World world{
      {{2.5, 3.0, 0.5}, {6.0, 2.5, 0.3}, {5.0, 6.5, 0.8}, {8.0, 7.5, 0.4}, {3.0, 8.0, 0.6}}};
  const Box box{{0, 0, -0.6}, {10, 10, 2.4}};
  const double truncation = 4 * voxel_size;
  TsdfLayer tsdf(voxel_size);
  std::vector<BlockIndex> changed;
  observe(tsdf, world, box, truncation, /*see_deep=*/true, changed);

  EsdfIntegratorOptions options;
  options.occupied_everywhere = occupied_everywhere;
  EsdfIntegrator integrator(options);
  integrator.setInitialPosition(kFarAway);
  EsdfLayer esdf(voxel_size);
  const auto start = std::chrono::steady_clock::now();
  integrator.recompute(tsdf, kFarAway, esdf);
  const double ms = millisecondsSince(start);

  const float band = static_cast<float>(options.surface_band_voxels * voxel_size);
  std::vector<double> free_errors, inside_errors;
  forEachVoxel(tsdf, box, [&](const VoxelIndex& v) {
    const Eigen::Vector3d c = tsdf.voxelCenter(v);
    const double world_truth = world.signedDistance(c);
    const double truth =
        occupied_everywhere
            ? std::copysign(std::min(std::abs(world_truth), unobservedDistance(tsdf, v, options)),
                            world_truth)
            : world_truth;
    const EsdfVoxel* voxel = esdf.voxel(v);
    ASSERT_NE(voxel, nullptr);
    ASSERT_TRUE(voxel->observed);
    EXPECT_EQ(voxel->fixed, std::abs(tsdf.voxel(v)->distance) <= band);
    if (voxel->fixed) return;
    if (truth >= options.max_distance) {
      EXPECT_FLOAT_EQ(voxel->distance, options.max_distance);
    } else if (truth > 0 && truth < options.max_distance - voxel_size) {
      free_errors.push_back((voxel->distance - truth) / voxel_size);
    } else if (truth < 0 && world.containing(c) == 1) {
      // Where objects overlap, the minimum of their distances is not the distance to the union.
      inside_errors.push_back((truth - voxel->distance) / voxel_size);
    }
  });
  ASSERT_GT(free_errors.size(), 1000u);
  ASSERT_GT(inside_errors.size(), 100u);
  const double free_mean = mean(free_errors), free_p95 = percentile(free_errors, 0.95);
  const double inside_mean = mean(inside_errors), inside_p95 = percentile(inside_errors, 0.95);
  std::printf(
      "voxel %.2f m: recompute %.1f ms, %zu blocks; error [voxels] free (%zu): mean %.3f p95 "
      "%.3f min %.3f max %.3f; inside (%zu): mean %.3f p95 %.3f min %.3f max %.3f\n",
      voxel_size, ms, esdf.numBlocks(), free_errors.size(), free_mean, free_p95,
      percentile(free_errors, 0), percentile(free_errors, 1), inside_errors.size(), inside_mean,
      inside_p95, percentile(inside_errors, 0), percentile(inside_errors, 1));
  // Paths from a site carrying its exact distance never beat the straight line (triangle
  // inequality), so the ESDF only overestimates.
  EXPECT_GE(percentile(free_errors, 0), -1e-3);
  EXPECT_LT(free_mean, 0.5);
  EXPECT_LT(free_p95, 1.5);
  EXPECT_GE(percentile(inside_errors, 0), -1e-3);
  EXPECT_LT(inside_mean, 0.5);
  EXPECT_LT(inside_p95, 1.5);
}

TEST(EsdfIntegrator, GroundTruthAt20cm) {
  checkGroundTruth(0.2, /*occupied_everywhere=*/true);
}
TEST(EsdfIntegrator, GroundTruthAt10cm) {
  checkGroundTruth(0.1, /*occupied_everywhere=*/true);
}
TEST(EsdfIntegrator, GroundTruthWithTheOccupiedSphereAt20cm) {
  checkGroundTruth(0.2, /*occupied_everywhere=*/false);
}
TEST(EsdfIntegrator, GroundTruthWithTheOccupiedSphereAt10cm) {
  checkGroundTruth(0.1, /*occupied_everywhere=*/false);
}

// ---------------------------------------------------------------------------------------------

// A random sequence of TSDF edits and vehicle moves; after each update() the layer must equal
// recompute() and the report must name exactly the blocks that changed. Returns the final layer.
Snapshot runRandomSequence(uint64_t seed, int steps, bool check, bool occupied_everywhere) {
  std::mt19937_64 rng(seed);
  auto uniform = [&](double lo, double hi) {
    return std::uniform_real_distribution<>(lo, hi)(rng);
  };
  const double vs = 0.2;
  const double truncation = 4 * vs;
  EsdfIntegratorOptions options;
  // Spheres and saturation smaller than the 8 x 8 m world, so that all of them act in it.
  options.max_distance = 1.2;
  options.clear_radius = 1.0;
  options.occupied_radius = 2.4;
  options.occupied_everywhere = occupied_everywhere;
  World world;
  for (int i = 0; i < 4; ++i) {
    world.cylinders.push_back({uniform(1, 7), uniform(1, 7), uniform(0.2, 0.6)});
  }
  auto cylinderBox = [&](const Cylinder& c) {
    const double r = c.radius + truncation + vs;
    return Box{{c.x - r, c.y - r, -1.0}, {c.x + r, c.y + r, 3.0}};
  };
  auto randomBox = [&]() {
    const Eigen::Vector3d lo(uniform(-1, 7), uniform(-1, 7), uniform(-1, 2));
    return Box{lo, lo + Eigen::Vector3d(uniform(0.5, 3), uniform(0.5, 3), uniform(0.5, 2))};
  };

  TsdfLayer tsdf(vs);
  std::vector<BlockIndex> changed;
  observe(tsdf, world, Box{{0, 0, -1}, {4, 8, 3}}, truncation, /*see_deep=*/false, changed);
  Eigen::Vector3d position(2, 2, 1.5);
  EsdfIntegrator integrator(options);
  integrator.setInitialPosition(position);
  EsdfIntegrator reference(options);
  reference.setInitialPosition(position);
  EsdfLayer esdf(vs);
  // The first update builds from scratch: a mirror must take its blocks whole.
  const EsdfUpdateResult first = integrator.update(tsdf, changed, position, esdf);
  EXPECT_FALSE(first.changed_blocks.empty());
  EXPECT_EQ(first.changed_voxels.size(), first.changed_blocks.size());
  for (const BlockVoxels& voxels : first.changed_voxels) EXPECT_TRUE(voxels == BlockVoxels::all());

  for (int step = 0; step < steps; ++step) {
    changed.clear();
    const int kind = std::uniform_int_distribution<>(0, 6)(rng);
    switch (kind) {
      case 0: {  // a new obstacle (lowers)
        world.cylinders.push_back({uniform(0, 8), uniform(0, 8), uniform(0.2, 0.7)});
        observe(tsdf, world, cylinderBox(world.cylinders.back()), truncation, false, changed);
        break;
      }
      case 1: {  // an obstacle disappears (raises)
        if (world.cylinders.empty()) break;
        const size_t i = std::uniform_int_distribution<size_t>(0, world.cylinders.size() - 1)(rng);
        const Box box = cylinderBox(world.cylinders[i]);
        world.cylinders.erase(world.cylinders.begin() + i);
        observe(tsdf, world, box, truncation, /*see_deep=*/true, changed);
        break;
      }
      case 2: {  // sign flips and arbitrary values in one block
        const std::vector<BlockIndex> blocks = tsdf.blockIndices();
        if (blocks.empty()) break;
        const BlockIndex b =
            blocks[std::uniform_int_distribution<size_t>(0, blocks.size() - 1)(rng)];
        auto& voxels = tsdf.block(b)->voxels;
        for (int i = 0; i < 400; ++i) {
          TsdfVoxel& v = voxels[std::uniform_int_distribution<>(0, kVoxelsPerBlock - 1)(rng)];
          v.distance = i % 2 ? -v.distance : static_cast<float>(uniform(-truncation, truncation));
        }
        changed.push_back(b);
        break;
      }
      case 3:  // reveal space, possibly in blocks never seen before
        observe(tsdf, world, randomBox(), truncation, false, changed);
        break;
      case 4:  // forget space (weights to 0)
        forEachVoxel(tsdf, randomBox(), [&](const VoxelIndex& v) {
          if (TsdfVoxel* voxel = tsdf.voxel(v)) {
            voxel->weight = 0;
            changed.push_back(thicket::blockOfVoxel(v));
          }
        });
        break;
      case 5:  // re-integration near the vehicle: every voxel moves by up to half a voxel, so
               // that one call both raises and lowers neighbouring sites, as a depth frame does
        forEachVoxel(tsdf,
                     Box{(position.array() - 2.0).matrix(), (position.array() + 2.0).matrix()},
                     [&](const VoxelIndex& v) {
                       if (TsdfVoxel* voxel = tsdf.voxel(v)) {
                         voxel->distance += static_cast<float>(uniform(-0.5 * vs, 0.5 * vs));
                         changed.push_back(thicket::blockOfVoxel(v));
                       }
                     });
        break;
      default: {  // a whole TSDF block deleted
        const std::vector<BlockIndex> blocks = tsdf.blockIndices();
        if (blocks.empty()) break;
        const BlockIndex b =
            blocks[std::uniform_int_distribution<size_t>(0, blocks.size() - 1)(rng)];
        tsdf.removeBlock(b);
        changed.push_back(b);
        break;
      }
    }
    const double move = uniform(0, 1);
    if (move < 0.6) {
      position += Eigen::Vector3d(uniform(-0.5, 0.5), uniform(-0.5, 0.5), uniform(-0.2, 0.2));
    } else if (move < 0.85) {
      position = Eigen::Vector3d(uniform(0, 8), uniform(0, 8), uniform(0.5, 2.5));
    }
    const Snapshot before = check ? snapshot(esdf) : Snapshot{};
    const EsdfUpdateResult result = integrator.update(tsdf, changed, position, esdf);
    if (!check) continue;
    SCOPED_TRACE("seed " + std::to_string(seed) + " step " + std::to_string(step) + " kind " +
                 std::to_string(kind));
    expectReportMatches(before, snapshot(esdf), result);
    EsdfLayer expected(vs);
    reference.recompute(tsdf, position, expected);
    EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));
  }
  return snapshot(esdf);
}

TEST(EsdfIntegrator, IncrementalEqualsRecomputeOnRandomEdits) {
  for (const bool everywhere : {true, false}) {
    SCOPED_TRACE(everywhere ? "occupied everywhere" : "occupied sphere");
    for (const uint64_t seed : {1, 2, 3}) runRandomSequence(seed, 25, /*check=*/true, everywhere);
  }
}

TEST(EsdfIntegrator, DeterministicBytes) {
  for (const bool everywhere : {true, false}) {
    EXPECT_EQ(runRandomSequence(7, 15, false, everywhere),
              runRandomSequence(7, 15, false, everywhere));
  }
}

// ---------------------------------------------------------------------------------------------

TEST(EsdfIntegrator, UnknownSpacePolicy) {
  const double vs = 0.2;
  EsdfIntegratorOptions options;        // r_c 1.5, r_o 5, max 2
  options.occupied_everywhere = false;  // the sphere's policy: unobserved beyond r_o is unknown
  const TsdfLayer tsdf(vs);
  // Off the voxel centres, so that no centre lies exactly on a sphere (where rounding decides).
  const Eigen::Vector3d start(0.13, 0.07, 1.11);
  EsdfIntegrator integrator(options);
  integrator.setInitialPosition(start);
  EsdfLayer esdf(vs);
  integrator.update(tsdf, kNoChange, start, esdf);
  // The voxel at p, or an unknown one if its block is not allocated.
  auto at = [&](const Eigen::Vector3d& p) {
    const EsdfVoxel* v = esdf.voxel(esdf.voxelIndex(p));
    return v != nullptr ? *v : EsdfVoxel{};
  };
  auto isUnknown = [&](const Eigen::Vector3d& p) {
    const EsdfVoxel v = at(p);
    return !v.observed && !v.fixed && v.distance == 0;
  };
  // Exactly the blocks with a voxel centre in r_c, free voxels there, and the occupied ones
  // between r_c and r_o shown as unknown (they act through the distances inside r_c).
  auto expectSpheres = [&](const Eigen::Vector3d& position) {
    std::set<std::array<int, 3>> expected;
    const VoxelIndex lo = esdf.voxelIndex((position.array() - 6.0).matrix());
    const VoxelIndex hi = esdf.voxelIndex((position.array() + 6.0).matrix());
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const VoxelIndex v(x, y, z);
          const Eigen::Vector3d c = esdf.voxelCenter(v);
          const bool clear = (c - start).norm() <= options.clear_radius;
          const bool occupied = !clear && (c - position).norm() <= options.occupied_radius;
          if (clear) {
            const BlockIndex b = thicket::blockOfVoxel(v);
            expected.insert({b.x(), b.y(), b.z()});
          }
          const EsdfVoxel* voxel = esdf.voxel(v);
          if (clear) {
            ASSERT_NE(voxel, nullptr);
            EXPECT_TRUE(voxel->observed && !voxel->fixed && voxel->distance > 0);
          } else if (occupied) {
            EXPECT_TRUE(isUnknown(c)) << c.transpose();
          }
        }
      }
    }
    std::set<std::array<int, 3>> actual;
    for (const BlockIndex& b : esdf.blockIndices()) actual.insert({b.x(), b.y(), b.z()});
    EXPECT_EQ(actual, expected);
  };
  // Inside r_c, the distance is the shortest 26-connected path to the occupied shell around it.
  auto expectShellDistance = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& position) {
    const VoxelIndex v = esdf.voxelIndex(p);
    double best = options.max_distance;
    for (int z = -12; z <= 12; ++z) {
      for (int y = -12; y <= 12; ++y) {
        for (int x = -12; x <= 12; ++x) {
          const Eigen::Vector3d c = esdf.voxelCenter(v + VoxelIndex(x, y, z));
          if ((c - start).norm() > options.clear_radius &&
              (c - position).norm() <= options.occupied_radius) {
            best = std::min(best, vs * octile(VoxelIndex(x, y, z)));
          }
        }
      }
    }
    EXPECT_NEAR(at(p).distance, best, 1e-5) << p.transpose();
    return best;
  };
  expectSpheres(start);
  // Next to the shell: one voxel; at the centre less than r_c + 1 voxel (a diagonal path to a
  // shell voxel beats the 8 voxels along an axis).
  EXPECT_NEAR(expectShellDistance(start + Eigen::Vector3d(1.4, 0, 0), start), 0.2, 1e-5);
  EXPECT_NEAR(expectShellDistance(start + Eigen::Vector3d(0, -1.0, 0), start), 0.6, 1e-5);
  const double at_start = expectShellDistance(start, start);
  EXPECT_GT(at_start, options.clear_radius);
  EXPECT_LT(at_start, options.clear_radius + vs);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<> uniform(-options.clear_radius, options.clear_radius);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d offset(uniform(rng), uniform(rng), uniform(rng));
    if (offset.norm() < options.clear_radius - vs) expectShellDistance(start + offset, start);
  }
  EXPECT_TRUE(isUnknown(start + Eigen::Vector3d(-5.4, 0, 0)));

  // The vehicle moves 3 m along x: the occupied sphere follows it, through unobserved space only
  // (the shell around r_c stays in it), so nothing the layer shows changes.
  const Eigen::Vector3d moved = start + Eigen::Vector3d(3, 0, 0);
  const Snapshot before = snapshot(esdf);
  const EsdfUpdateResult result = integrator.update(tsdf, kNoChange, moved, esdf);
  expectReportMatches(before, snapshot(esdf), result);
  EXPECT_TRUE(result.changed_blocks.empty());
  EXPECT_TRUE(result.removed_blocks.empty());
  EXPECT_EQ(result.voxels_updated, 0);
  expectSpheres(moved);
  EXPECT_TRUE(isUnknown(start + Eigen::Vector3d(-4, 0, 0)));       // left the sphere
  EXPECT_TRUE(isUnknown(start + Eigen::Vector3d(7.6, 0, 0)));      // entered it: a site, unseen
  EXPECT_NEAR(expectShellDistance(start, moved), at_start, 1e-5);  // r_c stays at the start
  EsdfLayer expected(vs);
  EsdfIntegrator reference(options);
  reference.setInitialPosition(start);
  reference.recompute(tsdf, moved, expected);
  EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));

  // A new initial position moves the clear sphere: the next update() starts over.
  integrator.setInitialPosition(moved);
  integrator.update(tsdf, kNoChange, moved, esdf);
  reference.setInitialPosition(moved);
  reference.recompute(tsdf, moved, expected);
  EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));
  EXPECT_TRUE(at(moved).observed && !at(moved).fixed);
  EXPECT_TRUE(isUnknown(start));  // outside the new clear sphere: occupied now, shown unknown
  EXPECT_NEAR(at(moved + Eigen::Vector3d(1.4, 0, 0)).distance, 0.2, 1e-5);  // next to its shell

  // Flown 40 m on through unobserved space, a metre per update, the occupied sphere keeps its
  // state only around the vehicle: the blocks it left are dropped, whether their voxels went
  // through the wavefront or not (far from free space they do not), and the layer shows the clear
  // sphere only, as a recompute at the end does.
  const size_t state_here = integrator.memoryBytes();
  const size_t blocks = esdf.numBlocks();
  Eigen::Vector3d p = moved;
  for (int i = 0; i < 40; ++i) {
    p.x() += 1.0;
    const Snapshot last = snapshot(esdf);
    const EsdfUpdateResult step = integrator.update(tsdf, kNoChange, p, esdf);
    expectReportMatches(last, snapshot(esdf), step);
  }
  EXPECT_EQ(esdf.numBlocks(), blocks);
  // The same sphere away from the clear one: no more state than here, with its larger work
  // lists, give or take the blocks a sphere straddles.
  EXPECT_LT(integrator.memoryBytes(), state_here * 3 / 2);
  reference.recompute(tsdf, p, expected);
  EXPECT_TRUE(sameEsdf(esdf, expected, 0));
  EXPECT_LT(reference.memoryBytes(), state_here * 3 / 2);
}

// ---------------------------------------------------------------------------------------------

TEST(EsdfIntegrator, RaiseWhenAnObstacleDisappears) {
  const double vs = 0.2;
  const double truncation = 4 * vs;
  const EsdfIntegratorOptions options;
  World world{{{3.0, 3.0, 0.5}}};
  // Observed up to 4 m, so that the unobserved space above (occupied) is farther from the points
  // below than the ground is.
  const Box box{{0, 0, -0.6}, {6, 6, 4.0}};
  TsdfLayer tsdf(vs);
  std::vector<BlockIndex> changed;
  observe(tsdf, world, box, truncation, true, changed);
  EsdfIntegrator integrator(options);
  integrator.setInitialPosition(kFarAway);
  EsdfLayer esdf(vs);
  integrator.update(tsdf, changed, kFarAway, esdf);
  EsdfLayer original(vs);
  EsdfIntegrator reference(options);
  reference.setInitialPosition(kFarAway);
  reference.recompute(tsdf, kFarAway, original);
  const Eigen::Vector3d beside(3.1, 3.9, 1.7);  // 0.41 m from the cylinder, 1.7 m from the ground
  const Eigen::Vector3d axis(3.1, 3.1, 1.7);    // 0.36 m inside it
  EXPECT_NEAR(distanceAt(esdf, beside), 0.41, 0.1);
  EXPECT_LT(distanceAt(esdf, axis), -0.3);

  // Nothing changed: nothing to do.
  EsdfUpdateResult result = integrator.update(tsdf, kNoChange, kFarAway, esdf);
  EXPECT_TRUE(result.changed_blocks.empty());
  EXPECT_EQ(result.voxels_updated, 0);

  // The cylinder disappears: distances around it grow to the ground's (raise) and its inside
  // becomes free.
  world.cylinders.clear();
  changed.clear();
  observe(tsdf, world, {{1.5, 1.5, -0.6}, {4.5, 4.5, 4.0}}, truncation, true, changed);
  const Snapshot before = snapshot(esdf);
  result = integrator.update(tsdf, changed, kFarAway, esdf);
  expectReportMatches(before, snapshot(esdf), result);
  EXPECT_NEAR(distanceAt(esdf, beside), 1.7, 1e-5);
  EXPECT_NEAR(distanceAt(esdf, axis), 1.7, 1e-5);
  EsdfLayer expected(vs);
  reference.recompute(tsdf, kFarAway, expected);
  EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));

  // And back (lower): the original field again.
  world.cylinders.push_back({3.0, 3.0, 0.5});
  changed.clear();
  observe(tsdf, world, {{1.5, 1.5, -0.6}, {4.5, 4.5, 4.0}}, truncation, true, changed);
  integrator.update(tsdf, changed, kFarAway, esdf);
  EXPECT_TRUE(sameEsdf(esdf, original, 1e-5));
}

// ---------------------------------------------------------------------------------------------

TEST(EsdfIntegrator, RefusesBadInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto with = [](auto change) {
    EsdfIntegratorOptions o;
    change(o);
    return o;
  };
  EXPECT_THROW(EsdfIntegrator(with([](auto& o) { o.max_distance = 0; })), std::invalid_argument);
  EXPECT_THROW(EsdfIntegrator(with([&](auto& o) { o.clear_radius = nan; })), std::invalid_argument);
  EXPECT_THROW(EsdfIntegrator(with([](auto& o) { o.occupied_radius = -1; })),
               std::invalid_argument);
  EXPECT_THROW(EsdfIntegrator(with([](auto& o) { o.surface_band_voxels = 0; })),
               std::invalid_argument);
  EXPECT_THROW(
      EsdfIntegrator(with([](auto& o) { o.min_weight = std::numeric_limits<double>::infinity(); })),
      std::invalid_argument);
  EXPECT_NO_THROW(EsdfIntegrator(with([](auto& o) { o.occupied_radius = 1.0; })));

  const TsdfLayer tsdf(0.2);
  EsdfLayer esdf(0.2);
  EsdfIntegrator integrator{EsdfIntegratorOptions{}};
  EXPECT_THROW(integrator.update(tsdf, kNoChange, Eigen::Vector3d::Zero(), esdf), std::logic_error);
  EXPECT_THROW(integrator.recompute(tsdf, Eigen::Vector3d::Zero(), esdf), std::logic_error);
  EXPECT_THROW(integrator.setInitialPosition(Eigen::Vector3d(nan, 0, 0)), std::invalid_argument);
  integrator.setInitialPosition(Eigen::Vector3d::Zero());
  EsdfLayer coarse(0.4);
  EXPECT_THROW(integrator.update(tsdf, kNoChange, Eigen::Vector3d::Zero(), coarse),
               std::invalid_argument);
  EXPECT_THROW(integrator.update(tsdf, kNoChange, Eigen::Vector3d(0, nan, 0), esdf),
               std::invalid_argument);
  EXPECT_THROW(integrator.update(tsdf, kNoChange, Eigen::Vector3d(0, 0, 1e300), esdf),
               std::invalid_argument);
  EXPECT_EQ(esdf.numBlocks(), 0u);
  integrator.update(tsdf, kNoChange, Eigen::Vector3d::Zero(), esdf);
  EXPECT_GT(esdf.numBlocks(), 0u);
  // A report without a voxel set per changed block.
  thicket::mapper::TsdfIntegrationResult report;
  report.changed_blocks.push_back(BlockIndex(0, 0, 0));
  report.observed_weight = static_cast<float>(EsdfIntegratorOptions{}.min_weight);
  EXPECT_THROW(integrator.update(tsdf, report, Eigen::Vector3d::Zero(), esdf),
               std::invalid_argument);
  // After a throw the next call recomputes: a layer with a foreign block is rebuilt without it.
  esdf.allocateBlock(BlockIndex(100, 0, 0));
  const EsdfUpdateResult rebuilt =
      integrator.update(tsdf, kNoChange, Eigen::Vector3d::Zero(), esdf);
  EXPECT_EQ(rebuilt.removed_blocks, std::vector<BlockIndex>{BlockIndex(100, 0, 0)});
  // A layer that is not the previous call's is refused.
  esdf.allocateBlock(BlockIndex(100, 0, 0));
  EXPECT_THROW(integrator.update(tsdf, kNoChange, Eigen::Vector3d::Zero(), esdf), std::logic_error);

  // The options load from YAML with the same validation.
  EXPECT_THROW(thicket::loadParamsFromString<EsdfIntegratorOptions>("max_distance: -1\n", "t"),
               thicket::ParamError);
  EXPECT_EQ(
      thicket::loadParamsFromString<EsdfIntegratorOptions>("clear_radius: 2.5\n", "t").clear_radius,
      2.5);
  EXPECT_NE(thicket::describeParams<EsdfIntegratorOptions>().find("occupied_radius"),
            std::string::npos);
}

// ---------------------------------------------------------------------------------------------

// A forest flown through at 0.5 m per frame; each frame observes the voxels in a 90 x 74 deg view
// up to `range` ahead (no occlusion) as a TSDF would, averaging measurements with uniform noise of
// +-noise. Prints the update() times; checks the end result.
void flyThroughForest(double noise, double range, const char* label) {
  const double vs = 0.2;
  const double truncation = 4 * vs;
  std::mt19937_64 rng(11);
  auto uniform = [&](double lo, double hi) {
    return std::uniform_real_distribution<>(lo, hi)(rng);
  };
  World world;
  for (int i = 0; i < 60; ++i) {
    world.cylinders.push_back({uniform(0, 24), uniform(0, 12), uniform(0.1, 0.5)});
  }
  TsdfLayer tsdf(vs);
  EsdfLayer esdf(vs);
  const EsdfIntegratorOptions options;
  EsdfIntegrator integrator(options);
  Eigen::Vector3d position(1, 6, 1.5);
  integrator.setInitialPosition(position);
  std::vector<double> times, blocks, updated;
  for (int frame = 0; frame < 30; ++frame) {
    position.x() += 0.5;
    std::set<std::array<int, 3>> touched;
    forEachVoxel(
        tsdf, Box{(position.array() - range).matrix(), (position.array() + range).matrix()},
        [&](const VoxelIndex& v) {
          const Eigen::Vector3d ray = tsdf.voxelCenter(v) - position;
          if (ray.x() <= 0.1 || ray.norm() > range || std::abs(ray.y()) > ray.x() ||
              std::abs(ray.z()) > 0.75 * ray.x()) {
            return;
          }
          const double d = world.signedDistance(tsdf.voxelCenter(v));
          if (d < -truncation) return;
          TsdfVoxel& voxel = tsdf.allocateVoxel(v);
          const double measured = std::clamp(d + uniform(-noise, noise), -truncation, truncation);
          voxel.distance =
              static_cast<float>((voxel.distance * voxel.weight + measured) / (voxel.weight + 1));
          voxel.weight += 1;
          const BlockIndex b = thicket::blockOfVoxel(v);
          touched.insert({b.x(), b.y(), b.z()});
        });
    std::vector<BlockIndex> changed;
    for (const auto& b : touched) changed.emplace_back(b[0], b[1], b[2]);
    const auto start = std::chrono::steady_clock::now();
    const EsdfUpdateResult result = integrator.update(tsdf, changed, position, esdf);
    if (frame > 0) {  // the first call recomputes
      times.push_back(millisecondsSince(start));
      blocks.push_back(static_cast<double>(changed.size()));
      updated.push_back(static_cast<double>(result.voxels_updated));
    }
  }
  EsdfLayer expected(vs);
  EsdfIntegrator reference(options);
  reference.setInitialPosition(Eigen::Vector3d(1, 6, 1.5));
  const auto start = std::chrono::steady_clock::now();
  reference.recompute(tsdf, position, expected);
  const double recompute_ms = millisecondsSince(start);
  std::printf(
      "forest (%s): update median %.2f ms, max %.2f ms over %zu frames; %.0f TSDF blocks and "
      "%.0f ESDF voxels changed per frame (median); recompute of the final map (%zu blocks) "
      "%.1f ms\n",
      label, percentile(times, 0.5), percentile(times, 1), times.size(), percentile(blocks, 0.5),
      percentile(updated, 0.5), esdf.numBlocks(), recompute_ms);
  EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));
}

// A 7 m view changes about 26 TSDF blocks per frame.
TEST(EsdfIntegrator, FrameTimesWithExactMeasurements) {
  flyThroughForest(0, 7, "exact");
}
TEST(EsdfIntegrator, FrameTimesWithNoisyMeasurements) {
  flyThroughForest(0.05, 7, "noisy, +-5 cm");
}

// ---------------------------------------------------------------------------------------------

// The mapping benchmark's flight (tools/bench/bench_mapper.cc): 80 depth frames of forest50 at
// density 0.2, seed 1, every 0.25 m, integrated into the TSDF and the ESDF as the mapper does
// (by default every unobserved voxel occupied; the sphere following the vehicle when the options
// say so). update() must equal recompute() after every
// `check_every`-th frame and the last.
// Maps the benchmark flight twice: from the integration's report of changed voxels, and from
// the whole changed blocks. Both give the same layer at every frame, bit for bit, and equal a
// recompute every check_every-th frame and at the end, bit for bit too: the distances are the
// one fixed point of the propagation, whatever order the wavefront visits voxels in.
void flyBenchmarkFlight(double voxel_size, size_t check_every,
                        const EsdfIntegratorOptions& options = {}) {
  const std::vector<thicket::Pose> poses = thicket::bench::flightPoses(0.25, 80);
  const thicket::sim::DepthRenderer renderer(thicket::bench::forest(),
                                             thicket::sim::DepthCameraOptions{});
  const thicket::mapper::TsdfIntegrator tsdf_integrator{thicket::mapper::TsdfIntegratorOptions{}};
  EsdfIntegrator integrator(options);
  integrator.setInitialPosition(poses.front().position);
  EsdfIntegrator by_blocks(options);
  by_blocks.setInitialPosition(poses.front().position);
  EsdfIntegrator reference(options);
  reference.setInitialPosition(poses.front().position);
  TsdfLayer tsdf(voxel_size);
  EsdfLayer esdf(voxel_size);
  EsdfLayer esdf_by_blocks(voxel_size);
  int64_t utime = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const thicket::DepthImage image = renderer.renderImage(poses[i], utime += 250'000);
    const auto changed = tsdf_integrator.integrate(image, poses[i] * renderer.cameraInBody(), tsdf);
    const EsdfUpdateResult result = integrator.update(tsdf, changed, poses[i].position, esdf);
    const EsdfUpdateResult result_by_blocks =
        by_blocks.update(tsdf, changed.changed_blocks, poses[i].position, esdf_by_blocks);
    ASSERT_TRUE(sameEsdf(esdf, esdf_by_blocks, 0)) << "frame " << i;
    EXPECT_EQ(result.changed_blocks, result_by_blocks.changed_blocks) << "frame " << i;
    EXPECT_EQ(result.voxels_updated, result_by_blocks.voxels_updated) << "frame " << i;
    if ((i + 1) % check_every != 0 && i + 1 != poses.size()) continue;
    EsdfLayer expected(voxel_size);
    reference.recompute(tsdf, poses[i].position, expected);
    EXPECT_TRUE(sameEsdf(esdf, expected, 0)) << "frame " << i;
  }
  // The wavefront state kept between frames: a node per block of the layer or of the occupied
  // sphere (three quarters of a layer block's bytes) and the work lists of recent frames, not the
  // first frame's whole sphere.
  EXPECT_GT(integrator.memoryBytes(), esdf.memoryBytes() / 2);
  EXPECT_LE(integrator.memoryBytes(), 2 * esdf.memoryBytes());
}

// A report made for another weight than min_weight may miss voxels whose observed-ness changed
// at min_weight: the integrator classifies the whole changed blocks again. Here the reports name
// no voxel at all, for weight 0.5, and the layer still equals a recompute at every frame.
TEST(EsdfIntegrator, AReportForAnotherWeightFallsBackToTheWholeBlocks) {
  const std::vector<thicket::Pose> poses = thicket::bench::flightPoses(0.25, 8);
  const thicket::sim::DepthRenderer renderer(thicket::bench::forest(),
                                             thicket::sim::DepthCameraOptions{});
  const thicket::mapper::TsdfIntegrator tsdf_integrator{thicket::mapper::TsdfIntegratorOptions{}};
  EsdfIntegrator integrator{EsdfIntegratorOptions{}};
  integrator.setInitialPosition(poses.front().position);
  EsdfIntegrator reference{EsdfIntegratorOptions{}};
  reference.setInitialPosition(poses.front().position);
  TsdfLayer tsdf(0.2);
  EsdfLayer esdf(0.2);
  int64_t utime = 0;
  for (const thicket::Pose& pose : poses) {
    const thicket::DepthImage image = renderer.renderImage(pose, utime += 250'000);
    thicket::mapper::TsdfIntegrationResult report =
        tsdf_integrator.integrate(image, pose * renderer.cameraInBody(), tsdf);
    report.observed_weight = 0.5f;
    std::fill(report.changed_voxels.begin(), report.changed_voxels.end(), thicket::BlockVoxels{});
    integrator.update(tsdf, report, pose.position, esdf);
    EsdfLayer expected(0.2);
    reference.recompute(tsdf, pose.position, expected);
    EXPECT_TRUE(sameEsdf(esdf, expected, 1e-5));
  }
}

// A saturated voxel whose stored distance is -0 (as a map loaded from elsewhere may hold) and that
// a frame measures at +0 changes only the sign of its zero: that is still a change, of the block
// and of the voxel, and the ESDF site it makes carries the new sign, as a recompute gives it.
TEST(EsdfIntegrator, AZeroThatChangesSignIsAChange) {
  using thicket::mapper::TsdfIntegrator;
  using thicket::mapper::TsdfIntegratorOptions;
  for (const auto method :
       {TsdfIntegratorOptions::Method::kProjective, TsdfIntegratorOptions::Method::kRaycast}) {
    const double vs = 0.125;
    TsdfIntegratorOptions options;
    options.method = method;
    options.max_weight = 2.0;
    const TsdfIntegrator tsdf_integrator(options);
    thicket::DepthImage image;
    image.camera = thicket::PinholeCamera{1, 1, 1.0, 1.0, 0.0, 0.0};
    image.min_range = 0.05;
    image.max_range = 20;
    image.depth = {1.0625f};  // sdf +0 at voxel (0, 0, 8)
    thicket::Pose pose;
    pose.position = Eigen::Vector3d(0.5 * vs, 0.5 * vs, 0);
    TsdfLayer tsdf(vs);
    for (int i = 0; i < 100; ++i) tsdf_integrator.integrate(image, pose, tsdf);  // saturated
    tsdf.block(BlockIndex(0, 0, 0))->voxels[8 * 256].distance = -0.0f;
    EsdfIntegrator integrator{EsdfIntegratorOptions{}};
    integrator.setInitialPosition(kFarAway);
    EsdfLayer esdf(vs);
    integrator.update(tsdf, kNoChange, kFarAway, esdf);
    const auto report = tsdf_integrator.integrate(image, pose, tsdf);
    ASSERT_EQ(report.changed_blocks, std::vector<BlockIndex>{BlockIndex(0, 0, 0)});
    EXPECT_TRUE(report.changed_voxels.front().contains(8 * 256));
    integrator.update(tsdf, report, kFarAway, esdf);
    EsdfIntegrator reference{EsdfIntegratorOptions{}};
    reference.setInitialPosition(kFarAway);
    EsdfLayer expected(vs);
    reference.recompute(tsdf, kFarAway, expected);
    EXPECT_EQ(std::bit_cast<uint32_t>(esdf.voxel(VoxelIndex(0, 0, 8))->distance),
              std::bit_cast<uint32_t>(expected.voxel(VoxelIndex(0, 0, 8))->distance));
    EXPECT_EQ(std::bit_cast<uint32_t>(esdf.voxel(VoxelIndex(0, 0, 8))->distance), 0u);  // +0
  }
}

TEST(EsdfIntegrator, IncrementalEqualsRecomputeOnBenchmarkFlightAt20cm) {
  flyBenchmarkFlight(0.2, 1);
}
// Every 20th frame, to keep the test short: checking all 80 takes about four times as long.
TEST(EsdfIntegrator, IncrementalEqualsRecomputeOnBenchmarkFlightAt10cm) {
  flyBenchmarkFlight(0.1, 20);
}

TEST(EsdfIntegrator, IncrementalEqualsRecomputeWithTheOccupiedSphere) {
  EsdfIntegratorOptions options;
  options.occupied_everywhere = false;
  flyBenchmarkFlight(0.2, 1, options);
}

// occupied_everywhere against the occupied sphere on the benchmark flight at 0.2 m: the same
// blocks and flags everywhere, the same distances bit for bit within occupied_radius -
// max_distance - one voxel of the vehicle, and no longer ones anywhere (more sites). Some voxels
// farther out do differ, or the option would have changed nothing.
TEST(EsdfIntegrator, OccupiedEverywhereEqualsTheSphereNearTheVehicle) {
  const double voxel_size = 0.2;
  const std::vector<thicket::Pose> poses = thicket::bench::flightPoses(0.25, 80);
  const thicket::sim::DepthRenderer renderer(thicket::bench::forest(),
                                             thicket::sim::DepthCameraOptions{});
  const thicket::mapper::TsdfIntegrator tsdf_integrator{thicket::mapper::TsdfIntegratorOptions{}};
  EsdfIntegratorOptions sphere;
  sphere.occupied_everywhere = false;
  EsdfIntegratorOptions everywhere;
  everywhere.occupied_everywhere = true;
  EsdfIntegrator with_sphere(sphere);
  EsdfIntegrator without(everywhere);
  with_sphere.setInitialPosition(poses.front().position);
  without.setInitialPosition(poses.front().position);
  TsdfLayer tsdf(voxel_size);
  EsdfLayer a(voxel_size);
  EsdfLayer b(voxel_size);
  const double exact_radius = sphere.occupied_radius - sphere.max_distance - voxel_size;
  int64_t utime = 0;
  int64_t near = 0;
  int64_t far_shorter = 0;
  for (size_t i = 0; i < poses.size(); i += 4) {
    const thicket::DepthImage image = renderer.renderImage(poses[i], utime += 1'000'000);
    const auto changed = tsdf_integrator.integrate(image, poses[i] * renderer.cameraInBody(), tsdf);
    const Eigen::Vector3d p = poses[i].position;
    with_sphere.update(tsdf, changed, p, a);
    without.update(tsdf, changed, p, b);
    ASSERT_EQ(a.blockIndices(), b.blockIndices()) << "frame " << i;
    for (const BlockIndex& index : a.blockIndices()) {
      const auto& va = a.block(index)->voxels;
      const auto& vb = b.block(index)->voxels;
      for (int lin = 0; lin < kVoxelsPerBlock; ++lin) {
        const VoxelIndex v =
            index * thicket::kVoxelsPerSide + VoxelIndex(lin & 15, (lin >> 4) & 15, lin >> 8);
        const Eigen::Vector3d centre = (v.cast<double>().array() + 0.5).matrix() * voxel_size;
        ASSERT_EQ(va[lin].observed, vb[lin].observed)
            << "frame " << i << " voxel " << v.transpose();
        ASSERT_EQ(va[lin].fixed, vb[lin].fixed) << "frame " << i << " voxel " << v.transpose();
        if ((centre - p).norm() <= exact_radius) {
          ASSERT_EQ(std::bit_cast<uint32_t>(va[lin].distance),
                    std::bit_cast<uint32_t>(vb[lin].distance))
              << "frame " << i << " voxel " << v.transpose();
          near += va[lin].observed;
        } else {
          ASSERT_LE(std::abs(vb[lin].distance), std::abs(va[lin].distance))
              << "frame " << i << " voxel " << v.transpose();
          far_shorter += std::abs(vb[lin].distance) < std::abs(va[lin].distance);
        }
      }
    }
  }
  EXPECT_GT(near, 10000);
  EXPECT_GT(far_shorter, 1000);
  // No state for the unobserved space of the sphere.
  EXPECT_LT(without.memoryBytes(), with_sphere.memoryBytes());
}

}  // namespace

// The voxel map core: indexing, ESDF queries against analytic fields, serialization and the
// mirror's revision logic.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "thicket/common/esdf_query.h"
#include "thicket/common/map_update.h"
#include "thicket/common/voxel_layer.h"

namespace thicket {
namespace {

TEST(VoxelLayer, IndexesVoxelsAndBlocksAcrossTheOrigin) {
  TsdfLayer layer(0.2);
  EXPECT_DOUBLE_EQ(layer.blockSize(), 3.2);
  EXPECT_EQ(layer.voxelIndex({0.1, -0.1, 3.3}), VoxelIndex(0, -1, 16));
  EXPECT_EQ(layer.blockIndex({0.1, -0.1, 3.3}), BlockIndex(0, -1, 1));
  EXPECT_EQ(blockOfVoxel({-16, -17, 15}), BlockIndex(-1, -2, 0));
  EXPECT_LT((layer.voxelCenter({-1, 0, 2}) - Eigen::Vector3d(-0.1, 0.1, 0.5)).norm(), 1e-12);
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<int> coordinate(-1000, 1000);
  for (int i = 0; i < 1000; ++i) {
    const VoxelIndex v(coordinate(rng), coordinate(rng), coordinate(rng));
    EXPECT_EQ(voxelOfBlock(blockOfVoxel(v), linearIndexInBlock(v)), v);
    EXPECT_EQ(layer.voxelIndex(layer.voxelCenter(v)), v);
  }
  EXPECT_EQ(layer.voxel({5, 5, 5}), nullptr);
  layer.allocateVoxel({5, 5, 5}).weight = 2;
  ASSERT_NE(layer.voxel({5, 5, 5}), nullptr);
  EXPECT_EQ(layer.voxel({5, 5, 5})->weight, 2);
  EXPECT_EQ(layer.voxel({5, 5, 6})->weight, 0);
  EXPECT_EQ(layer.numBlocks(), 1u);
  EXPECT_EQ(layer.memoryBytes(), sizeof(Block<TsdfVoxel>));
  layer.allocateBlock({-1, 0, 0});
  EXPECT_EQ(layer.blockIndices(), (std::vector<BlockIndex>{{-1, 0, 0}, {0, 0, 0}}));
  // Inserting over a block and releasing one hand the block over.
  auto replacement = std::make_unique<Block<TsdfVoxel>>(BlockIndex(-1, 0, 0));
  Block<TsdfVoxel>* const inserted = replacement.get();
  const Block<TsdfVoxel>* const replaced = layer.block({-1, 0, 0});
  EXPECT_EQ(layer.insertBlock(std::move(replacement)).get(), replaced);
  EXPECT_EQ(layer.block({-1, 0, 0}), inserted);
  EXPECT_EQ(layer.insertBlock(std::make_unique<Block<TsdfVoxel>>(BlockIndex(3, 0, 0))), nullptr);
  EXPECT_EQ(layer.releaseBlock({3, 0, 0})->index, BlockIndex(3, 0, 0));
  EXPECT_EQ(layer.releaseBlock({3, 0, 0}), nullptr);
  EXPECT_EQ(layer.block({3, 0, 0}), nullptr);
  EXPECT_TRUE(layer.removeBlock({0, 0, 0}));
  EXPECT_FALSE(layer.removeBlock({0, 0, 0}));
  EXPECT_THROW(TsdfLayer(0), std::invalid_argument);
  EXPECT_THROW(TsdfLayer(NAN), std::invalid_argument);
}

// An ESDF whose voxels hold an analytic field over a box of voxels, all observed.
EsdfLayer fieldLayer(double voxel_size, const std::function<double(const Eigen::Vector3d&)>& f) {
  EsdfLayer layer(voxel_size);
  for (int x = -20; x < 20; ++x) {
    for (int y = -20; y < 20; ++y) {
      for (int z = -5; z < 20; ++z) {
        EsdfVoxel& voxel = layer.allocateVoxel({x, y, z});
        voxel.distance = static_cast<float>(f(layer.voxelCenter({x, y, z})));
        voxel.observed = true;
      }
    }
  }
  return layer;
}

TEST(EsdfQuery, TrilinearIsExactOnLinearFieldsAndGradientsMatchFiniteDifferences) {
  const auto linear = [](const Eigen::Vector3d& p) {
    return 0.3 * p.x() - 0.5 * p.y() + p.z() + 1;
  };
  const EsdfLayer layer = fieldLayer(0.2, linear);
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-3.5, 3.5);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), std::abs(u(rng)));
    const EsdfSample sample = sampleEsdf(layer, p);
    ASSERT_TRUE(sample.known);
    EXPECT_NEAR(sample.distance, linear(p), 1e-5);
    EXPECT_LT((sample.gradient - Eigen::Vector3d(0.3, -0.5, 1)).norm(), 1e-5);
  }
  // A curved field: the gradient is the derivative of the interpolant (finite differences
  // inside one cell), and close to the field's own.
  const auto sphere = [](const Eigen::Vector3d& p) {
    return (p - Eigen::Vector3d(0.3, 0.1, 1)).norm() - 0.5;
  };
  const EsdfLayer curved = fieldLayer(0.1, sphere);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p(0.8 * u(rng) / 3.5, 0.8 * u(rng) / 3.5, 1 + 0.5 * u(rng) / 3.5);
    const EsdfSample sample = sampleEsdf(curved, p);
    ASSERT_TRUE(sample.known);
    const double h = 1e-6;
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      step[axis] = h;
      const double numeric =
          (sampleEsdf(curved, p + step).distance - sampleEsdf(curved, p - step).distance) / (2 * h);
      EXPECT_NEAR(sample.gradient[axis], numeric, 1e-3) << p.transpose();
    }
    EXPECT_NEAR(sample.distance, sphere(p), 0.02);
  }
}

// Cells whose 8 voxels lie in 1, 2, 4 or 8 blocks (across a block's face, edge or corner, on
// either side of the origin) read each voxel from its own block.
TEST(EsdfQuery, CellsAcrossBlockFacesEdgesAndCornersReadEachVoxelFromItsBlock) {
  const auto linear = [](const Eigen::Vector3d& p) {
    return 0.3 * p.x() - 0.5 * p.y() + 0.7 * p.z() + 1;
  };
  const EsdfLayer layer = fieldLayer(0.2, linear);
  int crossings = 0;
  for (const int x : {-2, -1, 0, 14, 15}) {
    for (const int y : {-1, 0, 15}) {
      for (const int z : {-1, 0, 15}) {
        const VoxelIndex base(x, y, z);
        crossings += blockOfVoxel(base) != blockOfVoxel(base + VoxelIndex::Ones());
        // A point a third of the way across the cell from base's centre.
        const Eigen::Vector3d p = layer.voxelCenter(base) + Eigen::Vector3d(0.07, 0.05, 0.11);
        const EsdfSample sample = sampleEsdf(layer, p);
        ASSERT_TRUE(sample.known) << base.transpose();
        EXPECT_NEAR(sample.distance, linear(p), 1e-5) << base.transpose();
        EXPECT_LT((sample.gradient - Eigen::Vector3d(0.3, -0.5, 0.7)).norm(), 1e-5);
      }
    }
  }
  EXPECT_EQ(crossings, 5 * 3 * 3 - 3);  // all but the cells at (-2, 0 or 14; 0; 0)
}

TEST(EsdfQuery, AnyUnobservedOrMissingCornerIsUnknown) {
  EsdfLayer layer = fieldLayer(0.2, [](const Eigen::Vector3d&) { return 1.0; });
  const Eigen::Vector3d p(0.25, 0.25, 0.25);  // between voxels 0 and 1 on each axis
  EXPECT_TRUE(sampleEsdf(layer, p).known);
  layer.voxel({1, 1, 1})->observed = false;
  const EsdfSample sample = sampleEsdf(layer, p);
  EXPECT_FALSE(sample.known);
  EXPECT_EQ(sample.distance, 0);
  // Across a block boundary (voxels 15 and 16 on x), on either side.
  const Eigen::Vector3d q(16 * 0.2, 0.25, 0.25);
  EXPECT_TRUE(sampleEsdf(layer, q).known);
  layer.voxel({16, 1, 1})->observed = false;
  EXPECT_FALSE(sampleEsdf(layer, q).known);
  layer.voxel({16, 1, 1})->observed = true;
  layer.voxel({15, 0, 0})->observed = false;
  EXPECT_FALSE(sampleEsdf(layer, q).known);
  EXPECT_FALSE(sampleEsdf(layer, {100, 0, 0}).known);  // no block there
  EXPECT_FALSE(sampleEsdf(layer, {NAN, 0, 0}).known);
  EXPECT_FALSE(sampleEsdf(layer, {1e300, 0, 0}).known);
}

// The 8 TSDF voxels of the interpolation cell, as sampleEsdf picks them, must all have weight.
TEST(EsdfQuery, TsdfObservedAroundAsksTheSameEightVoxels) {
  TsdfLayer tsdf(0.2);
  for (int z = 0; z < 2; ++z) {
    for (int y = 0; y < 2; ++y) {
      for (int x = 15; x < 17; ++x) tsdf.allocateVoxel({x, y, z}) = {0.5f, 1.0f};
    }
  }
  const Eigen::Vector3d p(16 * 0.2, 0.25, 0.25);  // voxels 15 and 16 on x: across two blocks
  EXPECT_TRUE(tsdfObservedAround(tsdf, p));
  EXPECT_FALSE(tsdfObservedAround(tsdf, p + Eigen::Vector3d(0.2, 0, 0)));  // voxel 17 missing
  tsdf.voxel({15, 1, 0})->weight = 0;
  EXPECT_FALSE(tsdfObservedAround(tsdf, p));
  EXPECT_FALSE(tsdfObservedAround(tsdf, {NAN, 0, 0}));
  EXPECT_FALSE(tsdfObservedAround(tsdf, {1e300, 0, 0}));
}

TsdfLayer randomTsdf(uint64_t seed, int blocks) {
  TsdfLayer layer(0.1);
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> index(-4, 4);
  std::uniform_real_distribution<float> distance(-0.4f, 0.4f), weight(0, 50);
  for (int b = 0; b < blocks; ++b) {
    Block<TsdfVoxel>& block = layer.allocateBlock({index(rng), index(rng), index(rng)});
    for (TsdfVoxel& voxel : block.voxels) voxel = {distance(rng), weight(rng)};
  }
  return layer;
}

TEST(MapUpdate, SnapshotsRoundTripInPartsUnderTheSizeLimit) {
  const TsdfLayer layer = randomTsdf(3, 60);  // random voxels barely compress: many parts
  const std::vector<map_update_t> parts =
      encodeMapUpdate(layer, {5, 7, 12, true}, {}, {}, 200 * 1024);
  ASSERT_GT(parts.size(), 3u);
  MapMirror<TsdfVoxel> mirror;
  for (size_t i = 0; i < parts.size(); ++i) {
    EXPECT_LE(parts[i].getEncodedSize(), 200 * 1024 + 40 * 1024);
    EXPECT_EQ(parts[i].num_parts, static_cast<int>(parts.size()));
    const auto result = mirror.apply(parts[i]);
    EXPECT_EQ(result.outcome, i + 1 < parts.size() ? MapMirror<TsdfVoxel>::Outcome::kPartial
                                                   : MapMirror<TsdfVoxel>::Outcome::kApplied)
        << result.reason;
  }
  ASSERT_NE(mirror.layer(), nullptr);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), layer));
  EXPECT_EQ(mirror.revision(), 12);
  EXPECT_EQ(mirror.mapId(), 7);
  EXPECT_EQ(mirror.utime(), 5);
  EXPECT_FALSE(mirror.needsSnapshot());
}

// Raw blocks (a graph inside one process) give the mirror the same layer, split by their raw size.
TEST(MapUpdate, RawBlocksRoundTripLikeCompressedOnes) {
  const TsdfLayer layer = randomTsdf(4, 20);
  const std::vector<map_update_t> parts =
      encodeMapUpdate(layer, {5, 7, 12, true}, {}, {}, 100 * 1024, false);
  ASSERT_GT(parts.size(), 3u);
  MapMirror<TsdfVoxel> mirror;
  for (const map_update_t& part : parts) {
    EXPECT_LE(part.getEncodedSize(), 100 * 1024 + 40 * 1024);
    for (const map_block_t& block : part.blocks) {
      EXPECT_EQ(block.compression, int8_t{map_block_t::COMPRESSION_NONE});
      EXPECT_EQ(block.size, block.raw_size);
    }
    mirror.apply(part);
  }
  ASSERT_NE(mirror.layer(), nullptr);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), layer));
  EXPECT_EQ(mirror.revision(), 12);
}

TEST(MapUpdate, EsdfVoxelsKeepTheirFlags) {
  EsdfLayer layer(0.2);
  Block<EsdfVoxel>& block = layer.allocateBlock({1, -2, 0});
  for (int i = 0; i < kVoxelsPerBlock; ++i) {
    block.voxels[i] = {static_cast<float>(i) * 0.001f - 2, i % 3 == 0, i % 5 == 0};
  }
  MapMirror<EsdfVoxel> mirror;
  for (const map_update_t& part : encodeMapUpdate(layer, {1, 1, 0, true}, {}, {})) {
    mirror.apply(part);
  }
  ASSERT_NE(mirror.layer(), nullptr);
  for (int i = 0; i < kVoxelsPerBlock; ++i) {
    const EsdfVoxel& voxel = mirror.layer()->block({1, -2, 0})->voxels[i];
    EXPECT_EQ(voxel.distance, block.voxels[i].distance);
    EXPECT_EQ(voxel.observed, block.voxels[i].observed);
    EXPECT_EQ(voxel.fixed, block.voxels[i].fixed);
  }
}

// The reason a mirror gives for refusing layer's snapshot (one uncompressed message) with one byte
// of its first block's payload set to value; the mirror must keep no part of it.
template <class Voxel>
std::string refusalWithByte(const Layer<Voxel>& layer, size_t byte, uint8_t value) {
  map_update_t msg = encodeMapUpdate(layer, {1, 1, 0, true}, {}, {}, 1 << 20, false)[0];
  msg.blocks[0].data[byte] = value;
  MapMirror<Voxel> mirror;
  const auto result = mirror.apply(msg);
  EXPECT_EQ(result.outcome, MapMirror<Voxel>::Outcome::kRefused);
  EXPECT_EQ(mirror.layer(), nullptr);
  return result.reason;
}

// A bad voxel anywhere in a block refuses the message, naming what is wrong with it, and the
// mirror keeps no part of it.
TEST(MapUpdate, ABadVoxelInsideABlockIsRefusedWithItsReason) {
  EsdfLayer layer(0.2);
  layer.allocateBlock({0, 0, 0}).voxels.fill({1.0f, true, false});
  constexpr size_t kVoxel = 2345 * 5;  // five bytes a voxel: float distance, flags
  EXPECT_NE(refusalWithByte(layer, kVoxel + 4, 0x04).find("unknown flag bits"), std::string::npos);
  // 1.0f is 0x3f800000; with its top byte 0x7f, +infinity.
  EXPECT_NE(refusalWithByte(layer, kVoxel + 3, 0x7f).find("non-finite distance"),
            std::string::npos);
}

// The same for a TSDF block, whose payload is its voxels' bytes, checked after one copy.
TEST(MapUpdate, ABadTsdfVoxelInsideABlockIsRefusedWithItsReason) {
  TsdfLayer layer(0.2);
  layer.allocateBlock({0, 0, 0}).voxels.fill({1.0f, 1.0f});
  constexpr size_t kVoxel = 2345 * 8;  // eight bytes a voxel: float distance, float weight
  // 1.0f is 0x3f800000: with its top byte 0x7f, +infinity; with 0xbf, -1.
  EXPECT_NE(refusalWithByte(layer, kVoxel + 3, 0x7f).find("non-finite distance"),
            std::string::npos);
  EXPECT_NE(refusalWithByte(layer, kVoxel + 7, 0x7f).find("bad weight"), std::string::npos);
  EXPECT_NE(refusalWithByte(layer, kVoxel + 7, 0xbf).find("bad weight"), std::string::npos);
  // The last voxel of the block too.
  EXPECT_NE(refusalWithByte(layer, 4095 * 8 + 7, 0xbf).find("bad weight"), std::string::npos);
}

// Layers compare by value: the padding bytes of an ESDF voxel (a float and two bools) hold
// whatever the memory held before and must not make equal layers differ.
TEST(VoxelLayer, IdenticalLayersIgnorePaddingButNotValues) {
  static_assert(sizeof(EsdfVoxel) > sizeof(float) + 2 * sizeof(bool), "EsdfVoxel has padding");
  EsdfLayer a(0.1), b(0.1);
  auto& va = a.allocateBlock({1, 2, 3}).voxels;
  auto& vb = b.allocateBlock({1, 2, 3}).voxels;
  std::memset(static_cast<void*>(va.data()), 0x00, sizeof(va));
  std::memset(static_cast<void*>(vb.data()), 0xa5, sizeof(vb));
  for (size_t i = 0; i < va.size(); ++i) {
    for (auto* v : {&va[i], &vb[i]}) {
      v->distance = 0.25f * static_cast<float>(i % 7);
      v->observed = i % 2 == 0;
      v->fixed = i % 3 == 0;
    }
  }
  EXPECT_TRUE(identicalLayers(a, b));
  vb[5].fixed = !vb[5].fixed;
  EXPECT_FALSE(identicalLayers(a, b));
  vb[5].fixed = va[5].fixed;
  vb[6].distance = -0.0f;  // va[6] is +0: bit for bit, they differ
  va[6].distance = 0.0f;
  EXPECT_FALSE(identicalLayers(a, b));
}

TEST(MapMirror, AppliesDeltasInOrderAndHealsGapsWithASnapshot) {
  using Outcome = MapMirror<TsdfVoxel>::Outcome;
  TsdfLayer mapper = randomTsdf(4, 5);
  MapMirror<TsdfVoxel> mirror;
  // Deltas before any snapshot cannot apply.
  const auto delta = [&](int64_t revision, const std::vector<BlockIndex>& changed,
                         const std::vector<BlockIndex>& removed = {}) {
    return encodeMapUpdate(mapper, {revision * 10, 1, revision, false}, changed, removed);
  };
  EXPECT_EQ(mirror.apply(delta(1, {})[0]).outcome, Outcome::kNeedSnapshot);
  EXPECT_TRUE(mirror.needsSnapshot());
  EXPECT_EQ(mirror.request(0, "test").last_revision, -1);
  for (const auto& part : encodeMapUpdate(mapper, {10, 1, 1, true}, {}, {})) mirror.apply(part);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), mapper));

  // Revision 2 changes a block and adds one; revision 3 removes one.
  mapper.allocateBlock({9, 9, 9}).voxels[7] = {0.05f, 3};
  const BlockIndex first = mapper.blockIndices()[0];
  mapper.block(first)->voxels[0] = {-0.1f, 1};
  EXPECT_EQ(mirror.apply(delta(2, {{9, 9, 9}, first})[0]).outcome, Outcome::kApplied);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), mapper));
  mapper.removeBlock(first);
  EXPECT_EQ(mirror.apply(delta(3, {}, {first})[0]).outcome, Outcome::kApplied);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), mapper));
  EXPECT_EQ(mirror.apply(delta(3, {})[0]).outcome, Outcome::kIgnored);  // a duplicate

  // Revision 4 is lost: 5 is a gap, and the mirror keeps revision 3 until a snapshot.
  mapper.allocateBlock({-9, 0, 0});
  const auto lost = delta(4, {{-9, 0, 0}});
  const auto result = mirror.apply(delta(5, {})[0]);
  EXPECT_EQ(result.outcome, Outcome::kNeedSnapshot);
  EXPECT_EQ(result.reason, "gap after revision 3");
  const map_request_t request = mirror.request(55, "planner");
  EXPECT_EQ(request.last_revision, 3);
  EXPECT_EQ(request.map_id, 1);
  EXPECT_EQ(request.layer, +map_update_t::LAYER_TSDF);
  EXPECT_EQ(request.reason, "gap after revision 3");
  EXPECT_EQ(mirror.revision(), 3);
  for (const auto& part : encodeMapUpdate(mapper, {50, 1, 5, true}, {}, {})) mirror.apply(part);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), mapper));
  // Another mirror's snapshot of the same revision: nothing to apply, nothing to replan on.
  const auto twice = mirror.apply(encodeMapUpdate(mapper, {50, 1, 5, true}, {}, {})[0]);
  EXPECT_EQ(twice.outcome, Outcome::kIgnored);
  EXPECT_EQ(twice.reason, "a snapshot of revision 5, which the mirror has");
  EXPECT_EQ(mirror.apply(delta(6, {})[0]).outcome, Outcome::kApplied);

  // A restarted mapper (new map id) needs a snapshot too, even at the next revision number.
  const auto restarted = encodeMapUpdate(mapper, {70, 2, 7, false}, {}, {});
  EXPECT_EQ(mirror.apply(restarted[0]).outcome, Outcome::kNeedSnapshot);
  // So does one that restarted empty under a fixed map id: its revisions start over at 1, which
  // would otherwise be ignored as old until they overtook the mirror's.
  const auto again = mirror.apply(delta(1, {})[0]);
  EXPECT_EQ(again.outcome, Outcome::kNeedSnapshot);
  EXPECT_EQ(again.reason, "the mapper restarted");
}

// The mirror decodes new blocks into the memory of blocks it let go of: after many revisions of
// changed, added and removed blocks, sent in several parts, it still holds exactly the mapper's
// layer, nothing of a block's earlier contents left over.
TEST(MapMirror, FollowsManyRevisionsThroughRecycledBlocks) {
  TsdfLayer mapper = randomTsdf(8, 30);
  MapMirror<TsdfVoxel> mirror;
  for (const auto& part : encodeMapUpdate(mapper, {1, 1, 1, true}, {}, {})) mirror.apply(part);
  std::mt19937_64 rng(9);
  std::uniform_int_distribution<int> index(-4, 4);
  std::uniform_real_distribution<float> distance(-0.4f, 0.4f), weight(0, 50);
  for (int64_t revision = 2; revision < 40; ++revision) {
    std::vector<BlockIndex> changed, removed;
    for (int k = 0; k < 6; ++k) {
      const BlockIndex b(index(rng), index(rng), index(rng));
      if (std::find(changed.begin(), changed.end(), b) != changed.end() ||
          std::find(removed.begin(), removed.end(), b) != removed.end()) {
        continue;
      }
      if (k % 3 == 2 && mapper.block(b) != nullptr) {
        mapper.removeBlock(b);
        removed.push_back(b);
        continue;
      }
      // Half the voxels of a changed block keep their values, so stale ones would show.
      Block<TsdfVoxel>& block = mapper.allocateBlock(b);
      for (size_t i = revision % 2; i < block.voxels.size(); i += 2) {
        block.voxels[i] = {distance(rng), weight(rng)};
      }
      changed.push_back(b);
    }
    MapMirror<TsdfVoxel>::Outcome last = MapMirror<TsdfVoxel>::Outcome::kRefused;
    for (const auto& part :
         encodeMapUpdate(mapper, {revision, 1, revision, false}, changed, removed, 70 * 1024)) {
      last = mirror.apply(part).outcome;
    }
    ASSERT_EQ(last, MapMirror<TsdfVoxel>::Outcome::kApplied) << "revision " << revision;
    ASSERT_TRUE(identicalLayers(*mirror.layer(), mapper)) << "revision " << revision;
  }
}

// Whether the mirror refuses `good` corrupted by `corrupt`, saying why.
template <class Voxel>
bool refusedWithAReason(MapMirror<Voxel>& mirror, const map_update_t& good,
                        const std::function<void(map_update_t&)>& corrupt) {
  map_update_t msg = good;
  corrupt(msg);
  const auto result = mirror.apply(msg);
  EXPECT_FALSE(result.reason.empty());
  return result.outcome == MapMirror<Voxel>::Outcome::kRefused;
}

// Deltas in the changes format carry only the voxels that changed, which the mirror writes over
// its blocks (over zero voxels in a block new to it): through revisions that change scattered
// voxels, add blocks, remove blocks and add them back, in several parts, it holds exactly the
// mapper's layer, at a fraction of the whole blocks' bytes.
TEST(MapMirror, FollowsDeltasThatCarryOnlyTheChangedVoxels) {
  EsdfLayer mapper(0.2);
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> index(-3, 3), voxel(0, kVoxelsPerBlock - 1);
  std::uniform_real_distribution<float> distance(-2, 2);
  const auto randomVoxel = [&] {
    return EsdfVoxel{distance(rng), voxel(rng) % 2 == 0, voxel(rng) % 3 == 0};
  };
  for (int b = 0; b < 10; ++b) {
    for (EsdfVoxel& v : mapper.allocateBlock({index(rng), index(rng), index(rng)}).voxels) {
      v = randomVoxel();
    }
  }
  MapMirror<EsdfVoxel> mirror;
  for (const auto& part : encodeMapUpdate(mapper, {1, 1, 1, true}, {}, {})) mirror.apply(part);
  std::vector<BlockIndex> removed_before;
  int re_added = 0, listed_twice = 0;  // revisions' cases seen: each must come up
  for (int64_t revision = 2; revision < 40; ++revision) {
    std::vector<BlockIndex> changed, removed;
    std::vector<BlockVoxels> changed_voxels;
    // Blocks removed last revision come back with a few voxels: the rest must read zero.
    for (const BlockIndex& b : removed_before) {
      ++re_added;
      BlockVoxels& voxels = changed_voxels.emplace_back();
      for (int k = 0; k < 50; ++k) {
        const int lin = voxel(rng);
        mapper.allocateBlock(b).voxels[lin] = randomVoxel();
        voxels.insert(lin);
      }
      changed.push_back(b);
    }
    for (int k = 0; k < 8; ++k) {
      const BlockIndex b(index(rng), index(rng), index(rng));
      if (std::find(changed.begin(), changed.end(), b) != changed.end()) {
        // Listed twice: the sets' union travels. A second, separate set for the same block.
        ++listed_twice;
        BlockVoxels& voxels = changed_voxels.emplace_back();
        const int lin = voxel(rng);
        mapper.allocateBlock(b).voxels[lin] = randomVoxel();
        voxels.insert(lin);
        changed.push_back(b);
        continue;
      }
      if (std::find(removed.begin(), removed.end(), b) != removed.end()) continue;
      if (k == 7 && mapper.block(b) != nullptr) {
        mapper.removeBlock(b);
        removed.push_back(b);
        continue;
      }
      BlockVoxels& voxels = changed_voxels.emplace_back();
      Block<EsdfVoxel>& block = mapper.allocateBlock(b);
      for (int n = 0; n < 300; ++n) {
        const int lin = voxel(rng);
        block.voxels[lin] = randomVoxel();
        voxels.insert(lin);
      }
      changed.push_back(b);
    }
    const auto parts = encodeMapUpdate(mapper, {revision, 1, revision, false}, changed, removed,
                                       8 * 1024, revision % 2 == 0, changed_voxels);
    MapMirror<EsdfVoxel>::Outcome last = MapMirror<EsdfVoxel>::Outcome::kRefused;
    size_t raw_bytes = 0;
    for (const auto& part : parts) {
      EXPECT_EQ(part.voxel_format, int8_t{map_update_t::FORMAT_ESDF_F32_U8_CHANGES});
      for (const map_block_t& block : part.blocks) raw_bytes += block.raw_size;
      last = mirror.apply(part).outcome;
    }
    ASSERT_EQ(last, MapMirror<EsdfVoxel>::Outcome::kApplied) << "revision " << revision;
    ASSERT_TRUE(identicalLayers(*mirror.layer(), mapper)) << "revision " << revision;
    // A block of 300 changed voxels: 512 bytes of set and 1500 of voxels, not 20480.
    EXPECT_LT(raw_bytes, changed.size() * 2100) << "revision " << revision;
    removed_before = removed;
  }
  EXPECT_GT(re_added, 0);
  EXPECT_GT(listed_twice, 0);
}

// The changes format names its voxels and must carry exactly as many, and only as a delta.
TEST(MapMirror, RefusesMalformedChanges) {
  using Outcome = MapMirror<EsdfVoxel>::Outcome;
  EsdfLayer layer(0.2);
  layer.allocateBlock({0, 0, 0}).voxels.fill({1.0f, true, false});
  MapMirror<EsdfVoxel> mirror;
  for (const auto& part : encodeMapUpdate(layer, {1, 1, 1, true}, {}, {})) mirror.apply(part);
  layer.block({0, 0, 0})->voxels[7] = {1.5f, true, true};  // 0x3fc00000
  BlockVoxels voxels;
  voxels.insert(7);
  const map_update_t good =
      encodeMapUpdate(layer, {2, 1, 2, false}, {{0, 0, 0}}, {}, 1 << 20, false, {voxels})[0];
  ASSERT_EQ(good.blocks[0].raw_size, 512 + 5);
  const auto refused = [&](const std::function<void(map_update_t&)>& corrupt) {
    return refusedWithAReason(mirror, good, corrupt);
  };
  EXPECT_TRUE(refused([](map_update_t& m) { m.full_snapshot = true; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].data[0] |= 1; }));  // two voxels named
  EXPECT_TRUE(refused([](map_update_t& m) {  // one named, none carried
    m.blocks[0].data.resize(512);
    m.blocks[0].size = m.blocks[0].raw_size = 512;
  }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].data[512 + 3] = 0x7f; }));  // NaN
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].data[512 + 4] = 0x04; }));  // flag bits
  EXPECT_TRUE(refused([](map_update_t& m) {  // under the set's own bytes
    m.blocks[0].data.resize(100);
    m.blocks[0].size = m.blocks[0].raw_size = 100;
  }));
  EXPECT_EQ(mirror.layer()->block({0, 0, 0})->voxels[7].distance, 1.0f);
  EXPECT_EQ(mirror.apply(good).outcome, Outcome::kApplied);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), layer));
  EXPECT_THROW(
      encodeMapUpdate(layer, {3, 1, 3, false}, {{0, 0, 0}}, {}, 1 << 20, false, {voxels, voxels}),
      std::invalid_argument);
}

TEST(MapMirror, ALostPartDropsTheRevision) {
  using Outcome = MapMirror<TsdfVoxel>::Outcome;
  const TsdfLayer big = randomTsdf(5, 40);
  MapMirror<TsdfVoxel> mirror;
  const auto snapshot = encodeMapUpdate(big, {1, 1, 1, true}, {}, {}, 100 * 1024);
  ASSERT_GT(snapshot.size(), 2u);
  for (size_t i = 0; i + 1 < snapshot.size(); ++i) mirror.apply(snapshot[i]);  // last one lost
  EXPECT_EQ(mirror.layer(), nullptr);
  EXPECT_EQ(mirror.apply(snapshot[0]).outcome, Outcome::kIgnored);  // stored already
  // The next snapshot replaces the incomplete one and applies.
  const auto next = encodeMapUpdate(big, {2, 1, 2, true}, {}, {}, 100 * 1024);
  Outcome last = Outcome::kRefused;
  for (const auto& part : next) last = mirror.apply(part).outcome;
  EXPECT_EQ(last, Outcome::kApplied);
  EXPECT_TRUE(identicalLayers(*mirror.layer(), big));
}

TEST(MapMirror, RefusesMalformedMessagesWithoutChangingTheMap) {
  using Outcome = MapMirror<TsdfVoxel>::Outcome;
  const TsdfLayer layer = randomTsdf(6, 2);
  MapMirror<TsdfVoxel> mirror;
  for (const auto& part : encodeMapUpdate(layer, {1, 1, 1, true}, {}, {})) mirror.apply(part);
  const map_update_t good = encodeMapUpdate(layer, {2, 1, 2, false}, layer.blockIndices(), {})[0];
  const auto refused = [&](const std::function<void(map_update_t&)>& corrupt) {
    return refusedWithAReason(mirror, good, corrupt);
  };
  EXPECT_TRUE(refused([](map_update_t& m) { m.layer = map_update_t::LAYER_ESDF; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.voxel_format = 7; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.voxels_per_side = 8; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.voxel_size = NAN; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.part_index = 1; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.num_blocks = 5; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].compression = 9; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].data[3] ^= 0xff; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].raw_size = 100; }));
  EXPECT_TRUE(refused([](map_update_t& m) { m.blocks[0].size = 1; }));
  EXPECT_TRUE(refused([](map_update_t& m) {
    m.blocks.push_back(m.blocks[0]);
    ++m.num_blocks;
  }));
  EXPECT_TRUE(refused([](map_update_t& m) {  // a NaN distance, uncompressed
    std::vector<uint8_t> raw(kVoxelsPerBlock * 8, 0);
    const float nan = NAN;
    std::memcpy(raw.data(), &nan, 4);
    m.blocks[0].compression = map_block_t::COMPRESSION_NONE;
    m.blocks[0].data = raw;
    m.blocks[0].size = static_cast<int32_t>(raw.size());
  }));
  EXPECT_TRUE(refused([](map_update_t& m) {  // a negative weight
    std::vector<uint8_t> raw(kVoxelsPerBlock * 8, 0);
    const float negative = -1;
    std::memcpy(raw.data() + 4, &negative, 4);
    m.blocks[0].compression = map_block_t::COMPRESSION_NONE;
    m.blocks[0].data = raw;
    m.blocks[0].size = static_cast<int32_t>(raw.size());
  }));
  EXPECT_TRUE(identicalLayers(*mirror.layer(), layer));
  EXPECT_EQ(mirror.apply(good).outcome, Outcome::kApplied);
}

}  // namespace
}  // namespace thicket

// The voxel map (docs/design.md §1): layers of 16^3-voxel blocks in a hash map, allocated where
// something was observed. A TSDF layer is what the mapper integrates depth into; an ESDF layer is
// what the planner and the explorer query. Voxel (i, j, k) covers [i, i+1) x [j, j+1) x [k, k+1)
// times the voxel size, its centre at (i + 0.5, j + 0.5, k + 0.5) times the voxel size; block
// (a, b, c) holds voxels 16a .. 16a + 15 along x, and so on.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace thicket {

constexpr int kVoxelsPerSide = 16;
constexpr int kVoxelsPerBlock = kVoxelsPerSide * kVoxelsPerSide * kVoxelsPerSide;

using BlockIndex = Eigen::Vector3i;
using VoxelIndex = Eigen::Vector3i;  // global: the voxel's integer coordinates in the world

/// A set of a block's voxels, a row along x at a time: bit x of rows[y + 16 z] for voxel (x, y, z)
/// (local coordinates; the bit of linear index i is bit i % 16 of rows[i / 16]).
struct BlockVoxels {
  std::array<uint16_t, kVoxelsPerSide * kVoxelsPerSide> rows{};

  static BlockVoxels all() {
    BlockVoxels set;
    set.rows.fill(0xffff);
    return set;
  }
  void insert(int linear) {
    rows[linear / kVoxelsPerSide] |= static_cast<uint16_t>(1u << (linear % kVoxelsPerSide));
  }
  bool contains(int linear) const {
    return (rows[linear / kVoxelsPerSide] >> (linear % kVoxelsPerSide) & 1) != 0;
  }
  bool empty() const {
    return std::all_of(rows.begin(), rows.end(), [](uint16_t row) { return row == 0; });
  }
  int count() const {
    int n = 0;
    for (size_t r = 0; r < rows.size(); r += 4) {  // four rows a word: a quarter of the calls
      uint64_t word;
      std::memcpy(&word, &rows[r], sizeof(word));
      n += std::popcount(word);
    }
    return n;
  }
  /// Calls f(linear index) for each voxel in the set, in index order.
  template <class F>
  void forEach(F&& f) const {
    for (int r = 0; r < kVoxelsPerSide * kVoxelsPerSide; ++r) {
      for (unsigned row = rows[r]; row != 0; row &= row - 1) {
        f(r * kVoxelsPerSide + std::countr_zero(row));
      }
    }
  }
  BlockVoxels& operator|=(const BlockVoxels& other) {
    for (size_t r = 0; r < rows.size(); ++r) rows[r] |= other.rows[r];
    return *this;
  }
  bool operator==(const BlockVoxels&) const = default;
};

struct IndexHash {
  size_t operator()(const Eigen::Vector3i& i) const {
    // Large odd multipliers spread neighbouring indices over the buckets.
    return static_cast<size_t>(static_cast<int64_t>(i.x()) * 73856093 ^
                               static_cast<int64_t>(i.y()) * 19349669 ^
                               static_cast<int64_t>(i.z()) * 83492791);
  }
};

/// Orders indices lexicographically (x, then y, then z): for deterministic iteration.
inline bool indexLess(const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
  return a.x() != b.x() ? a.x() < b.x() : a.y() != b.y() ? a.y() < b.y() : a.z() < b.z();
}

/// The block holding a voxel.
inline BlockIndex blockOfVoxel(const VoxelIndex& v) {
  // Arithmetic shift floors for negative indices too.
  return {v.x() >> 4, v.y() >> 4, v.z() >> 4};
}

/// A voxel's position in its block's array: x fastest, then y, then z.
inline int linearIndexInBlock(const VoxelIndex& v) {
  return (v.x() & 15) + 16 * (v.y() & 15) + 256 * (v.z() & 15);
}

/// The global index of voxel `linear` of a block.
inline VoxelIndex voxelOfBlock(const BlockIndex& b, int linear) {
  return {16 * b.x() + (linear & 15), 16 * b.y() + ((linear >> 4) & 15),
          16 * b.z() + (linear >> 8)};
}

/// Truncated signed distance: distance to the nearest surface along the viewing rays [m],
/// positive in front of it (free), negative behind; weight 0 means never observed.
struct TsdfVoxel {
  float distance = 0;
  float weight = 0;
};

/// Euclidean signed distance [m] to the nearest occupied voxel, capped at the ESDF's maximum
/// distance. observed: the TSDF saw it (or the unknown-space policy cleared it for take-off);
/// fixed: an observed voxel whose distance comes from the TSDF (near a surface), not from
/// propagation. Unobserved voxels read as distance 0, neither observed nor fixed.
struct EsdfVoxel {
  float distance = 0;
  bool observed = false;
  bool fixed = false;
};

template <class Voxel>
struct Block {
  explicit Block(const BlockIndex& block_index) : index(block_index) {}
  BlockIndex index;
  std::array<Voxel, kVoxelsPerBlock> voxels{};
};

/// A sparse voxel grid: blocks allocated on demand, found by index in O(1).
template <class Voxel>
class Layer {
 public:
  using BlockType = Block<Voxel>;

  /// Throws std::invalid_argument unless voxel_size is positive and finite.
  explicit Layer(double voxel_size) : voxel_size_(voxel_size) {
    if (!(voxel_size > 0 && std::isfinite(voxel_size))) {
      throw std::invalid_argument("Layer: the voxel size must be positive and finite");
    }
  }

  /// Copies are deep (every block).
  Layer(const Layer& other) : voxel_size_(other.voxel_size_) {
    for (const auto& [index, block] : other.blocks_) {
      blocks_.emplace(index, std::make_unique<BlockType>(*block));
    }
  }
  Layer& operator=(const Layer& other) {
    if (this != &other) *this = Layer(other);
    return *this;
  }
  Layer(Layer&&) noexcept = default;
  Layer& operator=(Layer&&) noexcept = default;

  double voxelSize() const { return voxel_size_; }
  double blockSize() const { return voxel_size_ * kVoxelsPerSide; }

  /// The voxel containing point p (p finite).
  VoxelIndex voxelIndex(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d scaled = p / voxel_size_;
    return {static_cast<int>(std::floor(scaled.x())), static_cast<int>(std::floor(scaled.y())),
            static_cast<int>(std::floor(scaled.z()))};
  }
  Eigen::Vector3d voxelCenter(const VoxelIndex& v) const {
    return (v.cast<double>().array() + 0.5).matrix() * voxel_size_;
  }
  BlockIndex blockIndex(const Eigen::Vector3d& p) const { return blockOfVoxel(voxelIndex(p)); }

  const BlockType* block(const BlockIndex& b) const {
    const auto it = blocks_.find(b);
    return it == blocks_.end() ? nullptr : it->second.get();
  }
  BlockType* block(const BlockIndex& b) {
    const auto it = blocks_.find(b);
    return it == blocks_.end() ? nullptr : it->second.get();
  }
  /// The block, allocated (all voxels default) if it did not exist.
  BlockType& allocateBlock(const BlockIndex& b) {
    std::unique_ptr<BlockType>& slot = blocks_[b];
    if (!slot) slot = std::make_unique<BlockType>(b);
    return *slot;
  }
  /// Adds a whole block, replacing any block at its index; the replaced block, or nullptr.
  std::unique_ptr<BlockType> insertBlock(std::unique_ptr<BlockType> block) {
    const BlockIndex index = block->index;
    std::swap(blocks_[index], block);
    return block;
  }
  /// Removes the block at b; whether there was one.
  bool removeBlock(const BlockIndex& b) { return releaseBlock(b) != nullptr; }
  /// Removes the block at b and hands it over, or nullptr when there is none.
  std::unique_ptr<BlockType> releaseBlock(const BlockIndex& b) {
    const auto it = blocks_.find(b);
    if (it == blocks_.end()) return nullptr;
    std::unique_ptr<BlockType> block = std::move(it->second);
    blocks_.erase(it);
    return block;
  }
  void clear() { blocks_.clear(); }

  /// The voxel, or nullptr when its block is not allocated.
  const Voxel* voxel(const VoxelIndex& v) const {
    const BlockType* b = block(blockOfVoxel(v));
    return b ? &b->voxels[linearIndexInBlock(v)] : nullptr;
  }
  Voxel* voxel(const VoxelIndex& v) {
    BlockType* b = block(blockOfVoxel(v));
    return b ? &b->voxels[linearIndexInBlock(v)] : nullptr;
  }
  Voxel& allocateVoxel(const VoxelIndex& v) {
    return allocateBlock(blockOfVoxel(v)).voxels[linearIndexInBlock(v)];
  }

  size_t numBlocks() const { return blocks_.size(); }
  /// Bytes of voxel storage (blocks only; the hash map's own overhead is small beside them).
  size_t memoryBytes() const { return blocks_.size() * sizeof(BlockType); }

  /// Every allocated block's index, sorted (indexLess): iterate these where order matters.
  std::vector<BlockIndex> blockIndices() const {
    std::vector<BlockIndex> indices;
    indices.reserve(blocks_.size());
    for (const auto& [index, block] : blocks_) indices.push_back(index);
    std::sort(indices.begin(), indices.end(), indexLess);
    return indices;
  }

 private:
  double voxel_size_;
  std::unordered_map<BlockIndex, std::unique_ptr<BlockType>, IndexHash> blocks_;
};

/// Voxel lookups in a layer through a small direct-mapped cache of blocks, for many lookups that
/// mostly fall in a few blocks (a frustum's points, a ray's voxels, a tree's edges): nearly every
/// lookup skips the hash map. Blocks whose indices agree modulo 4 on every axis share a slot: a
/// conflict costs one more lookup, never a wrong voxel. Valid while no block of the layer is
/// added or removed.
template <typename Voxel>
class VoxelLookup {
 public:
  using BlockType = typename Layer<Voxel>::BlockType;

  explicit VoxelLookup(const Layer<Voxel>& layer) : layer_(layer) {}

  /// The voxel, or nullptr when its block is not allocated.
  const Voxel* voxel(const VoxelIndex& v) {
    const BlockType* b = block(blockOfVoxel(v));
    return b != nullptr ? &b->voxels[linearIndexInBlock(v)] : nullptr;
  }
  /// The voxel holding point p (finite), or nullptr when its block is not allocated.
  const Voxel* voxelAt(const Eigen::Vector3d& p) { return voxel(layer_.voxelIndex(p)); }

  /// The block, or nullptr when it is not allocated.
  const BlockType* block(const BlockIndex& b) {
    Slot& slot = slots_[(b.x() & 3) | (b.y() & 3) << 2 | (b.z() & 3) << 4];
    if (!slot.valid || slot.index != b) {
      slot.index = b;
      slot.block = layer_.block(b);
      slot.valid = true;
    }
    return slot.block;
  }

 private:
  struct Slot {
    bool valid = false;
    BlockIndex index = BlockIndex::Zero();
    const BlockType* block = nullptr;
  };
  const Layer<Voxel>& layer_;
  std::array<Slot, 64> slots_{};
};

/// Whether two voxels hold the same values, floats compared bit for bit (so -0 differs from 0 and
/// a NaN equals itself); padding bytes, which hold no value, are not compared.
inline bool identicalVoxels(const TsdfVoxel& a, const TsdfVoxel& b) {
  return std::bit_cast<uint32_t>(a.distance) == std::bit_cast<uint32_t>(b.distance) &&
         std::bit_cast<uint32_t>(a.weight) == std::bit_cast<uint32_t>(b.weight);
}
inline bool identicalVoxels(const EsdfVoxel& a, const EsdfVoxel& b) {
  return std::bit_cast<uint32_t>(a.distance) == std::bit_cast<uint32_t>(b.distance) &&
         a.observed == b.observed && a.fixed == b.fixed;
}

/// Whether two layers have the same voxel size, the same blocks and identical voxels
/// (identicalVoxels): what determinism and round-trip checks compare.
template <class Voxel>
bool identicalLayers(const Layer<Voxel>& a, const Layer<Voxel>& b) {
  if (a.voxelSize() != b.voxelSize() || a.blockIndices() != b.blockIndices()) return false;
  for (const BlockIndex& index : a.blockIndices()) {
    const auto& va = a.block(index)->voxels;
    const auto& vb = b.block(index)->voxels;
    for (size_t i = 0; i < va.size(); ++i) {
      if (!identicalVoxels(va[i], vb[i])) return false;
    }
  }
  return true;
}

using TsdfLayer = Layer<TsdfVoxel>;
using EsdfLayer = Layer<EsdfVoxel>;

}  // namespace thicket

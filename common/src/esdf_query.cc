#include "thicket/common/esdf_query.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

namespace thicket {

namespace {

// The cell between the 8 voxel centres around p (centres sit at (i + 0.5) * voxel_size): its
// lowest voxel, and p's fraction of the way across it per axis. None for a non-finite or far-off p.
struct Cell {
  VoxelIndex base;
  Eigen::Vector3d t;
};
std::optional<Cell> cellAround(const Eigen::Vector3d& p, double voxel_size) {
  const Eigen::Vector3d scaled = p / voxel_size - Eigen::Vector3d::Constant(0.5);
  const Eigen::Vector3d lower = scaled.array().floor();
  if (!(lower.array().abs() < 1e9).all()) return std::nullopt;
  return Cell{lower.cast<int>(), scaled - lower};
}

// The 8 voxels of the cell whose lowest voxel is base, x fastest (corner i at base + (i & 1,
// i >> 1 & 1, i >> 2)); nullptr where the block is not allocated. Each block the cell touches is
// looked up once: usually one, as a cell crosses a block face only from a block's last layer.
template <typename Voxel>
std::array<const Voxel*, 8> cellVoxels(const Layer<Voxel>& layer, const VoxelIndex& base) {
  const BlockIndex first = blockOfVoxel(base);
  // Per axis, 1 where the cell's upper voxels lie in the next block.
  const VoxelIndex across = blockOfVoxel(base + VoxelIndex::Ones()) - first;
  const int leaves = across.x() | across.y() << 1 | across.z() << 2;
  std::array<const Voxel*, 8> voxels{};
  if (leaves == 0) {  // the common case: no axis leaves the block (82 % of cells)
    const typename Layer<Voxel>::BlockType* block = layer.block(first);
    if (block == nullptr) return voxels;
    const Voxel* v = &block->voxels[linearIndexInBlock(base)];
    constexpr int kY = kVoxelsPerSide;
    constexpr int kZ = kVoxelsPerSide * kVoxelsPerSide;
    return {v, v + 1, v + kY, v + kY + 1, v + kZ, v + kZ + 1, v + kZ + kY, v + kZ + kY + 1};
  }
  std::array<const typename Layer<Voxel>::BlockType*, 8> blocks{};
  for (int i = 0; i < 8; ++i) {
    const VoxelIndex corner(i & 1, i >> 1 & 1, i >> 2);
    // The corner's block is that of the corner with only the axes that leave: an earlier one, or
    // this one.
    const int same = i & leaves;
    blocks[i] = same == i ? layer.block(first + corner.cwiseProduct(across)) : blocks[same];
    if (blocks[i] != nullptr) voxels[i] = &blocks[i]->voxels[linearIndexInBlock(base + corner)];
  }
  return voxels;
}

}  // namespace

bool tsdfObservedAround(const TsdfLayer& tsdf, const Eigen::Vector3d& p) {
  const std::optional<Cell> cell = cellAround(p, tsdf.voxelSize());
  if (!cell) return false;
  const std::array<const TsdfVoxel*, 8> voxels = cellVoxels(tsdf, cell->base);
  return std::all_of(voxels.begin(), voxels.end(),
                     [](const TsdfVoxel* t) { return t != nullptr && t->weight > 0; });
}

EsdfSample sampleEsdf(const EsdfLayer& esdf, const Eigen::Vector3d& p) {
  if (!p.allFinite()) return {};
  const std::optional<Cell> cell = cellAround(p, esdf.voxelSize());
  if (!cell) return {};
  const VoxelIndex& base = cell->base;
  const Eigen::Vector3d& t = cell->t;
  // This is the planner's inner loop.
  const std::array<const EsdfVoxel*, 8> voxels = cellVoxels(esdf, base);
  double values[2][2][2];
  for (int i = 0; i < 8; ++i) {
    if (voxels[i] == nullptr || !voxels[i]->observed) return {};
    values[i >> 2][i >> 1 & 1][i & 1] = voxels[i]->distance;
  }
  // Interpolate along x, then y, then z, keeping the partial derivatives of each stage.
  double along_x[2][2], d_along_x[2][2];
  for (int dz = 0; dz < 2; ++dz) {
    for (int dy = 0; dy < 2; ++dy) {
      const double a = values[dz][dy][0];
      const double b = values[dz][dy][1];
      along_x[dz][dy] = a + t.x() * (b - a);
      d_along_x[dz][dy] = b - a;
    }
  }
  double along_y[2], dx_along_y[2], dy_along_y[2];
  for (int dz = 0; dz < 2; ++dz) {
    along_y[dz] = along_x[dz][0] + t.y() * (along_x[dz][1] - along_x[dz][0]);
    dx_along_y[dz] = d_along_x[dz][0] + t.y() * (d_along_x[dz][1] - d_along_x[dz][0]);
    dy_along_y[dz] = along_x[dz][1] - along_x[dz][0];
  }
  EsdfSample sample;
  sample.known = true;
  sample.distance = along_y[0] + t.z() * (along_y[1] - along_y[0]);
  sample.gradient = Eigen::Vector3d(dx_along_y[0] + t.z() * (dx_along_y[1] - dx_along_y[0]),
                                    dy_along_y[0] + t.z() * (dy_along_y[1] - dy_along_y[0]),
                                    along_y[1] - along_y[0]) /
                    esdf.voxelSize();
  return sample;
}

}  // namespace thicket

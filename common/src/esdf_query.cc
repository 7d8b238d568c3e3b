#include "thicket/common/esdf_query.h"

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

}  // namespace

bool tsdfObservedAround(const TsdfLayer& tsdf, const Eigen::Vector3d& p) {
  const std::optional<Cell> cell = cellAround(p, tsdf.voxelSize());
  if (!cell) return false;
  for (int i = 0; i < 8; ++i) {
    const TsdfVoxel* t = tsdf.voxel(cell->base + VoxelIndex(i & 1, (i >> 1) & 1, i >> 2));
    if (t == nullptr || !(t->weight > 0)) return false;
  }
  return true;
}

EsdfSample sampleEsdf(const EsdfLayer& esdf, const Eigen::Vector3d& p) {
  if (!p.allFinite()) return {};
  const std::optional<Cell> cell = cellAround(p, esdf.voxelSize());
  if (!cell) return {};
  const VoxelIndex& base = cell->base;
  const Eigen::Vector3d& t = cell->t;
  double values[2][2][2];
  // Usually all 8 voxels share one block: look it up once (this is the planner's inner loop).
  const BlockIndex block_index = blockOfVoxel(base);
  const bool one_block = blockOfVoxel(base + VoxelIndex(1, 1, 1)) == block_index;
  const EsdfLayer::BlockType* block = one_block ? esdf.block(block_index) : nullptr;
  if (one_block && block == nullptr) return {};
  for (int dz = 0; dz < 2; ++dz) {
    for (int dy = 0; dy < 2; ++dy) {
      for (int dx = 0; dx < 2; ++dx) {
        const VoxelIndex v = base + VoxelIndex(dx, dy, dz);
        const EsdfVoxel* voxel = one_block ? &block->voxels[linearIndexInBlock(v)] : esdf.voxel(v);
        if (voxel == nullptr || !voxel->observed) return {};
        values[dz][dy][dx] = voxel->distance;
      }
    }
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

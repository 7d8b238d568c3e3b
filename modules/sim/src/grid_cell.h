// Uniform grids over the world's xy plane, shared by the ground truth's cylinder buckets and the
// oracle's search grid.
#pragma once

namespace thicket::sim {

/// Index of the grid cell holding coordinate x, clamped to [0, cells - 1] (NaN gives 0).
inline int cellIndex(double x, double origin, double cell_size, int cells) {
  const double f = (x - origin) / cell_size;
  return f > 0 ? (f < cells ? static_cast<int>(f) : cells - 1) : 0;
}

}  // namespace thicket::sim

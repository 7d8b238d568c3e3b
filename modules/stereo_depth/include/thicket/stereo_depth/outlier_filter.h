// Optional statistical outlier removal on the point cloud of a depth image (PCL): a point whose
// mean distance to its mean_k nearest neighbours is more than stddev_mul standard deviations
// above the image's average is removed (its depth set to 0).
#pragma once

#include <vector>

#include "thicket/common/camera.h"
#include "thicket/common/params.h"

namespace thicket::stereo_depth {

struct OutlierFilterOptions {
  bool enabled = false;
  int mean_k = 20;          ///< neighbours per point
  double stddev_mul = 2.0;  ///< threshold in standard deviations
  int stride = 2;           ///< only every stride-th pixel in u and v enters the cloud

  void declare(Params& p);
};

/// Removes the outliers of depth_m (camera's size) in place; returns how many pixels it zeroed.
/// With a stride, the cloud holds the top-left pixel of every stride x stride block, and removing
/// it clears its whole block.
/// Does nothing when disabled.
int removeOutliers(std::vector<float>& depth_m, const PinholeCamera& camera,
                   const OutlierFilterOptions& options);

}  // namespace thicket::stereo_depth

// The only file that sees PCL.
#include "thicket/stereo_depth/outlier_filter.h"

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace thicket::stereo_depth {

void OutlierFilterOptions::declare(Params& p) {
  p("enabled", enabled, "remove statistical outliers from the point cloud (PCL)");
  p("mean_k", mean_k, "neighbours whose mean distance is compared", Range::atLeast(1));
  p("stddev_mul", stddev_mul,
    "a point farther than this many standard deviations above the mean is removed",
    Range::positive());
  p("stride", stride, "only every stride-th pixel in u and v enters the cloud [pixels]",
    Range::between(1, 16));
}

int removeOutliers(std::vector<float>& depth_m, const PinholeCamera& camera,
                   const OutlierFilterOptions& options) {
  if (!options.enabled) return 0;
  const int stride = std::max(1, options.stride);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<size_t> pixel_of_point;
  for (int v = 0; v < camera.height; v += stride) {
    for (int u = 0; u < camera.width; u += stride) {
      const size_t i = static_cast<size_t>(v) * camera.width + u;
      if (!(depth_m[i] > 0)) continue;
      const Eigen::Vector3d p = camera.backProject(u, v, depth_m[i]);
      cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                     static_cast<float>(p.z())));
      pixel_of_point.push_back(i);
    }
  }
  if (static_cast<int>(cloud->size()) <= options.mean_k) return 0;
  pcl::StatisticalOutlierRemoval<pcl::PointXYZ> filter(/*extract_removed_indices=*/true);
  filter.setInputCloud(cloud);
  filter.setMeanK(options.mean_k);
  filter.setStddevMulThresh(options.stddev_mul);
  pcl::PointCloud<pcl::PointXYZ> kept;
  filter.filter(kept);
  int removed = 0;
  for (const int index : *filter.getRemovedIndices()) {
    const size_t i = pixel_of_point[static_cast<size_t>(index)];
    const int u0 = static_cast<int>(i % static_cast<size_t>(camera.width));
    const int v0 = static_cast<int>(i / static_cast<size_t>(camera.width));
    for (int v = v0; v < std::min(v0 + stride, camera.height); ++v) {
      for (int u = u0; u < std::min(u0 + stride, camera.width); ++u) {
        float& d = depth_m[static_cast<size_t>(v) * camera.width + u];
        if (d > 0) {
          d = 0;
          ++removed;
        }
      }
    }
  }
  return removed;
}

}  // namespace thicket::stereo_depth

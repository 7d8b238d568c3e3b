// Rendered stereo pairs of forest50 and their true depth, shared by the stereo_depth tests.
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "forest_flight.h"
#include "thicket/common/camera.h"
#include "thicket/common/geometry.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"
#include "thicket/stereo_depth/calibration.h"
#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth::testing {

using bench::flightPoses;
using bench::forest;

/// The true depth (optical z) [m] that `camera` at world_T_camera sees, by exact ray casting; 0
/// beyond max_range along the ray.
inline std::vector<float> trueDepth(const sim::World& world, const Pose& world_T_camera,
                                    const PinholeCamera& camera, double max_range = 20) {
  const sim::RayCaster caster(world);
  const sim::RayCaster::View view = caster.view(world_T_camera.position, max_range);
  std::vector<float> depth(static_cast<size_t>(camera.width) * camera.height, 0.0f);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray = camera.backProject(u, v, 1.0);
      const Eigen::Vector3d unit = ray.normalized();
      const double range = view.cast(world_T_camera.orientation * unit);
      if (range != sim::RayCaster::kNoHit) {
        depth[static_cast<size_t>(v) * camera.width + u] = static_cast<float>(range * unit.z());
      }
    }
  }
  return depth;
}

/// How a depth image compares with the truth.
struct DepthScore {
  double valid = 0;       ///< fraction of all pixels with a depth
  double near_valid = 0;  ///< of pixels whose true depth is within near_m, those with a depth
  double near_bad = 0;    ///< of those with a depth, the fraction off by more than 5 %
  double median_rel = 0;  ///< median relative error of the near pixels with a depth
};

inline DepthScore scoreDepth(const std::vector<float>& depth, const std::vector<float>& truth,
                             double near_m = 5.0) {
  DepthScore s;
  size_t valid = 0, near = 0, near_valid = 0, near_bad = 0;
  std::vector<double> rel;
  for (size_t i = 0; i < depth.size(); ++i) {
    valid += depth[i] > 0 ? 1 : 0;
    if (!(truth[i] > 0) || truth[i] > near_m) continue;
    ++near;
    if (!(depth[i] > 0)) continue;
    ++near_valid;
    const double e = std::abs(depth[i] - truth[i]) / truth[i];
    rel.push_back(e);
    if (e > 0.05) ++near_bad;
  }
  s.valid = static_cast<double>(valid) / static_cast<double>(depth.size());
  s.near_valid = near == 0 ? 0 : static_cast<double>(near_valid) / static_cast<double>(near);
  s.near_bad =
      near_valid == 0 ? 1 : static_cast<double>(near_bad) / static_cast<double>(near_valid);
  if (!rel.empty()) {
    std::nth_element(rel.begin(), rel.begin() + rel.size() / 2, rel.end());
    s.median_rel = rel[rel.size() / 2];
  }
  return s;
}

/// A temporary file holding `text`, removed with the object.
class TempFile {
 public:
  TempFile(const std::string& name, const std::string& text)
      : path_(::testing::TempDir() + "/" + name) {
    std::ofstream(path_, std::ios::binary) << text;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

inline GrayImage grayImage(int width, int height, std::vector<uint8_t> pixels) {
  return GrayImage{width, height, std::move(pixels)};
}

}  // namespace thicket::stereo_depth::testing

// The exploration gain of a view (docs/design.md §1, local exploration): the fraction of unknown
// voxels in the camera frustum at a pose. The frustum is sampled on a grid of voxel-size spacing in
// the camera's optical frame, (i + 0.5, j + 0.5, k + 0.5) * voxel_size (z from min_range to
// max_range, projecting into the half-open image), every point looked up in the TSDF; "every s-th
// frustum voxel" takes every s-th grid point in a fixed order, so the estimate is deterministic and
// its cost falls by s. The order is the Z-order (Morton code) of the grid indices: runs of
// consecutive points are compact clusters, so every s-th point is a stratified sample (a row-major
// order aliases with upright trunks). The occlusion variant (for NBVP) counts only unknown points
// the camera could see: those whose ray from the camera meets no observed voxel at or behind a
// surface (TSDF distance <= 0) before reaching them; hidden points count as checked but not
// unknown. Unknown voxels hide nothing.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/camera.h"
#include "thicket/common/geometry.h"
#include "thicket/common/params.h"
#include "thicket/common/voxel_layer.h"

namespace thicket::explorer {

struct GainOptions {
  int width = 320;           ///< [pixels]
  int height = 240;          ///< [pixels]
  double hfov_deg = 90;      ///< horizontal field of view [deg]
  double min_range = 0.5;    ///< [m]
  double max_range = 5.0;    ///< [m]
  double min_weight = 1e-6;  ///< TSDF voxels with less weight are unknown

  void declare(Params& p);
};

/// What one gain evaluation found.
struct Gain {
  double unknown_fraction = 0;  ///< unknown (visible, with occlusion) / checked points
  int64_t checked = 0;          ///< frustum points looked up
  int64_t unknown = 0;          ///< of those, unknown (and visible, with occlusion)
};

class ExplorationGain {
 public:
  /// The frustum grid for this camera at `voxel_size` spacing. Throws std::invalid_argument on
  /// bad options or a non-positive voxel size.
  ExplorationGain(GainOptions options, double voxel_size);

  const GainOptions& options() const { return options_; }
  double voxelSize() const { return voxel_size_; }
  const PinholeCamera& camera() const { return camera_; }
  /// Grid points in the frustum (what stride 1 checks).
  int64_t frustumPoints() const;

  /// The unknown fraction seen from `world_T_camera` (optical frame), checking every `stride`-th
  /// frustum point (stride >= 1; 1 is exact). Throws std::invalid_argument on a stride < 1, a
  /// TSDF with another voxel size, or a pose that is not finite with a unit quaternion (within
  /// 1e-3) or lies too far out for voxel indices.
  Gain unknownFraction(const TsdfLayer& tsdf, const Pose& world_T_camera, int stride = 1) const;

  /// As unknownFraction, counting only unknown points not hidden behind an observed surface
  /// along the ray from the camera.
  Gain visibleUnknownFraction(const TsdfLayer& tsdf, const Pose& world_T_camera,
                              int stride = 1) const;

  /// visibleUnknownFraction when it is at least `at_least` and more than `more_than`, else
  /// nothing: the walk stops as soon as the points left cannot bring the fraction there, so
  /// choosing the best of several views costs little for the views that cannot win.
  std::optional<Gain> visibleUnknownFractionIfAbove(const TsdfLayer& tsdf,
                                                    const Pose& world_T_camera, int stride,
                                                    double at_least, double more_than) const;

  /// The optical-frame pose of a forward camera at `position` with heading `yaw` (no pitch).
  static Pose cameraAt(const Eigen::Vector3d& position, double yaw);

 private:
  GainOptions options_;
  double voxel_size_;
  PinholeCamera camera_;
  std::vector<Eigen::Vector3f> points_;  // frustum grid points in the optical frame
};

}  // namespace thicket::explorer

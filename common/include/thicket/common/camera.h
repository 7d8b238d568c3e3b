// The pinhole model shared by the renderer, the mapper's ray casting and the explorer's frustum
// gain, and how the camera is mounted on the body. Optical frame (docs/design.md §3): z along the
// optical axis, x right, y down. Pixel centres are at integer (u, v), so an image spans u in [-0.5,
// width - 0.5) and v in [-0.5, height - 0.5).
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Geometry>

#include "thicket/common/expected.h"
#include "thicket/common/geometry.h"

namespace thicket {

/// Intrinsics of an undistorted pinhole camera [pixels].
struct PinholeCamera {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;

  /// Square pixels, principal point at the image centre, and the outer edges of the outer pixels
  /// at ±horizontal_fov_rad / 2. Check the result with validated() when the inputs are untrusted.
  static PinholeCamera fromHorizontalFov(int width, int height, double horizontal_fov_rad);

  /// The largest image a message may describe: what decoding one allocates is bounded by it,
  /// whatever a (compressed) message claims.
  static constexpr int64_t kMaxPixels = int64_t{4096} * 4096;

  /// This camera, or why it cannot be used: a non-positive size or one of more than kMaxPixels,
  /// non-finite or non-positive focal lengths, or a non-finite principal point.
  Expected<PinholeCamera> validated() const;

  /// Angle between the left edge of the first column and the right edge of the last [rad].
  double horizontalFov() const;
  /// Angle between the top edge of the first row and the bottom edge of the last [rad].
  double verticalFov() const;

  /// Pixel coordinates of an optical-frame point; nullopt behind or on the image plane (z <= 0).
  /// Does not check the image bounds: see inImage.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_camera) const;
  /// Whether pixel coordinates fall on the image.
  bool inImage(const Eigen::Vector2d& uv) const;
  /// The optical-frame point seen at (u, v) whose z is depth.
  Eigen::Vector3d backProject(double u, double v, double depth) const;

  /// Whether a point has min_depth <= z <= max_depth and projects onto the image.
  bool inFrustum(const Eigen::Vector3d& p_camera, double min_depth, double max_depth) const;
  /// Conservative sphere-frustum test for culling voxel blocks: never false when part of the
  /// sphere is in the frustum, but may be true for spheres just outside an edge or corner.
  bool sphereIntersectsFrustum(const Eigen::Vector3d& center_camera, double radius,
                               double min_depth, double max_depth) const;
};

/// The rotation taking optical-frame vectors to body-frame vectors for a camera looking along body
/// x: optical z = body x, optical x = body -y, optical y = body -z.
Eigen::Quaterniond opticalToBody();

/// The camera-in-body pose (optical frame to body) of a forward camera at position_in_body,
/// pitched down by pitch_down_rad about body y (positive looks down).
Pose cameraMount(const Eigen::Vector3d& position_in_body, double pitch_down_rad);

}  // namespace thicket

// Rectification of a calibrated pair, computed once from the calibration (cv::stereoRectify with
// zero disparity at infinity, cv::initUndistortRectifyMap) and applied to every pair. Rectified
// images are row-aligned: a point seen at (u, v) on the left is seen at (u - d, v) on the right,
// with depth z = camera().fx * baseline() / d.
#pragma once

#include <memory>

#include <Eigen/Geometry>

#include "thicket/common/camera.h"
#include "thicket/common/expected.h"
#include "thicket/stereo_depth/calibration.h"
#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth {

class Rectifier {
 public:
  /// The rectification of a valid calibration. alpha is cv::stereoRectify's free scaling: -1
  /// keeps OpenCV's default, 0 crops to valid pixels only, 1 keeps every source pixel. Refuses an
  /// invalid calibration, a vertical pair (the baseline mostly along y) and a right camera that
  /// is on the left of the left one.
  static Expected<Rectifier> create(const StereoCalibration& calibration, double alpha = -1);

  /// The intrinsics of both rectified cameras (same size as the calibration).
  const PinholeCamera& camera() const { return camera_; }
  /// Distance between the rectified optical centres [m].
  double baseline() const { return baseline_; }
  /// The rotation taking vectors in the rectified left optical frame to the original left optical
  /// frame (R1^T of cv::stereoRectify): compose with the left camera's mount to get the mount of
  /// the rectified frame.
  const Eigen::Quaterniond& rectifiedInLeft() const { return rectified_in_left_; }
  const StereoCalibration& calibration() const { return calibration_; }

  /// Remaps a pair (bilinear); both images must have the calibration's size (else
  /// std::invalid_argument). Pixels that map outside the source image become 0.
  void rectify(const GrayImage& left, const GrayImage& right, GrayImage& left_out,
               GrayImage& right_out) const;

 private:
  struct Maps;
  Rectifier() = default;

  StereoCalibration calibration_;
  PinholeCamera camera_;
  double baseline_ = 0;
  Eigen::Quaterniond rectified_in_left_ = Eigen::Quaterniond::Identity();
  std::shared_ptr<const Maps> maps_;  // immutable once built; copies share it
};

}  // namespace thicket::stereo_depth

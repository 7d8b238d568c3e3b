// A stereo calibration as cv::stereoCalibrate describes a pair, read from OpenCV FileStorage YAML
// (the keys thicket::sim::StereoRenderer::calibrationYaml writes): image_width, image_height,
// camera_matrix_left/right (3x3), distortion_left/right (1xN or Nx1, N in {4, 5, 8, 12, 14}),
// R (3x3) and T (3x1) with x_right = R x_left + T [m], and calibration_id. A calibration is either
// fully valid or refused with the reason.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/expected.h"

namespace thicket::stereo_depth {

struct StereoCalibration {
  /// Names the calibration; a pair's calibration_id must match it. Empty when the file has no
  /// calibration_id (as files written by OpenCV's own tools): pairs are then not checked.
  std::string calibration_id;
  int width = 0;   ///< image size the calibration holds for [pixels]
  int height = 0;  ///< [pixels]
  Eigen::Matrix3d camera_matrix_left = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d camera_matrix_right = Eigen::Matrix3d::Identity();
  std::vector<double> distortion_left;  ///< OpenCV order k1, k2, p1, p2[, k3, ...]
  std::vector<double> distortion_right;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< x_right = R x_left + T
  Eigen::Vector3d T = Eigen::Vector3d::Zero();      ///< [m]

  /// This calibration, or why it cannot be used: a size outside [1, 16384], camera matrices that
  /// are not upper triangular with a last row of (0, 0, 1), non-positive or non-finite focal
  /// lengths, a non-finite principal point or distortion, a distortion count OpenCV does not
  /// know, an R that is not a rotation (|R^T R - I| > 1e-6 or det < 0), a non-finite or zero
  /// (< 1 mm) baseline.
  Expected<StereoCalibration> validated() const;
};

/// Parses FileStorage YAML text; `source` names it in messages ("source: key 'R': ..."). Refuses
/// unparsable text, missing keys, wrong matrix sizes and everything validated() refuses.
Expected<StereoCalibration> parseStereoCalibration(const std::string& yaml,
                                                   const std::string& source);

/// Reads and parses the file at `path`; refuses a missing or unreadable file.
Expected<StereoCalibration> loadStereoCalibration(const std::string& path);

/// The calibration as FileStorage YAML that parseStereoCalibration reads back exactly.
std::string stereoCalibrationYaml(const StereoCalibration& calibration);

}  // namespace thicket::stereo_depth

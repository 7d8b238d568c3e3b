// Calibrating a stereo pair from views of a chessboard (cv::stereoCalibrate), into the calibration
// the node reads (calibration.h). Each camera is calibrated alone first (cv::calibrateCamera), then
// the pair's R and T with both cameras' intrinsics fixed; the reprojection errors of both steps
// are reported, and the pairs where the board was not found in both images are named.
#pragma once

#include <string>
#include <vector>

#include "thicket/common/expected.h"
#include "thicket/stereo_depth/calibration.h"
#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth {

struct ChessboardSpec {
  int columns = 9;           ///< inner corners along a row
  int rows = 6;              ///< inner corners along a column
  double square_size = 0.0;  ///< side of one square [m]; sets the scale of T
};

/// One view of the board by both cameras.
struct GrayPair {
  std::string name;  ///< for messages, e.g. the left file's name
  GrayImage left, right;
};

struct StereoCalibrationResult {
  StereoCalibration calibration;
  double rms_left = 0;    ///< cv::calibrateCamera's RMS reprojection error, left camera [px]
  double rms_right = 0;   ///< [px]
  double rms_stereo = 0;  ///< cv::stereoCalibrate's over both cameras, intrinsics fixed [px]
  /// Mean distance of a corner to the epipolar line of its match in the other image [px].
  double epipolar_error = 0;
  int pairs_used = 0;
  std::vector<std::string> pairs_skipped;  ///< "name: why"
};

/// Needs at least 3 pairs in which the whole board is found in both images; refuses images of
/// differing sizes or whose pixels do not fill them, non-positive board dimensions or square size,
/// and a result the calibration's validation refuses. `calibration_id` names the result (empty:
/// none).
Expected<StereoCalibrationResult> calibrateStereo(const std::vector<GrayPair>& pairs,
                                                  const ChessboardSpec& board,
                                                  const std::string& calibration_id);

}  // namespace thicket::stereo_depth

#include "thicket/stereo_depth/calibrate.h"

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "opencv_view.h"

namespace thicket::stereo_depth {

namespace {

using Corners = std::vector<cv::Point2f>;

// The board's inner corners in a gray image, refined to a tenth of a pixel; empty when the whole
// board is not found.
Corners findBoard(const cv::Mat& gray, const cv::Size& pattern) {
  Corners corners;
  const int flags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  if (!cv::findChessboardCorners(gray, pattern, corners, flags)) return {};
  cv::cornerSubPix(gray, corners, cv::Size(11, 11), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
  return corners;
}

std::vector<double> toVector(const cv::Mat& m) {
  cv::Mat flat = m.reshape(1, 1);
  return std::vector<double>(flat.begin<double>(), flat.end<double>());
}

// Mean distance of each corner to the epipolar line of its match, over both images, with the
// distortion removed first (as the OpenCV sample's check).
double epipolarError(const std::vector<Corners>& left, const std::vector<Corners>& right,
                     const cv::Mat& k_left, const cv::Mat& d_left, const cv::Mat& k_right,
                     const cv::Mat& d_right, const cv::Mat& fundamental) {
  double sum = 0;
  size_t count = 0;
  for (size_t i = 0; i < left.size(); ++i) {
    Corners l, r;
    cv::undistortPoints(left[i], l, k_left, d_left, cv::noArray(), k_left);
    cv::undistortPoints(right[i], r, k_right, d_right, cv::noArray(), k_right);
    std::vector<cv::Vec3f> lines_in_right, lines_in_left;
    cv::computeCorrespondEpilines(l, 1, fundamental, lines_in_right);
    cv::computeCorrespondEpilines(r, 2, fundamental, lines_in_left);
    for (size_t j = 0; j < l.size(); ++j) {
      const cv::Vec3f& a = lines_in_right[j];
      const cv::Vec3f& b = lines_in_left[j];
      sum += std::abs(r[j].x * a[0] + r[j].y * a[1] + a[2]) +
             std::abs(l[j].x * b[0] + l[j].y * b[1] + b[2]);
      count += 2;
    }
  }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

}  // namespace

Expected<StereoCalibrationResult> calibrateStereo(const std::vector<GrayPair>& pairs,
                                                  const ChessboardSpec& board,
                                                  const std::string& calibration_id) {
  if (board.columns < 2 || board.rows < 2) {
    return unexpected("the board needs at least 2 x 2 inner corners, not " +
                      std::to_string(board.columns) + " x " + std::to_string(board.rows));
  }
  if (!(board.square_size > 0) || !std::isfinite(board.square_size)) {
    return unexpected("the square size must be a positive length in metres");
  }
  if (pairs.empty()) return unexpected("no image pairs");
  const cv::Size pattern(board.columns, board.rows);
  const cv::Size size(pairs.front().left.width, pairs.front().left.height);
  StereoCalibrationResult result;
  std::vector<Corners> left_corners, right_corners;
  for (const GrayPair& pair : pairs) {
    for (const GrayImage* image : {&pair.left, &pair.right}) {
      const std::string side = image == &pair.left ? "left" : "right";
      if (image->width != size.width || image->height != size.height) {
        return unexpected(pair.name + ": the " + side + " image is " +
                          std::to_string(image->width) + "x" + std::to_string(image->height) +
                          ", the first pair's " + std::to_string(size.width) + "x" +
                          std::to_string(size.height));
      }
      if (size.width <= 0 || size.height <= 0 ||
          image->pixels.size() != static_cast<size_t>(size.width) * size.height) {
        return unexpected(pair.name + ": the " + side + " image's pixels do not fill it");
      }
    }
    Corners l = findBoard(asMat(pair.left), pattern);
    Corners r = l.empty() ? Corners{} : findBoard(asMat(pair.right), pattern);
    if (l.empty() || r.empty()) {
      result.pairs_skipped.push_back(pair.name + ": the board was not found in the " +
                                     (l.empty() ? "left" : "right") + " image");
      continue;
    }
    left_corners.push_back(std::move(l));
    right_corners.push_back(std::move(r));
  }
  result.pairs_used = static_cast<int>(left_corners.size());
  if (result.pairs_used < 3) {
    return unexpected("the board was found in both images of " + std::to_string(result.pairs_used) +
                      " pairs; at least 3 are needed");
  }
  std::vector<cv::Point3f> board_points;
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 0; c < board.columns; ++c) {
      board_points.emplace_back(static_cast<float>(c * board.square_size),
                                static_cast<float>(r * board.square_size), 0.0f);
    }
  }
  const std::vector<std::vector<cv::Point3f>> object_points(left_corners.size(), board_points);
  cv::Mat k_left, d_left, k_right, d_right, rotation, translation, essential, fundamental;
  try {
    result.rms_left = cv::calibrateCamera(object_points, left_corners, size, k_left, d_left,
                                          cv::noArray(), cv::noArray());
    result.rms_right = cv::calibrateCamera(object_points, right_corners, size, k_right, d_right,
                                           cv::noArray(), cv::noArray());
    result.rms_stereo = cv::stereoCalibrate(
        object_points, left_corners, right_corners, k_left, d_left, k_right, d_right, size,
        rotation, translation, essential, fundamental, cv::CALIB_FIX_INTRINSIC,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6));
  } catch (const cv::Exception& e) {
    return unexpected(std::string("OpenCV could not calibrate: ") + e.what());
  }
  result.epipolar_error =
      epipolarError(left_corners, right_corners, k_left, d_left, k_right, d_right, fundamental);
  StereoCalibration& c = result.calibration;
  c.calibration_id = calibration_id;
  c.width = size.width;
  c.height = size.height;
  cv::cv2eigen(k_left, c.camera_matrix_left);
  cv::cv2eigen(k_right, c.camera_matrix_right);
  c.distortion_left = toVector(d_left);
  c.distortion_right = toVector(d_right);
  cv::cv2eigen(rotation, c.R);
  cv::cv2eigen(translation, c.T);
  auto valid = c.validated();
  if (!valid) return unexpected("the calibration is not usable: " + valid.error());
  c = *valid;
  return result;
}

}  // namespace thicket::stereo_depth

#include "thicket/stereo_depth/rectifier.h"

#include <cmath>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "opencv_view.h"

namespace thicket::stereo_depth {

struct Rectifier::Maps {
  cv::Mat left_x, left_y, right_x, right_y;  // fixed-point maps for cv::remap
};

namespace {

cv::Mat toCv(const Eigen::Matrix3d& m) {
  cv::Mat out(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.at<double>(r, c) = m(r, c);
  }
  return out;
}

cv::Mat toCv(const std::vector<double>& v) {
  return cv::Mat(1, static_cast<int>(v.size()), CV_64F, const_cast<double*>(v.data())).clone();
}

void remapImage(const GrayImage& in, const cv::Mat& map_x, const cv::Mat& map_y, GrayImage& out) {
  const cv::Mat src = asMat(in);
  out.width = map_x.cols;
  out.height = map_x.rows;
  out.pixels.resize(static_cast<size_t>(out.width) * static_cast<size_t>(out.height));
  cv::Mat dst(out.height, out.width, CV_8UC1, out.pixels.data());
  cv::remap(src, dst, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
}

}  // namespace

Expected<Rectifier> Rectifier::create(const StereoCalibration& calibration, double alpha) {
  auto valid = calibration.validated();
  if (!valid) return unexpected("invalid calibration: " + valid.error());
  if (!std::isfinite(alpha) || alpha < -1 || alpha > 1) {
    return unexpected("rectification alpha must be in [-1, 1]");
  }
  const Eigen::Vector3d& t = calibration.T;
  if (std::abs(t.y()) > std::abs(t.x())) {
    return unexpected(
        "the calibration is of a vertical pair (|T_y| > |T_x|); only horizontal "
        "pairs are supported");
  }
  if (t.x() >= 0) {
    return unexpected(
        "the right camera is left of the left camera (T_x >= 0): swap the images "
        "or the calibration");
  }
  const cv::Size size(calibration.width, calibration.height);
  const cv::Mat k1 = toCv(calibration.camera_matrix_left);
  const cv::Mat k2 = toCv(calibration.camera_matrix_right);
  const cv::Mat d1 = toCv(calibration.distortion_left);
  const cv::Mat d2 = toCv(calibration.distortion_right);
  const cv::Mat r = toCv(calibration.R);
  const cv::Mat tv = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
  cv::Mat r1, r2, p1, p2, q;
  try {
    cv::stereoRectify(k1, d1, k2, d2, size, r, tv, r1, r2, p1, p2, q, cv::CALIB_ZERO_DISPARITY,
                      alpha, size);
  } catch (const cv::Exception& e) {
    return unexpected(std::string("cv::stereoRectify failed: ") + e.err);
  }
  const double f = p1.at<double>(0, 0);
  const double baseline = -p2.at<double>(0, 3) / p2.at<double>(0, 0);
  if (!std::isfinite(f) || f <= 0 || !std::isfinite(baseline) || baseline <= 0) {
    return unexpected("rectification gives no usable camera (focal " + std::to_string(f) +
                      ", baseline " + std::to_string(baseline) + ")");
  }
  Rectifier rectifier;
  rectifier.calibration_ = calibration;
  rectifier.camera_.width = calibration.width;
  rectifier.camera_.height = calibration.height;
  rectifier.camera_.fx = p1.at<double>(0, 0);
  rectifier.camera_.fy = p1.at<double>(1, 1);
  rectifier.camera_.cx = p1.at<double>(0, 2);
  rectifier.camera_.cy = p1.at<double>(1, 2);
  if (auto camera = rectifier.camera_.validated(); !camera) {
    return unexpected("rectification gives no usable camera: " + camera.error());
  }
  rectifier.baseline_ = baseline;
  Eigen::Matrix3d r1e;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r1e(i, j) = r1.at<double>(i, j);
  }
  // R1 takes unrectified left coordinates to rectified ones; the frame's orientation is R1^T.
  rectifier.rectified_in_left_ = Eigen::Quaterniond(r1e.transpose()).normalized();
  auto maps = std::make_shared<Maps>();
  cv::initUndistortRectifyMap(k1, d1, r1, p1, size, CV_16SC2, maps->left_x, maps->left_y);
  cv::initUndistortRectifyMap(k2, d2, r2, p2, size, CV_16SC2, maps->right_x, maps->right_y);
  rectifier.maps_ = std::move(maps);
  return rectifier;
}

void Rectifier::rectify(const GrayImage& left, const GrayImage& right, GrayImage& left_out,
                        GrayImage& right_out) const {
  for (const GrayImage* image : {&left, &right}) {
    if (image->width != calibration_.width || image->height != calibration_.height ||
        image->pixels.size() != static_cast<size_t>(image->width) * image->height) {
      throw std::invalid_argument("Rectifier::rectify: the image is not of the calibration's size");
    }
  }
  remapImage(left, maps_->left_x, maps_->left_y, left_out);
  remapImage(right, maps_->right_x, maps_->right_y, right_out);
}

}  // namespace thicket::stereo_depth

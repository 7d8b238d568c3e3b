// Calibrating a stereo pair from chessboard views, against ground truth: views of a board rendered
// (by homography, with antialiasing) through two cameras whose intrinsics, rotation and baseline
// are known, and OpenCV's own stereo chessboard set where opencv-doc is installed.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "thicket/stereo_depth/calibrate.h"
#include "thicket/stereo_depth/stereo_depth.h"

namespace thicket::stereo_depth {
namespace {

constexpr int kWidth = 640, kHeight = 480;
constexpr int kColumns = 9, kRows = 6;  // inner corners
constexpr double kSquare = 0.04;        // [m]

// The true pair: the right camera 0.12 m to the right of the left one, turned by 1 degree about
// its vertical axis, with intrinsics a little different from the left camera's.
struct TruePair {
  Eigen::Matrix3d k_left, k_right, R;
  Eigen::Vector3d T;
  TruePair() {
    k_left << 420, 0, 322, 0, 418, 238, 0, 0, 1;
    k_right << 415, 0, 317, 0, 414, 243, 0, 0, 1;
    R = Eigen::AngleAxisd(M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T = Eigen::Vector3d(-0.12, 0.002, 0.001);
  }
};

// The board as a camera with intrinsics k sees it at pose (board_R, board_t) (board frame to
// camera frame; the board lies in its z = 0 plane, corners from (0, 0)): rendered 4 times larger,
// then averaged down, so that edges are antialiased as a real lens and sensor blur them.
GrayImage renderBoard(const Eigen::Matrix3d& k, const Eigen::Matrix3d& board_R,
                      const Eigen::Vector3d& board_t) {
  constexpr int kScale = 4, kPixelsPerSquare = 40;
  // The board texture: (columns + 1) x (rows + 1) squares with a white margin of one square.
  const int tex_w = (kColumns + 3) * kPixelsPerSquare, tex_h = (kRows + 3) * kPixelsPerSquare;
  cv::Mat texture(tex_h, tex_w, CV_8UC1, cv::Scalar(255));
  for (int r = 0; r < kRows + 1; ++r) {
    for (int c = 0; c < kColumns + 1; ++c) {
      if ((r + c) % 2 == 0) {
        texture(cv::Rect((c + 1) * kPixelsPerSquare, (r + 1) * kPixelsPerSquare, kPixelsPerSquare,
                         kPixelsPerSquare))
            .setTo(0);
      }
    }
  }
  // Texture pixel (u, v) is at board point ((u - 2 s) m, (v - 2 s) m) with m = square / s: the
  // first inner corner sits at texture pixel (2 s, 2 s).
  const double m = kSquare / kPixelsPerSquare;
  Eigen::Matrix3d texture_to_board;
  texture_to_board << m, 0, -2 * kPixelsPerSquare * m, 0, m, -2 * kPixelsPerSquare * m, 0, 0, 1;
  Eigen::Matrix3d board_to_image;
  board_to_image.col(0) = board_R.col(0);
  board_to_image.col(1) = board_R.col(1);
  board_to_image.col(2) = board_t;
  Eigen::Matrix3d upscale = Eigen::Matrix3d::Identity();
  upscale(0, 0) = upscale(1, 1) = kScale;
  // Pixel centres: OpenCV's image coordinates put pixel (0, 0)'s centre at (0, 0) at both scales.
  upscale(0, 2) = upscale(1, 2) = (kScale - 1) / 2.0;
  const Eigen::Matrix3d h = upscale * k * board_to_image * texture_to_board;
  cv::Mat homography(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) homography.at<double>(r, c) = h(r, c);
  }
  cv::Mat large, small;
  cv::warpPerspective(texture, large, homography, cv::Size(kWidth * kScale, kHeight * kScale),
                      cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(128));
  cv::resize(large, small, cv::Size(kWidth, kHeight), 0, 0, cv::INTER_AREA);
  GrayImage image{kWidth, kHeight, {}};
  image.pixels.assign(small.datastart, small.dataend);
  return image;
}

// Views of the board from in front of the pair, tilted and turned differently each time.
std::vector<GrayPair> renderViews(const TruePair& truth) {
  std::vector<GrayPair> pairs;
  const Eigen::Vector3d centre_offset(-0.5 * (kColumns - 1) * kSquare, -0.5 * (kRows - 1) * kSquare,
                                      0);
  for (int i = 0; i < 12; ++i) {
    const double a = 0.35 * std::sin(1.3 * i), b = 0.35 * std::cos(0.9 * i + 0.4);
    const double roll = 0.25 * std::sin(2.1 * i);
    const Eigen::Matrix3d board_R = (Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()) *
                                     Eigen::AngleAxisd(b, Eigen::Vector3d::UnitX()) *
                                     Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                                        .toRotationMatrix();
    const Eigen::Vector3d centre(0.06 + 0.08 * std::sin(0.7 * i), 0.05 * std::cos(1.1 * i),
                                 0.75 + 0.25 * std::sin(0.5 * i));
    const Eigen::Vector3d board_t = centre + board_R * centre_offset;
    GrayPair pair;
    pair.name = "view " + std::to_string(i);
    pair.left = renderBoard(truth.k_left, board_R, board_t);
    pair.right = renderBoard(truth.k_right, truth.R * board_R, truth.R * board_t + truth.T);
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

TEST(CalibrateStereo, RecoversTheIntrinsicsRotationAndBaselineOfRenderedViews) {
  const TruePair truth;
  const auto result = calibrateStereo(renderViews(truth), {kColumns, kRows, kSquare}, "rig");
  ASSERT_TRUE(result) << result.error();
  EXPECT_EQ(result->pairs_used, 12);
  EXPECT_TRUE(result->pairs_skipped.empty());
  EXPECT_LT(result->rms_left, 0.2);
  EXPECT_LT(result->rms_right, 0.2);
  EXPECT_LT(result->rms_stereo, 0.2);
  EXPECT_LT(result->epipolar_error, 0.2);
  const StereoCalibration& c = result->calibration;
  EXPECT_EQ(c.calibration_id, "rig");
  EXPECT_EQ(c.width, kWidth);
  EXPECT_EQ(c.height, kHeight);
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(c.camera_matrix_left(i, i), truth.k_left(i, i), 1.0) << i;
    EXPECT_NEAR(c.camera_matrix_right(i, i), truth.k_right(i, i), 1.0) << i;
    EXPECT_NEAR(c.camera_matrix_left(i, 2), truth.k_left(i, 2), 1.0) << i;
    EXPECT_NEAR(c.camera_matrix_right(i, 2), truth.k_right(i, 2), 1.0) << i;
  }
  // Focal lengths and principal points within 1 px (measured: 0.5 px at most), the rotation
  // within 0.2 degree (0.12: about the principal points' error, 0.14 degree per pixel at this
  // focal length), the baseline within 2 mm (0.6 mm).
  const double angle = Eigen::AngleAxisd(c.R * truth.R.transpose()).angle();
  EXPECT_LT(angle, 0.2 * M_PI / 180.0) << angle;
  EXPECT_LT((c.T - truth.T).norm(), 0.002) << c.T.transpose();
  // The node can rectify with it.
  StereoDepthOptions options;
  EXPECT_TRUE(StereoDepth::create(options, c)) << "the calibration does not rectify";
}

TEST(CalibrateStereo, NamesThePairsWithoutTheBoardAndRefusesTooFew) {
  const TruePair truth;
  std::vector<GrayPair> pairs = renderViews(truth);
  pairs.resize(4);
  pairs[1].right.pixels.assign(pairs[1].right.pixels.size(), 200);  // the board is gone
  auto result = calibrateStereo(pairs, {kColumns, kRows, kSquare}, "");
  ASSERT_TRUE(result) << result.error();
  EXPECT_EQ(result->pairs_used, 3);
  ASSERT_EQ(result->pairs_skipped.size(), 1u);
  EXPECT_EQ(result->pairs_skipped[0], "view 1: the board was not found in the right image");

  pairs[2].left.pixels.assign(pairs[2].left.pixels.size(), 200);
  result = calibrateStereo(pairs, {kColumns, kRows, kSquare}, "");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().find("2 pairs; at least 3"), std::string::npos) << result.error();
}

TEST(CalibrateStereo, RefusesBadInput) {
  const TruePair truth;
  std::vector<GrayPair> pairs = renderViews(truth);
  pairs.resize(3);
  EXPECT_FALSE(calibrateStereo(pairs, {kColumns, kRows, 0.0}, ""));
  EXPECT_FALSE(calibrateStereo(pairs, {kColumns, kRows, std::nan("")}, ""));
  EXPECT_FALSE(calibrateStereo(pairs, {1, kRows, kSquare}, ""));
  EXPECT_FALSE(calibrateStereo({}, {kColumns, kRows, kSquare}, ""));
  std::vector<GrayPair> torn = pairs;
  torn[2].right.pixels.resize(10);
  auto result = calibrateStereo(torn, {kColumns, kRows, kSquare}, "");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().find("view 2: the right image's pixels"), std::string::npos)
      << result.error();
  std::vector<GrayPair> sizes = pairs;
  sizes[1].left.width = 320;
  result = calibrateStereo(sizes, {kColumns, kRows, kSquare}, "");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().find("view 1: the left image is 320x480"), std::string::npos)
      << result.error();
}

}  // namespace
}  // namespace thicket::stereo_depth

// Rectification against a calibration with a known rotation: the right camera of a rendered
// rectified pair is turned by a small known rotation Q (its image warped by the homography
// K Q^T K^-1) and the calibration says so (R = Q^T, T = -Q^T (b, 0, 0)). Rectified, the pair
// gives depth as good as the unrotated pair, in the rectified frame the Rectifier reports; with
// the identity calibration instead, the same images give much worse depth.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stereo_test_support.h"
#include "thicket/sim/render.h"
#include "thicket/stereo_depth/stereo_depth.h"

namespace thicket::stereo_depth {
namespace {

using testing::forest;
using testing::scoreDepth;

constexpr double kDeg = std::numbers::pi / 180;

Eigen::Matrix3d cameraMatrix(const PinholeCamera& c) {
  Eigen::Matrix3d k;
  k << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1;
  return k;
}

// The image a camera turned by q (new camera to old camera) sees, from the old camera's image.
GrayImage turn(const GrayImage& image, const Eigen::Matrix3d& k, const Eigen::Matrix3d& q) {
  const Eigen::Matrix3d h = k * q.transpose() * k.inverse();  // old pixel -> new pixel
  cv::Mat hm(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) hm.at<double>(r, c) = h(r, c);
  }
  const cv::Mat src(image.height, image.width, CV_8UC1, const_cast<uint8_t*>(image.pixels.data()));
  GrayImage out{image.width, image.height,
                std::vector<uint8_t>(static_cast<size_t>(image.width) * image.height)};
  cv::Mat dst(out.height, out.width, CV_8UC1, out.pixels.data());
  cv::warpPerspective(src, dst, hm, src.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  return out;
}

TEST(Rectification, AKnownRotationOfTheRightCameraIsUndone) {
  const sim::StereoRenderer renderer(forest(), sim::StereoCameraOptions{});
  const PinholeCamera camera = renderer.camera();
  const Eigen::Matrix3d k = cameraMatrix(camera);
  const Eigen::Matrix3d q = (Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(-1.0 * kDeg, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(0.7 * kDeg, Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const double b = renderer.baseline();

  auto ideal = parseStereoCalibration(renderer.calibrationYaml("cam"), "sim");
  ASSERT_TRUE(ideal) << ideal.error();
  StereoCalibration turned = *ideal;
  turned.R = q.transpose();
  turned.T = -q.transpose() * Eigen::Vector3d(b, 0, 0);
  // The calibration survives a round trip through its YAML.
  auto reread = parseStereoCalibration(stereoCalibrationYaml(turned), "turned");
  ASSERT_TRUE(reread) << reread.error();
  EXPECT_TRUE(reread->R.isApprox(turned.R, 1e-15));
  EXPECT_TRUE(reread->T.isApprox(turned.T, 1e-15));

  auto straight = StereoDepth::create(StereoDepthOptions{}, *ideal);
  auto rotated = StereoDepth::create(StereoDepthOptions{}, *reread);
  auto unaware = StereoDepth::create(StereoDepthOptions{}, *ideal);
  ASSERT_TRUE(straight && rotated && unaware);
  const Rectifier& rectifier = *rotated->rectifier();
  EXPECT_NEAR(rectifier.baseline(), b, 1e-9);
  // stereoRectify turns each camera part of the way (half the relative rotation, then both to
  // put the baseline on x): the rectified frame is turned, by less than the whole rotation.
  const double half = Eigen::AngleAxisd(rectifier.rectifiedInLeft()).angle();
  const double full = Eigen::AngleAxisd(q).angle();
  std::printf("relative rotation %.3f deg, rectified left frame turned %.3f deg\n", full / kDeg,
              half / kDeg);
  EXPECT_GT(half, 0.1 * full);
  EXPECT_LT(half, full);

  for (const Pose& body : testing::flightPoses(3.0, 2)) {
    StereoPair pair;
    pair.calibration_id = "cam";
    pair.left = {camera.width, camera.height, {}};
    pair.right = {camera.width, camera.height, {}};
    renderer.render(body, pair.left.pixels, pair.right.pixels);
    auto reference = straight->process(pair);
    ASSERT_TRUE(reference);
    const Pose world_T_left = body * renderer.leftInBody();
    const auto reference_score =
        scoreDepth(reference->depth, testing::trueDepth(forest(), world_T_left, camera));

    pair.right = turn(pair.right, k, q);
    auto frame = rotated->process(pair);
    ASSERT_TRUE(frame) << frame.error();
    const Pose world_T_rectified =
        world_T_left * Pose{Eigen::Vector3d::Zero(), frame->rectified_in_left};
    const auto truth = testing::trueDepth(forest(), world_T_rectified, frame->camera);
    const auto score = scoreDepth(frame->depth, truth);
    const auto unaware_frame = unaware->process(pair);
    ASSERT_TRUE(unaware_frame);
    const auto unaware_score =
        scoreDepth(unaware_frame->depth, testing::trueDepth(forest(), world_T_left, camera));
    std::printf(
        "pose (%.1f, %.1f): unrotated valid %.3f bad %.4f; rotated and rectified valid "
        "%.3f bad %.4f; rotated, identity calibration valid %.3f bad %.4f\n",
        body.position.x(), body.position.y(), reference_score.valid, reference_score.near_bad,
        score.valid, score.near_bad, unaware_score.valid, unaware_score.near_bad);
    // The warp and the rectification leave black borders where nothing matches.
    EXPECT_GT(score.valid, reference_score.valid - 0.08);
    EXPECT_LT(score.near_bad, reference_score.near_bad + 0.03);
    EXPECT_LT(score.median_rel, 0.02);
    // Without the rotation in the calibration the rows do not line up.
    EXPECT_LT(unaware_score.valid, score.valid - 0.2);
  }
}

}  // namespace
}  // namespace thicket::stereo_depth

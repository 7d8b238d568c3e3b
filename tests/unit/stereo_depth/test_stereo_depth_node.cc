// thicket-stereo-depth's node in a memq:// composite: a STEREO pair gives one CAMERA_DEPTH with
// the rectified intrinsics, the camera mount and the range limits, then MODULE_TIMING; refused
// pairs publish nothing and are reported with the reason.
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <thicket/depth_image_t.hpp>
#include <thicket/module_timing_t.hpp>

#include "stereo_depth_node.h"
#include "stereo_test_support.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/loop.h"

namespace thicket::stereo_depth {
namespace {

using testing::forest;
using testing::TempFile;

class Recorder : public Node {
 public:
  explicit Recorder(lcm::LCM& lcm) : Node("recorder", lcm) {
    subscribe<depth_image_t>("CAMERA_DEPTH", [this](const depth_image_t& m, const MessageInfo&) {
      depths.push_back(m);
      order.push_back("CAMERA_DEPTH");
    });
    subscribe<module_timing_t>("MODULE_TIMING",
                               [this](const module_timing_t& m, const MessageInfo&) {
                                 timings.push_back(m);
                                 order.push_back("MODULE_TIMING");
                               });
  }
  std::vector<depth_image_t> depths;
  std::vector<module_timing_t> timings;
  std::vector<std::string> order;
};

sim::StereoCameraOptions cameraOptions() {
  sim::StereoCameraOptions o;
  o.width = 376;
  o.height = 240;
  o.position_in_body = Eigen::Vector3d(0.1, 0.0, 0.05);
  o.pitch_down_deg = 5;
  return o;
}

class StereoDepthNodeTest : public ::testing::Test {
 protected:
  StereoDepthNodeTest()
      : renderer(forest(), cameraOptions()),
        calibration("stereo_node_calib.yaml", renderer.calibrationYaml("sim_stereo")) {}

  StereoDepthNodeOptions nodeOptions() const {
    StereoDepthNodeOptions o;
    o.stereo.calibration_file = calibration.path();
    o.camera_position_in_body = cameraOptions().position_in_body;
    o.camera_pitch_down_deg = cameraOptions().pitch_down_deg;
    return o;
  }

  stereo_image_t pair(int64_t utime, bool rectified = false) const {
    std::vector<uint8_t> left, right;
    renderer.render(testing::flightPoses(3.0, 1)[0], left, right);
    const PinholeCamera c = renderer.camera();
    stereo_image_t msg{};
    msg.utime = utime;
    msg.calibration_id = "sim_stereo";
    msg.rectified = rectified;
    msg.left = rawImageMessage({c.width, c.height, left}, utime, "left");
    msg.right = rawImageMessage({c.width, c.height, right}, utime, "right");
    return msg;
  }

  sim::StereoRenderer renderer;
  TempFile calibration;
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  Recorder recorder{lcm};
  Node camera{"camera", lcm};
};

TEST_F(StereoDepthNodeTest, APairGivesDepthWithTheRectifiedCameraThenItsTiming) {
  StereoDepthNode node(lcm, nodeOptions());
  camera.publish("STEREO", pair(1'000'000));
  loop.drain();
  ASSERT_EQ(recorder.depths.size(), 1u) << node.lastError();
  EXPECT_EQ(recorder.order, (std::vector<std::string>{"CAMERA_DEPTH", "MODULE_TIMING"}));
  auto image = decodeDepthImage(recorder.depths[0]);
  ASSERT_TRUE(image) << image.error();
  EXPECT_EQ(image->utime, 1'000'000);
  EXPECT_EQ(recorder.depths[0].camera_id, "stereo");
  const PinholeCamera c = renderer.camera();
  EXPECT_EQ(image->camera.width, c.width);
  EXPECT_NEAR(image->camera.fx, c.fx, 1e-6);
  EXPECT_NEAR(image->camera.cx, c.cx, 1e-6);
  EXPECT_NEAR(image->camera.cy, c.cy, 1e-6);
  EXPECT_LT((image->camera_in_body.position - renderer.leftInBody().position).norm(), 1e-9);
  EXPECT_LT(image->camera_in_body.orientation.angularDistance(renderer.leftInBody().orientation),
            1e-6);
  EXPECT_EQ(image->min_range, 0.2);
  EXPECT_EQ(image->max_range, 20.0);
  size_t valid = 0;
  for (float z : image->depth) valid += z > 0 ? 1 : 0;
  EXPECT_GT(static_cast<double>(valid) / static_cast<double>(image->depth.size()), 0.6);
  ASSERT_EQ(recorder.timings.size(), 1u);
  const module_timing_t& t = recorder.timings[0];
  EXPECT_EQ(t.module, "stereo_depth");
  EXPECT_EQ(t.utime, 1'000'000);
  EXPECT_EQ(t.sequence, 0);
  EXPECT_EQ(t.stages, (std::vector<std::string>{"rectify", "match", "depth"}));
  EXPECT_EQ(t.num_stages, 3);
  EXPECT_EQ(node.published(), 1);
  EXPECT_EQ(node.refused(), 0);
  EXPECT_NE(node.summary().find("1 pairs published (0 refused)"), std::string::npos)
      << node.summary();

  // A pair that arrives rectified skips rectification and gives the same depth here.
  camera.publish("STEREO", pair(2'000'000, true));
  loop.drain();
  ASSERT_EQ(recorder.depths.size(), 2u);
  auto again = decodeDepthImage(recorder.depths[1]);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->depth, image->depth);
}

TEST_F(StereoDepthNodeTest, TheMountIsTheRectifiedFramesWhenTheCalibrationTurnsTheCameras) {
  auto calibration_in = parseStereoCalibration(renderer.calibrationYaml("sim_stereo"), "sim");
  ASSERT_TRUE(calibration_in);
  StereoCalibration turned = *calibration_in;
  const Eigen::Matrix3d q =
      Eigen::AngleAxisd(2.0 * std::numbers::pi / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  turned.R = q.transpose();
  turned.T = -q.transpose() * Eigen::Vector3d(renderer.baseline(), 0, 0);
  TempFile file("stereo_node_turned.yaml", stereoCalibrationYaml(turned));
  StereoDepthNodeOptions options = nodeOptions();
  options.stereo.calibration_file = file.path();
  StereoDepthNode node(lcm, options);
  // The right camera pitched by 2 degrees (about the baseline): the rectified frames share the
  // mean viewing direction, so the rectified left frame is pitched too. (A turn about the
  // vertical axis would leave the left frame as it is: its x already lies on the baseline.)
  const Eigen::Quaterniond left = renderer.leftInBody().orientation;
  EXPECT_GT(node.rectifiedInBody().orientation.angularDistance(left), 0.1 * std::numbers::pi / 180);
  camera.publish("STEREO", pair(1000));
  loop.drain();
  ASSERT_EQ(recorder.depths.size(), 1u) << node.lastError();
  auto image = decodeDepthImage(recorder.depths[0]);
  ASSERT_TRUE(image);
  EXPECT_LT(image->camera_in_body.orientation.angularDistance(node.rectifiedInBody().orientation),
            1e-6);
}

TEST_F(StereoDepthNodeTest, RefusedPairsPublishNothingAndSayWhy) {
  StereoDepthNode node(lcm, nodeOptions());
  const auto refused = [&](stereo_image_t msg, const std::string& words) {
    const int64_t before = node.badMessageCount();
    camera.publish("STEREO", msg);
    loop.drain();
    EXPECT_EQ(node.badMessageCount(), before + 1) << words;
    EXPECT_NE(node.lastError().find(words), std::string::npos) << node.lastError();
  };
  stereo_image_t msg = pair(1000);
  msg.right.utime = 1001;
  refused(msg, "timestamps differ");
  msg = pair(1000);
  msg.calibration_id = "other_camera";
  refused(msg, "calibration 'other_camera'");
  msg = pair(1000);
  const GrayImage small{10, 10, std::vector<uint8_t>(100, 7)};
  msg.left = rawImageMessage(small, 1000, "left");
  msg.right = rawImageMessage(small, 1000, "right");
  refused(msg, "the calibration is for 376x240");
  msg = pair(1000);
  msg.left.encoding = image_t::ENCODING_JPEG;
  refused(msg, "left image: the data is not JPEG");
  EXPECT_TRUE(recorder.depths.empty());
  EXPECT_TRUE(recorder.timings.empty());
  EXPECT_EQ(node.refused(), 4);
}

TEST_F(StereoDepthNodeTest, RectifiedPairsWithoutACalibrationNeedIntrinsics) {
  StereoDepthNodeOptions options;
  {
    StereoDepthNode node(lcm, options);
    camera.publish("STEREO", pair(1000, true));
    camera.publish("STEREO", pair(2000, false));
    loop.drain();
    EXPECT_TRUE(recorder.depths.empty());
    EXPECT_EQ(node.refused(), 2);
    EXPECT_NE(node.lastError().find("not rectified and there is no calibration"), std::string::npos)
        << node.lastError();
  }
  const PinholeCamera c = renderer.camera();
  options.stereo.rectified.fx = c.fx;
  options.stereo.rectified.baseline = renderer.baseline();
  StereoDepthNode node(lcm, options);
  camera.publish("STEREO", pair(3000, true));
  loop.drain();
  ASSERT_EQ(recorder.depths.size(), 1u) << node.lastError();
  auto image = decodeDepthImage(recorder.depths[0]);
  ASSERT_TRUE(image);
  EXPECT_NEAR(image->camera.cx, c.cx, 1e-9);  // the image centre
}

TEST_F(StereoDepthNodeTest, AMissingOrInvalidCalibrationStopsTheStart) {
  StereoDepthNodeOptions options;
  options.stereo.calibration_file = "/nonexistent/stereo.yaml";
  EXPECT_THROW(StereoDepthNode(lcm, options), std::invalid_argument);
  TempFile bad("stereo_node_bad.yaml", "%YAML:1.0\n---\nimage_width: 10\n");
  options.stereo.calibration_file = bad.path();
  try {
    StereoDepthNode node(lcm, options);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("missing key 'image_height'"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace thicket::stereo_depth

// thicket-stereo-depth as a user runs it: the shipped parameter file is current, bad
// configurations stop the node at start, and the offline file mode writes a PFM disparity and a
// 16-bit millimetre depth PNG from image files, or says why not.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "cli.h"
#include "stereo_depth_node.h"
#include "stereo_test_support.h"

namespace thicket::stereo_depth {
namespace {

using thicket::testing::CliResult;

CliResult stereoDepth(const std::string& args) {
  return thicket::testing::runCommand(std::string(THICKET_STEREO_DEPTH) + " " + args);
}

TEST(StereoDepthCli, TheShippedParameterFileIsCurrent) {
  thicket::testing::expectParamsFileCurrent<StereoDepthNodeOptions>(
      THICKET_STEREO_DEPTH, "thicket-stereo-depth",
      std::string(THICKET_SOURCE_DIR) + "/config/params/stereo_depth.yaml");
}

TEST(StereoDepthCli, RefusesBadConfigurationsWithAMessage) {
  const std::string config =
      ::testing::TempDir() + "/stereo_cli_" + std::to_string(::getpid()) + ".yaml";
  const auto run_with = [&](const std::string& yaml) {
    std::ofstream(config) << yaml;
    return stereoDepth("--lcm-url memq:// --config " + config);
  };
  EXPECT_EQ(stereoDepth("--config /nonexistent.yaml").status, 2);
  CliResult result = run_with("stereo:\n  matcher:\n    num_disparities: 40\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("multiple of 16"), std::string::npos) << result.output;
  result = run_with("stereo:\n  matcher:\n    mode: fast\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("mode"), std::string::npos) << result.output;
  result = run_with("stereo:\n  calibration_file: /nonexistent/stereo.yaml\n");
  EXPECT_EQ(result.status, 2);
  EXPECT_NE(result.output.find("cannot read"), std::string::npos) << result.output;
  EXPECT_EQ(stereoDepth("--bogus").status, 2);
  std::remove(config.c_str());
}

class StereoDepthFileMode : public ::testing::Test {
 protected:
  void SetUp() override {
    sim::StereoCameraOptions options;
    const sim::StereoRenderer renderer(testing::forest(), options);
    const Pose body = testing::flightPoses(3.0, 1)[0];
    GrayImage left{options.width, options.height, {}}, right{options.width, options.height, {}};
    renderer.render(body, left.pixels, right.pixels);
    ASSERT_EQ(writeGrayImageFile(dir + "left.png", left), "");
    ASSERT_EQ(writeGrayImageFile(dir + "right.png", right), "");
    std::ofstream(dir + "calib.yaml") << renderer.calibrationYaml("sim_stereo");
    sim::DepthCameraOptions depth_options;
    depth_options.width = options.width;
    depth_options.height = options.height;
    sim::DepthRenderer(testing::forest(), depth_options).render(body, truth);
  }
  void TearDown() override {
    for (const char* f :
         {"left.png", "right.png", "calib.yaml", "d.pfm", "z.png", "z2.png", "small.png"}) {
      std::remove((dir + f).c_str());
    }
  }
  std::string files(const std::string& args) const {
    std::string out = args;
    for (size_t at; (at = out.find("@")) != std::string::npos;) out.replace(at, 1, dir);
    return out;
  }

  std::string dir = ::testing::TempDir() + "/stereo_file_" + std::to_string(::getpid()) + "_";
  std::vector<float> truth;
};

TEST_F(StereoDepthFileMode, CalibratedPairToPfmAndMillimetrePng) {
  const CliResult result = stereoDepth(
      files("file --calib @calib.yaml --left @left.png --right @right.png --disparity-out "
            "@d.pfm --depth-out @z.png"));
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("valid depth"), std::string::npos) << result.output;
  auto disparity = readPfm(dir + "d.pfm");
  ASSERT_TRUE(disparity) << disparity.error();
  EXPECT_EQ(disparity->width, 752);
  EXPECT_EQ(disparity->height, 480);
  auto depth = readDepthPngMm(dir + "z.png");
  ASSERT_TRUE(depth) << depth.error();
  ASSERT_EQ(depth->depth_m.size(), truth.size());
  // Depth and disparity agree (z = f b / d, to the millimetre rounding), and match the truth.
  const double fb = 376.0 * 0.11;
  size_t checked = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const float d = disparity->values[i];
    const float z = depth->depth_m[i];
    if (z > 0) {
      ASSERT_GT(d, 0);
      EXPECT_NEAR(z, fb / d, 6e-4);
      ++checked;
    }
  }
  EXPECT_GT(checked, truth.size() / 2);
  const auto score = testing::scoreDepth(depth->depth_m, truth);
  EXPECT_LT(score.near_bad, 0.15);

  // The same pair as already rectified: the same disparities.
  const CliResult rectified = stereoDepth(
      files("file --rectified --focal 376 --baseline 0.11 --left @left.png --right @right.png "
            "--depth-out @z2.png --max-disparity 100"));
  ASSERT_EQ(rectified.status, 0) << rectified.output;
  EXPECT_NE(rectified.output.find("112 disparities"), std::string::npos) << rectified.output;
  auto depth2 = readDepthPngMm(dir + "z2.png");
  ASSERT_TRUE(depth2);
  EXPECT_LT(testing::scoreDepth(depth2->depth_m, truth).near_bad, 0.15);
}

TEST_F(StereoDepthFileMode, RefusesWithAMessageAndExitCode2) {
  const auto refused = [&](const std::string& args, const std::string& words) {
    const CliResult result = stereoDepth(files(args));
    EXPECT_EQ(result.status, 2) << args << "\n" << result.output;
    EXPECT_NE(result.output.find(words), std::string::npos) << args << "\n" << result.output;
  };
  refused("file --left @left.png --right @right.png --depth-out @z.png",
          "one of --calib and --rectified");
  refused(
      "file --calib @calib.yaml --rectified --left @left.png --right @right.png "
      "--depth-out @z.png",
      "--calib excludes --rectified");
  refused("file --calib @calib.yaml --left @left.png --depth-out @z.png", "--right");
  refused("file --calib @calib.yaml --left @left.png --right @right.png", "nothing to write");
  refused("file --rectified --left @left.png --right @right.png --depth-out @z.png",
          "--focal and --baseline");
  refused(
      "file --rectified --focal -3 --baseline 0.1 --left @left.png --right @right.png "
      "--depth-out @z.png",
      "--focal");
  refused(
      "file --calib @calib.yaml --left @left.png --right @right.png --depth-out @z.png "
      "--max-disparity 0",
      "--max-disparity");
  refused(
      "file --calib /nonexistent.yaml --left @left.png --right @right.png --depth-out "
      "@z.png",
      "cannot read");
  refused("file --calib @calib.yaml --left @missing.png --right @right.png --depth-out @z.png",
          "cannot read the image");
  ASSERT_EQ(writeGrayImageFile(dir + "small.png", GrayImage{32, 24, std::vector<uint8_t>(768)}),
            "");
  refused("file --calib @calib.yaml --left @left.png --right @small.png --depth-out @z.png",
          "differ in size");
  refused("file --calib @calib.yaml --left @small.png --right @small.png --depth-out @z.png",
          "the calibration is for 752x480");
  refused("file --calib @calib.yaml --left @left.png --right @right.png --bogus 1", "--bogus");
}

// `calibrate` on OpenCV's own stereo chessboard set (a real camera pair, 9 x 6 inner corners; the
// opencv-doc package, installed by scripts/setup): it writes a calibration the node loads and
// rectifies with, the reprojection errors of a real calibration, and the right camera to the
// right of the left one. Square size 1 as in OpenCV's sample: T is then in squares.
TEST(StereoDepthCli, CalibrateFromOpenCvsStereoChessboardSet) {
  const std::string data = "/usr/share/doc/opencv-doc/examples/data/";
  if (!std::filesystem::exists(data + "left01.jpg")) {
    GTEST_SKIP() << "OpenCV's sample images are not installed (apt-get install opencv-doc)";
  }
  std::string left = " --left", right = " --right";
  for (int i : {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14}) {
    const std::string n = (i < 10 ? "0" : "") + std::to_string(i);
    left += " " + data + "left" + n + ".jpg";
    right += " " + data + "right" + n + ".jpg";
  }
  const std::string out =
      ::testing::TempDir() + "/calibrate_" + std::to_string(::getpid()) + ".yaml";
  const CliResult result = stereoDepth("calibrate" + left + right +
                                       " --corners 9 6 --square 1 --id opencv --out " + out);
  ASSERT_EQ(result.status, 0) << result.output;
  EXPECT_NE(result.output.find("from 13 of 13 pairs (640x480)"), std::string::npos)
      << result.output;
  const auto calibration = loadStereoCalibration(out);
  ASSERT_TRUE(calibration) << calibration.error();
  EXPECT_EQ(calibration->calibration_id, "opencv");
  EXPECT_GT(calibration->camera_matrix_left(0, 0), 400);
  EXPECT_LT(calibration->camera_matrix_left(0, 0), 700);
  EXPECT_LT(calibration->T.x(), -3.0);
  EXPECT_LT(std::abs(calibration->T.y()) + std::abs(calibration->T.z()), 0.5);
  StereoDepthOptions options;
  options.calibration_file = out;
  EXPECT_TRUE(StereoDepth::create(options));
  const double stereo_rms = [&] {
    const auto at = result.output.find("px right, ");
    return at == std::string::npos ? 99.0 : std::stod(result.output.substr(at + 10));
  }();
  EXPECT_LT(stereo_rms, 1.0) << result.output;

  // Refused with a message: unpaired images, a board that is not there.
  const CliResult unpaired = stereoDepth("calibrate" + left + " --right " + data +
                                         "right01.jpg --corners 9 6 --square 1 --out " + out);
  EXPECT_EQ(unpaired.status, 2);
  EXPECT_NE(unpaired.output.find("13 left and 1 right images"), std::string::npos)
      << unpaired.output;
  const CliResult wrong_board =
      stereoDepth("calibrate" + left + right + " --corners 7 7 --square 1 --out " + out);
  EXPECT_EQ(wrong_board.status, 2);
  EXPECT_NE(wrong_board.output.find("0 pairs; at least 3 are needed"), std::string::npos)
      << wrong_board.output;
  std::remove(out.c_str());
}

}  // namespace
}  // namespace thicket::stereo_depth

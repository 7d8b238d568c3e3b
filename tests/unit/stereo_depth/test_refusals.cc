// Every input thicket-stereo-depth refuses, refused with a reason that says what is wrong:
// calibrations (missing, unreadable, incomplete, invalid), pairs (timestamps, sizes, encodings,
// truncated data), and pairs that do not fit the calibration.
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "stereo_test_support.h"
#include "thicket/common/time.h"
#include "thicket/stereo_depth/stereo_depth.h"

namespace thicket::stereo_depth {
namespace {

using testing::TempFile;

// A 64x48 textured image (value noise, deterministic).
GrayImage texture(int width = 64, int height = 48, int seed = 1) {
  GrayImage image{width, height, std::vector<uint8_t>(static_cast<size_t>(width) * height)};
  uint32_t state = 2463534242u + static_cast<uint32_t>(seed);
  for (uint8_t& p : image.pixels) {
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    p = static_cast<uint8_t>(state & 0xff);
  }
  return image;
}

StereoCalibration goodCalibration(int width = 64, int height = 48) {
  StereoCalibration c;
  c.calibration_id = "cam";
  c.width = width;
  c.height = height;
  c.camera_matrix_left << 50, 0, 31.5, 0, 50, 23.5, 0, 0, 1;
  c.camera_matrix_right = c.camera_matrix_left;
  c.distortion_left = {0, 0, 0, 0, 0};
  c.distortion_right = {0, 0, 0, 0, 0};
  c.T = Eigen::Vector3d(-0.1, 0, 0);
  return c;
}

void expectRefused(const Expected<StereoCalibration>& result, const std::string& words) {
  ASSERT_FALSE(result) << "accepted; expected a refusal mentioning '" << words << "'";
  EXPECT_NE(result.error().find(words), std::string::npos) << result.error();
}

// Replaces the first line of `yaml` starting with `key` (and the matrix lines after it) by
// `replacement` (empty: removes the key).
std::string replaceKey(const std::string& yaml, const std::string& key,
                       const std::string& replacement) {
  const size_t start = yaml.find("\n" + key + ":");
  if (start == std::string::npos) return yaml;
  size_t end = yaml.find('\n', start + 1);
  while (end != std::string::npos && end + 1 < yaml.size() && yaml[end + 1] == ' ') {
    end = yaml.find('\n', end + 1);
  }
  return yaml.substr(0, start + 1) + (replacement.empty() ? "" : replacement + "\n") +
         (end == std::string::npos ? "" : yaml.substr(end + 1));
}

TEST(CalibrationRefusals, TheSimulatorsFileLoadsAndTheFileRoundTrips) {
  const std::string yaml = stereoCalibrationYaml(goodCalibration());
  auto c = parseStereoCalibration(yaml, "good");
  ASSERT_TRUE(c) << c.error();
  EXPECT_EQ(c->calibration_id, "cam");
  EXPECT_EQ(c->width, 64);
  EXPECT_EQ(c->T, Eigen::Vector3d(-0.1, 0, 0));
  TempFile file("calib_good.yaml", yaml);
  EXPECT_TRUE(loadStereoCalibration(file.path()));
  // Without an id (as OpenCV's own tools write) it loads, with an empty id.
  auto no_id = parseStereoCalibration(replaceKey(yaml, "calibration_id", ""), "no id");
  ASSERT_TRUE(no_id) << no_id.error();
  EXPECT_EQ(no_id->calibration_id, "");
}

TEST(CalibrationRefusals, MissingUnreadableAndIncompleteFiles) {
  expectRefused(loadStereoCalibration("/nonexistent/calib.yaml"), "cannot read");
  TempFile empty("calib_empty.yaml", "");
  expectRefused(loadStereoCalibration(empty.path()), "empty");
  expectRefused(parseStereoCalibration("this: [is not: {opencv", "junk"), "junk");
  const std::string yaml = stereoCalibrationYaml(goodCalibration());
  for (const char* key : {"image_width", "image_height", "camera_matrix_left",
                          "camera_matrix_right", "distortion_left", "distortion_right", "R", "T"}) {
    expectRefused(parseStereoCalibration(replaceKey(yaml, key, ""), "f"),
                  "missing key '" + std::string(key) + "'");
  }
  expectRefused(parseStereoCalibration(replaceKey(yaml, "R",
                                                  "R: !!opencv-matrix\n   rows: 2\n   cols: 2\n"
                                                  "   dt: d\n   data: [ 1, 0, 0, 1 ]"),
                                       "f"),
                "expected 3x3");
  expectRefused(
      parseStereoCalibration(replaceKey(yaml, "image_width", "image_width: \"wide\""), "f"),
      "not an integer");
}

TEST(CalibrationRefusals, InvalidValues) {
  const auto refused = [](auto mutate, const std::string& words) {
    StereoCalibration c = goodCalibration();
    mutate(c);
    expectRefused(c.validated(), words);
    // The same through the file format (where the value can be written).
    expectRefused(parseStereoCalibration(stereoCalibrationYaml(c), "f"), words);
  };
  refused([](StereoCalibration& c) { c.width = 0; }, "image size");
  refused([](StereoCalibration& c) { c.height = 20000; }, "image size");
  refused([](StereoCalibration& c) { c.camera_matrix_left(0, 0) = 0; }, "non-positive focal");
  refused([](StereoCalibration& c) { c.camera_matrix_right(1, 1) = -5; }, "non-positive focal");
  refused([](StereoCalibration& c) { c.camera_matrix_left(0, 2) = std::nan(""); }, "non-finite");
  refused([](StereoCalibration& c) { c.camera_matrix_left(2, 2) = 2; }, "not a camera matrix");
  refused([](StereoCalibration& c) { c.distortion_left = {0, 0, 0}; }, "3 coefficients");
  refused(
      [](StereoCalibration& c) { c.distortion_right[0] = std::numeric_limits<double>::infinity(); },
      "non-finite");
  refused([](StereoCalibration& c) { c.R(0, 0) = 1.1; }, "not a rotation");
  refused([](StereoCalibration& c) { c.R = -Eigen::Matrix3d::Identity(); }, "not a rotation");
  refused([](StereoCalibration& c) { c.T.setZero(); }, "baseline");
  refused([](StereoCalibration& c) { c.T.x() = std::nan(""); }, "T has non-finite");
}

TEST(CalibrationRefusals, PairsThatCannotBeRectifiedHorizontally) {
  StereoCalibration vertical = goodCalibration();
  vertical.T = Eigen::Vector3d(0, -0.1, 0);
  auto r = Rectifier::create(vertical);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("vertical"), std::string::npos) << r.error();
  StereoCalibration swapped = goodCalibration();
  swapped.T = Eigen::Vector3d(0.1, 0, 0);
  r = Rectifier::create(swapped);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("swap"), std::string::npos) << r.error();
  StereoDepthOptions options;
  options.calibration_file = "/nonexistent/calib.yaml";
  auto pipeline = StereoDepth::create(options);
  ASSERT_FALSE(pipeline);
  EXPECT_NE(pipeline.error().find("cannot read"), std::string::npos) << pipeline.error();
}

TEST(MatcherOptions, InconsistentOptionsAreRefused) {
  const auto refused = [](auto mutate, const std::string& words) {
    StereoMatcherOptions o;
    mutate(o);
    auto v = o.validated();
    ASSERT_FALSE(v) << words;
    EXPECT_NE(v.error().find(words), std::string::npos) << v.error();
    EXPECT_THROW(StereoMatcher{o}, std::invalid_argument);
  };
  refused([](StereoMatcherOptions& o) { o.num_disparities = 40; }, "multiple of 16");
  refused([](StereoMatcherOptions& o) { o.block_size = 4; }, "odd");
  refused([](StereoMatcherOptions& o) { o.p1 = 500, o.p2 = 400; }, "p2");
  refused([](StereoMatcherOptions& o) { o.mode = "fast"; }, "mode");
  refused([](StereoMatcherOptions& o) { o.max_range = 0.1; }, "range");
  // Each field's rule from its YAML declaration holds for options built in code too.
  refused([](StereoMatcherOptions& o) { o.uniqueness_ratio = 200; }, "uniqueness_ratio");
  refused([](StereoMatcherOptions& o) { o.block_size = 33; }, "block_size");
  refused([](StereoMatcherOptions& o) { o.max_range = std::nan(""); }, "max_range");
}

TEST(PipelineOptions, EveryFieldKeepsItsYamlRule) {
  const auto refused = [](auto mutate, const std::string& words) {
    StereoDepthOptions o;
    mutate(o);
    auto pipeline = StereoDepth::create(o);
    ASSERT_FALSE(pipeline) << words;
    EXPECT_NE(pipeline.error().find(words), std::string::npos) << pipeline.error();
  };
  refused([](StereoDepthOptions& o) { o.outliers.stride = 0; }, "stride");
  refused([](StereoDepthOptions& o) { o.outliers.stddev_mul = -1; }, "stddev_mul");
  refused([](StereoDepthOptions& o) { o.rectify_alpha = 2; }, "rectify_alpha");
  refused([](StereoDepthOptions& o) { o.rectified.fx = -376; }, "fx");
  EXPECT_TRUE(StereoDepth::create(StereoDepthOptions{}));
}

stereo_image_t pairMessage(int64_t utime = 1000) {
  stereo_image_t msg{};
  msg.utime = utime;
  msg.calibration_id = "cam";
  msg.left = rawImageMessage(texture(64, 48, 1), utime, "left");
  msg.right = rawImageMessage(texture(64, 48, 2), utime, "right");
  return msg;
}

void expectRefused(const Expected<StereoPair>& result, const std::string& words) {
  ASSERT_FALSE(result) << "accepted; expected a refusal mentioning '" << words << "'";
  EXPECT_NE(result.error().find(words), std::string::npos) << result.error();
}

TEST(PairRefusals, TimestampsThatDiffer) {
  ASSERT_TRUE(decodeStereoPair(pairMessage()));
  stereo_image_t msg = pairMessage();
  msg.right.utime += 1;
  expectRefused(decodeStereoPair(msg), "timestamps differ");
  EXPECT_TRUE(decodeStereoPair(msg, 1));  // within a configured tolerance
  msg = pairMessage();
  msg.utime += 5000;
  expectRefused(decodeStereoPair(msg), "timestamps differ");
}

TEST(PairRefusals, StampsThatAreNotTimes) {
  // Far apart as they are, such stamps once overflowed the difference and passed as equal.
  stereo_image_t msg = pairMessage();
  msg.utime = 1;
  msg.left.utime = msg.right.utime = -std::numeric_limits<int64_t>::max();
  expectRefused(decodeStereoPair(msg), "left image utime -9223372036854775807 us is outside");
  msg = pairMessage();
  msg.utime = std::numeric_limits<int64_t>::min();
  expectRefused(decodeStereoPair(msg, std::numeric_limits<int64_t>::max()), "pair utime");
  msg = pairMessage();
  msg.right.utime = kMaxUtime + 1;
  expectRefused(decodeStereoPair(msg), "right image utime");
}

TEST(PairRefusals, ImagesOfDifferentSizes) {
  stereo_image_t msg = pairMessage();
  msg.right = rawImageMessage(texture(60, 48), msg.utime, "right");
  expectRefused(decodeStereoPair(msg), "differ in size");
}

TEST(PairRefusals, BadEncodingsAndTruncatedData) {
  const auto refusedRight = [](auto mutate, const std::string& words) {
    stereo_image_t msg = pairMessage();
    mutate(msg.right);
    expectRefused(decodeStereoPair(msg), "right image: ");
    expectRefused(decodeStereoPair(msg), words);
  };
  refusedRight([](image_t& i) { i.encoding = 7; }, "unknown encoding");
  refusedRight([](image_t& i) { i.pixel_format = 9; }, "unknown pixel format");
  refusedRight([](image_t& i) { i.pixel_format = image_t::PIXEL_GRAY16; }, "GRAY16");
  refusedRight([](image_t& i) { i.width = 0; }, "image size");
  refusedRight([](image_t& i) { i.size -= 1; }, "size field");
  refusedRight(
      [](image_t& i) {
        i.data.resize(i.data.size() - 64);  // one row short
        i.size = static_cast<int32_t>(i.data.size());
      },
      "expected 3072");
  refusedRight([](image_t& i) { i.row_stride = 10; }, "row_stride");
  refusedRight([](image_t& i) { i.pixel_format = image_t::PIXEL_RGB8; }, "row_stride");
  refusedRight([](image_t& i) { i.encoding = image_t::ENCODING_PNG; }, "not PNG");
  refusedRight([](image_t& i) { i.encoding = image_t::ENCODING_JPEG; }, "not JPEG");
  for (int8_t encoding : {image_t::ENCODING_PNG, image_t::ENCODING_JPEG}) {
    const char* name = encoding == image_t::ENCODING_PNG ? "PNG" : "JPEG";
    refusedRight(
        [&](image_t& i) {
          i = compressedImageMessage(texture(64, 48, 2), i.utime, "right", encoding);
          i.data.resize(i.data.size() / 3);  // truncated
          i.size = static_cast<int32_t>(i.data.size());
        },
        "cannot decode the " + std::string(name));
    refusedRight(
        [&](image_t& i) {
          i = compressedImageMessage(texture(64, 48, 2), i.utime, "right", encoding);
          i.width = 32;  // the message lies about the size
        },
        "the message says 32x48");
  }
}

TEST(PairDecoding, RawWithPaddingColourPngAndJpeg) {
  const GrayImage gray = texture(64, 48, 3);
  stereo_image_t msg = pairMessage();
  // Raw rows padded to 80 bytes.
  image_t padded = rawImageMessage(gray, msg.utime, "right");
  padded.row_stride = 80;
  padded.data.assign(80 * 48, 0xee);
  for (int v = 0; v < 48; ++v) {
    std::copy_n(gray.pixels.begin() + v * 64, 64, padded.data.begin() + v * 80);
  }
  padded.size = static_cast<int32_t>(padded.data.size());
  msg.right = padded;
  auto pair = decodeStereoPair(msg);
  ASSERT_TRUE(pair) << pair.error();
  EXPECT_EQ(pair->right.pixels, gray.pixels);
  // Colour: a gray image as RGB8 and BGR8 decodes to the same gray.
  for (int8_t format : {image_t::PIXEL_RGB8, image_t::PIXEL_BGR8}) {
    image_t colour = rawImageMessage(gray, msg.utime, "right");
    colour.pixel_format = format;
    colour.row_stride = 64 * 3;
    colour.data.clear();
    for (uint8_t p : gray.pixels) colour.data.insert(colour.data.end(), {p, p, p});
    colour.size = static_cast<int32_t>(colour.data.size());
    auto decoded = decodeImage(colour);
    ASSERT_TRUE(decoded) << decoded.error();
    EXPECT_EQ(decoded->pixels, gray.pixels);
  }
  auto png = decodeImage(compressedImageMessage(gray, 0, "x", image_t::ENCODING_PNG));
  ASSERT_TRUE(png) << png.error();
  EXPECT_EQ(png->pixels, gray.pixels);  // lossless
  auto jpeg = decodeImage(compressedImageMessage(gray, 0, "x", image_t::ENCODING_JPEG));
  ASSERT_TRUE(jpeg) << jpeg.error();
  EXPECT_EQ(jpeg->width, 64);
  EXPECT_EQ(jpeg->height, 48);
}

TEST(PipelineRefusals, PairsThatDoNotFitTheCalibration) {
  // 64 pixels are too narrow for the default search (64 disparities and a 5-pixel block).
  auto narrow = StereoDepth::create(StereoDepthOptions{}, goodCalibration());
  ASSERT_FALSE(narrow);
  EXPECT_NE(narrow.error().find("64 pixels wide, narrower than the 69"), std::string::npos)
      << narrow.error();
  StereoDepthOptions fits;
  fits.matcher.num_disparities = 16;
  auto pipeline = StereoDepth::create(fits, goodCalibration());
  ASSERT_TRUE(pipeline) << pipeline.error();
  auto pair = decodeStereoPair(pairMessage());
  ASSERT_TRUE(pair);
  EXPECT_TRUE(pipeline->process(*pair));

  StereoPair other_id = *pair;
  other_id.calibration_id = "other";
  auto r = pipeline->process(other_id);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("calibration 'other'"), std::string::npos) << r.error();

  StereoPair small = *pair;
  small.left = texture(32, 24, 1);
  small.right = texture(32, 24, 2);
  r = pipeline->process(small);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("the calibration is for 64x48"), std::string::npos) << r.error();
  small.rectified = true;  // rectified pairs must fit the calibration too
  EXPECT_FALSE(pipeline->process(small));

  // Without a calibration: unrectified pairs are refused; rectified ones must fit the
  // configured size, and give depth only with intrinsics.
  StereoDepthOptions options = fits;
  options.rectified.width = 64;
  options.rectified.height = 48;
  auto bare = StereoDepth::create(options);
  ASSERT_TRUE(bare) << bare.error();
  r = bare->process(*pair);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("not rectified and there is no calibration"), std::string::npos);
  small.rectified = true;
  r = bare->process(small);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("rectified pairs are 64x48"), std::string::npos) << r.error();
  StereoPair rectified = *pair;
  rectified.rectified = true;
  r = bare->process(rectified);
  ASSERT_TRUE(r) << r.error();
  EXPECT_FALSE(r->has_depth);
  // Rectified pairs of any size are checked against the search when they arrive.
  auto any_size = StereoDepth::create(StereoDepthOptions{});
  ASSERT_TRUE(any_size) << any_size.error();
  r = any_size->process(rectified);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("the pair's images are 64 pixels wide"), std::string::npos) << r.error();
}

TEST(Files, PfmAndDepthPngRoundTrip) {
  const std::string pfm = ::testing::TempDir() + "/stereo_roundtrip.pfm";
  std::vector<float> values = {0.0f, -1.0f, 1.5f, 63.0625f, 1e-3f, 12.25f};
  ASSERT_EQ(writePfm(pfm, 3, 2, values), "");
  auto read = readPfm(pfm);
  ASSERT_TRUE(read) << read.error();
  EXPECT_EQ(read->width, 3);
  EXPECT_EQ(read->height, 2);
  EXPECT_EQ(read->values, values);
  // Rows are stored bottom to top: the first row in the file is the image's last. The header is
  // three lines: "Pf", "<width> <height>", the scale (negative: little-endian).
  {
    std::ifstream in(pfm, std::ios::binary);
    std::string file((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(file.substr(0, 7), "Pf\n3 2\n");
    const size_t data = file.find('\n', 7) + 1;
    EXPECT_EQ(file[7], '-');
    ASSERT_EQ(file.size(), data + 6 * sizeof(float));
    float first;
    std::memcpy(&first, file.data() + data, 4);
    EXPECT_EQ(first, 63.0625f);
  }
  // Truncated and colour files are refused.
  std::string bytes;
  {
    std::ifstream in(pfm, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::ofstream(pfm, std::ios::binary) << bytes.substr(0, bytes.size() - 3);
  auto truncated = readPfm(pfm);
  ASSERT_FALSE(truncated);
  EXPECT_NE(truncated.error().find("cannot read the PFM"), std::string::npos) << truncated.error();
  std::ofstream(pfm, std::ios::binary) << "PF\n1 1\n-1.0\n" << std::string(12, '\0');
  auto colour = readPfm(pfm);
  ASSERT_FALSE(colour);
  EXPECT_NE(colour.error().find("3 channels"), std::string::npos) << colour.error();
  std::remove(pfm.c_str());

  const std::string png = ::testing::TempDir() + "/stereo_roundtrip.png";
  const std::vector<float> depth = {0.0f, 1.2344f, 65.535f, 70.0f, 0.0004f, 3.0f};
  ASSERT_EQ(writeDepthPngMm(png, 3, 2, depth), "");
  auto back = readDepthPngMm(png);
  ASSERT_TRUE(back) << back.error();
  const std::vector<float> expected = {0.0f, 1.234f, 65.535f, 0.0f, 0.0f, 3.0f};
  ASSERT_EQ(back->depth_m.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(back->depth_m[i], expected[i], 1e-6);
  std::remove(png.c_str());
}

}  // namespace
}  // namespace thicket::stereo_depth

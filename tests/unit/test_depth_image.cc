#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "thicket/common/depth_image.h"

namespace thicket {
namespace {

DepthImage sampleImage() {
  DepthImage image;
  image.utime = 123456;
  image.camera = PinholeCamera::fromHorizontalFov(8, 6, M_PI / 2);
  image.camera_in_body = cameraMount(Eigen::Vector3d(0.1, 0, 0.05), 0.2);
  image.min_range = 0.1;
  image.max_range = 20.0;
  image.depth.resize(48);
  for (size_t i = 0; i < image.depth.size(); ++i) {
    image.depth[i] = i % 7 == 0 ? 0.0f : 0.5f + 0.3217f * static_cast<float>(i);
  }
  return image;
}

depth_image_t encoded(int8_t encoding, int8_t compression) {
  return encodeDepthImage(sampleImage(), encoding, compression);
}

void expectRefused(const depth_image_t& msg, const std::string& words) {
  auto decoded = decodeDepthImage(msg);
  ASSERT_FALSE(decoded) << "expected a refusal mentioning '" << words << "'";
  EXPECT_NE(decoded.error().find(words), std::string::npos) << decoded.error();
}

TEST(DepthImage, FloatRoundTripIsExactWithAndWithoutCompression) {
  const DepthImage original = sampleImage();
  for (int8_t compression : {depth_image_t::COMPRESSION_NONE, depth_image_t::COMPRESSION_ZSTD}) {
    auto decoded = decodeDepthImage(encoded(depth_image_t::DEPTH_FLOAT32_M, compression));
    ASSERT_TRUE(decoded) << decoded.error();
    EXPECT_EQ(decoded->depth, original.depth);
    EXPECT_EQ(decoded->utime, original.utime);
    EXPECT_EQ(decoded->camera.fx, original.camera.fx);
    EXPECT_EQ(decoded->camera.cy, original.camera.cy);
    EXPECT_TRUE(decoded->camera_in_body.position.isApprox(original.camera_in_body.position));
    EXPECT_NEAR(
        decoded->camera_in_body.orientation.angularDistance(original.camera_in_body.orientation),
        0.0, 1e-12);
    EXPECT_EQ(decoded->max_range, 20.0);
  }
}

TEST(DepthImage, MillimetreEncodingRoundsAndMarksOverflowAsNoReturn) {
  DepthImage image = sampleImage();
  image.depth[1] = 1.23449f;
  image.depth[2] = 70.0f;    // beyond 65.535 m: no return
  image.depth[3] = 0.0004f;  // rounds to 0 mm: no return
  auto decoded = decodeDepthImage(encodeDepthImage(image, depth_image_t::DEPTH_UINT16_MM));
  ASSERT_TRUE(decoded) << decoded.error();
  EXPECT_FLOAT_EQ(decoded->depth[1], 1.234f);
  EXPECT_EQ(decoded->depth[2], 0.0f);
  EXPECT_EQ(decoded->depth[3], 0.0f);
  for (size_t i = 4; i < image.depth.size(); ++i) {
    EXPECT_NEAR(decoded->depth[i], image.depth[i], 0.0005 + 1e-6) << i;
  }
}

TEST(DepthImage, CompressionShrinksSmoothImages) {
  DepthImage image = sampleImage();
  image.camera = PinholeCamera::fromHorizontalFov(320, 240, M_PI / 2);
  image.depth.assign(320 * 240, 4.0f);
  const depth_image_t msg = encodeDepthImage(image);
  EXPECT_LT(msg.data.size(), 320u * 240u * 2u / 20u);
  ASSERT_TRUE(decodeDepthImage(msg));
}

TEST(DepthImage, RefusesInconsistentSizes) {
  depth_image_t msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.width = 9;
  expectRefused(msg, "bytes for 54 pixels");
  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.size += 1;
  expectRefused(msg, "size field");
  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_ZSTD);
  msg.height = 5;
  expectRefused(msg, "expected 80");
  msg.width = -1;
  expectRefused(msg, "not plausible");
}

TEST(DepthImage, RefusesCorruptCompressedPayloads) {
  depth_image_t msg = encoded(depth_image_t::DEPTH_FLOAT32_M, depth_image_t::COMPRESSION_ZSTD);
  msg.data.resize(msg.data.size() / 2);
  msg.size = static_cast<int32_t>(msg.data.size());
  expectRefused(msg, "does not decompress");
  msg.data.assign(16, 0xAB);
  msg.size = 16;
  expectRefused(msg, "no valid frame");
}

TEST(DepthImage, NonFiniteFloatDepthsAreNoReturnAndNegativeOnesAreRefused) {
  for (float none :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
        -std::numeric_limits<float>::infinity()}) {
    DepthImage image = sampleImage();
    ASSERT_GT(image.depth[5], 0.0f);
    image.depth[5] = none;
    const auto decoded = decodeDepthImage(encodeDepthImage(image, depth_image_t::DEPTH_FLOAT32_M));
    ASSERT_TRUE(decoded.ok()) << decoded.error();
    EXPECT_EQ(decoded->depth[5], 0.0f);
    EXPECT_EQ(decoded->depth[4], image.depth[4]);
  }
  DepthImage image = sampleImage();
  image.depth[5] = -1.0f;
  image.depth[6] = -0.5f;
  expectRefused(encodeDepthImage(image, depth_image_t::DEPTH_FLOAT32_M), "2 pixels are negative");
}

TEST(DepthImage, RefusesBadMetadata) {
  depth_image_t msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.depth_encoding = 7;
  expectRefused(msg, "unknown depth encoding 7");

  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.compression = depth_image_t::COMPRESSION_PNG;
  expectRefused(msg, "unsupported compression");

  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.fx = std::nan("");
  expectRefused(msg, "f");

  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.camera_in_body_orientation[0] = 2.0;
  expectRefused(msg, "camera mount");

  msg = encoded(depth_image_t::DEPTH_UINT16_MM, depth_image_t::COMPRESSION_NONE);
  msg.max_range = 0.05;
  expectRefused(msg, "range limits");
}

TEST(DepthImage, EncoderRefusesWhatItCannotWrite) {
  DepthImage image = sampleImage();
  image.depth.pop_back();
  EXPECT_THROW(encodeDepthImage(image), std::invalid_argument);
  EXPECT_THROW(encodeDepthImage(sampleImage(), 9), std::invalid_argument);
}

}  // namespace
}  // namespace thicket

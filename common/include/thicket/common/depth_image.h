// Depth images on the wire (thicket::depth_image_t): encoding for publishers and validated
// decoding for consumers. A decoded image is either fully valid or refused with the reason.
#pragma once

#include <cstdint>
#include <vector>

#include <thicket/depth_image_t.hpp>

#include "thicket/common/camera.h"
#include "thicket/common/expected.h"
#include "thicket/common/geometry.h"

namespace thicket {

/// A depth image in memory: optical-frame z per pixel in metres, row-major; 0 = no return.
struct DepthImage {
  int64_t utime = 0;
  PinholeCamera camera;
  Pose camera_in_body;  // camera (optical) frame in the body frame
  double min_range = 0;
  double max_range = 0;
  std::vector<float> depth;
};

/// Encodes as DEPTH_UINT16_MM (rounded to the nearest millimetre; depths that do not fit in 16
/// bits become 0, "no return") or DEPTH_FLOAT32_M, optionally zstd-compressed.
depth_image_t encodeDepthImage(const DepthImage& image,
                               int8_t depth_encoding = depth_image_t::DEPTH_UINT16_MM,
                               int8_t compression = depth_image_t::COMPRESSION_ZSTD);

/// Decodes and validates: known encoding and compression, consistent sizes (width * height
/// pixels, data size, decompressed size; at most PinholeCamera::kMaxPixels), valid intrinsics
/// and mount, non-negative depths, sane range limits. NaN and ±inf in float images are "no
/// return" (0), as depth_image_t says.
Expected<DepthImage> decodeDepthImage(const depth_image_t& msg);

}  // namespace thicket

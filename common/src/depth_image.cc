#include "thicket/common/depth_image.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "thicket/common/compression.h"

namespace thicket {
namespace {

// Largest image accepted: far beyond any real depth camera, small enough to refuse garbage.
constexpr int64_t kMaxPixels = 4096 * 4096;

std::vector<uint8_t> rawBytes(const DepthImage& image, int8_t depth_encoding) {
  std::vector<uint8_t> bytes;
  if (depth_encoding == depth_image_t::DEPTH_FLOAT32_M) {
    bytes.resize(image.depth.size() * 4);
    for (size_t i = 0; i < image.depth.size(); ++i) {
      uint32_t bits;
      std::memcpy(&bits, &image.depth[i], 4);
      for (int b = 0; b < 4; ++b) bytes[4 * i + b] = static_cast<uint8_t>(bits >> (8 * b));
    }
  } else {
    bytes.resize(image.depth.size() * 2);
    for (size_t i = 0; i < image.depth.size(); ++i) {
      const double mm = std::round(static_cast<double>(image.depth[i]) * 1000.0);
      const uint16_t value = (mm >= 1.0 && mm <= 65535.0) ? static_cast<uint16_t>(mm) : 0;
      bytes[2 * i] = static_cast<uint8_t>(value);
      bytes[2 * i + 1] = static_cast<uint8_t>(value >> 8);
    }
  }
  return bytes;
}

}  // namespace

depth_image_t encodeDepthImage(const DepthImage& image, int8_t depth_encoding, int8_t compression) {
  if (depth_encoding != depth_image_t::DEPTH_UINT16_MM &&
      depth_encoding != depth_image_t::DEPTH_FLOAT32_M) {
    throw std::invalid_argument("unknown depth encoding " + std::to_string(depth_encoding));
  }
  if (compression != depth_image_t::COMPRESSION_NONE &&
      compression != depth_image_t::COMPRESSION_ZSTD) {
    throw std::invalid_argument("encodeDepthImage supports no compression or zstd");
  }
  if (image.depth.size() != static_cast<size_t>(image.camera.width) * image.camera.height) {
    throw std::invalid_argument("depth has " + std::to_string(image.depth.size()) +
                                " pixels, the camera " + std::to_string(image.camera.width) + "x" +
                                std::to_string(image.camera.height));
  }
  depth_image_t msg{};
  msg.utime = image.utime;
  msg.width = image.camera.width;
  msg.height = image.camera.height;
  msg.fx = image.camera.fx;
  msg.fy = image.camera.fy;
  msg.cx = image.camera.cx;
  msg.cy = image.camera.cy;
  poseToArrays(image.camera_in_body, msg.camera_in_body_position, msg.camera_in_body_orientation);
  msg.min_range = image.min_range;
  msg.max_range = image.max_range;
  msg.depth_encoding = depth_encoding;
  msg.compression = compression;
  std::vector<uint8_t> raw = rawBytes(image, depth_encoding);
  msg.data = compression == depth_image_t::COMPRESSION_ZSTD ? zstdCompress(raw) : std::move(raw);
  msg.size = static_cast<int32_t>(msg.data.size());
  return msg;
}

Expected<DepthImage> decodeDepthImage(const depth_image_t& msg) {
  if (msg.width <= 0 || msg.height <= 0 ||
      static_cast<int64_t>(msg.width) * msg.height > kMaxPixels) {
    return unexpected("image size " + std::to_string(msg.width) + "x" + std::to_string(msg.height) +
                      " is not plausible");
  }
  if (msg.size < 0 || static_cast<size_t>(msg.size) != msg.data.size()) {
    return unexpected("size field " + std::to_string(msg.size) + " but " +
                      std::to_string(msg.data.size()) + " bytes of data");
  }
  size_t bytes_per_pixel = 0;
  if (msg.depth_encoding == depth_image_t::DEPTH_UINT16_MM) {
    bytes_per_pixel = 2;
  } else if (msg.depth_encoding == depth_image_t::DEPTH_FLOAT32_M) {
    bytes_per_pixel = 4;
  } else {
    return unexpected("unknown depth encoding " + std::to_string(msg.depth_encoding));
  }
  DepthImage image;
  image.utime = msg.utime;
  image.camera = PinholeCamera{msg.width, msg.height, msg.fx, msg.fy, msg.cx, msg.cy};
  if (auto valid = image.camera.validated(); !valid) return unexpected(valid.error());
  auto mount = poseFromArrays(msg.camera_in_body_position, msg.camera_in_body_orientation);
  if (!mount) return unexpected("camera mount: " + mount.error());
  image.camera_in_body = *mount;
  if (!std::isfinite(msg.min_range) || !std::isfinite(msg.max_range) || msg.min_range < 0 ||
      msg.max_range <= msg.min_range) {
    return unexpected("range limits [" + std::to_string(msg.min_range) + ", " +
                      std::to_string(msg.max_range) + "] are not valid");
  }
  image.min_range = msg.min_range;
  image.max_range = msg.max_range;

  const size_t pixels = static_cast<size_t>(msg.width) * static_cast<size_t>(msg.height);
  const size_t raw_size = pixels * bytes_per_pixel;
  std::vector<uint8_t> decompressed;
  const uint8_t* raw = msg.data.data();
  if (msg.compression == depth_image_t::COMPRESSION_ZSTD) {
    auto content = zstdDecompress(msg.data, raw_size);
    if (!content) return unexpected(content.error());
    decompressed = std::move(*content);
    raw = decompressed.data();
  } else if (msg.compression == depth_image_t::COMPRESSION_NONE) {
    if (msg.data.size() != raw_size) {
      return unexpected(std::to_string(msg.data.size()) + " bytes for " + std::to_string(pixels) +
                        " pixels of " + std::to_string(bytes_per_pixel) + " bytes");
    }
  } else {
    return unexpected("unsupported compression " + std::to_string(msg.compression));
  }

  image.depth.resize(pixels);
  size_t bad = 0;
  for (size_t i = 0; i < pixels; ++i) {
    if (bytes_per_pixel == 2) {
      image.depth[i] = static_cast<float>(raw[2 * i] | (raw[2 * i + 1] << 8)) * 0.001f;
    } else {
      uint32_t bits = 0;
      for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(raw[4 * i + b]) << (8 * b);
      float value;
      std::memcpy(&value, &bits, 4);
      // NaN and infinities are "no return" (depth_image_t; REP 117's too far, too close and
      // invalid); a negative depth is a broken sensor.
      if (!std::isfinite(value)) {
        value = 0;
      } else if (value < 0) {
        ++bad;
        value = 0;
      }
      image.depth[i] = value;
    }
  }
  if (bad > 0) {
    return unexpected(std::to_string(bad) + " pixels are negative");
  }
  return image;
}

}  // namespace thicket

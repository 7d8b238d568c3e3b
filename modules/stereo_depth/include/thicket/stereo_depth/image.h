// Images as the stereo pipeline takes them: 8-bit grayscale in memory, decoded and validated from
// thicket::image_t / stereo_image_t (raw GRAY8, RGB8 or BGR8 rows with a stride; PNG or JPEG), or
// read from image files for the offline mode.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <thicket/image_t.hpp>
#include <thicket/stereo_image_t.hpp>

#include "thicket/common/expected.h"

namespace thicket::stereo_depth {

/// 8-bit grayscale, row-major, no padding: pixels.size() == width * height.
struct GrayImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;
};

/// Images larger than this on either side are refused [pixels].
inline constexpr int kMaxImageSide = 16384;

/// Decodes one image to grayscale (colour as OpenCV's BGR/RGB to gray). Refuses sizes outside
/// [1, kMaxImageSide], unknown encodings or pixel formats, GRAY16, a size field that disagrees
/// with the data, raw rows shorter than the width or data that is not row_stride * height bytes,
/// compressed data that is not of the encoding it claims or does not decode, and decoded images
/// whose size is not the declared width and height.
Expected<GrayImage> decodeImage(const image_t& image);

/// A synchronized pair, decoded.
struct StereoPair {
  int64_t utime = 0;
  std::string calibration_id;
  bool rectified = false;
  GrayImage left;
  GrayImage right;
};

/// Decodes and checks a pair: the pair, left and right timestamps must be equal (to within
/// max_time_difference_us), both images must decode, and they must have the same size. The
/// reason names the side ("left image: ...").
Expected<StereoPair> decodeStereoPair(const stereo_image_t& msg,
                                      int64_t max_time_difference_us = 0);

/// A raw GRAY8 image_t holding `image` (row_stride = width), stamped utime.
image_t rawImageMessage(const GrayImage& image, int64_t utime, const std::string& camera_id);

/// A PNG (encoding ENCODING_PNG) or JPEG (ENCODING_JPEG, quality 95) image_t holding `image`.
/// Throws std::invalid_argument for another encoding.
image_t compressedImageMessage(const GrayImage& image, int64_t utime, const std::string& camera_id,
                               int8_t encoding);

/// An image file (anything cv::imread reads) as grayscale, or why not.
Expected<GrayImage> readGrayImageFile(const std::string& path);

/// The image averaged down by `factor` (each output pixel the mean of factor x factor input
/// pixels); the sides must be multiples of factor (std::invalid_argument otherwise).
GrayImage downscaleGray(const GrayImage& image, int factor);

/// Writes `image` (PNG, ...: by the extension); empty on success, else why not.
std::string writeGrayImageFile(const std::string& path, const GrayImage& image);

/// Depth [m] as a 16-bit grayscale PNG in millimetres (rounded; 0 = no depth, and depths that do
/// not fit in 16 bits become 0). Empty on success, else why not.
std::string writeDepthPngMm(const std::string& path, int width, int height,
                            const std::vector<float>& depth_m);
/// Reads such a PNG back [m].
struct DepthFile {
  int width = 0;
  int height = 0;
  std::vector<float> depth_m;
};
Expected<DepthFile> readDepthPngMm(const std::string& path);

/// A single-channel float image as PFM (OpenCV's codec: "Pf", rows bottom to top as the format
/// wants; `values` row-major top to bottom). Empty on success, else why not.
std::string writePfm(const std::string& path, int width, int height,
                     const std::vector<float>& values);
/// Reads a single-channel PFM of either byte order, rows returned top to bottom. Refuses colour
/// PFMs ("PF") and what OpenCV cannot decode (bad headers, truncated data).
struct PfmImage {
  int width = 0;
  int height = 0;
  std::vector<float> values;
};
Expected<PfmImage> readPfm(const std::string& path);

}  // namespace thicket::stereo_depth

#include <cmath>
#include <cstring>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "thicket/common/time.h"
#include "thicket/stereo_depth/image.h"

#include "opencv_view.h"

namespace thicket::stereo_depth {
namespace {

std::string sizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

bool isPng(const std::vector<uint8_t>& data) {
  static const uint8_t kMagic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return data.size() >= 8 && std::memcmp(data.data(), kMagic, 8) == 0;
}

bool isJpeg(const std::vector<uint8_t>& data) {
  return data.size() >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff;
}

// Whether the end-of-image marker FF D9 is among the last bytes (encoders may pad after it).
bool endsWithJpegEoi(const std::vector<uint8_t>& data) {
  const size_t from = data.size() > 32 ? data.size() - 32 : 0;
  for (size_t i = data.size(); i-- > from + 1;) {
    if (data[i - 1] == 0xff && data[i] == 0xd9) return true;
  }
  return false;
}

GrayImage fromMat(const cv::Mat& gray) {
  GrayImage out;
  out.width = gray.cols;
  out.height = gray.rows;
  out.pixels.resize(static_cast<size_t>(gray.cols) * static_cast<size_t>(gray.rows));
  for (int v = 0; v < gray.rows; ++v) {
    std::memcpy(out.pixels.data() + static_cast<size_t>(v) * gray.cols, gray.ptr<uint8_t>(v),
                static_cast<size_t>(gray.cols));
  }
  return out;
}

Expected<GrayImage> decodeRaw(const image_t& image) {
  int channels = 0;
  switch (image.pixel_format) {
    case image_t::PIXEL_GRAY8:
      channels = 1;
      break;
    case image_t::PIXEL_RGB8:
    case image_t::PIXEL_BGR8:
      channels = 3;
      break;
    case image_t::PIXEL_GRAY16:
      return unexpected("GRAY16 pixels are not supported (send GRAY8, RGB8 or BGR8)");
    default:
      return unexpected("unknown pixel format " + std::to_string(image.pixel_format));
  }
  const int64_t row_bytes = static_cast<int64_t>(image.width) * channels;
  if (image.row_stride < row_bytes) {
    return unexpected("row_stride " + std::to_string(image.row_stride) +
                      " is shorter than a row (" + std::to_string(row_bytes) + " bytes)");
  }
  const int64_t expected = static_cast<int64_t>(image.row_stride) * image.height;
  if (static_cast<int64_t>(image.data.size()) != expected) {
    return unexpected("raw data has " + std::to_string(image.data.size()) + " bytes, expected " +
                      std::to_string(expected) + " (row_stride * height)");
  }
  const cv::Mat src(image.height, image.width, channels == 1 ? CV_8UC1 : CV_8UC3,
                    const_cast<uint8_t*>(image.data.data()), static_cast<size_t>(image.row_stride));
  if (channels == 1) return fromMat(src);
  cv::Mat gray;
  cv::cvtColor(src, gray,
               image.pixel_format == image_t::PIXEL_RGB8 ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
  return fromMat(gray);
}

Expected<GrayImage> decodeCompressed(const image_t& image) {
  const bool png = image.encoding == image_t::ENCODING_PNG;
  const char* name = png ? "PNG" : "JPEG";
  if (png ? !isPng(image.data) : !isJpeg(image.data)) {
    return unexpected(std::string("the data is not ") + name + " (wrong magic bytes)");
  }
  if (!png && !endsWithJpegEoi(image.data)) {
    // libjpeg decodes a truncated stream into a partly gray image rather than failing.
    return unexpected("cannot decode the JPEG data: truncated (no end-of-image marker)");
  }
  cv::Mat gray;
  try {
    const cv::Mat buffer(1, static_cast<int>(image.data.size()), CV_8UC1,
                         const_cast<uint8_t*>(image.data.data()));
    gray = cv::imdecode(buffer, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    return unexpected(std::string("cannot decode the ") + name + " data: " + e.err);
  }
  if (gray.empty()) return unexpected(std::string("cannot decode the ") + name + " data");
  if (gray.cols != image.width || gray.rows != image.height) {
    return unexpected(std::string("the ") + name + " image is " + sizeText(gray.cols, gray.rows) +
                      ", the message says " + sizeText(image.width, image.height));
  }
  if (gray.depth() != CV_8U) return unexpected(std::string("the ") + name + " image is not 8-bit");
  return fromMat(gray);
}

}  // namespace

Expected<GrayImage> decodeImage(const image_t& image) {
  if (image.width < 1 || image.height < 1 || image.width > kMaxImageSide ||
      image.height > kMaxImageSide) {
    return unexpected("image size " + sizeText(image.width, image.height) + " is outside [1, " +
                      std::to_string(kMaxImageSide) + "]");
  }
  if (image.size != static_cast<int64_t>(image.data.size())) {
    return unexpected("size field " + std::to_string(image.size) + " disagrees with " +
                      std::to_string(image.data.size()) + " data bytes");
  }
  switch (image.encoding) {
    case image_t::ENCODING_RAW:
      return decodeRaw(image);
    case image_t::ENCODING_PNG:
    case image_t::ENCODING_JPEG:
      return decodeCompressed(image);
    default:
      return unexpected("unknown encoding " + std::to_string(image.encoding));
  }
}

Expected<StereoPair> decodeStereoPair(const stereo_image_t& msg, int64_t max_time_difference_us) {
  // Stamps first: the differences below cannot overflow between stamps in [0, kMaxUtime].
  for (const auto& [what, utime] : {std::pair{"pair", msg.utime},
                                    {"left image", msg.left.utime},
                                    {"right image", msg.right.utime}}) {
    if (!isTime(utime)) return unexpected(notATime(what, utime));
  }
  for (const auto& [side, utime] :
       {std::pair{"left", msg.left.utime}, {"right", msg.right.utime}}) {
    if (std::llabs(utime - msg.utime) > max_time_difference_us) {
      return unexpected(std::string("timestamps differ: the ") + side + " image at " +
                        std::to_string(utime) + " us, the pair at " + std::to_string(msg.utime) +
                        " us");
    }
  }
  if (std::llabs(msg.left.utime - msg.right.utime) > max_time_difference_us) {
    return unexpected("timestamps differ: left " + std::to_string(msg.left.utime) + " us, right " +
                      std::to_string(msg.right.utime) + " us");
  }
  StereoPair pair;
  pair.utime = msg.utime;
  pair.calibration_id = msg.calibration_id;
  pair.rectified = msg.rectified;
  auto left = decodeImage(msg.left);
  if (!left) return unexpected("left image: " + left.error());
  auto right = decodeImage(msg.right);
  if (!right) return unexpected("right image: " + right.error());
  if (left->width != right->width || left->height != right->height) {
    return unexpected("the images differ in size: left " + sizeText(left->width, left->height) +
                      ", right " + sizeText(right->width, right->height));
  }
  pair.left = std::move(*left);
  pair.right = std::move(*right);
  return pair;
}

image_t rawImageMessage(const GrayImage& image, int64_t utime, const std::string& camera_id) {
  image_t msg{};
  msg.utime = utime;
  msg.camera_id = camera_id;
  msg.width = image.width;
  msg.height = image.height;
  msg.row_stride = image.width;
  msg.pixel_format = image_t::PIXEL_GRAY8;
  msg.encoding = image_t::ENCODING_RAW;
  msg.data = image.pixels;
  msg.size = static_cast<int32_t>(msg.data.size());
  return msg;
}

image_t compressedImageMessage(const GrayImage& image, int64_t utime, const std::string& camera_id,
                               int8_t encoding) {
  if (encoding != image_t::ENCODING_PNG && encoding != image_t::ENCODING_JPEG) {
    throw std::invalid_argument("compressedImageMessage: encoding must be PNG or JPEG");
  }
  image_t msg = rawImageMessage(image, utime, camera_id);
  msg.row_stride = 0;
  msg.encoding = encoding;
  std::vector<uint8_t> bytes;
  const bool png = encoding == image_t::ENCODING_PNG;
  cv::imencode(png ? ".png" : ".jpg", asMat(image), bytes,
               png ? std::vector<int>{} : std::vector<int>{cv::IMWRITE_JPEG_QUALITY, 95});
  msg.data = std::move(bytes);
  msg.size = static_cast<int32_t>(msg.data.size());
  return msg;
}

Expected<GrayImage> readGrayImageFile(const std::string& path) {
  cv::Mat gray;
  try {
    gray = cv::imread(path, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    return unexpected(path + ": cannot read the image: " + e.err);
  }
  if (gray.empty()) return unexpected(path + ": cannot read the image (missing or not an image)");
  if (gray.depth() != CV_8U) return unexpected(path + ": not an 8-bit image");
  return fromMat(gray);
}

GrayImage downscaleGray(const GrayImage& image, int factor) {
  if (factor < 1 || image.width % factor != 0 || image.height % factor != 0) {
    throw std::invalid_argument("downscaleGray: the sides must be multiples of the factor");
  }
  cv::Mat small;
  cv::resize(asMat(image), small, cv::Size(image.width / factor, image.height / factor), 0, 0,
             cv::INTER_AREA);
  return fromMat(small);
}

std::string writeGrayImageFile(const std::string& path, const GrayImage& image) {
  try {
    if (!cv::imwrite(path, asMat(image))) return "cannot write " + path;
  } catch (const cv::Exception& e) {
    return "cannot write " + path + ": " + e.err;
  }
  return {};
}

std::string writeDepthPngMm(const std::string& path, int width, int height,
                            const std::vector<float>& depth_m) {
  if (width < 1 || height < 1 || depth_m.size() != static_cast<size_t>(width) * height) {
    return "cannot write " + path + ": the depth image has the wrong size";
  }
  cv::Mat image(height, width, CV_16UC1);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const double mm =
          std::round(static_cast<double>(depth_m[static_cast<size_t>(v) * width + u]) * 1000.0);
      image.at<uint16_t>(v, u) = (mm >= 1 && mm <= 65535) ? static_cast<uint16_t>(mm) : 0;
    }
  }
  try {
    if (!cv::imwrite(path, image)) return "cannot write " + path;
  } catch (const cv::Exception& e) {
    return "cannot write " + path + ": " + e.err;
  }
  return {};
}

Expected<DepthFile> readDepthPngMm(const std::string& path) {
  cv::Mat image;
  try {
    image = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return unexpected(path + ": cannot read: " + e.err);
  }
  if (image.empty()) return unexpected(path + ": cannot read the depth image");
  if (image.type() != CV_16UC1) return unexpected(path + ": not a 16-bit grayscale image");
  DepthFile out;
  out.width = image.cols;
  out.height = image.rows;
  out.depth_m.resize(static_cast<size_t>(image.cols) * image.rows);
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      out.depth_m[static_cast<size_t>(v) * image.cols + u] =
          static_cast<float>(image.at<uint16_t>(v, u) * 1e-3);
    }
  }
  return out;
}

std::string writePfm(const std::string& path, int width, int height,
                     const std::vector<float>& values) {
  if (width < 1 || height < 1 || values.size() != static_cast<size_t>(width) * height) {
    return "cannot write " + path + ": the image has the wrong size";
  }
  const cv::Mat image(height, width, CV_32FC1, const_cast<float*>(values.data()));
  try {
    if (!cv::imwrite(path, image)) return "cannot write " + path;
  } catch (const cv::Exception& e) {
    return "cannot write " + path + ": " + e.err;
  }
  return {};
}

Expected<PfmImage> readPfm(const std::string& path) {
  cv::Mat image;
  try {
    image = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return unexpected(path + ": cannot read: " + e.err);
  }
  if (image.empty())
    return unexpected(path + ": cannot read the PFM (missing, damaged or not one)");
  if (image.type() != CV_32FC1) {
    return unexpected(path + ": " + std::to_string(image.channels()) +
                      " channels; expected one float channel (Pf)");
  }
  PfmImage out;
  out.width = image.cols;
  out.height = image.rows;
  out.values.assign(image.ptr<float>(0), image.ptr<float>(0) + image.total());
  return out;
}

}  // namespace thicket::stereo_depth

#include "png.h"

#include <cmath>

#include <opencv2/imgcodecs.hpp>

namespace thicket::sim {
namespace {

std::string write(const std::string& path, const cv::Mat& image) {
  try {
    if (!cv::imwrite(path, image)) return "cannot write " + path;
  } catch (const cv::Exception& e) {
    return "cannot write " + path + ": " + e.what();
  }
  return {};
}

std::string sizeError(const std::string& path, int width, int height, size_t pixels) {
  if (width >= 1 && height >= 1 && pixels == static_cast<size_t>(width) * height) return {};
  return "cannot write " + path + ": " + std::to_string(pixels) + " pixels for a " +
         std::to_string(width) + " x " + std::to_string(height) + " image";
}

}  // namespace

std::string writeDepthPng(const std::string& path, int width, int height,
                          const std::vector<float>& depth_m) {
  if (auto error = sizeError(path, width, height, depth_m.size()); !error.empty()) return error;
  cv::Mat image(height, width, CV_16UC1);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const double mm =
          std::round(static_cast<double>(depth_m[static_cast<size_t>(v) * width + u]) * 1000.0);
      image.at<uint16_t>(v, u) = (mm >= 1 && mm <= 65535) ? static_cast<uint16_t>(mm) : 0;
    }
  }
  return write(path, image);
}

std::string writeGrayPng(const std::string& path, int width, int height,
                         const std::vector<uint8_t>& pixels) {
  if (auto error = sizeError(path, width, height, pixels.size()); !error.empty()) return error;
  cv::Mat image(height, width, CV_8UC1, const_cast<uint8_t*>(pixels.data()));
  return write(path, image);
}

}  // namespace thicket::sim

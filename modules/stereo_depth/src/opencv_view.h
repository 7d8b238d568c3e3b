// A GrayImage seen by OpenCV without a copy: for the sources that hand images to OpenCV (never a
// public header: OpenCV stays inside src/).
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth {

/// The pixels as an 8-bit single-channel cv::Mat; OpenCV must only read them.
inline cv::Mat asMat(const GrayImage& image) {
  return cv::Mat(image.height, image.width, CV_8UC1, const_cast<uint8_t*>(image.pixels.data()));
}

}  // namespace thicket::stereo_depth

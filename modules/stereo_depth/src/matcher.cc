#include "thicket/stereo_depth/matcher.h"

#include <cmath>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace thicket::stereo_depth {

void StereoMatcherOptions::declare(Params& p) {
  p("min_disparity", min_disparity, "smallest disparity searched [pixels]",
    Range::between(-1024, 1024));
  p("num_disparities", num_disparities,
    "disparities searched from min_disparity, a multiple of 16 [pixels]; raise it for close or "
    "wide-baseline scenes",
    Range::between(16, 1024));
  p("block_size", block_size, "matched block side, odd [pixels]", Range::between(1, 31));
  p("p1", p1, "penalty on disparity changes of 1 between neighbours; 0: 8 * block_size^2",
    Range::atLeast(0));
  p("p2", p2, "penalty on larger disparity changes, > p1; 0: 32 * block_size^2", Range::atLeast(0));
  p("uniqueness_ratio", uniqueness_ratio,
    "margin by which the best match must beat the second best [%]", Range::between(0, 100));
  p("disp12_max_diff", disp12_max_diff,
    "left-right consistency tolerance [pixels]; -1 turns the check off", Range::atLeast(-1));
  p("pre_filter_cap", pre_filter_cap, "clip of the prefiltered image derivatives",
    Range::between(1, 63));
  p("speckle_window_size", speckle_window_size,
    "connected regions of similar disparity smaller than this are removed [pixels]; 0: off",
    Range::atLeast(0));
  p("speckle_range", speckle_range,
    "largest disparity step within one connected region for speckle filtering [pixels]",
    Range::atLeast(0));
  p.choice("mode", mode, {"sgbm", "hh", "3way"},
           "OpenCV SGBM variant: 3way (3 directions, about half the time of sgbm for the same "
           "depth within 5 m), sgbm (5 directions, a few % more valid pixels far away), hh (8 "
           "directions, full image, slowest)");
  p("min_range", min_range, "depths below this are dropped [m]", Range::atLeast(0));
  p("max_range", max_range, "depths above this are dropped [m]", Range::positive());
}

Expected<StereoMatcherOptions> StereoMatcherOptions::validated() const {
  // Each field's own rule, as the YAML declaration above states it; then what relates fields.
  if (const std::string error = paramsError(*this); !error.empty()) return unexpected(error);
  if (num_disparities % 16 != 0) {
    return unexpected("num_disparities (" + std::to_string(num_disparities) +
                      ") must be a positive multiple of 16");
  }
  if (block_size % 2 == 0) {
    return unexpected("block_size (" + std::to_string(block_size) + ") must be odd and positive");
  }
  const int eff_p1 = p1 > 0 ? p1 : 8 * block_size * block_size;
  const int eff_p2 = p2 > 0 ? p2 : 32 * block_size * block_size;
  if (eff_p2 <= eff_p1) {
    return unexpected("p2 (" + std::to_string(eff_p2) + ") must be greater than p1 (" +
                      std::to_string(eff_p1) + ")");
  }
  if (!(max_range > min_range)) {
    return unexpected("the range limits must satisfy 0 <= min_range < max_range < inf");
  }
  return *this;
}

int StereoMatcherOptions::minImageWidth() const {
  return std::max(min_disparity, 0) + num_disparities + block_size;
}

struct StereoMatcher::Impl {
  cv::Ptr<cv::StereoSGBM> sgbm;
};

StereoMatcher::StereoMatcher(const StereoMatcherOptions& options) : options_(options) {
  auto valid = options.validated();
  if (!valid) throw std::invalid_argument("stereo matcher: " + valid.error());
  const int b2 = options.block_size * options.block_size;
  const int mode = options.mode == "hh"     ? cv::StereoSGBM::MODE_HH
                   : options.mode == "3way" ? cv::StereoSGBM::MODE_SGBM_3WAY
                                            : cv::StereoSGBM::MODE_SGBM;
  impl_ = std::make_unique<Impl>();
  impl_->sgbm = cv::StereoSGBM::create(
      options.min_disparity, options.num_disparities, options.block_size,
      options.p1 > 0 ? options.p1 : 8 * b2, options.p2 > 0 ? options.p2 : 32 * b2,
      options.disp12_max_diff, options.pre_filter_cap, options.uniqueness_ratio,
      options.speckle_window_size, options.speckle_range, mode);
}

StereoMatcher::~StereoMatcher() = default;
StereoMatcher::StereoMatcher(StereoMatcher&&) noexcept = default;
StereoMatcher& StereoMatcher::operator=(StereoMatcher&&) noexcept = default;

std::vector<float> StereoMatcher::disparity(const GrayImage& left, const GrayImage& right) const {
  if (left.width <= 0 || left.height <= 0 || left.width != right.width ||
      left.height != right.height ||
      left.pixels.size() != static_cast<size_t>(left.width) * left.height ||
      right.pixels.size() != left.pixels.size()) {
    throw std::invalid_argument("StereoMatcher::disparity: empty images or different sizes");
  }
  if (left.width < options_.minImageWidth()) {
    throw std::invalid_argument("StereoMatcher::disparity: images narrower than the search");
  }
  const cv::Mat l(left.height, left.width, CV_8UC1, const_cast<uint8_t*>(left.pixels.data()));
  const cv::Mat r(right.height, right.width, CV_8UC1, const_cast<uint8_t*>(right.pixels.data()));
  cv::Mat raw;  // CV_16S, 4 fractional bits; (min_disparity - 1) * 16 where invalid
  impl_->sgbm->compute(l, r, raw);
  std::vector<float> out(left.pixels.size(), 0.0f);
  const int invalid_below = options_.min_disparity * cv::StereoMatcher::DISP_SCALE;
  for (int v = 0; v < raw.rows; ++v) {
    const int16_t* row = raw.ptr<int16_t>(v);
    float* dst = out.data() + static_cast<size_t>(v) * left.width;
    for (int u = 0; u < raw.cols; ++u) {
      const int d = row[u];
      if (d >= invalid_below && d > 0) {
        dst[u] = static_cast<float>(d) / static_cast<float>(cv::StereoMatcher::DISP_SCALE);
      }
    }
  }
  return out;
}

std::vector<float> depthFromDisparity(const std::vector<float>& disparity, double focal_px,
                                      double baseline_m, double min_range, double max_range) {
  std::vector<float> depth(disparity.size(), 0.0f);
  const double fb = focal_px * baseline_m;
  for (size_t i = 0; i < disparity.size(); ++i) {
    const double d = disparity[i];
    if (!(d > 0)) continue;
    const double z = fb / d;
    if (z >= min_range && z <= max_range) depth[i] = static_cast<float>(z);
  }
  return depth;
}

}  // namespace thicket::stereo_depth

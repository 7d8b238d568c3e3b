// Semi-global matching (OpenCV StereoSGBM) of a rectified pair into a disparity image, and
// disparity to depth. Disparities are in pixels of the left image; invalid pixels are 0.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "thicket/common/expected.h"
#include "thicket/common/params.h"
#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth {

struct StereoMatcherOptions {
  int min_disparity = 0;          ///< smallest disparity searched [pixels]
  int num_disparities = 64;       ///< search range, a multiple of 16 [pixels]
  int block_size = 5;             ///< matched block side, odd [pixels]
  int p1 = 0;                     ///< smoothness penalty for +-1 disparity changes; 0: 8 * block^2
  int p2 = 0;                     ///< penalty for larger changes, > p1; 0: 32 * block^2
  int uniqueness_ratio = 10;      ///< [%] margin by which the best cost must win
  int disp12_max_diff = 1;        ///< left-right check tolerance [pixels]; -1 turns it off
  int pre_filter_cap = 63;        ///< clip of the prefiltered image derivatives
  int speckle_window_size = 100;  ///< speckles smaller than this are removed [pixels]; 0: off
  int speckle_range = 2;          ///< disparity variation within one component [pixels]
  std::string mode = "3way";      ///< 3way, sgbm (5 directions), hh (full 2-pass)
  double min_range = 0.2;         ///< depths below are dropped [m]
  double max_range = 20.0;        ///< depths above are dropped [m]

  void declare(Params& p);
  /// These options, or what is inconsistent (num_disparities not a multiple of 16, even block,
  /// p2 <= p1, max_range <= min_range, ...).
  Expected<StereoMatcherOptions> validated() const;
  /// The narrowest image the search fits in: a full search range plus a block beside it.
  int minImageWidth() const;
};

class StereoMatcher {
 public:
  /// Throws std::invalid_argument with the reason on invalid options.
  explicit StereoMatcher(const StereoMatcherOptions& options);
  ~StereoMatcher();
  StereoMatcher(StereoMatcher&&) noexcept;
  StereoMatcher& operator=(StereoMatcher&&) noexcept;

  const StereoMatcherOptions& options() const { return options_; }

  /// The disparity of every left pixel [pixels], row-major; 0 where there is no valid match.
  /// Throws std::invalid_argument when the images are empty, of different sizes or narrower than
  /// options().minImageWidth().
  std::vector<float> disparity(const GrayImage& left, const GrayImage& right) const;

 private:
  struct Impl;
  StereoMatcherOptions options_;
  std::unique_ptr<Impl> impl_;
};

/// z = focal_px * baseline_m / d per pixel [m]; 0 where d <= 0 or z is outside
/// [min_range, max_range].
std::vector<float> depthFromDisparity(const std::vector<float>& disparity, double focal_px,
                                      double baseline_m, double min_range, double max_range);

}  // namespace thicket::stereo_depth

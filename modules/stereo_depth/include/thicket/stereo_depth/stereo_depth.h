// The whole per-pair pipeline of thicket-stereo-depth, without LCM: checks a decoded pair against
// the calibration (or the intrinsics of already rectified pairs), rectifies it with maps computed
// once, matches it (SGBM with speckle filtering), converts disparity to depth and optionally
// removes statistical outliers. The node and the offline file mode both drive this.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "thicket/common/camera.h"
#include "thicket/common/expected.h"
#include "thicket/common/params.h"
#include "thicket/stereo_depth/calibration.h"
#include "thicket/stereo_depth/image.h"
#include "thicket/stereo_depth/matcher.h"
#include "thicket/stereo_depth/outlier_filter.h"
#include "thicket/stereo_depth/rectifier.h"

namespace thicket::stereo_depth {

/// The intrinsics of pairs that arrive rectified when there is no calibration file.
struct RectifiedCameraOptions {
  int width = 0;        ///< 0: any size [pixels]
  int height = 0;       ///< 0: any size [pixels]
  double fx = 0;        ///< 0: unknown (disparity only, no depth) [pixels]
  double fy = 0;        ///< 0: fx [pixels]
  double cx = -1;       ///< negative: the image centre [pixels]
  double cy = -1;       ///< negative: the image centre [pixels]
  double baseline = 0;  ///< distance between the optical centres; 0: unknown [m]

  void declare(Params& p);
};

struct StereoDepthOptions {
  /// OpenCV YAML calibration of the pair; empty: only rectified pairs (intrinsics from
  /// `rectified`) are accepted.
  std::string calibration_file;
  double rectify_alpha = -1;  ///< cv::stereoRectify free scaling in [-1, 1]; -1: OpenCV's default
  RectifiedCameraOptions rectified;
  int64_t max_time_difference_us = 0;  ///< tolerated left/right/pair timestamp difference [µs]
  /// Match at 1/downscale of the resolution (1 or 2): the rectified pair is averaged down by this
  /// factor, and the disparity, the depth and their intrinsics are at that size. The matcher's
  /// num_disparities counts pixels of the matched images. The image sides must be multiples.
  int downscale = 1;
  StereoMatcherOptions matcher;
  OutlierFilterOptions outliers;

  void declare(Params& p);
};

/// What one pair gives.
struct StereoFrame {
  PinholeCamera camera;  ///< rectified left intrinsics (valid only when has_depth)
  double baseline = 0;   ///< [m] (0 when unknown)
  /// Rectified left optical frame to the original left optical frame: the calibration's
  /// (Rectifier::rectifiedInLeft), also for pairs that arrive rectified; identity without one.
  Eigen::Quaterniond rectified_in_left = Eigen::Quaterniond::Identity();
  GrayImage left_rectified;      ///< what was matched (at 1/downscale of the pair's size)
  std::vector<float> disparity;  ///< left pixels [pixels]; 0 where invalid
  bool has_depth = false;        ///< false for rectified input without focal length or baseline
  std::vector<float> depth;      ///< [m]; 0 where invalid or out of range; empty without depth
  int outliers_removed = 0;
  double rectify_ms = 0, match_ms = 0, depth_ms = 0, outliers_ms = 0;  ///< measured durations
  double validFraction() const;  ///< of pixels with depth (or disparity, without depth)
};

class StereoDepth {
 public:
  /// From options alone (loads options.calibration_file when set), or with a calibration given
  /// in memory (options.calibration_file is then ignored). Refuses invalid matcher options, an
  /// unreadable or invalid calibration, and calibrations that cannot be rectified.
  static Expected<StereoDepth> create(const StereoDepthOptions& options);
  static Expected<StereoDepth> create(const StereoDepthOptions& options,
                                      std::optional<StereoCalibration> calibration);

  /// Processes one decoded pair. Refuses, with the reason: a pair whose calibration_id is not the
  /// calibration's (when the calibration has an id), a size other than the calibration's (or the
  /// configured rectified size), and an unrectified pair without a calibration. now_ms only
  /// measures the stages.
  Expected<StereoFrame> process(const StereoPair& pair,
                                const std::function<double()>& now_ms = {}) const;

  const StereoDepthOptions& options() const { return options_; }
  const std::optional<Rectifier>& rectifier() const { return rectifier_; }

 private:
  StereoDepth(StereoDepthOptions options, std::optional<Rectifier> rectifier,
              StereoMatcher matcher);

  StereoDepthOptions options_;
  std::optional<Rectifier> rectifier_;
  StereoMatcher matcher_;
};

}  // namespace thicket::stereo_depth

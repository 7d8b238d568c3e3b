// thicket-stereo-depth as an LCM node: STEREO pairs in, CAMERA_DEPTH out (rectified intrinsics,
// the rectified left camera's mount, the matcher's range limits), with MODULE_TIMING per pair
// (stages rectify, match, depth, and outliers when enabled). Pairs it cannot use are refused
// through reportBadMessage with the reason, and nothing is published for them.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <thicket/stereo_image_t.hpp>

#include "thicket/common/geometry.h"
#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/stereo_depth/stereo_depth.h"

namespace thicket::stereo_depth {

struct StereoDepthNodeOptions {
  StereoDepthOptions stereo;
  /// The left camera's optical centre in the body frame [m] and its pitch (positive looks down),
  /// as the simulator's stereo_camera options describe the mount.
  Eigen::Vector3d camera_position_in_body = Eigen::Vector3d::Zero();
  double camera_pitch_down_deg = 0;
  std::string camera_id = "stereo";  ///< camera_id of the published depth images
  std::string depth_encoding = "uint16_mm";

  void declare(Params& p);
};

class StereoDepthNode : public Node {
 public:
  /// now_ms measures durations for MODULE_TIMING (never used to decide). Throws
  /// std::invalid_argument with the reason on bad options or an unusable calibration.
  StereoDepthNode(lcm::LCM& lcm, const StereoDepthNodeOptions& options,
                  std::function<double()> now_ms = {});

  int64_t published() const { return published_; }
  int64_t refused() const { return refused_; }
  /// The mount of the rectified left optical frame in the body frame, for calibrated pairs.
  const Pose& rectifiedInBody() const { return rectified_in_body_; }
  /// "N pairs published (R refused); valid depth median P %; rectify median X ms, match ... ms,
  /// depth ... ms; total p95 Y ms".
  std::string summary() const;

 private:
  void onStereo(const stereo_image_t& msg);
  void refuse(const std::string& reason);

  StereoDepthNodeOptions options_;
  std::function<double()> now_ms_;
  StereoDepth pipeline_;
  Pose left_in_body_;
  Pose rectified_in_body_;
  int64_t published_ = 0;
  int64_t refused_ = 0;
  std::vector<double> rectify_ms_, match_ms_, depth_ms_, total_ms_, valid_fraction_;
};

}  // namespace thicket::stereo_depth

#include "stereo_depth_node.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include <thicket/depth_image_t.hpp>
#include <thicket/module_timing_t.hpp>

#include "thicket/common/camera.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/statistics.h"

namespace thicket::stereo_depth {
namespace {

StereoDepth makePipeline(const StereoDepthNodeOptions& options) {
  auto pipeline = StereoDepth::create(options.stereo);
  if (!pipeline) throw std::invalid_argument(pipeline.error());
  return std::move(*pipeline);
}

}  // namespace

void StereoDepthNodeOptions::declare(Params& p) {
  p.group("stereo", stereo, "calibration, rectification, matching and filtering");
  p("camera_position_in_body", camera_position_in_body,
    "optical centre of the left camera in the body frame [m]");
  p("camera_pitch_down_deg", camera_pitch_down_deg,
    "pitch of the stereo camera, positive looks down [deg]", Range::between(-90, 90));
  p("camera_id", camera_id, "camera_id of the published depth images");
  p.choice("depth_encoding", depth_encoding, {"uint16_mm", "float32_m"},
           "depth encoding on CAMERA_DEPTH (zstd-compressed)");
}

StereoDepthNode::StereoDepthNode(lcm::LCM& lcm, const StereoDepthNodeOptions& options,
                                 std::function<double()> now_ms)
    : Node("stereo_depth", lcm),
      options_(options),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      pipeline_(makePipeline(options)),
      left_in_body_(cameraMount(options.camera_position_in_body,
                                options.camera_pitch_down_deg * std::numbers::pi / 180)) {
  rectified_in_body_ = left_in_body_;
  if (pipeline_.rectifier()) {
    rectified_in_body_ =
        left_in_body_ * Pose{Eigen::Vector3d::Zero(), pipeline_.rectifier()->rectifiedInLeft()};
  }
  subscribe<stereo_image_t>(
      "STEREO", [this](const stereo_image_t& msg, const MessageInfo&) { onStereo(msg); });
}

void StereoDepthNode::refuse(const std::string& reason) {
  ++refused_;
  reportBadMessage("STEREO", reason);
}

void StereoDepthNode::onStereo(const stereo_image_t& msg) {
  const double t0 = now_ms_();
  auto pair = decodeStereoPair(msg, options_.stereo.max_time_difference_us);
  if (!pair) return refuse(pair.error());
  auto frame = pipeline_.process(*pair, now_ms_);
  if (!frame) return refuse(frame.error());
  if (!frame->has_depth) {
    return refuse(
        "a rectified pair without known intrinsics: set stereo.calibration_file, or "
        "stereo.rectified.fx and stereo.rectified.baseline");
  }
  DepthImage image;
  image.utime = msg.utime;
  image.camera = frame->camera;
  image.camera_in_body = left_in_body_ * Pose{Eigen::Vector3d::Zero(), frame->rectified_in_left};
  image.min_range = options_.stereo.matcher.min_range;
  image.max_range = options_.stereo.matcher.max_range;
  image.depth = std::move(frame->depth);
  depth_image_t out = encodeDepthImage(image, options_.depth_encoding == "float32_m"
                                                  ? depth_image_t::DEPTH_FLOAT32_M
                                                  : depth_image_t::DEPTH_UINT16_MM);
  out.camera_id = options_.camera_id;
  publish("CAMERA_DEPTH", out);
  ++published_;

  rectify_ms_.push_back(frame->rectify_ms);
  match_ms_.push_back(frame->match_ms);
  depth_ms_.push_back(frame->depth_ms);
  total_ms_.push_back(now_ms_() - t0);
  size_t valid = 0;
  for (float z : image.depth) valid += z > 0 ? 1 : 0;
  valid_fraction_.push_back(image.depth.empty() ? 0.0
                                                : static_cast<double>(valid) /
                                                      static_cast<double>(image.depth.size()));
  module_timing_t timing;
  timing.utime = msg.utime;
  timing.module = "stereo_depth";
  timing.sequence = published_ - 1;
  timing.stages = {"rectify", "match", "depth"};
  timing.durations_ms = {frame->rectify_ms, frame->match_ms, frame->depth_ms};
  if (options_.stereo.outliers.enabled) {
    timing.stages.push_back("outliers");
    timing.durations_ms.push_back(frame->outliers_ms);
  }
  timing.num_stages = static_cast<int32_t>(timing.stages.size());
  publish("MODULE_TIMING", timing);
}

std::string StereoDepthNode::summary() const {
  char text[256];
  std::snprintf(
      text, sizeof(text),
      "%lld pairs published (%lld refused); valid depth median %.1f %%; rectify median %.2f ms, "
      "match median %.2f ms, depth median %.2f ms; total p95 %.2f ms",
      static_cast<long long>(published_), static_cast<long long>(refused_),
      100 * median(valid_fraction_), median(rectify_ms_), median(match_ms_), median(depth_ms_),
      quantile(total_ms_, 0.95));
  return text;
}

}  // namespace thicket::stereo_depth

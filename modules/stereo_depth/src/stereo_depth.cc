#include "thicket/stereo_depth/stereo_depth.h"

#include <cmath>

namespace thicket::stereo_depth {

void RectifiedCameraOptions::declare(Params& p) {
  p("width", width, "image width of rectified pairs; 0: any [pixels]", Range::between(0, 16384));
  p("height", height, "image height of rectified pairs; 0: any [pixels]", Range::between(0, 16384));
  p("fx", fx, "focal length; 0: unknown, no depth [pixels]", Range::atLeast(0));
  p("fy", fy, "focal length; 0: fx [pixels]", Range::atLeast(0));
  p("cx", cx, "principal point; negative: the image centre [pixels]");
  p("cy", cy, "principal point; negative: the image centre [pixels]");
  p("baseline", baseline, "distance between the optical centres; 0: unknown, no depth [m]",
    Range::atLeast(0));
}

void StereoDepthOptions::declare(Params& p) {
  p("calibration_file", calibration_file,
    "OpenCV YAML stereo calibration (intrinsics, distortion, R, T, image size); empty: only "
    "pairs that arrive rectified, with the intrinsics below");
  p("rectify_alpha", rectify_alpha,
    "cv::stereoRectify free scaling: -1 OpenCV's default, 0 valid pixels only, 1 all pixels",
    Range::between(-1, 1));
  p.group("rectified", rectified,
          "intrinsics of pairs that arrive rectified, when there is no calibration file");
  p("max_time_difference_us", max_time_difference_us,
    "largest tolerated difference between the left, right and pair timestamps [us]",
    Range::atLeast(0));
  p("downscale", downscale,
    "match at 1/this of the resolution (1 or 2): disparity, depth and intrinsics at that size; "
    "num_disparities in matched pixels",
    Range::between(1, 2));
  p.group("matcher", matcher, "semi-global matching (OpenCV StereoSGBM) and the depth range");
  p.group("outliers", outliers, "statistical outlier removal on the point cloud (PCL)");
}

double StereoFrame::validFraction() const {
  const std::vector<float>& v = has_depth ? depth : disparity;
  if (v.empty()) return 0;
  size_t valid = 0;
  for (float x : v) valid += x > 0 ? 1 : 0;
  return static_cast<double>(valid) / static_cast<double>(v.size());
}

StereoDepth::StereoDepth(StereoDepthOptions options, std::optional<Rectifier> rectifier,
                         StereoMatcher matcher)
    : options_(std::move(options)),
      rectifier_(std::move(rectifier)),
      matcher_(std::move(matcher)) {}

Expected<StereoDepth> StereoDepth::create(const StereoDepthOptions& options) {
  std::optional<StereoCalibration> calibration;
  if (!options.calibration_file.empty()) {
    auto loaded = loadStereoCalibration(options.calibration_file);
    if (!loaded) return unexpected(loaded.error());
    calibration = std::move(*loaded);
  }
  return create(options, std::move(calibration));
}

namespace {

// Why images `width` pixels wide cannot hold the matcher's search, or "".
std::string tooNarrow(int width, const StereoMatcherOptions& matcher) {
  if (width >= matcher.minImageWidth()) return {};
  return "images are " + std::to_string(width) + " pixels wide, narrower than the " +
         std::to_string(matcher.minImageWidth()) +
         " the disparity search needs (num_disparities + min_disparity + block_size): lower "
         "matcher.num_disparities";
}

}  // namespace

Expected<StereoDepth> StereoDepth::create(const StereoDepthOptions& options,
                                          std::optional<StereoCalibration> calibration) {
  if (const std::string error = paramsError(options); !error.empty()) return unexpected(error);
  auto matcher_options = options.matcher.validated();
  if (!matcher_options) return unexpected("matcher: " + matcher_options.error());
  std::optional<Rectifier> rectifier;
  if (calibration) {
    auto created = Rectifier::create(*calibration, options.rectify_alpha);
    if (!created) return unexpected(created.error());
    if (const std::string narrow =
            tooNarrow(calibration->width / options.downscale, options.matcher);
        !narrow.empty()) {
      return unexpected("the calibration's " + narrow);
    }
    rectifier = std::move(*created);
  }
  return StereoDepth(options, std::move(rectifier), StereoMatcher(options.matcher));
}

Expected<StereoFrame> StereoDepth::process(const StereoPair& pair,
                                           const std::function<double()>& now_ms) const {
  const auto now = [&] { return now_ms ? now_ms() : 0.0; };
  const auto size = [](int w, int h) { return std::to_string(w) + "x" + std::to_string(h); };
  const int width = pair.left.width;
  const int height = pair.left.height;
  if (width != pair.right.width || height != pair.right.height) {
    return unexpected("the images differ in size");
  }
  StereoFrame frame;
  const double t0 = now();
  GrayImage right_rectified;
  const GrayImage* left = &pair.left;
  const GrayImage* right = &pair.right;
  if (rectifier_) {
    const StereoCalibration& c = rectifier_->calibration();
    if (!c.calibration_id.empty() && pair.calibration_id != c.calibration_id) {
      return unexpected("the pair names calibration '" + pair.calibration_id +
                        "', the calibration loaded is '" + c.calibration_id + "'");
    }
    if (width != c.width || height != c.height) {
      return unexpected("the images are " + size(width, height) + ", the calibration is for " +
                        size(c.width, c.height));
    }
    frame.camera = rectifier_->camera();
    frame.baseline = rectifier_->baseline();
    frame.has_depth = true;
    // Pairs that arrive rectified are taken to be in this calibration's rectified frame.
    frame.rectified_in_left = rectifier_->rectifiedInLeft();
    if (!pair.rectified) {
      rectifier_->rectify(pair.left, pair.right, frame.left_rectified, right_rectified);
      left = &frame.left_rectified;
      right = &right_rectified;
    }
  } else {
    if (!pair.rectified) {
      return unexpected(
          "the pair is not rectified and there is no calibration (set "
          "calibration_file)");
    }
    const RectifiedCameraOptions& r = options_.rectified;
    if ((r.width != 0 && r.width != width) || (r.height != 0 && r.height != height)) {
      return unexpected("the images are " + size(width, height) + ", rectified pairs are " +
                        size(r.width, r.height));
    }
    frame.camera.width = width;
    frame.camera.height = height;
    frame.camera.fx = r.fx;
    frame.camera.fy = r.fy > 0 ? r.fy : r.fx;
    frame.camera.cx = r.cx >= 0 ? r.cx : (width - 1) / 2.0;
    frame.camera.cy = r.cy >= 0 ? r.cy : (height - 1) / 2.0;
    frame.baseline = r.baseline;
    frame.has_depth = r.fx > 0 && r.baseline > 0;
  }
  const int k = options_.downscale;
  if (width % k != 0 || height % k != 0) {
    return unexpected("the images are " + size(width, height) + ": downscale " + std::to_string(k) +
                      " needs sides that are multiples of it");
  }
  if (const std::string narrow = tooNarrow(width / k, options_.matcher); !narrow.empty()) {
    return unexpected("the pair's " + narrow);
  }
  GrayImage right_small;
  if (k > 1) {
    // Output pixel u averages input pixels k u .. k u + k - 1, whose centres average k u +
    // (k - 1) / 2: so x = k u + (k - 1) / 2 in the input maps to u.
    frame.left_rectified = downscaleGray(*left, k);
    right_small = downscaleGray(*right, k);
    left = &frame.left_rectified;
    right = &right_small;
    frame.camera.width = width / k;
    frame.camera.height = height / k;
    frame.camera.fx /= k;
    frame.camera.fy /= k;
    frame.camera.cx = (frame.camera.cx - (k - 1) / 2.0) / k;
    frame.camera.cy = (frame.camera.cy - (k - 1) / 2.0) / k;
  }
  if (frame.left_rectified.pixels.empty()) frame.left_rectified = pair.left;
  const double t1 = now();
  frame.disparity = matcher_.disparity(*left, *right);
  const double t2 = now();
  if (frame.has_depth) {
    const StereoMatcherOptions& m = options_.matcher;
    frame.depth = depthFromDisparity(frame.disparity, frame.camera.fx, frame.baseline, m.min_range,
                                     m.max_range);
  }
  const double t3 = now();
  if (frame.has_depth && options_.outliers.enabled) {
    frame.outliers_removed = removeOutliers(frame.depth, frame.camera, options_.outliers);
  }
  const double t4 = now();
  frame.rectify_ms = t1 - t0;
  frame.match_ms = t2 - t1;
  frame.depth_ms = t3 - t2;
  frame.outliers_ms = t4 - t3;
  return frame;
}

}  // namespace thicket::stereo_depth

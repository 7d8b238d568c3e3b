// DepthRenderer and StereoRenderer: the simulated cameras, one ray per pixel through a View.
#include "thicket/sim/render.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <future>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "calibration_yaml.h"

namespace thicket::sim {
namespace {

using Surface = SurfaceHit::Surface;
using std::numbers::pi;

// Counter-based, so that a pixel's random numbers depend on (key, pixel) only: SplitMix64's
// output function (Steele et al. 2014) applied to key + counter.
uint64_t splitMix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Box-Muller on two counter-based uniforms; std::normal_distribution differs between standard
// libraries and keeps state, this does neither.
double standardNormal(uint64_t key, uint64_t index) {
  const double u1 = (static_cast<double>(splitMix64(key + 2 * index) >> 11) + 1.0) * 0x1.0p-53;
  const double u2 = static_cast<double>(splitMix64(key + 2 * index + 1) >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * pi * u2);
}

// The unit centre ray of every pixel in the optical frame, row-major: computed once per camera,
// since normalizing costs a square root and a division per pixel and frame otherwise.
std::vector<Eigen::Vector3d> opticalRays(const PinholeCamera& camera) {
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(static_cast<size_t>(camera.width) * camera.height);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      rays.push_back(camera.backProject(u, v, 1.0).normalized());
    }
  }
  return rays;
}

// Casts every pixel's centre ray (optical_rays, from opticalRays) from the view and hands the
// results over a line of pixels at a time: visit(first, stride, dirs, ranges, hits) for pixels
// first + k * stride, whose world rays are dirs[k]; hits is empty unless with_hits. A level
// camera (optical x and z horizontal) goes column by column, each column a fan (see
// View::castFan); any other row by row. A ray's result depends on its own pixel only.
template <class Visit>
void castImage(const RayCaster::View& view, const PinholeCamera& camera,
               const std::vector<Eigen::Vector3d>& optical_rays,
               const Eigen::Matrix3d& world_R_camera, bool with_hits, Visit&& visit) {
  const bool level =
      std::abs(world_R_camera(2, 0)) <= 1e-12 && std::abs(world_R_camera(2, 2)) <= 1e-12;
  const int lines = level ? camera.width : camera.height;
  const int length = level ? camera.height : camera.width;
  const int stride = level ? camera.width : 1;
  std::vector<Eigen::Vector3d> dirs(length);
  std::vector<double> ranges(length);
  std::vector<SurfaceHit> hits(with_hits ? length : 0);
  for (int line = 0; line < lines; ++line) {
    const int first = level ? line : line * camera.width;
    for (int k = 0; k < length; ++k) {
      dirs[k] = world_R_camera * optical_rays[static_cast<size_t>(first) + k * stride];
    }
    if (level) {
      const Eigen::Vector3d& top = optical_rays[first];
      const Eigen::Vector2d azimuth =
          (world_R_camera.col(0) * top.x() + world_R_camera.col(2) * top.z()).head<2>();
      view.castFan(azimuth.normalized(), dirs, ranges, hits);
    } else {
      view.cast(dirs, ranges, hits);
    }
    visit(first, stride, dirs, ranges, hits);
  }
}

PinholeCamera checkedCamera(const char* what, int width, int height, double horizontal_fov_deg,
                            double max_range, double pitch_down_deg,
                            const Eigen::Vector3d& position_in_body) {
  const auto fail = [what](const std::string& problem) {
    throw std::invalid_argument(std::string(what) + ": " + problem);
  };
  if (width <= 0 || height <= 0) fail("image size must be positive");
  if (!(horizontal_fov_deg > 0 && horizontal_fov_deg < 180)) {
    fail("horizontal_fov_deg must be in (0, 180)");
  }
  if (!(max_range > 0)) fail("max_range must be positive");
  if (!std::isfinite(pitch_down_deg) || !position_in_body.allFinite()) {
    fail("the mount must be finite");
  }
  return PinholeCamera::fromHorizontalFov(width, height, horizontal_fov_deg * pi / 180);
}

}  // namespace

// --- DepthRenderer ----------------------------------------------------------------------------

// The image size, field of view and mount that depth and stereo cameras share.
void declareCameraGeometry(Params& p, int& width, int& height, double& horizontal_fov_deg,
                           double& pitch_down_deg, Eigen::Vector3d& position_in_body,
                           const char* position_doc) {
  p("width", width, "image width [pixels]", Range::atLeast(1));
  p("height", height, "image height [pixels]", Range::atLeast(1));
  p("horizontal_fov_deg", horizontal_fov_deg, "horizontal field of view [deg]",
    Range::between(1, 179));
  p("pitch_down_deg", pitch_down_deg, "mount pitch, positive looks down [deg]",
    Range::between(-90, 90));
  p("position_in_body", position_in_body, position_doc);
}

void DepthCameraOptions::declare(Params& p) {
  declareCameraGeometry(p, width, height, horizontal_fov_deg, pitch_down_deg, position_in_body,
                        "optical centre in the body frame [m]");
  p("max_range", max_range, "longest return, as range along the ray [m]", Range::positive());
  p("noise_stddev_at_1m", noise_stddev_at_1m,
    "depth noise sigma = this * depth^2, 0 = noiseless [1/m]", Range::atLeast(0));
}

DepthRenderer::DepthRenderer(const World& world, DepthCameraOptions options)
    : caster_(world),
      options_(options),
      camera_(checkedCamera("DepthRenderer", options.width, options.height,
                            options.horizontal_fov_deg, options.max_range, options.pitch_down_deg,
                            options.position_in_body)),
      camera_in_body_(cameraMount(options.position_in_body, options.pitch_down_deg * pi / 180)),
      optical_rays_(opticalRays(camera_)) {
  if (!(options_.noise_stddev_at_1m >= 0)) {
    throw std::invalid_argument("DepthRenderer: noise_stddev_at_1m must be >= 0");
  }
}

DepthImage DepthRenderer::renderImage(const Pose& world_T_body, int64_t utime,
                                      uint64_t noise_seed) const {
  DepthImage image;
  image.utime = utime;
  image.camera = camera_;
  image.camera_in_body = camera_in_body_;
  image.min_range = kMinRange;
  image.max_range = options_.max_range;
  render(world_T_body, image.depth, noise_seed);
  return image;
}

void DepthRenderer::render(const Pose& world_T_body, std::vector<float>& depth_m,
                           uint64_t noise_seed) const {
  const Pose world_T_camera = world_T_body * camera_in_body_;
  const RayCaster::View view = caster_.view(world_T_camera.position, options_.max_range);
  const double noise = options_.noise_stddev_at_1m;
  const uint64_t noise_key = splitMix64(noise_seed);
  depth_m.assign(static_cast<size_t>(camera_.width) * camera_.height, 0.0f);
  castImage(view, camera_, optical_rays_, world_T_camera.orientation.toRotationMatrix(), false,
            [&](int first, int stride, const std::vector<Eigen::Vector3d>&,
                const std::vector<double>& ranges, const std::vector<SurfaceHit>&) {
              for (size_t k = 0; k < ranges.size(); ++k) {
                if (ranges[k] == RayCaster::kNoHit) continue;
                const size_t i = first + k * stride;
                double depth = ranges[k] * optical_rays_[i].z();
                if (noise > 0) {
                  depth += noise * depth * depth * standardNormal(noise_key, i);
                  if (!(depth > 0)) depth = 0;
                }
                depth_m[i] = static_cast<float>(depth);
              }
            });
}

// --- StereoRenderer ---------------------------------------------------------------------------

void StereoCameraOptions::declare(Params& p) {
  declareCameraGeometry(p, width, height, horizontal_fov_deg, pitch_down_deg, position_in_body,
                        "left optical centre in the body frame [m]");
  p("baseline", baseline, "distance of the right camera along the left's x [m]", Range::positive());
  p("max_range", max_range, "surfaces beyond this range look like the sky [m]", Range::positive());
  p("calibration_id", calibration_id,
    "the calibration the pairs name (the stereo depth node refuses pairs of another one)");
}

StereoRenderer::StereoRenderer(const World& world, StereoCameraOptions options)
    : surface_textures_(surfaceTextures(world.cylinders)),
      caster_(world),
      options_(options),
      camera_(checkedCamera("StereoRenderer", options.width, options.height,
                            options.horizontal_fov_deg, options.max_range, options.pitch_down_deg,
                            options.position_in_body)),
      left_in_body_(cameraMount(options.position_in_body, options.pitch_down_deg * pi / 180)),
      optical_rays_(opticalRays(camera_)) {
  if (!validCalibrationId(options_.calibration_id)) {
    throw std::invalid_argument("StereoRenderer: calibration_id must be non-empty [A-Za-z0-9_.-]");
  }
  if (!(options_.baseline > 0 && std::isfinite(options_.baseline))) {
    throw std::invalid_argument("StereoRenderer: baseline must be positive");
  }
}

Pose StereoRenderer::rightInBody() const {
  return left_in_body_ *
         Pose{Eigen::Vector3d(options_.baseline, 0, 0), Eigen::Quaterniond::Identity()};
}

void StereoRenderer::render(const Pose& world_T_body, std::vector<uint8_t>& left,
                            std::vector<uint8_t>& right) const {
  // The cameras share nothing but read-only state: the right one renders on a second thread, and
  // each image is the same as rendered alone (pixels depend on their own ray only).
  std::future<void> right_done =
      std::async(std::launch::async, [&] { renderCamera(world_T_body * rightInBody(), right); });
  renderCamera(world_T_body * left_in_body_, left);
  right_done.get();
}

void StereoRenderer::renderCamera(const Pose& world_T_camera, std::vector<uint8_t>& image) const {
  const RayCaster::View view = caster_.view(world_T_camera.position, options_.max_range);
  image.assign(static_cast<size_t>(camera_.width) * camera_.height, kSkyIntensity);
  const Eigen::Matrix3d world_R_camera = world_T_camera.orientation.toRotationMatrix();
  const Eigen::Vector3d image_right = world_R_camera.col(0);
  castImage(view, camera_, optical_rays_, world_R_camera, true,
            [&](int first, int stride, const std::vector<Eigen::Vector3d>& dirs,
                const std::vector<double>& ranges, const std::vector<SurfaceHit>& hits) {
              shadeLine(dirs, ranges, hits, image_right, image.data() + first, stride);
            });
}

}  // namespace thicket::sim

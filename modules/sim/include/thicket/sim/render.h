// What the simulated cameras see (docs/design.md §2, sim): an exact ray caster against the
// ground-truth World, a depth camera (CAMERA_DEPTH), and a rectified grayscale stereo pair (STEREO)
// whose surfaces carry a procedural texture so that stereo matching has something to match at 1-20
// m. Everything is deterministic and computed per pixel, independently of the other pixels.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/camera.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/geometry.h"
#include "thicket/common/params.h"
#include "thicket/sim/world.h"

namespace thicket::sim {

/// Which surface of the world a ray hit, and where: what texturing needs.
struct SurfaceHit {
  enum class Surface { kNone, kGround, kWall, kCylinderSide, kCylinderCap };
  Surface surface = Surface::kNone;
  /// The wall (0: at x min, 1: x max, 2: y min, 3: y max) or the cylinder (index into
  /// World::cylinders); -1 for the ground and for kNone.
  int index = -1;
  /// Where the ray met the surface, in the world frame [m]; the ray's origin at range 0.
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
};

/// Exact ray casting against a World. Surfaces: the ground plane z = bounds_min.z (unbounded); the
/// four walls on the x/y bounds, from the ground up to bounds_max.z, infinitely thin and seen from
/// both sides; solid vertical cylinders from z = 0 to their height, closed by a flat top cap.
/// A ray that starts inside a cylinder (surface included) or below the ground hits that solid at
/// range 0 (reported as the cylinder's side, or the ground).
///
/// Rays from one point (a camera) go through a View: exact too, and fast. Its cylinders are sorted
/// into azimuth bins around the eye, each bin nearest first: since the cylinders are vertical, a
/// ray's azimuth alone decides which of them it can hit, whatever its elevation. A ray tests the
/// cylinders of its bin in order until none can be nearer than its best hit (or than the ground
/// or a wall): about one per ray in a forest of 0.2 trees/m^2. A 2-D grid walked by DDA would
/// visit several cells per ray, each with cylinders overlapping it, and suits rays from many
/// points; rays from one point are what cameras cast. A camera without roll or pitch casts each
/// image column as a fan (View::castFan): its rays share an azimuth, so they share the cylinders
/// they pass, found once per column.
class RayCaster {
 public:
  /// The range returned when no surface is within the maximum range.
  static constexpr double kNoHit = std::numeric_limits<double>::infinity();

  /// Rays from one eye point, up to a maximum range (see the class comment). Build one per camera
  /// and frame: it takes time and memory linear in the cylinders and in the bins they span
  /// (about 50 µs for 420 cylinders).
  class View {
   public:
    /// Range t to the first surface along eye + t * unit_dir with 0 <= t <= maxRange(), or
    /// kNoHit. Fills hit when given (surface kNone without a hit). Exact, and equal to
    /// RayCaster::cast from the eye up to rounding.
    double cast(const Eigen::Vector3d& unit_dir, SurfaceHit* hit = nullptr) const;
    /// cast() for many rays: ranges[i] and, unless hits is empty, hits[i] for unit_dirs[i],
    /// bit for bit as one at a time but faster, because the rays' tests interleave. Throws
    /// std::invalid_argument when the sizes differ.
    void cast(std::span<const Eigen::Vector3d> unit_dirs, std::span<double> ranges,
              std::span<SurfaceHit> hits = {}) const;

    /// cast() for a vertical fan: rays whose xy parts all point along the unit 2-D azimuth
    /// (within 1e-9 rad), such as a column of a camera without roll or pitch. They share which
    /// cylinders they pass and where, so the fan finds those once and each ray only checks
    /// heights: several times faster than cast(), and equal to it up to rounding. Rays with
    /// (almost) no xy part are cast one by one. Throws std::invalid_argument when the sizes
    /// differ, azimuth is not a unit vector, or a ray is not in the fan.
    void castFan(const Eigen::Vector2d& azimuth, std::span<const Eigen::Vector3d> unit_dirs,
                 std::span<double> ranges, std::span<SurfaceHit> hits = {}) const;

    const Eigen::Vector3d& eye() const { return eye_; }
    double maxRange() const { return max_range_; }

   private:
    friend class RayCaster;

    // Checks the sizes of a cast's results; fills them and returns false when the eye is inside
    // a solid, so that every ray hits it at range 0.
    bool startCasting(const char* caller, size_t rays, std::span<double> ranges,
                      std::span<SurfaceHit> hits) const;

    // A cylinder as the intersection test wants it.
    struct Solid {
      double x, y, radius_sq, height;
    };
    // A cylinder in an azimuth bin: min_xy_travel is a lower bound on how far in xy a ray from
    // the eye travels before it can reach it (xy distance minus radius, rounded down). 8 bytes,
    // as a cylinder near the eye spans hundreds of bins.
    struct Candidate {
      float min_xy_travel;
      int index;
    };

    Eigen::Vector3d eye_ = Eigen::Vector3d::Zero();
    double max_range_ = 0;
    Eigen::Vector3d bounds_min_ = Eigen::Vector3d::Zero();
    Eigen::Vector3d bounds_max_ = Eigen::Vector3d::Zero();
    bool eye_inside_walls_ = false;      // rays meet the wall they leave the walls' box through
    bool walls_in_range_ = true;         // false: no wall is within max_range_ of the eye
    SurfaceHit containing_solid_;        // surface kNone unless the eye is inside a solid
    std::vector<Solid> solids_;          // World::cylinders, by index
    std::vector<int> around_eye_;        // footprints containing the eye: every azimuth
    std::vector<uint32_t> bin_begin_;    // bin b holds candidates_[bin_begin_[b], [b + 1])
    std::vector<Candidate> candidates_;  // then a sentinel that no ray can reach
  };

  explicit RayCaster(const World& world);

  /// Range t to the first surface along origin + t * unit_dir with 0 <= t <= max_range, or
  /// kNoHit; fills hit when given. Tests every cylinder: cast many rays from one point through
  /// view() instead. Throws std::invalid_argument for a negative or NaN max_range.
  double cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& unit_dir, double max_range,
              SurfaceHit* hit = nullptr) const;

  /// Prepares casting from eye up to max_range (may be infinite). Throws std::invalid_argument
  /// for a negative or NaN max_range.
  View view(const Eigen::Vector3d& eye, double max_range) const;

 private:
  // The solid that p is inside of or on the boundary of; surface kNone when p is in free space.
  SurfaceHit containingSolid(const Eigen::Vector3d& p) const;

  Eigen::Vector3d bounds_min_;
  Eigen::Vector3d bounds_max_;
  std::vector<Cylinder> cylinders_;
};

/// A simulated depth camera looking forward along body x (docs/benchmark.md: 320x240, 90°, 20 m).
struct DepthCameraOptions {
  int width = 320;                 ///< [pixels]
  int height = 240;                ///< [pixels]
  double horizontal_fov_deg = 90;  ///< between the outer edges of the outer pixels [deg]
  double max_range = 20;           ///< longest return, as range along the ray [m]
  double pitch_down_deg = 0;       ///< mount pitch, positive looks down [deg]
  /// Optical centre in the body frame [m].
  Eigen::Vector3d position_in_body = Eigen::Vector3d::Zero();
  /// Depth noise: a Gaussian with sigma = noise_stddev_at_1m * z^2 (stereo-like growth with the
  /// square of the depth z) [1/m]; 0 turns noise off.
  double noise_stddev_at_1m = 0;

  void declare(Params& p);
};

/// Renders depth images of a World.
class DepthRenderer {
 public:
  /// Throws std::invalid_argument when the options make no camera (non-positive size or range,
  /// field of view outside (0, 180) degrees, negative noise).
  DepthRenderer(const World& world, DepthCameraOptions options);

  PinholeCamera camera() const { return camera_; }
  /// The optical frame in the body frame.
  Pose cameraInBody() const { return camera_in_body_; }
  const DepthCameraOptions& options() const { return options_; }

  /// The image seen from world_T_body into depth_m (resized to width * height, row-major): the
  /// optical-frame z of the first surface along each pixel's centre ray [m], or 0 (no return)
  /// when it is farther than max_range along the ray. With noise on, pixel i's noise comes from
  /// a generator keyed by (noise_seed, i), so it does not depend on the order pixels are
  /// rendered in; a return that noise would push to or below zero becomes 0.
  void render(const Pose& world_T_body, std::vector<float>& depth_m, uint64_t noise_seed = 0) const;

  /// The same as a DepthImage stamped utime: the camera, its mount, and the range limits (returns
  /// closer than kMinRange are not trusted, as on a real depth camera).
  DepthImage renderImage(const Pose& world_T_body, int64_t utime, uint64_t noise_seed = 0) const;
  static constexpr double kMinRange = 0.05;  ///< [m]

 private:
  RayCaster caster_;
  DepthCameraOptions options_;
  PinholeCamera camera_;
  Pose camera_in_body_;
  std::vector<Eigen::Vector3d> optical_rays_;  // every pixel's unit centre ray, optical frame
};

/// A simulated rectified stereo camera looking forward along body x (a VI-Sensor-like pair).
struct StereoCameraOptions {
  int width = 752;                 ///< [pixels]
  int height = 480;                ///< [pixels]
  double horizontal_fov_deg = 90;  ///< between the outer edges of the outer pixels [deg]
  double baseline = 0.11;          ///< the right camera sits this far along the left's x [m]
  double max_range = 20;           ///< surfaces beyond this range look like the sky [m]
  double pitch_down_deg = 0;       ///< mount pitch, positive looks down [deg]
  /// Optical centre of the left camera in the body frame [m].
  Eigen::Vector3d position_in_body = Eigen::Vector3d::Zero();
  /// The calibration the pairs name (stereo_image_t.calibration_id, calibrationYaml's id):
  /// "vehicle" lets the simulator stand in for the vehicle's camera driver.
  std::string calibration_id = "sim_stereo";

  void declare(Params& p);
};

/// Renders rectified grayscale stereo pairs of a World: both cameras share intrinsics and
/// orientation, the right one is displaced by the baseline along the left's optical x. Every
/// surface carries a procedural texture, a tile of value noise in surface coordinates (seven
/// octaves, cells of 2 cm up to 1.28 m, repeating every 10.24 m) at the surface's own offset,
/// that depends on the surface point only, so both cameras see the same texture; there is no
/// lighting. The texture is stored in 16-bit texels, within 1/128 gray level of the exact noise.
/// A pixel samples the texture at its centre ray's hit, low-pass filtered to the pixel's footprint
/// there by mip-mapping (from the mip level nearest the footprint, blended with the next one in
/// the middle quarter of the octave between them), rather than supersampled: one ray per pixel
/// instead of four, and no aliasing along the rows, where the two cameras sample the surface at
/// different points. The footprint is the one along the row: along a column both cameras sample
/// the same epipolar plane, so whatever aliasing there is, they share.
class StereoRenderer {
 public:
  /// The gray level of pixels that see nothing within max_range.
  static constexpr uint8_t kSkyIntensity = 210;

  /// Throws std::invalid_argument when the options make no camera (non-positive size, range or
  /// baseline, field of view outside (0, 180) degrees).
  StereoRenderer(const World& world, StereoCameraOptions options);

  /// The pair seen from world_T_body, each image resized to width * height, row-major.
  void render(const Pose& world_T_body, std::vector<uint8_t>& left,
              std::vector<uint8_t>& right) const;

  /// The intrinsics of both cameras.
  PinholeCamera camera() const { return camera_; }
  double baseline() const { return options_.baseline; }
  /// The optical frames of the cameras in the body frame.
  Pose leftInBody() const { return left_in_body_; }
  Pose rightInBody() const;
  const StereoCameraOptions& options() const { return options_; }

  /// The gray level (about [0, 255], before clamping) of the texture at a hit surface point
  /// (surface not kNone), filtered to a pixel footprint of footprint_m: what a pixel with that
  /// footprint sees there. Throws std::invalid_argument for surface kNone.
  double surfaceIntensity(const SurfaceHit& hit, double footprint_m) const;

  /// The calibration as OpenCV FileStorage YAML, as cv::stereoCalibrate would describe this
  /// pair: image_width, image_height, camera_matrix_left/right, distortion_left/right (zeros),
  /// R (identity) and T = [-baseline, 0, 0] (x_right = R x_left + T), and calibration_id.
  /// Throws std::invalid_argument unless id is non-empty and made of [A-Za-z0-9_.-].
  std::string calibrationYaml(const std::string& id) const;

 private:
  void renderCamera(const Pose& world_T_camera, std::vector<uint8_t>& image) const;
  // Shades one line of pixels that castImage cast (stereo_texture.cc): pixels[k * stride] sees
  // the hit hits[k] at ranges[k] along the unit ray dirs[k], or nothing (left as it is) at
  // RayCaster::kNoHit; image_right is the image's x axis, all in the world frame.
  void shadeLine(std::span<const Eigen::Vector3d> dirs, std::span<const double> ranges,
                 std::span<const SurfaceHit> hits, const Eigen::Vector3d& image_right,
                 uint8_t* pixels, size_t stride) const;

  // How one surface shows the texture: its offset in the tile [texels] and mean gray level; on
  // a cylinder side also the axis and the texels per quarter turn around it (stereo_texture.cc).
  struct SurfaceTexture {
    double offset_x = 0, offset_y = 0;
    double mean = 0;
    double axis_x = 0, axis_y = 0, inverse_radius = 0, texels_per_quarter_turn = 0;
  };
  // The ground's, the four walls', then each cylinder's side and cap, in that order.
  static std::vector<SurfaceTexture> surfaceTextures(const std::vector<Cylinder>& cylinders);

  std::vector<SurfaceTexture> surface_textures_;
  RayCaster caster_;
  StereoCameraOptions options_;
  PinholeCamera camera_;
  Pose left_in_body_;
  std::vector<Eigen::Vector3d> optical_rays_;  // every pixel's unit centre ray, optical frame
};

}  // namespace thicket::sim

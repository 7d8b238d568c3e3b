#include "thicket/mapper/tsdf_integrator.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace thicket::mapper {
namespace {

using Method = TsdfIntegratorOptions::Method;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();

// What one pixel says about the voxels on its line of sight, in the method's distance metric
// (optical z for the projective method, range along the ray for the ray caster).
struct PixelMeasurement {
  double distance = kInf;  // to the return; +inf when none was seen
  double max_voxel = 0;    // voxels farther than this are not updated
  double weight = 0;       // 0: the pixel says nothing
};

// What updates did: whether a block's stored values changed, and whether the voxel at hand
// changed in what the ESDF reads (TsdfIntegrationResult::changed_voxels).
struct Changes {
  bool block = false;
  bool voxel = false;
};

// The per-voxel update rule shared by both methods (see the header).
class VoxelUpdater {
 public:
  VoxelUpdater(double voxel_size, double truncation, double max_weight, bool new_surfaces_replace,
               double new_surface_shadow, float observed_weight)
      : voxel_size_(voxel_size),
        truncation_(truncation),
        max_weight_(max_weight),
        new_surfaces_replace_(new_surfaces_replace),
        new_surface_shadow_(new_surface_shadow),
        observed_weight_(observed_weight) {}

  float observedWeight() const { return observed_weight_; }

  double truncation() const { return truncation_; }
  double newSurfaceShadow() const { return new_surface_shadow_; }

  // Whether the map has the voxel as clearly free: observed, beyond half the truncation from any
  // surface. A return there is a new surface.
  bool clearlyFree(const TsdfVoxel& voxel) const {
    return voxel.weight > 0 && voxel.distance > 0.5 * truncation_;
  }

  // Behind a new surface, more than a voxel deep and at most new_surface_shadow deeper than the
  // truncation: what the map has there as free is stale, and the voxel becomes unobserved, so
  // that within the truncation it takes the frame's measurement alone (update) and beyond it
  // waits for a view. Returns whether the voxel was in that shadow and free (it was then reset).
  bool clearShadow(TsdfVoxel& voxel, double sdf, Changes& changes) const {
    if (!(sdf < -voxel_size_ && sdf > -truncation_ - new_surface_shadow_)) return false;
    if (!(voxel.weight > 0 && voxel.distance > 0)) return false;
    store(voxel, 0.0f, 0.0f, changes);
    return true;
  }

  // Applies the measurement when the voxel is within the truncation behind the surface; returns
  // whether it was applied, and records what changed.
  bool update(TsdfVoxel& voxel, double sdf, double weight, Changes& changes) const {
    if (!(sdf > -truncation_)) return false;
    if (sdf < -voxel_size_) weight *= (truncation_ + sdf) / (truncation_ - voxel_size_);
    sdf = std::min(sdf, truncation_);
    if (new_surfaces_replace_ && std::abs(sdf) <= voxel_size_ && clearlyFree(voxel)) {
      // A return within a voxel of a voxel the map had as clearly free: something is there now
      // (an obstacle that appeared, or a surface earlier views only passed by). Averaged in, it
      // would take several frames to outweigh the free-space history while the ESDF promised
      // clearance that is not there; the measurement replaces the history instead.
      store(voxel, static_cast<float>(sdf), static_cast<float>(std::min(weight, max_weight_)),
            changes);
      return true;
    }
    // In double, then rounded once: repeated equal measurements leave the distance bit for bit
    // unchanged, so saturated voxels do not count as changed.
    const double old_weight = voxel.weight;
    const double sum = old_weight + weight;
    store(voxel, static_cast<float>((old_weight * voxel.distance + weight * sdf) / sum),
          static_cast<float>(std::min(sum, max_weight_)), changes);
    return true;
  }

 private:
  // Stores a voxel's new values: the block changed if they differ (the distance bit for bit, so
  // that a zero that changes sign counts too), and the voxel is reported
  // (TsdfIntegrationResult::changed_voxels) if its distance did or whether its weight reaches
  // observed_weight. Unchanged voxels are not written: their cache lines stay clean.
  void store(TsdfVoxel& voxel, float distance, float weight, Changes& changes) const {
    const bool distance_changed =
        std::bit_cast<uint32_t>(distance) != std::bit_cast<uint32_t>(voxel.distance);
    if (!distance_changed && weight == voxel.weight) return;
    changes.block = true;
    changes.voxel |=
        distance_changed || (weight >= observed_weight_) != (voxel.weight >= observed_weight_);
    voxel.distance = distance;
    voxel.weight = weight;
  }

  double voxel_size_;
  double truncation_;
  double max_weight_;
  bool new_surfaces_replace_;
  double new_surface_shadow_;
  float observed_weight_;
};

double measurementWeight(double depth) {
  const double z = std::max(depth, TsdfIntegrator::kMinWeightDepth);
  return 1.0 / (z * z);
}

void validate(const DepthImage& image, const Pose& world_T_camera) {
  if (const auto camera = image.camera.validated(); !camera) {
    throw std::invalid_argument("TsdfIntegrator: " + camera.error());
  }
  const size_t pixels = static_cast<size_t>(image.camera.width) * image.camera.height;
  if (image.depth.size() != pixels) {
    throw std::invalid_argument("TsdfIntegrator: the image has " +
                                std::to_string(image.depth.size()) + " depths for " +
                                std::to_string(pixels) + " pixels");
  }
  if (!(std::isfinite(image.min_range) && std::isfinite(image.max_range) && image.min_range >= 0 &&
        image.max_range > image.min_range)) {
    throw std::invalid_argument("TsdfIntegrator: invalid range limits [" +
                                std::to_string(image.min_range) + ", " +
                                std::to_string(image.max_range) + "]");
  }
  const Eigen::Quaterniond& q = world_T_camera.orientation;
  if (!world_T_camera.position.allFinite() || !q.coeffs().allFinite() ||
      std::abs(q.norm() - 1) > 1e-3) {
    throw std::invalid_argument(
        "TsdfIntegrator: the camera pose is not finite with a unit quaternion");
  }
}

// Throws on a negative or non-finite depth, before anything is integrated: one branch-free pass
// over the image, then a search for the first bad pixel only if there is one.
void checkDepths(const DepthImage& image) {
  bool bad = false;
  for (const float d : image.depth) bad |= !(d >= 0 && d <= std::numeric_limits<float>::max());
  if (!bad) return;
  const int width = image.camera.width;
  for (size_t i = 0; i < image.depth.size(); ++i) {
    const float depth = image.depth[i];
    if (!(std::isfinite(depth) && depth >= 0)) {
      throw std::invalid_argument("TsdfIntegrator: pixel (" + std::to_string(i % width) + ", " +
                                  std::to_string(i / width) + ") has depth " +
                                  std::to_string(depth));
    }
  }
}

// Whether a pixel's (checked) optical depth is a return within range: one that measurePixel
// (scale 1) integrates as a surface.
inline bool returnInRange(double depth, const DepthImage& image, double range) {
  return depth > 0 && depth >= image.min_range && depth <= image.max_range && depth <= range;
}

// What a pixel of (checked) depth says; scale converts its depth to the method's distance (the
// ray caster's range along the pixel's ray; 1 for the optical z). Without carving, a pixel that
// sees nothing within range says nothing.
inline PixelMeasurement measurePixel(double depth, double scale, const DepthImage& image,
                                     double range, bool carve = true) {
  if (depth > 0 && depth < image.min_range) return {};
  const bool returned = depth > 0 && depth <= image.max_range;
  const double distance = returned ? depth * scale : kInf;
  if (distance <= range) return {distance, kInf, measurementWeight(depth)};
  if (!carve) return {};
  return {distance, range, measurementWeight(range)};
}

// PinholeCamera::backProject at a camera's pixels, each column's and row's division done once:
// (u - cx) / fx * depth as there, bit for bit where the compiler does not fuse multiplies and adds
// (x86-64 without FMA; targets with FMA need -ffp-contract=off for that); and each pixel's unit
// ray, at(u, v, 1).normalized(), computed once per camera (forCamera).
class PixelRays {
 public:
  explicit PixelRays(const PinholeCamera& camera)
      : camera_(camera), xs_(camera.width), ys_(camera.height) {
    for (int u = 0; u < camera.width; ++u) xs_[u] = (u - camera.cx) / camera.fx;
    for (int v = 0; v < camera.height; ++v) ys_[v] = (v - camera.cy) / camera.fy;
    units_.reserve(static_cast<size_t>(camera.width) * camera.height);
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) units_.push_back(at(u, v, 1.0).normalized());
    }
  }

  // The rays of the camera, built when this thread last saw another one.
  static const PixelRays& forCamera(const PinholeCamera& camera) {
    thread_local std::optional<PixelRays> cached;
    const PinholeCamera* c = cached ? &cached->camera_ : nullptr;
    if (!c || c->width != camera.width || c->height != camera.height || c->fx != camera.fx ||
        c->fy != camera.fy || c->cx != camera.cx || c->cy != camera.cy) {
      cached.emplace(camera);
    }
    return *cached;
  }

  Eigen::Vector3d at(int u, int v, double depth) const {
    return {xs_[u] * depth, ys_[v] * depth, depth};
  }
  const Eigen::Vector3d& unit(size_t pixel) const { return units_[pixel]; }

 private:
  PinholeCamera camera_;
  std::vector<double> xs_;
  std::vector<double> ys_;
  std::vector<Eigen::Vector3d> units_;
};

// Per pixel, the cosine of the angle between its ray and the surface normal estimated from the
// neighbouring depths, at least kMinSurfaceCosine; 0 where no normal can be estimated (no valid
// neighbour on an axis). Computed when normal distances or new-surface shadows need it; else
// empty. With normal_distances it is how much of a distance measured along the line of sight
// lies along the normal (alongNormal): a TSDF of raw line-of-sight distances overstates the
// distance to a surface seen at a slant by 1 / cosine, which on a cylinder's flank promised the
// planner 0.1-0.3 m of clearance that was not there.
constexpr double kMinSurfaceCosine = 0.3;

// The factor from a line-of-sight distance to one along the normal: the cosine, or 1 (the distance
// taken as it is) where no normal was estimated.
inline double alongNormal(float cosine) {
  return cosine > 0 ? cosine : 1.0;
}

std::vector<float> surfaceCosines(const DepthImage& image, const PixelRays& rays,
                                  const TsdfIntegratorOptions& options) {
  const PinholeCamera& camera = image.camera;
  const int width = camera.width;
  const int height = camera.height;
  const double range = options.max_integration_range;
  if (!options.normal_distances && !(options.new_surface_shadow > 0)) return {};
  std::vector<float> cosines(image.depth.size(), 0.0f);
  const auto valid = [&](double d) { return d >= image.min_range && d > 0 && d <= range; };
  // The neighbour on one axis whose depth is closest to the pixel's, so that a tangent is not
  // taken across an occluding edge when the other side continues the surface.
  const auto tangent = [&](int u, int v, int du, int dv, Eigen::Vector3d& t)
      __attribute__((always_inline)) {
    const double d = image.depth[static_cast<size_t>(v) * width + u];
    double best = kInf;
    for (const int sign : {-1, 1}) {
      const int un = u + sign * du;
      const int vn = v + sign * dv;
      if (un < 0 || un >= width || vn < 0 || vn >= height) continue;
      const size_t n = static_cast<size_t>(vn) * width + un;
      const double dn = image.depth[n];
      if (!valid(dn) || std::abs(dn - d) >= best) continue;
      best = std::abs(dn - d);
      t = rays.at(un, vn, dn) - rays.at(u, v, d);
    }
    return best < kInf;
  };
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      if (!valid(image.depth[i])) continue;
      Eigen::Vector3d along_u, along_v;
      if (!tangent(u, v, 1, 0, along_u) || !tangent(u, v, 0, 1, along_v)) continue;
      const Eigen::Vector3d normal = along_u.cross(along_v);
      const double norm = normal.norm();
      if (!(norm > 0)) continue;
      const Eigen::Vector3d& ray = rays.unit(i);
      cosines[i] =
          static_cast<float>(std::clamp(std::abs(normal.dot(ray)) / norm, kMinSurfaceCosine, 1.0));
    }
  }
  return cosines;
}

// How many voxels behind a return must be clearly free, as well as the return's own, for it to
// be a new surface. The return's own voxel alone is not enough: at a trunk's silhouette, rays that
// passed beside the trunk through a voxel the surface cuts left it clearly free (the TSDF stores
// the distance to each ray's own return), and a later view that hits the trunk there is no new
// surface. Three voxels deep the probes are inside the trunk, which no ray saw free; inside an
// obstacle that appeared where the map saw free space they are not.
constexpr int kNewSurfaceProbes = 3;
// Returns seen at a slant steeper than this cosine are no evidence of a new surface: near a
// trunk's silhouette a ray runs a short chord through the trunk and the probes come out beside
// it, where the map rightly has free space.
constexpr double kMinNewSurfaceCosine = 0.5;

// The pixels that see a new surface: a return within the integration range (as optical z),
// seen at a cosine of at least kMinNewSurfaceCosine, whose voxel and the kNewSurfaceProbes voxels
// behind it along the ray the map has as clearly free, before this frame changes anything. Behind
// such a return the map's free space is stale (an obstacle appeared where it saw free space), so
// the integrators reset it (VoxelUpdater::clearShadow).
struct NewSurfaces {
  std::vector<uint8_t> pixels;  ///< 1 for a pixel that sees one; empty when none does
  double max_depth = 0;         ///< the largest optical z of such a return [m]
  bool at(size_t pixel) const { return !pixels.empty() && pixels[pixel] != 0; }
};

// q * v as Eigen computes it (QuaternionBase::_transformVector), bit for bit, but always inlined:
// GCC at -O2 leaves Eigen's out of line, a call per pixel.
[[gnu::always_inline]] inline Eigen::Vector3d rotate(const Eigen::Quaterniond& q,
                                                     const Eigen::Vector3d& v) {
  Eigen::Vector3d uv = q.vec().cross(v);
  uv += uv;
  return v + q.w() * uv + q.vec().cross(uv);
}

NewSurfaces newSurfacePixels(const DepthImage& image, const PixelRays& rays,
                             const Pose& world_T_camera, const std::vector<float>& cosines,
                             const TsdfIntegratorOptions& options, const VoxelUpdater& updater,
                             const TsdfLayer& layer) {
  NewSurfaces found;
  if (!(updater.newSurfaceShadow() > 0)) return found;
  const PinholeCamera& camera = image.camera;
  const double step = layer.voxelSize();
  std::vector<uint8_t>& flags = found.pixels;
  // Consecutive probes mostly land in one block: it is looked up only when that changes.
  BlockIndex cached_index = BlockIndex::Constant(std::numeric_limits<int>::min());
  const TsdfLayer::BlockType* cached = nullptr;
  const auto clearlyFreeAt = [&](const Eigen::Vector3d& p) __attribute__((always_inline)) {
    const VoxelIndex voxel = layer.voxelIndex(p);
    const BlockIndex b = blockOfVoxel(voxel);
    if (b != cached_index) {
      cached_index = b;
      cached = layer.block(b);
    }
    return cached && updater.clearlyFree(cached->voxels[linearIndexInBlock(voxel)]);
  };
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const size_t i = static_cast<size_t>(v) * camera.width + u;
      const double depth = image.depth[i];
      if (!returnInRange(depth, image, options.max_integration_range)) continue;
      if (cosines[i] < kMinNewSurfaceCosine) continue;
      const Eigen::Vector3d ray = rotate(world_T_camera.orientation, rays.at(u, v, 1.0));
      const Eigen::Vector3d hit = world_T_camera.position + depth * ray;
      // Most returns end in a voxel that is not clearly free: the probes behind it wait.
      bool stale = clearlyFreeAt(hit);
      if (!stale) continue;
      const Eigen::Vector3d deeper = step * ray.normalized();
      for (int k = 1; k <= kNewSurfaceProbes && stale; ++k) stale = clearlyFreeAt(hit + k * deeper);
      if (!stale) continue;
      if (flags.empty()) flags.assign(image.depth.size(), 0);
      flags[i] = 1;
      found.max_depth = std::max(found.max_depth, depth);
    }
  }
  return found;
}

// A voxel's signed distance from the line-of-sight distance `along` and the pixel's factor to
// the surface normal. Only the free side is scaled: it is what promises clearance, while behind
// the surface the line-of-sight depth keeps the truncation band as deep as before.
inline double towardSurface(double along, double to_surface) {
  return along > 0 ? along * to_surface : along;
}

// Every pixel's measurement along its ray, for the ray caster.
std::vector<PixelMeasurement> measurePixelsAlongRays(const DepthImage& image, const PixelRays& rays,
                                                     const TsdfIntegratorOptions& options) {
  const PinholeCamera& camera = image.camera;
  std::vector<PixelMeasurement> pixels(image.depth.size());
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const size_t i = static_cast<size_t>(v) * camera.width + u;
      pixels[i] = measurePixel(image.depth[i], rays.at(u, v, 1.0).norm(), image,
                               options.max_integration_range);
    }
  }
  return pixels;
}

// Blocks whose voxel centres may lie in the frustum up to max_depth, in indexLess order.
std::vector<BlockIndex> frustumBlocks(const PinholeCamera& camera, const Pose& world_T_camera,
                                      const Pose& camera_T_world, const TsdfLayer& layer,
                                      double max_depth) {
  const double w = camera.width - 0.5;
  const double h = camera.height - 0.5;
  Eigen::Vector3d lo = world_T_camera.position;
  Eigen::Vector3d hi = lo;
  for (const auto& [u, v] : {std::pair{-0.5, -0.5}, {w, -0.5}, {-0.5, h}, {w, h}}) {
    const Eigen::Vector3d corner = world_T_camera.transform(camera.backProject(u, v, max_depth));
    lo = lo.cwiseMin(corner);
    hi = hi.cwiseMax(corner);
  }
  const BlockIndex first = layer.blockIndex(lo);
  const BlockIndex last = layer.blockIndex(hi);
  // The sphere around a block's voxel centres, a hair larger so rounding cannot cull a voxel.
  const double half_span = 0.5 * (kVoxelsPerSide - 1) * layer.voxelSize();
  const double radius = std::sqrt(3.0) * half_span * (1 + 1e-9);
  std::vector<BlockIndex> blocks;
  for (int x = first.x(); x <= last.x(); ++x) {
    for (int y = first.y(); y <= last.y(); ++y) {
      for (int z = first.z(); z <= last.z(); ++z) {
        const BlockIndex b(x, y, z);
        const Eigen::Vector3d center =
            layer.voxelCenter(voxelOfBlock(b, 0)) + Eigen::Vector3d::Constant(half_span);
        if (camera.sphereIntersectsFrustum(camera_T_world.transform(center), radius, 0.0,
                                           max_depth)) {
          blocks.push_back(b);
        }
      }
    }
  }
  return blocks;
}

// The image cut into tiles of kTile x kTile pixels, each with its nearest and farthest return
// within range (returnInRange).
class DepthTiles {
 public:
  static constexpr int kTile = 4;

  DepthTiles(const DepthImage& image, double range)
      : camera_(image.camera),
        tiles_x_((camera_.width + kTile - 1) / kTile),
        tiles_y_((camera_.height + kTile - 1) / kTile) {
    // Returns in range are the depths in [lowest, highest] compared as floats: the same pixels
    // as returnInRange's double comparisons.
    float lowest = static_cast<float>(image.min_range);
    if (lowest < image.min_range) lowest = std::nextafter(lowest, kInfF);
    lowest = std::max(lowest, std::numeric_limits<float>::denorm_min());  // depth 0: no return
    const double max_depth = std::min(image.max_range, range);
    float highest = static_cast<float>(max_depth);
    if (highest > max_depth) highest = std::nextafter(highest, -kInfF);
    const size_t tiles = static_cast<size_t>(tiles_x_) * tiles_y_;
    nearest_.assign(tiles, kInfF);
    farthest_.assign(tiles, -kInfF);
    for (int v = 0; v < camera_.height; ++v) {
      const float* depths = image.depth.data() + static_cast<size_t>(v) * camera_.width;
      const size_t row = static_cast<size_t>(v / kTile) * tiles_x_;
      for (int tx = 0; tx < tiles_x_; ++tx) {
        float nearest = nearest_[row + tx];
        float farthest = farthest_[row + tx];
        for (int u = tx * kTile; u < std::min((tx + 1) * kTile, camera_.width); ++u) {
          const float depth = depths[u];
          const bool valid = (depth >= lowest) & (depth <= highest);
          nearest = std::min(nearest, valid ? depth : kInfF);
          farthest = std::max(farthest, valid ? depth : -kInfF);
        }
        nearest_[row + tx] = nearest;
        farthest_[row + tx] = farthest;
      }
    }
  }

  int tilesX() const { return tiles_x_; }
  int tilesY() const { return tiles_y_; }

  // Over tiles tx0..tx1 x ty0..ty1 (inclusive): the nearest and the farthest return in range
  // (+inf and -inf: none).
  struct Bounds {
    float nearest = kInfF;
    float farthest = -kInfF;
  };
  Bounds bounds(int tx0, int ty0, int tx1, int ty1) const {
    Bounds b;
    for (int ty = ty0; ty <= ty1; ++ty) {
      for (int tx = tx0; tx <= tx1; ++tx) {
        const size_t t = static_cast<size_t>(ty) * tiles_x_ + tx;
        b.nearest = std::min(b.nearest, nearest_[t]);
        b.farthest = std::max(b.farthest, farthest_[t]);
      }
    }
    return b;
  }

  // The tiles that the voxel centres of a block project into, its corners c[0..7] given in the
  // camera frame, as bounds(); nullopt when part of the block is not in front of the camera.
  std::optional<Bounds> blockBounds(const std::array<Eigen::Vector3d, 8>& corners) const {
    double u_lo = kInf, u_hi = -kInf, v_lo = kInf, v_hi = -kInf;
    for (const Eigen::Vector3d& c : corners) {
      if (!(c.z() > 0)) return std::nullopt;
      const double u = camera_.fx * c.x() / c.z() + camera_.cx + 0.5;
      const double v = camera_.fy * c.y() / c.z() + camera_.cy + 0.5;
      u_lo = std::min(u_lo, u);
      u_hi = std::max(u_hi, u);
      v_lo = std::min(v_lo, v);
      v_hi = std::max(v_hi, v);
    }
    if (u_hi < -1 || v_hi < -1 || u_lo > camera_.width + 1 || v_lo > camera_.height + 1) {
      return Bounds{};  // off the image: no pixel at all
    }
    // The tile of pixel coordinate c, with a pixel of slack against rounding.
    const auto tile = [](double c, int pixels) {
      return static_cast<int>(std::clamp(std::floor(c), 0.0, pixels - 1.0)) / kTile;
    };
    const int tx0 = tile(u_lo - 1, camera_.width);
    const int tx1 = tile(u_hi + 1, camera_.width);
    const int ty0 = tile(v_lo - 1, camera_.height);
    const int ty1 = tile(v_hi + 1, camera_.height);
    return bounds(tx0, ty0, tx1, ty1);
  }

 private:
  const PinholeCamera& camera_;
  int tiles_x_;
  int tiles_y_;
  std::vector<float> nearest_;
  std::vector<float> farthest_;
};

// Without carving, the blocks the frame may update: those within a voxel of the stretch of some
// pixel's line of sight from the truncation in front of its return (along the normal: up to
// 1 / kMinSurfaceCosine times that in optical z) to the truncation behind it (and down to the
// new-surface shadow's end where the frame sees a new surface), in indexLess order. A rectangle
// of tiles is covered by the box around its frustum section between the nearest and the farthest
// end of its stretches; one whose returns spread deeper than kMaxSpreadVoxels is split into
// quarters, down to single tiles, so that boxes stay tight at edges.
class SurfaceBlocks {
 public:
  SurfaceBlocks(const DepthTiles& tiles, const PinholeCamera& camera, const Pose& world_T_camera,
                const TsdfIntegratorOptions& options, const VoxelUpdater& updater, double behind,
                const TsdfLayer& layer)
      : tiles_(tiles),
        world_T_camera_(world_T_camera),
        layer_(layer),
        // Normal distances shrink the free side's by the cosine, at least kMinSurfaceCosine.
        front_(updater.truncation() / (options.normal_distances ? kMinSurfaceCosine : 1.0)),
        behind_(behind),
        max_spread_(kMaxSpreadVoxels * layer.voxelSize()) {
    // The rays through the tiles' corners (pixel edges), in the world frame: R (x, y, 1) as
    // x R0 + (y R1 + R2), the terms per column and per row.
    constexpr int kTile = DepthTiles::kTile;
    const Eigen::Matrix3d world_R_camera = world_T_camera.orientation.toRotationMatrix();
    std::vector<Eigen::Vector3d> along_x(tiles.tilesX() + 1);
    for (int tx = 0; tx <= tiles.tilesX(); ++tx) {
      const double x = camera.backProject(std::min(tx * kTile, camera.width) - 0.5, 0, 1).x();
      along_x[tx] = x * world_R_camera.col(0);
    }
    rays_.resize(static_cast<size_t>(tiles.tilesX() + 1) * (tiles.tilesY() + 1));
    for (int ty = 0; ty <= tiles.tilesY(); ++ty) {
      const double y = camera.backProject(0, std::min(ty * kTile, camera.height) - 0.5, 1).y();
      const Eigen::Vector3d along_y = y * world_R_camera.col(1) + world_R_camera.col(2);
      for (int tx = 0; tx <= tiles.tilesX(); ++tx) {
        rays_[static_cast<size_t>(ty) * (tiles.tilesX() + 1) + tx] = along_x[tx] + along_y;
      }
    }
  }

  std::vector<BlockIndex> operator()() {
    constexpr int kStart = 4;  // tiles per side of the first rectangles
    for (int ty = 0; ty < tiles_.tilesY(); ty += kStart) {
      for (int tx = 0; tx < tiles_.tilesX(); tx += kStart) {
        cover(tx, ty, std::min(tx + kStart, tiles_.tilesX()) - 1,
              std::min(ty + kStart, tiles_.tilesY()) - 1);
      }
    }
    std::sort(blocks_.begin(), blocks_.end(), indexLess);
    blocks_.erase(std::unique(blocks_.begin(), blocks_.end()), blocks_.end());
    return std::move(blocks_);
  }

 private:
  // Returns spreading deeper than this many voxels split a rectangle.
  static constexpr double kMaxSpreadVoxels = 8;

  // Tiles tx0..tx1 x ty0..ty1, inclusive.
  void cover(int tx0, int ty0, int tx1, int ty1) {
    const DepthTiles::Bounds b = tiles_.bounds(tx0, ty0, tx1, ty1);
    if (!(b.nearest <= b.farthest)) return;  // no return in range
    if (b.farthest - b.nearest > max_spread_ && (tx0 < tx1 || ty0 < ty1)) {
      const int xm = (tx0 + tx1) / 2;
      const int ym = (ty0 + ty1) / 2;
      cover(tx0, ty0, xm, ym);
      if (xm < tx1) cover(xm + 1, ty0, tx1, ym);
      if (ym < ty1) cover(tx0, ym + 1, xm, ty1);
      if (xm < tx1 && ym < ty1) cover(xm + 1, ym + 1, tx1, ty1);
      return;
    }
    const double near = std::max(b.nearest - front_, 0.0);
    const double far = b.farthest + behind_;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf);
    Eigen::Vector3d hi = -lo;
    for (const int ty : {ty0, ty1 + 1}) {
      for (const int tx : {tx0, tx1 + 1}) {
        const Eigen::Vector3d& ray = rays_[static_cast<size_t>(ty) * (tiles_.tilesX() + 1) + tx];
        for (const double z : {near, far}) {
          const Eigen::Vector3d p = world_T_camera_.position + z * ray;
          lo = lo.cwiseMin(p);
          hi = hi.cwiseMax(p);
        }
      }
    }
    const double margin = layer_.voxelSize();
    const BlockIndex first = layer_.blockIndex((lo.array() - margin).matrix());
    const BlockIndex last = layer_.blockIndex((hi.array() + margin).matrix());
    if (first == last_first_ && last == last_last_) return;  // as the rectangle before
    last_first_ = first;
    last_last_ = last;
    for (int z = first.z(); z <= last.z(); ++z) {
      for (int y = first.y(); y <= last.y(); ++y) {
        for (int x = first.x(); x <= last.x(); ++x) blocks_.emplace_back(x, y, z);
      }
    }
  }

  const DepthTiles& tiles_;
  const Pose& world_T_camera_;
  const TsdfLayer& layer_;
  double front_;                       // how far in front of a return the frame updates [m]
  double behind_;                      // how far behind a return the frame may update [m]
  double max_spread_;                  // [m] of optical z
  std::vector<Eigen::Vector3d> rays_;  // (tilesX + 1) x (tilesY + 1)
  std::vector<BlockIndex> blocks_;
  BlockIndex last_first_ = BlockIndex::Constant(std::numeric_limits<int>::min());
  BlockIndex last_last_ = last_first_;
};

// Each voxel of a block's row: the row and column of its pixel, and which voxels have one.
struct RowPixels {
  std::array<int, kVoxelsPerSide> rows;
  std::array<int, kVoxelsPerSide> columns;
  uint32_t seen = 0;  // bit i: voxel i has a pixel
};

// Projects the kVoxelsPerSide voxels of a block's row, from its first voxel `line` in the camera
// frame one step apart, to their pixels: the nearest pixel of each (its integer coordinates plus
// one half) where the voxel is in front of the camera, no deeper than max_depth and in the image.
// Branch-free, so that the compiler vectorizes it; on x86-64 cloned for AVX2 and AVX-512 (picked
// at load time), where the same operations give the same bits four and eight lanes at a time (the
// build keeps -ffp-contract=off, so no clone fuses a multiply and an add).
#if defined(__x86_64__)
#define THICKET_VECTOR_CLONES gnu::target_clones("avx512f", "avx2", "default"),
#else
#define THICKET_VECTOR_CLONES
#endif
struct RowProjection {
  double step[3];
  double fx, fy, column_offset, row_offset, width, height;

  void project(const Eigen::Vector3d& line, double max_depth, RowPixels& out) const {
    projectRow(this, line.x(), line.y(), line.z(), max_depth, out);
  }

  [[THICKET_VECTOR_CLONES gnu::noinline]] static void projectRow(const RowProjection* c, double lx,
                                                                 double ly, double lz,
                                                                 double max_depth, RowPixels& out) {
    std::array<int, kVoxelsPerSide> seen_at;
    for (int i = 0; i < kVoxelsPerSide; ++i) {
      const double x = lx + i * c->step[0];
      const double y = ly + i * c->step[1];
      const double z = lz + i * c->step[2];
      const double inverse_z = 1.0 / z;
      const double column = c->fx * x * inverse_z + c->column_offset;
      const double row = c->fy * y * inverse_z + c->row_offset;
      const bool seen = (z > 0) & (z <= max_depth) & (column >= 0) & (column < c->width) &
                        (row >= 0) & (row < c->height);
      seen_at[i] = seen;
      out.rows[i] = static_cast<int>(seen ? row : 0.0);
      out.columns[i] = static_cast<int>(seen ? column : 0.0);
    }
    uint32_t mask = 0;
    for (int i = 0; i < kVoxelsPerSide; ++i) mask |= static_cast<uint32_t>(seen_at[i]) << i;
    out.seen = mask;
  }
};

TsdfIntegrationResult integrateProjective(const DepthImage& image, const Pose& world_T_camera,
                                          const TsdfIntegratorOptions& options,
                                          const VoxelUpdater& updater, TsdfLayer& layer) {
  const PinholeCamera& camera = image.camera;
  const Pose camera_T_world = world_T_camera.inverse();
  const PixelRays& rays = PixelRays::forCamera(image.camera);
  const std::vector<float> cosines = surfaceCosines(image, rays, options);
  const NewSurfaces shadow =
      newSurfacePixels(image, rays, world_T_camera, cosines, options, updater, layer);
  // No voxel beyond this is updated: surfaces end at the integration range, plus the truncation
  // behind them; the shadows of new surfaces reach new_surface_shadow deeper.
  const double max_depth =
      std::max(options.max_integration_range,
               shadow.pixels.empty() ? 0.0 : shadow.max_depth + updater.newSurfaceShadow()) +
      updater.truncation();
  const double deepest =
      updater.truncation() + (shadow.pixels.empty() ? 0.0 : updater.newSurfaceShadow());
  const Eigen::Matrix3d camera_R_world = camera_T_world.orientation.toRotationMatrix();
  const Eigen::Matrix3d steps = camera_R_world * layer.voxelSize();  // column a: one voxel along a
  const Eigen::Vector3d step = steps.col(0);
  // Pixel centres sit at integer coordinates, so the nearest pixel of a projection is its
  // integer part plus one half.
  const RowProjection projection{{step.x(), step.y(), step.z()},
                                 camera.fx,
                                 camera.fy,
                                 camera.cx + 0.5,
                                 camera.cy + 0.5,
                                 static_cast<double>(camera.width),
                                 static_cast<double>(camera.height)};

  TsdfIntegrationResult result;
  // New blocks are filled here first and allocated only if some voxel was updated.
  std::vector<TsdfVoxel> scratch(kVoxelsPerBlock);
  // The voxels of the block at hand to report, cleared after a block that had some.
  BlockVoxels reported;
  // Without carving: where the returns are, for the blocks to visit and how deep.
  std::optional<DepthTiles> tiles;
  if (!options.carve_free_space) tiles.emplace(image, options.max_integration_range);
  const std::vector<BlockIndex> blocks =
      tiles ? SurfaceBlocks(*tiles, camera, world_T_camera, options, updater, deepest, layer)()
            : frustumBlocks(camera, world_T_camera, camera_T_world, layer, max_depth);
  result.changed_blocks.reserve(blocks.size());
  result.changed_voxels.reserve(blocks.size());
  for (const BlockIndex& b : blocks) {
    TsdfLayer::BlockType* block = layer.block(b);
    TsdfVoxel* voxels = block ? block->voxels.data() : scratch.data();
    const Eigen::Vector3d first = camera_T_world.transform(layer.voxelCenter(voxelOfBlock(b, 0)));
    // Without carving, voxels deeper than the farthest return their pixels see, by more than any
    // update or shadow reaches, need no visit.
    double block_depth = max_depth;
    if (tiles) {
      std::array<Eigen::Vector3d, 8> corners;
      for (int c = 0; c < 8; ++c) {
        corners[c] =
            first + (kVoxelsPerSide - 1) * ((c & 1) * steps.col(0) + (c >> 1 & 1) * steps.col(1) +
                                            (c >> 2) * steps.col(2));
      }
      if (const auto seen = tiles->blockBounds(corners)) {
        // A hair deeper, so that rounding cannot drop a voxel the exact test would keep.
        block_depth = std::min(block_depth, seen->farthest + deepest + 1e-6 * layer.voxelSize());
      }
      if (!(block_depth > 0)) continue;  // no return in view: nothing to update
    }
    int64_t updated = 0;
    Changes changes;
    bool any_reported = false;
    for (int k = 0; k < kVoxelsPerSide; ++k) {
      const Eigen::Vector3d slice = first + k * steps.col(2);
      for (int j = 0; j < kVoxelsPerSide; ++j) {
        const Eigen::Vector3d line = slice + j * steps.col(1);
        // A row behind the camera or beyond the block's depth bound at both ends is so
        // throughout (a voxel's z, computed as projectRow does, is monotonic along the row).
        const double z_last = line.z() + (kVoxelsPerSide - 1) * step.z();
        if ((line.z() > block_depth && z_last > block_depth) || (line.z() <= 0 && z_last <= 0)) {
          continue;
        }
        TsdfVoxel* row_voxels = voxels + kVoxelsPerSide * (j + kVoxelsPerSide * k);
        // First each voxel's pixel in a branch-free pass the compiler vectorizes, then the
        // updates of the voxels that have one.
        RowPixels pixels;
        projection.project(line, block_depth, pixels);
        unsigned row_reported = 0;
        for (uint32_t seen = pixels.seen; seen != 0; seen &= seen - 1) {
          const int i = std::countr_zero(seen);
          const size_t pixel =
              static_cast<size_t>(pixels.rows[i]) * camera.width + pixels.columns[i];
          const Eigen::Vector3d p = line + i * step;
          const double z = p.z();
          // Deeper behind its pixel's return than any update or shadow reaches (most voxels of
          // a block behind a surface): nothing to do.
          const double depth = image.depth[pixel];
          if (depth > 0 && depth <= image.max_range && depth - z <= -deepest) continue;
          const PixelMeasurement m = measurePixel(depth, 1.0, image, options.max_integration_range,
                                                  options.carve_free_space);
          if (m.weight == 0 || z > m.max_voxel) continue;
          // The optical-z difference as a distance along the line of sight (|p| / z), then
          // along the surface normal.
          const double to_surface =
              options.normal_distances ? p.norm() * (1.0 / z) * alongNormal(cosines[pixel]) : 1.0;
          const double sdf = towardSurface(m.distance - z, to_surface);
          // The stale free space behind a new surface goes first, so that what the frame
          // measures there is all the voxel holds.
          changes.voxel = false;
          const bool reset = shadow.at(pixel) && updater.clearShadow(row_voxels[i], sdf, changes);
          if (updater.update(row_voxels[i], sdf, m.weight, changes) || reset) ++updated;
          row_reported |= static_cast<unsigned>(changes.voxel) << i;
        }
        if (row_reported != 0) {
          reported.rows[j + kVoxelsPerSide * k] = static_cast<uint16_t>(row_reported);
          any_reported = true;
        }
      }
    }
    if (updated == 0) continue;
    if (!block) {
      std::copy(scratch.begin(), scratch.end(), layer.allocateBlock(b).voxels.begin());
      std::fill(scratch.begin(), scratch.end(), TsdfVoxel{});
    }
    result.voxels_updated += updated;
    if (changes.block) {
      result.changed_blocks.push_back(b);
      result.changed_voxels.push_back(reported);
    }
    if (any_reported) reported = BlockVoxels{};
  }
  result.observed_weight = updater.observedWeight();
  return result;
}

// One axis of an Amanatides-Woo voxel walk along a ray from the origin.
struct AxisWalk {
  int voxel;           // the current voxel's coordinate
  int step;            // +1 or -1
  double t_next;       // range at which the ray crosses into the next voxel along this axis
  double t_delta;      // range between two such crossings
  double center_step;  // how far a step moves the voxel centre's distance along the ray

  AxisWalk(int origin_voxel, double origin_in_voxels, double dir, double voxel_size)
      : voxel(origin_voxel),
        step(dir > 0 ? 1 : -1),
        t_next(kInf),
        t_delta(kInf),
        center_step(voxel_size * std::abs(dir)) {
    if (dir != 0) {
      const double boundary = origin_voxel + (dir > 0 ? 1 : 0);
      t_next = (boundary - origin_in_voxels) * voxel_size / dir;
      t_delta = voxel_size / std::abs(dir);
    }
  }
};

TsdfIntegrationResult integrateRaycast(const DepthImage& image, const Pose& world_T_camera,
                                       const TsdfIntegratorOptions& options,
                                       const VoxelUpdater& updater, TsdfLayer& layer) {
  const PixelRays& rays = PixelRays::forCamera(image.camera);
  const std::vector<PixelMeasurement> pixels = measurePixelsAlongRays(image, rays, options);
  const std::vector<float> cosines = surfaceCosines(image, rays, options);
  const NewSurfaces shadow =
      newSurfacePixels(image, rays, world_T_camera, cosines, options, updater, layer);
  const double voxel_size = layer.voxelSize();
  const Eigen::Vector3d& origin = world_T_camera.position;
  const Eigen::Vector3d origin_voxels = origin / voxel_size;
  const VoxelIndex origin_voxel = layer.voxelIndex(origin);
  const Eigen::Vector3d origin_center_offset = layer.voxelCenter(origin_voxel) - origin;

  TsdfIntegrationResult result;
  // Rays cross few blocks, and neighbouring rays the same ones: a block is looked up only when a
  // ray enters it. changed lists each changed block once, with its reported voxels.
  std::unordered_map<BlockIndex, BlockVoxels, IndexHash> changed;
  BlockIndex cached_index = blockOfVoxel(origin_voxel);
  TsdfLayer::BlockType* cached = layer.block(cached_index);
  BlockVoxels* cached_changed = nullptr;
  // Walks the pixel's ray from the camera up to range t_end: visit(block, linear index, sdf) at
  // every voxel, block null where none is allocated; visit allocates one when it must, and
  // returns what it changed.
  const auto walk = [&](size_t pixel, double t_end, auto&& visit) {
    const PixelMeasurement& m = pixels[pixel];
    const Eigen::Vector3d dir = world_T_camera.orientation * rays.unit(pixel);
    AxisWalk x(origin_voxel.x(), origin_voxels.x(), dir.x(), voxel_size);
    AxisWalk y(origin_voxel.y(), origin_voxels.y(), dir.y(), voxel_size);
    AxisWalk z(origin_voxel.z(), origin_voxels.z(), dir.z(), voxel_size);
    double center_along_ray = origin_center_offset.dot(dir);
    while (true) {
      const BlockIndex b(x.voxel >> 4, y.voxel >> 4, z.voxel >> 4);
      if (b != cached_index) {
        cached_index = b;
        cached = layer.block(b);
        const auto found = changed.find(b);
        cached_changed = found != changed.end() ? &found->second : nullptr;
      }
      const double sdf =
          towardSurface(m.distance - center_along_ray,
                        options.normal_distances ? alongNormal(cosines[pixel]) : 1.0);
      const int linear = (x.voxel & 15) + 16 * (y.voxel & 15) + 256 * (z.voxel & 15);
      const Changes changes = visit(b, linear, sdf);
      if (changes.block) {
        if (!cached_changed) cached_changed = &changed[b];
        if (changes.voxel) cached_changed->insert(linear);
      }
      AxisWalk& next =
          x.t_next <= y.t_next ? (x.t_next <= z.t_next ? x : z) : (y.t_next <= z.t_next ? y : z);
      if (next.t_next > t_end) break;
      next.voxel += next.step;
      next.t_next += next.t_delta;
      center_along_ray += next.center_step;
    }
  };
  // The shadows of new surfaces first: a voxel there that another ray of this frame sees is
  // then measured by it, not reset after it was.
  for (size_t pixel = 0; pixel < shadow.pixels.size(); ++pixel) {
    // A return within the range as optical z may lie beyond it along the ray, where the ray
    // caster integrates no surface.
    if (!shadow.pixels[pixel] || !std::isinf(pixels[pixel].max_voxel)) continue;
    const double t_end = pixels[pixel].distance + updater.truncation() + updater.newSurfaceShadow();
    walk(pixel, t_end, [&](const BlockIndex&, int linear, double sdf) {
      Changes changes;
      if (cached && updater.clearShadow(cached->voxels[linear], sdf, changes)) {
        ++result.voxels_updated;
      }
      return changes;
    });
  }
  for (size_t pixel = 0; pixel < pixels.size(); ++pixel) {
    const PixelMeasurement& m = pixels[pixel];
    if (m.weight == 0) continue;
    const double t_end = std::min(m.distance + updater.truncation(), m.max_voxel);
    walk(pixel, t_end, [&](const BlockIndex& b, int linear, double sdf) {
      Changes changes;
      if (sdf > -updater.truncation()) {
        if (!cached) cached = &layer.allocateBlock(b);
        updater.update(cached->voxels[linear], sdf, m.weight, changes);
        ++result.voxels_updated;
      }
      return changes;
    });
  }
  std::vector<std::pair<BlockIndex, BlockVoxels>> sorted(changed.begin(), changed.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return indexLess(a.first, b.first); });
  for (const auto& [b, voxels] : sorted) {
    result.changed_blocks.push_back(b);
    result.changed_voxels.push_back(voxels);
  }
  result.observed_weight = updater.observedWeight();
  return result;
}

}  // namespace

void TsdfIntegratorOptions::declare(Params& p) {
  std::string name = method == Method::kRaycast ? "raycast" : "projective";
  p.choice("method", name, {"projective", "raycast"},
           "projective: project voxels into the image (fast); raycast: walk each pixel's ray");
  method = name == "raycast" ? Method::kRaycast : Method::kProjective;
  p("truncation_voxels", truncation_voxels, "truncation distance [voxels]", Range::positive());
  p("max_integration_range", max_integration_range,
    "no surface is integrated and no space cleared beyond this [m]", Range::positive());
  p("max_weight", max_weight, "voxel weights saturate here, so the map can still change",
    Range::positive());
  p("carve_free_space", carve_free_space,
    "update every voxel the camera sees up to the integration range, pixels without a return "
    "clearing their line of sight; off: only blocks near returns (projective method only)");
  p("normal_distances", normal_distances,
    "store distances along the surface normal, not the line of sight");
  p("new_surfaces_replace", new_surfaces_replace,
    "a return within a voxel of a voxel the map had as clearly free (beyond half the "
    "truncation) replaces its history instead of being averaged in");
  p("new_surface_shadow", new_surface_shadow,
    "behind a return in a voxel the map had as clearly free, the free space this much deeper than "
    "the truncation becomes unobserved, being stale; 0: off [m]",
    Range::atLeast(0));
}

TsdfIntegrator::TsdfIntegrator(TsdfIntegratorOptions options) : options_(options) {
  if (options_.method != Method::kProjective && options_.method != Method::kRaycast) {
    throw std::invalid_argument("TsdfIntegrator: unknown method");
  }
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("TsdfIntegrator: " + error);
  }
  if (!(options_.observed_weight > 0 && std::isfinite(options_.observed_weight))) {
    throw std::invalid_argument("TsdfIntegrator: observed_weight must be positive and finite");
  }
  if (!options_.carve_free_space && options_.method == Method::kRaycast) {
    throw std::invalid_argument(
        "TsdfIntegrator: carve_free_space false needs the projective method");
  }
}

TsdfIntegrationResult TsdfIntegrator::integrate(const DepthImage& image, const Pose& world_T_camera,
                                                TsdfLayer& layer) const {
  validate(image, world_T_camera);
  checkDepths(image);
  const Pose pose{world_T_camera.position, world_T_camera.orientation.normalized()};
  const VoxelUpdater updater(layer.voxelSize(), options_.truncation_voxels * layer.voxelSize(),
                             options_.max_weight, options_.new_surfaces_replace,
                             options_.new_surface_shadow,
                             static_cast<float>(options_.observed_weight));
  return options_.method == Method::kProjective
             ? integrateProjective(image, pose, options_, updater, layer)
             : integrateRaycast(image, pose, options_, updater, layer);
}

}  // namespace thicket::mapper

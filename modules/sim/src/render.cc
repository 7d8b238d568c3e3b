#include "thicket/sim/render.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace thicket::sim {
namespace {

using Surface = SurfaceHit::Surface;
using std::numbers::pi;

// Azimuth bins of a RayCaster::View. A bin spans 0.11-0.22° (see pseudoAngle), a seventh of a
// 0.1 m trunk 15 m away, so a ray's bin holds few cylinders that its own azimuth would not.
constexpr int kAzimuthBins = 2048;

// A ray, with the squared length of its direction's xy part that every cylinder test needs.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d dir;
  double xy_sq;
};

Ray makeRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& unit_dir) {
  return {origin, unit_dir, unit_dir.x() * unit_dir.x() + unit_dir.y() * unit_dir.y()};
}

// The nearest hit offered so far.
struct Nearest {
  double t = RayCaster::kNoHit;
  Surface surface = Surface::kNone;
  int index = -1;

  void offer(double t_hit, Surface hit_surface, int hit_index) {
    if (t_hit < t) {
      t = t_hit;
      surface = hit_surface;
      index = hit_index;
    }
  }
};

// Whether p is within the walls (in x and y) and above the ground: then the walls form a convex
// box around it, and a ray meets the one it leaves the box through, if any.
bool insideWalls(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& p) {
  return p.x() >= lo.x() && p.x() <= hi.x() && p.y() >= lo.y() && p.y() <= hi.y() &&
         p.z() >= lo.z();
}

// Whether a ray from p can meet a wall within max_range; false only inside the walls farther
// than max_range from all four.
bool wallsInRange(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& p,
                  double max_range) {
  return !insideWalls(lo, hi, p) ||
         std::min({p.x() - lo.x(), hi.x() - p.x(), p.y() - lo.y(), hi.y() - p.y()}) <= max_range;
}

// The ground plane, and the walls when walls_in_range (see above). from_inside: the ray starts
// inside the walls (see insideWalls).
inline void intersectBoundary(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                              bool from_inside, bool walls_in_range, const Ray& ray,
                              Nearest& best) {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.dir;
  if (d.z() < 0) best.offer((lo.z() - o.z()) / d.z(), Surface::kGround, -1);
  if (!walls_in_range) return;
  if (from_inside) {
    // Where the ray leaves the box in x and in y: +inf when parallel, because the sign bit
    // picks the wall ahead, so the numerator has the sign of the (possibly zero) denominator.
    // It meets the wall it leaves through unless it passes over it (or under: then the ground
    // is nearer).
    const bool ahead_x = !std::signbit(d.x());
    const bool ahead_y = !std::signbit(d.y());
    const double t_x = ((ahead_x ? hi.x() : lo.x()) - o.x()) / d.x();
    const double t_y = ((ahead_y ? hi.y() : lo.y()) - o.y()) / d.y();
    const bool through_x = t_x <= t_y;
    const double t = through_x ? t_x : t_y;
    if (o.z() + t * d.z() <= hi.z()) {
      best.offer(t, Surface::kWall, through_x ? (ahead_x ? 1 : 0) : (ahead_y ? 3 : 2));
    }
    return;
  }
  for (int axis = 0; axis < 2; ++axis) {
    const int other = 1 - axis;
    for (int side = 0; side < 2; ++side) {
      const double t = ((side == 0 ? lo[axis] : hi[axis]) - o[axis]) / d[axis];
      const double q = o[other] + t * d[other];
      const double z = o.z() + t * d.z();
      if (t >= 0 && q >= lo[other] && q <= hi[other] && z >= lo.z() && z <= hi.z()) {
        best.offer(t, Surface::kWall, 2 * axis + side);
      }
    }
  }
}

// A solid vertical cylinder from z = 0 to height, for a ray that does not start inside it. The
// side test computes the root whether or not there is one and masks the result (NaN and infinite
// intermediates compare false) instead of branching: View::cast interleaves rays, and the CPU
// overlaps their square roots and divisions only as long as it does not mispredict.
inline void intersectCylinder(double x, double y, double radius_sq, double height, int index,
                              const Ray& ray, Nearest& best) {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.dir;
  const double px = o.x() - x;
  const double py = o.y() - y;
  // The side: the ray is inside the footprint where xy_sq t^2 + 2 b t + outside <= 0. It enters
  // from outside (outside > 0) while approaching the axis (b < 0) at the smaller root, written
  // in the form that stays exact for steep rays (xy_sq -> 0) and grazing ones. Entering below
  // z = 0 means passing under the base, i.e. through the ground.
  const double outside = px * px + py * py - radius_sq;
  const double b = px * d.x() + py * d.y();
  const double discriminant = b * b - ray.xy_sq * outside;
  const double t_side = outside / (std::sqrt(discriminant > 0 ? discriminant : 0.0) - b);
  const double z_side = o.z() + t_side * d.z();
  const bool side =
      (outside > 0) & (b < 0) & (discriminant >= 0) & (z_side >= 0) & (z_side <= height);
  if (side) best.offer(t_side, Surface::kCylinderSide, index);
  // The cap, from above only (below it is inside the solid). When the side is hit, the ray
  // crossed the cap's plane outside the footprint, so at most one of the two tests passes. The
  // branch is predictable: it depends on the eye being above the top, rarely on the ray.
  if (d.z() < 0 && o.z() > height) {
    const double t_cap = (height - o.z()) / d.z();
    const double qx = px + t_cap * d.x();
    const double qy = py + t_cap * d.y();
    if (qx * qx + qy * qy <= radius_sq) best.offer(t_cap, Surface::kCylinderCap, index);
  }
}

inline double report(const Nearest& best, const Ray& ray, double max_range, SurfaceHit* hit) {
  const bool found = best.t <= max_range;
  if (hit) {
    *hit =
        found ? SurfaceHit{best.surface, best.index, ray.origin + best.t * ray.dir} : SurfaceHit{};
  }
  return found ? best.t : RayCaster::kNoHit;
}

void checkMaxRange(double max_range, const char* caller) {
  if (!(max_range >= 0)) {
    throw std::invalid_argument(std::string(caller) + ": max_range must be >= 0");
  }
}

// A cheap stand-in for atan2(y, x) that increases with it: [0, 4) over a turn from +x, one unit
// per quadrant. Undefined at (0, 0).
double pseudoAngle(double x, double y) {
  if (y >= 0) return x >= 0 ? y / (x + y) : 1 - x / (y - x);
  return x < 0 ? 2 + y / (x + y) : 3 + x / (x - y);
}

int azimuthBin(double pseudo_angle) {
  return std::min(static_cast<int>(pseudo_angle * (kAzimuthBins / 4.0)), kAzimuthBins - 1);
}

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

// --- The stereo texture ---------------------------------------------------------------------

// The texture is one periodic tile of value noise that every surface shows at its own offset:
// 2^kTileBits texels of 1 / kTexelsPerMetre square (10.24 m), the sum of seven octaves whose
// lattice cells measure 2 texels (2 cm) up to 128 texels (1.28 m). Coarse octaves vary the
// brightness of a surface, fine ones give the pixel-scale detail a matcher needs. Box-filtered mip
// levels, sampled trilinearly as a GPU does, low-pass it to a pixel's footprint: eight texel reads
// per pixel, near each other for neighbouring pixels. The tile repeats every 10.24 m on a surface,
// at least 36 times the disparity at any range (fx * 10.24 m / z against fx * 0.11 m / z), so a
// matcher never confuses a point with its repeat.
constexpr int kTileBits = 10;
constexpr int kTileTexels = 1 << kTileBits;
constexpr double kTexelsPerMetre = 100;
constexpr int kOctaves = 7;
constexpr int kLevels = kTileBits + 1;  // 1024 x 1024 texels down to 1 x 1
// Texel coordinates are shifted by this multiple of the tile at every level, so that they are
// positive for surfaces within 160 km of the origin and truncation floors them.
constexpr double kTexelShift = 1 << 24;
// Gray levels per unit of noise: a forest image has a standard deviation of about 30 gray
// levels, and under 0.1 % of its pixels saturate.
constexpr double kContrast = 60;
// Grazing views stretch a pixel's footprint by 1 / cos(incidence), capped at 1 / this.
constexpr double kMinCosIncidence = 0.05;

inline uint32_t hash32(uint32_t h) {  // "lowbias32" (C. Wellons): an avalanching 32-bit mix
  h ^= h >> 16;
  h *= 0x7feb352dU;
  h ^= h >> 15;
  h *= 0x846ca68bU;
  h ^= h >> 16;
  return h;
}

inline double smoothStep(double t) {
  return t * t * (3.0 - 2.0 * t);
}

class TextureTile {
 public:
  static const TextureTile& instance() {
    static const TextureTile tile;
    return tile;
  }

  // The noise (mean about 0, within +-3.5) around level-0 texel coordinates (x, y), filtered to
  // a footprint of footprint_texels: level log2(footprint_texels), linearly between levels.
  double sample(double x, double y, double footprint_texels) const {
    x += kTexelShift;
    y += kTexelShift;
    if (!(footprint_texels > 1)) return bilinear(0, x, y);
    // log2 by the exponent and a linear mantissa: exact at powers of two, monotonic between.
    const uint64_t bits = std::bit_cast<uint64_t>(footprint_texels);
    const int level = static_cast<int>(bits >> 52) - 1023;
    if (level >= kLevels - 1) return bilinear(kLevels - 1, x, y);
    const double blend = static_cast<double>(bits & ((uint64_t{1} << 52) - 1)) * 0x1.0p-52;
    const double fine = bilinear(level, x, y);
    return fine + blend * (bilinear(level + 1, x, y) - fine);
  }

 private:
  TextureTile() {
    std::vector<float>& base = levels_[0];
    base.assign(size_t{1} << (2 * kTileBits), 0.0f);
    std::vector<double> lattice;
    for (int octave = 0; octave < kOctaves; ++octave) {
      const int cell = 2 << octave;  // texels
      const int cells = kTileTexels / cell;
      lattice.resize(static_cast<size_t>(cells) * cells);
      for (int cy = 0; cy < cells; ++cy) {
        for (int cx = 0; cx < cells; ++cx) {
          const uint32_t key = static_cast<uint32_t>((octave << 20) | (cy << 10) | cx);
          lattice[static_cast<size_t>(cy) * cells + cx] = hash32(key) * 0x1.0p-32 - 0.5;
        }
      }
      const auto at = [&](int cx, int cy) {
        return lattice[static_cast<size_t>(cy % cells) * cells + cx % cells];
      };
      for (int y = 0; y < kTileTexels; ++y) {
        const double fy = (y + 0.5) / cell;
        const int cy = static_cast<int>(fy);
        const double ty = smoothStep(fy - cy);
        for (int x = 0; x < kTileTexels; ++x) {
          const double fx = (x + 0.5) / cell;
          const int cx = static_cast<int>(fx);
          const double tx = smoothStep(fx - cx);
          const double bottom = at(cx, cy) + tx * (at(cx + 1, cy) - at(cx, cy));
          const double top = at(cx, cy + 1) + tx * (at(cx + 1, cy + 1) - at(cx, cy + 1));
          base[texelIndex(kTileBits, x, y)] += static_cast<float>(bottom + ty * (top - bottom));
        }
      }
    }
    for (int level = 1; level < kLevels; ++level) {
      const std::vector<float>& fine = levels_[level - 1];
      const int size = kTileTexels >> level;
      std::vector<float>& coarse = levels_[level];
      coarse.resize(static_cast<size_t>(size) * size);
      const int fine_bits = kTileBits - level + 1;
      for (uint32_t y = 0; y < static_cast<uint32_t>(size); ++y) {
        for (uint32_t x = 0; x < static_cast<uint32_t>(size); ++x) {
          coarse[texelIndex(fine_bits - 1, x, y)] =
              0.25f * (fine[texelIndex(fine_bits, 2 * x, 2 * y)] +
                       fine[texelIndex(fine_bits, 2 * x + 1, 2 * y)] +
                       fine[texelIndex(fine_bits, 2 * x, 2 * y + 1)] +
                       fine[texelIndex(fine_bits, 2 * x + 1, 2 * y + 1)]);
        }
      }
    }
  }

  // Where texel (x, y) of a level 2^bits texels square is stored: in blocks of 4 x 4 texels,
  // one cache line of floats, so that walking the texture along a row or a column (an image
  // column may run either way on a surface) reads a new line every four texels, not every one.
  static size_t texelIndex(int bits, uint32_t x, uint32_t y) {
    if (bits < 2) return (static_cast<size_t>(y) << bits) + x;
    const size_t block = (static_cast<size_t>(y >> 2) << (bits - 2)) + (x >> 2);
    return (block << 4) + ((y & 3) << 2) + (x & 3);
  }

  // Bilinear between the texel centres of a level, at shifted level-0 coordinates.
  [[gnu::always_inline]] double bilinear(int level, double x, double y) const {
    const int bits = kTileBits - level;
    const uint32_t mask = (uint32_t{1} << bits) - 1;
    const double scale = kLevelScale[level];
    const double lx = x * scale - 0.5;
    const double ly = y * scale - 0.5;
    const int64_t x0 = static_cast<int64_t>(lx);
    const int64_t y0 = static_cast<int64_t>(ly);
    const double tx = lx - static_cast<double>(x0);
    const double ty = ly - static_cast<double>(y0);
    const uint32_t col0 = static_cast<uint32_t>(x0) & mask;
    const uint32_t col1 = (col0 + 1) & mask;
    const uint32_t row0 = static_cast<uint32_t>(y0) & mask;
    const uint32_t row1 = (row0 + 1) & mask;
    const float* t = levels_[level].data();
    const double t00 = t[texelIndex(bits, col0, row0)];
    const double t10 = t[texelIndex(bits, col1, row0)];
    const double t01 = t[texelIndex(bits, col0, row1)];
    const double t11 = t[texelIndex(bits, col1, row1)];
    const double bottom = t00 + tx * (t10 - t00);
    const double top = t01 + tx * (t11 - t01);
    return bottom + ty * (top - bottom);
  }

  static constexpr std::array<double, kLevels> kLevelScale = [] {
    std::array<double, kLevels> scale{};
    for (int level = 0; level < kLevels; ++level) scale[level] = 1.0 / (1 << level);
    return scale;
  }();

  std::array<std::vector<float>, kLevels> levels_;
};

// A surface point in texture space: level-0 texel coordinates in the tile (surface coordinates
// plus the surface's own offset) and the surface's mean gray level.
struct TexturePoint {
  double x = 0, y = 0;
  double mean = 0;
};

// Surfaces of one kind share a mean gray level; each surface has its own offset in the tile, and
// each cylinder a mean offset of up to +-20 gray levels, so that neighbouring trees differ.
TexturePoint texturePoint(const SurfaceHit& hit, const std::vector<Cylinder>& cylinders) {
  const Eigen::Vector3d& p = hit.point;
  const uint32_t seed =
      hash32((static_cast<uint32_t>(hit.surface) << 24) ^ static_cast<uint32_t>(hit.index));
  const double mean_offset = (seed >> 24) * (40.0 / 255.0) - 20.0;
  const auto point = [seed](double s, double w, double mean) {
    return TexturePoint{s * kTexelsPerMetre + (seed & (kTileTexels - 1)),
                        w * kTexelsPerMetre + ((seed >> kTileBits) & (kTileTexels - 1)), mean};
  };
  switch (hit.surface) {
    case Surface::kGround:
      return point(p.x(), p.y(), 105);
    case Surface::kWall:
      return point(hit.index < 2 ? p.y() : p.x(), p.z(), 150);
    case Surface::kCylinderCap:
      return point(p.x(), p.y(), 140 + mean_offset);
    case Surface::kCylinderSide: {
      // Around the trunk: pseudoAngle scaled to the circumference, 0.79-1.57 times the arc
      // length and much cheaper than atan2. The texture has a seam where it wraps (on the +x
      // side), like a crack in the bark: both cameras see it alike.
      const Cylinder& c = cylinders[hit.index];
      const double dx = p.x() - c.x;
      const double dy = p.y() - c.y;
      const double quarter_turns = (dx == 0 && dy == 0) ? 0 : pseudoAngle(dx, dy);
      return point(quarter_turns * (0.5 * pi * c.radius), p.z(), 85 + mean_offset);
    }
    case Surface::kNone:
      break;
  }
  throw std::invalid_argument("surfaceIntensity: the hit has no surface");
}

Eigen::Vector3d surfaceNormal(const SurfaceHit& hit, const std::vector<Cylinder>& cylinders) {
  switch (hit.surface) {
    case Surface::kWall:
      return hit.index < 2 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    case Surface::kCylinderSide: {
      const Cylinder& c = cylinders[hit.index];
      return Eigen::Vector3d(hit.point.x() - c.x, hit.point.y() - c.y, 0) / c.radius;
    }
    default:
      return Eigen::Vector3d::UnitZ();
  }
}

void writeMatrix(std::ostream& out, const std::string& name, int rows, int cols,
                 const std::vector<double>& row_major) {
  out << name << ": !!opencv-matrix\n   rows: " << rows << "\n   cols: " << cols
      << "\n   dt: d\n   data: [ ";
  for (size_t i = 0; i < row_major.size(); ++i) {
    char number[32];
    std::snprintf(number, sizeof(number), "%.16e", row_major[i]);  // as cv::FileStorage writes
    out << (i > 0 ? ", " : "") << number;
  }
  out << " ]\n";
}

}  // namespace

// --- RayCaster --------------------------------------------------------------------------------

RayCaster::RayCaster(const World& world)
    : bounds_min_(world.bounds_min), bounds_max_(world.bounds_max), cylinders_(world.cylinders) {}

SurfaceHit RayCaster::containingSolid(const Eigen::Vector3d& p) const {
  if (p.z() < bounds_min_.z()) return {Surface::kGround, -1, p};
  for (size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder& c = cylinders_[i];
    const double dx = p.x() - c.x;
    const double dy = p.y() - c.y;
    if (p.z() >= 0 && p.z() <= c.height && dx * dx + dy * dy <= c.radius * c.radius) {
      return {Surface::kCylinderSide, static_cast<int>(i), p};
    }
  }
  return {};
}

double RayCaster::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& unit_dir,
                       double max_range, SurfaceHit* hit) const {
  checkMaxRange(max_range, "RayCaster::cast");
  if (const SurfaceHit solid = containingSolid(origin); solid.surface != Surface::kNone) {
    if (hit) *hit = solid;
    return 0;
  }
  const Ray ray = makeRay(origin, unit_dir);
  Nearest best;
  intersectBoundary(bounds_min_, bounds_max_, insideWalls(bounds_min_, bounds_max_, origin),
                    wallsInRange(bounds_min_, bounds_max_, origin, max_range), ray, best);
  for (size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder& c = cylinders_[i];
    intersectCylinder(c.x, c.y, c.radius * c.radius, c.height, static_cast<int>(i), ray, best);
  }
  return report(best, ray, max_range, hit);
}

RayCaster::View RayCaster::view(const Eigen::Vector3d& eye, double max_range) const {
  checkMaxRange(max_range, "RayCaster::view");
  View view;
  view.eye_ = eye;
  view.max_range_ = max_range;
  view.bounds_min_ = bounds_min_;
  view.bounds_max_ = bounds_max_;
  view.eye_inside_walls_ = insideWalls(bounds_min_, bounds_max_, eye);
  view.walls_in_range_ = wallsInRange(bounds_min_, bounds_max_, eye, max_range);
  view.containing_solid_ = containingSolid(eye);
  if (view.containing_solid_.surface != Surface::kNone) return view;

  // A cylinder can only be hit by rays whose azimuth lies between its two tangents from the eye
  // (for any elevation, since it is vertical), after travelling at least its xy distance minus
  // its radius in xy. Radii are padded so that rounding in the tangents or in a ray's azimuth
  // can only add candidates, never lose one.
  struct Span {
    View::Candidate candidate;
    int first_bin, last_bin;  // counter-clockwise, wrapping from the last bin to bin 0
  };
  std::vector<Span> spans;
  spans.reserve(cylinders_.size());
  view.solids_.reserve(cylinders_.size());
  for (size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder& c = cylinders_[i];
    view.solids_.push_back({c.x, c.y, c.radius * c.radius, c.height});
    const double dx = c.x - eye.x();
    const double dy = c.y - eye.y();
    const double distance = std::sqrt(dx * dx + dy * dy);
    const double padded_radius = c.radius * (1 + 1e-9) + 1e-9 * (1 + distance);
    if (distance <= padded_radius) {
      view.around_eye_.push_back(static_cast<int>(i));
      continue;
    }
    const double min_xy_travel = distance - padded_radius;
    if (min_xy_travel > max_range) continue;  // xy travel never exceeds the range
    float min_xy_travel_float = static_cast<float>(min_xy_travel);
    if (min_xy_travel_float > min_xy_travel) {
      min_xy_travel_float = std::nextafter(min_xy_travel_float, 0.0f);
    }
    const double ux = dx / distance;
    const double uy = dy / distance;
    const double sin_half = padded_radius / distance;
    const double cos_half = std::sqrt(1 - sin_half * sin_half);
    spans.push_back(
        {{min_xy_travel_float, static_cast<int>(i)},
         azimuthBin(pseudoAngle(cos_half * ux + sin_half * uy, cos_half * uy - sin_half * ux)),
         azimuthBin(pseudoAngle(cos_half * ux - sin_half * uy, cos_half * uy + sin_half * ux))});
  }
  // Filled nearest first, every bin comes out ordered by min_xy_travel.
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) {
    return a.candidate.min_xy_travel != b.candidate.min_xy_travel
               ? a.candidate.min_xy_travel < b.candidate.min_xy_travel
               : a.candidate.index < b.candidate.index;
  });
  const auto forEachBin = [](const Span& span, auto&& fn) {
    const bool wraps = span.first_bin > span.last_bin;
    for (int b = span.first_bin; b <= (wraps ? kAzimuthBins - 1 : span.last_bin); ++b) fn(b);
    if (wraps) {
      for (int b = 0; b <= span.last_bin; ++b) fn(b);
    }
  };
  view.bin_begin_.assign(kAzimuthBins + 1, 0);
  for (const Span& span : spans) forEachBin(span, [&](int b) { ++view.bin_begin_[b + 1]; });
  for (int b = 0; b < kAzimuthBins; ++b) view.bin_begin_[b + 1] += view.bin_begin_[b];
  view.candidates_.resize(view.bin_begin_.back());
  std::vector<uint32_t> next(view.bin_begin_.begin(), view.bin_begin_.end() - 1);
  for (const Span& span : spans) {
    forEachBin(span, [&](int b) { view.candidates_[next[b]++] = span.candidate; });
  }
  view.candidates_.push_back({std::numeric_limits<float>::infinity(), -1});  // the sentinel
  return view;
}

double RayCaster::View::cast(const Eigen::Vector3d& unit_dir, SurfaceHit* hit) const {
  double range;
  cast(std::span(&unit_dir, 1), std::span(&range, 1),
       hit ? std::span(hit, 1) : std::span<SurfaceHit>());
  return range;
}

bool RayCaster::View::startCasting(const char* caller, size_t rays, std::span<double> ranges,
                                   std::span<SurfaceHit> hits) const {
  if (ranges.size() != rays || !(hits.empty() || hits.size() == rays)) {
    throw std::invalid_argument(std::string(caller) + ": sizes of rays and results differ");
  }
  if (containing_solid_.surface == Surface::kNone) return true;
  std::fill(ranges.begin(), ranges.end(), 0.0);
  std::fill(hits.begin(), hits.end(), containing_solid_);
  return false;
}

void RayCaster::View::cast(std::span<const Eigen::Vector3d> unit_dirs, std::span<double> ranges,
                           std::span<SurfaceHit> hits) const {
  if (!startCasting("RayCaster::View::cast", unit_dirs.size(), ranges, hits)) return;
  // Rays go through in batches. Each ray first meets the boundary and the cylinders around the
  // eye, then its azimuth bin's candidates one per round, nearest first, while the next one can
  // be nearer than its best hit. A round takes one candidate of every ray still going, so that
  // their tests are independent work that the CPU overlaps.
  constexpr size_t kBatch = 64;
  std::array<Ray, kBatch> rays;
  std::array<Nearest, kBatch> best;
  std::array<uint32_t, kBatch> next, end;
  std::array<int, kBatch> going;
  // Reads one candidate past the bin's end when it is done, which the sentinel that ends
  // candidates_ keeps in bounds, instead of branching.
  const auto nextIsReachable = [&](size_t i) {
    const double min_travel = candidates_[next[i]].min_xy_travel;
    const double limit = std::min(best[i].t, max_range_);
    return (next[i] < end[i]) & (min_travel * min_travel <= limit * limit * rays[i].xy_sq);
  };
  for (size_t first = 0; first < unit_dirs.size(); first += kBatch) {
    const size_t count = std::min(kBatch, unit_dirs.size() - first);
    int num_going = 0;
    for (size_t i = 0; i < count; ++i) {
      const Ray& ray = rays[i] = makeRay(eye_, unit_dirs[first + i]);
      best[i] = Nearest{};
      intersectBoundary(bounds_min_, bounds_max_, eye_inside_walls_, walls_in_range_, ray, best[i]);
      for (const int j : around_eye_) {
        const Solid& c = solids_[j];
        intersectCylinder(c.x, c.y, c.radius_sq, c.height, j, ray, best[i]);
      }
      // A ray with no xy part can only hit what stands around the eye.
      const int bin = ray.xy_sq > 0 ? azimuthBin(pseudoAngle(ray.dir.x(), ray.dir.y())) : 0;
      next[i] = bin_begin_[bin];
      end[i] = ray.xy_sq > 0 ? bin_begin_[bin + 1] : next[i];
      going[num_going] = static_cast<int>(i);
      num_going += nextIsReachable(i);
    }
    while (num_going > 0) {
      int still_going = 0;
      for (int k = 0; k < num_going; ++k) {
        const int i = going[k];
        const Candidate& candidate = candidates_[next[i]++];
        const Solid& c = solids_[candidate.index];
        intersectCylinder(c.x, c.y, c.radius_sq, c.height, candidate.index, rays[i], best[i]);
        going[still_going] = i;
        still_going += nextIsReachable(i);
      }
      num_going = still_going;
    }
    for (size_t i = 0; i < count; ++i) {
      ranges[first + i] =
          report(best[i], rays[i], max_range_, hits.empty() ? nullptr : &hits[first + i]);
    }
  }
}

void RayCaster::View::castFan(const Eigen::Vector2d& azimuth,
                              std::span<const Eigen::Vector3d> unit_dirs, std::span<double> ranges,
                              std::span<SurfaceHit> hits) const {
  if (!(std::abs(azimuth.squaredNorm() - 1) <= 1e-12)) {
    throw std::invalid_argument("RayCaster::View::castFan: the azimuth must be a unit vector");
  }
  const double ax = azimuth.x();
  const double ay = azimuth.y();
  // In squares, to spare a square root per ray: the xy part is within 1e-9 rad of the azimuth.
  for (const Eigen::Vector3d& d : unit_dirs) {
    const double xy_sq = d.x() * d.x() + d.y() * d.y();
    const double cross = d.x() * ay - d.y() * ax;
    if (xy_sq > 1e-18 && !(cross * cross <= 1e-18 * xy_sq && d.x() * ax + d.y() * ay > 0)) {
      throw std::invalid_argument("RayCaster::View::castFan: a ray is not in the fan");
    }
  }
  if (!startCasting("RayCaster::View::castFan", unit_dirs.size(), ranges, hits)) return;
  // Where the fan's vertical half-plane crosses each cylinder footprint, as xy travel s from the
  // eye: the ray of slope m = dz / |dxy| is at height eye.z + m * s there. It enters the side
  // where the footprint starts (from outside it), or the cap from above in between.
  struct Crossing {
    double s_in, s_out;
    bool from_outside;
    int index;
  };
  std::vector<Crossing> crossings;
  const auto cross = [&](int j) {
    const Solid& c = solids_[j];
    const double px = eye_.x() - c.x;
    const double py = eye_.y() - c.y;
    const double outside = px * px + py * py - c.radius_sq;
    const double b = px * ax + py * ay;
    const double discriminant = b * b - outside;
    if (discriminant < 0 || (outside > 0 && b >= 0)) return;  // missed, or behind the eye
    const double far = std::sqrt(discriminant) - b;
    const double s_in = outside > 0 ? outside / far : 0.0;  // the stable form, as in cast()
    if (s_in <= max_range_) crossings.push_back({s_in, far, outside > 0, j});
  };
  for (const int j : around_eye_) cross(j);
  const int bin = azimuthBin(pseudoAngle(ax, ay));
  for (uint32_t k = bin_begin_[bin];
       k < bin_begin_[bin + 1] && candidates_[k].min_xy_travel <= max_range_; ++k) {
    cross(candidates_[k].index);
  }
  std::sort(crossings.begin(), crossings.end(), [](const Crossing& a, const Crossing& b) {
    return a.s_in != b.s_in ? a.s_in < b.s_in : a.index < b.index;
  });
  // The walls' vertical planes ahead, where the fan crosses them within the walls' extent.
  struct WallCrossing {
    double s;
    int index;
  };
  std::vector<WallCrossing> walls;
  for (int axis = 0; axis < 2 && walls_in_range_; ++axis) {
    const int other = 1 - axis;
    for (int side = 0; side < 2; ++side) {
      const double s =
          ((side == 0 ? bounds_min_[axis] : bounds_max_[axis]) - eye_[axis]) / azimuth[axis];
      const double q = eye_[other] + s * azimuth[other];
      if (s >= 0 && q >= bounds_min_[other] && q <= bounds_max_[other]) {
        walls.push_back({s, 2 * axis + side});
      }
    }
  }

  for (size_t i = 0; i < unit_dirs.size(); ++i) {
    const Eigen::Vector3d& d = unit_dirs[i];
    SurfaceHit* hit = hits.empty() ? nullptr : &hits[i];
    const double xy = std::sqrt(d.x() * d.x() + d.y() * d.y());
    if (!(xy > 1e-9)) {
      ranges[i] = cast(d, hit);  // (almost) vertical: in every fan
      continue;
    }
    const double slope = d.z() / xy;
    const double z0 = eye_.z();
    Nearest best;  // in xy travel until converted below
    if (slope < 0) best.offer((bounds_min_.z() - z0) / slope, Surface::kGround, -1);
    for (const WallCrossing& wall : walls) {
      const double z = z0 + slope * wall.s;
      if (z >= bounds_min_.z() && z <= bounds_max_.z())
        best.offer(wall.s, Surface::kWall, wall.index);
    }
    for (const Crossing& c : crossings) {
      if (c.s_in >= best.t) break;
      const double height = solids_[c.index].height;
      const double z_in = z0 + slope * c.s_in;
      if (c.from_outside && z_in >= 0 && z_in <= height) {
        best.offer(c.s_in, Surface::kCylinderSide, c.index);
      } else if (slope < 0 && z0 > height) {
        const double s_cap = (height - z0) / slope;
        if (s_cap >= c.s_in && s_cap <= c.s_out) best.offer(s_cap, Surface::kCylinderCap, c.index);
      }
    }
    best.t /= xy;
    ranges[i] = report(best, makeRay(eye_, d), max_range_, hit);
  }
}

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

namespace {

bool validCalibrationId(const std::string& id) {
  return !id.empty() && std::all_of(id.begin(), id.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '-';
  });
}

}  // namespace

void StereoCameraOptions::declare(Params& p) {
  declareCameraGeometry(p, width, height, horizontal_fov_deg, pitch_down_deg, position_in_body,
                        "left optical centre in the body frame [m]");
  p("baseline", baseline, "distance of the right camera along the left's x [m]", Range::positive());
  p("max_range", max_range, "surfaces beyond this range look like the sky [m]", Range::positive());
  p("calibration_id", calibration_id,
    "the calibration the pairs name (the stereo depth node refuses pairs of another one)");
}

StereoRenderer::StereoRenderer(const World& world, StereoCameraOptions options)
    : cylinders_(world.cylinders),
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
  renderCamera(world_T_body * left_in_body_, left);
  renderCamera(world_T_body * rightInBody(), right);
}

void StereoRenderer::renderCamera(const Pose& world_T_camera, std::vector<uint8_t>& image) const {
  const RayCaster::View view = caster_.view(world_T_camera.position, options_.max_range);
  image.assign(static_cast<size_t>(camera_.width) * camera_.height, kSkyIntensity);
  const Eigen::Matrix3d world_R_camera = world_T_camera.orientation.toRotationMatrix();
  const Eigen::Vector3d image_right = world_R_camera.col(0);
  castImage(view, camera_, optical_rays_, world_R_camera, true,
            [&](int first, int stride, const std::vector<Eigen::Vector3d>& dirs,
                const std::vector<double>& ranges, const std::vector<SurfaceHit>& hits) {
              for (size_t k = 0; k < ranges.size(); ++k) {
                if (ranges[k] == RayCaster::kNoHit) continue;
                const double footprint = pixelFootprint(hits[k], dirs[k], ranges[k], image_right);
                const double gray = surfaceIntensity(hits[k], footprint);
                image[first + k * stride] =
                    static_cast<uint8_t>(std::clamp(gray, 0.0, 255.0) + 0.5);
              }
            });
}

double StereoRenderer::pixelFootprint(const SurfaceHit& hit, const Eigen::Vector3d& unit_dir,
                                      double range, const Eigen::Vector3d& image_right) const {
  // One pixel to the right turns the ray by about 1 / fx rad, which moves its hit by about
  // range / fx along image_right, projected onto the surface along the ray. Only this
  // footprint is filtered: along a column the two cameras sample the same epipolar plane, so
  // whatever aliasing there is along it, they share.
  const Eigen::Vector3d normal = surfaceNormal(hit, cylinders_);
  const double cos_incidence = normal.dot(unit_dir);
  const double clamped =
      std::copysign(std::max(std::abs(cos_incidence), kMinCosIncidence), cos_incidence);
  const Eigen::Vector3d step = image_right - unit_dir * (normal.dot(image_right) / clamped);
  return range / camera_.fx * step.norm();
}

double StereoRenderer::surfaceIntensity(const SurfaceHit& hit, double footprint_m) const {
  const TexturePoint point = texturePoint(hit, cylinders_);
  return point.mean + kContrast * TextureTile::instance().sample(point.x, point.y,
                                                                 footprint_m * kTexelsPerMetre);
}

std::string StereoRenderer::calibrationYaml(const std::string& id) const {
  if (!validCalibrationId(id)) {
    throw std::invalid_argument("calibrationYaml: the id must be non-empty [A-Za-z0-9_.-]");
  }
  const PinholeCamera& c = camera_;
  const std::vector<double> camera_matrix = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
  const std::vector<double> no_distortion(5, 0.0);
  std::ostringstream out;
  out << "%YAML:1.0\n---\n";
  out << "calibration_id: \"" << id << "\"\n";
  out << "image_width: " << c.width << "\nimage_height: " << c.height << "\n";
  writeMatrix(out, "camera_matrix_left", 3, 3, camera_matrix);
  writeMatrix(out, "distortion_left", 1, 5, no_distortion);
  writeMatrix(out, "camera_matrix_right", 3, 3, camera_matrix);
  writeMatrix(out, "distortion_right", 1, 5, no_distortion);
  writeMatrix(out, "R", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1});
  // cv::stereoCalibrate's T maps left-camera coordinates into the right camera: x_r = R x_l + T.
  writeMatrix(out, "T", 3, 1, {-options_.baseline, 0, 0});
  return out.str();
}

}  // namespace thicket::sim

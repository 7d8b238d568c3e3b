#include "thicket/sim/render.h"

#include <algorithm>
#include <array>
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

// Row v's rays (from opticalRays) turned into the world. A ray depends on its own pixel only,
// so any split of the image (e.g. rows across threads) gives the same rays.
void rowRays(const std::vector<Eigen::Vector3d>& optical_rays, int width, int v,
             const Eigen::Matrix3d& world_R_camera, std::vector<Eigen::Vector3d>& dirs) {
  dirs.resize(width);
  const Eigen::Vector3d* row = optical_rays.data() + static_cast<size_t>(v) * width;
  for (int u = 0; u < width; ++u) dirs[u] = world_R_camera * row[u];
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

// Octave wavelengths halve from 1 m to 1.6 cm: coarse ones vary the brightness of a surface, the
// finest that a pixel resolves give the pixel-scale detail a matcher needs, at any range.
constexpr int kOctaves = 7;
constexpr double kCoarsestWavelength = 1.0;  // [m]
constexpr double kFinestWavelength = kCoarsestWavelength / (1 << (kOctaves - 1));
// Gray levels per unit of octave noise: a forest image has a standard deviation of about 30 gray
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

// Value noise reads its random lattice values from one 256 x 256 table, each octave of each
// surface at its own offset, rather than hashing four lattice points per octave. The table
// repeats every 256 cells, but an octave shows only where a cell spans two pixels or more, so a
// repeat is at least 512 pixels away: far beyond any disparity a matcher searches.
constexpr int kLatticeBits = 8;
constexpr int kLatticeMask = (1 << kLatticeBits) - 1;

// Lattice coordinates are shifted by this many cells, so that they are positive (for surfaces
// within 260 km of the origin) and truncation floors them: std::floor is a library call without
// SSE4.1.
constexpr double kLatticeShift = 1 << 24;

const double* latticeTable() {
  static const std::vector<double> table = [] {
    std::vector<double> values(1 << (2 * kLatticeBits));
    for (size_t i = 0; i < values.size(); ++i) {
      values[i] = hash32(static_cast<uint32_t>(i)) * 0x1.0p-32;
    }
    return values;
  }();
  return table.data();
}

inline double smoothStep(double t) {
  return t * t * (3.0 - 2.0 * t);
}

// Value noise in [0, 1) on the unit lattice: random values at integer points, smoothly
// interpolated.
inline double valueNoise(const double* table, double x, double y, uint32_t offset) {
  x += kLatticeShift;
  y += kLatticeShift;
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const double tx = smoothStep(x - x0);
  const double ty = smoothStep(y - y0);
  const int col0 = (x0 + static_cast<int>(offset)) & kLatticeMask;
  const int col1 = (col0 + 1) & kLatticeMask;
  const int row0 = ((y0 + static_cast<int>(offset >> kLatticeBits)) & kLatticeMask) << kLatticeBits;
  const int row1 = (row0 + (1 << kLatticeBits)) & (kLatticeMask << kLatticeBits);
  const double bottom = table[row0 + col0] + tx * (table[row0 + col1] - table[row0 + col0]);
  const double top = table[row1 + col0] + tx * (table[row1 + col1] - table[row1 + col0]);
  return bottom + ty * (top - bottom);
}

// A surface point in texture space: coordinates on the surface [m] and the surface's mean gray
// level and seed (which places its octaves in the lattice table).
struct TexturePoint {
  double s = 0, w = 0;
  double mean = 0;
  uint32_t seed = 0;
};

// How much of an octave a pixel with the given 1 / footprint shows: all of it down to four
// footprints per wavelength, none at two (the pixel's Nyquist limit), linear in between. An
// octave fades out to its mean, which keeps the average brightness of a surface at any range.
inline double octaveWeight(int octave, double inverse_footprint) {
  const double wavelength = kFinestWavelength * (1 << (kOctaves - 1 - octave));
  return std::min(0.5 * wavelength * inverse_footprint - 1.0, 1.0);
}

// An octave's contribution, before weighting: value noise in [-0.5, 0.5).
inline double octaveNoise(const double* table, int octave, const TexturePoint& point) {
  const double frequency = (1 << octave) / kCoarsestWavelength;
  const uint32_t offset = point.seed + 0x9e3779b9U * static_cast<uint32_t>(octave);
  return valueNoise(table, point.s * frequency, point.w * frequency, offset) - 0.5;
}

double gray(const TexturePoint& point, double octave_sum) {
  return point.mean + kContrast * octave_sum;
}

// Surfaces of one kind share a mean gray level; each surface has its own seed, and each cylinder
// an offset of up to +-20 gray levels, so that neighbouring trees differ.
TexturePoint texturePoint(const SurfaceHit& hit, const std::vector<Cylinder>& cylinders) {
  const Eigen::Vector3d& p = hit.point;
  const uint32_t seed =
      hash32((static_cast<uint32_t>(hit.surface) << 24) ^ static_cast<uint32_t>(hit.index));
  const double offset = (seed >> 24) * (40.0 / 255.0) - 20.0;
  switch (hit.surface) {
    case Surface::kGround:
      return {p.x(), p.y(), 105, seed};
    case Surface::kWall:
      return {hit.index < 2 ? p.y() : p.x(), p.z(), 150, seed};
    case Surface::kCylinderCap:
      return {p.x(), p.y(), 140 + offset, seed};
    case Surface::kCylinderSide: {
      // Around the trunk: pseudoAngle scaled to the circumference, 0.79-1.57 times the arc
      // length and much cheaper than atan2. The texture has a seam where it wraps (on the +x
      // side), like a crack in the bark: both cameras see it alike.
      const Cylinder& c = cylinders[hit.index];
      const double dx = p.x() - c.x;
      const double dy = p.y() - c.y;
      const double quarter_turns = (dx == 0 && dy == 0) ? 0 : pseudoAngle(dx, dy);
      return {quarter_turns * (0.5 * pi * c.radius), p.z(), 85 + offset, seed};
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

void RayCaster::View::cast(std::span<const Eigen::Vector3d> unit_dirs, std::span<double> ranges,
                           std::span<SurfaceHit> hits) const {
  if (ranges.size() != unit_dirs.size() || !(hits.empty() || hits.size() == unit_dirs.size())) {
    throw std::invalid_argument("RayCaster::View::cast: sizes of rays and results differ");
  }
  if (containing_solid_.surface != Surface::kNone) {
    std::fill(ranges.begin(), ranges.end(), 0.0);
    std::fill(hits.begin(), hits.end(), containing_solid_);
    return;
  }
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

void DepthRenderer::render(const Pose& world_T_body, std::vector<float>& depth_m,
                           uint64_t noise_seed) const {
  const Pose world_T_camera = world_T_body * camera_in_body_;
  const RayCaster::View view = caster_.view(world_T_camera.position, options_.max_range);
  const double noise = options_.noise_stddev_at_1m;
  const uint64_t noise_key = splitMix64(noise_seed);
  depth_m.assign(static_cast<size_t>(camera_.width) * camera_.height, 0.0f);
  const Eigen::Matrix3d world_R_camera = world_T_camera.orientation.toRotationMatrix();
  std::vector<Eigen::Vector3d> dirs;
  std::vector<double> ranges(camera_.width);
  for (int v = 0; v < camera_.height; ++v) {
    rowRays(optical_rays_, camera_.width, v, world_R_camera, dirs);
    view.cast(dirs, ranges);
    for (int u = 0; u < camera_.width; ++u) {
      if (ranges[u] == RayCaster::kNoHit) continue;
      const int i = v * camera_.width + u;
      double depth = ranges[u] * optical_rays_[i].z();
      if (noise > 0) {
        depth += noise * depth * depth * standardNormal(noise_key, i);
        if (!(depth > 0)) depth = 0;
      }
      depth_m[i] = static_cast<float>(depth);
    }
  }
}

// --- StereoRenderer ---------------------------------------------------------------------------

void StereoCameraOptions::declare(Params& p) {
  declareCameraGeometry(p, width, height, horizontal_fov_deg, pitch_down_deg, position_in_body,
                        "left optical centre in the body frame [m]");
  p("baseline", baseline, "distance of the right camera along the left's x [m]", Range::positive());
  p("max_range", max_range, "surfaces beyond this range look like the sky [m]", Range::positive());
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
  const double* table = latticeTable();
  image.assign(static_cast<size_t>(camera_.width) * camera_.height, kSkyIntensity);
  const Eigen::Matrix3d world_R_camera = world_T_camera.orientation.toRotationMatrix();
  const Eigen::Vector3d image_right = world_R_camera.col(0);
  std::vector<Eigen::Vector3d> dirs;
  std::vector<double> ranges(camera_.width), inverse_footprints(camera_.width),
      octave_sums(camera_.width);
  std::vector<SurfaceHit> hits(camera_.width);
  std::vector<TexturePoint> points(camera_.width);
  for (int v = 0; v < camera_.height; ++v) {
    rowRays(optical_rays_, camera_.width, v, world_R_camera, dirs);
    view.cast(dirs, ranges, hits);
    for (int u = 0; u < camera_.width; ++u) {
      octave_sums[u] = 0;
      inverse_footprints[u] = 0;  // shows no octave
      if (ranges[u] == RayCaster::kNoHit) continue;
      points[u] = texturePoint(hits[u], cylinders_);
      inverse_footprints[u] = 1.0 / pixelFootprint(hits[u], dirs[u], ranges[u], image_right);
    }
    // Octave by octave over the whole row: the same sums as surfaceIntensity, whose per-pixel
    // loop would leave the CPU waiting on one pixel at a time.
    for (int octave = 0; octave < kOctaves; ++octave) {
      for (int u = 0; u < camera_.width; ++u) {
        const double weight = octaveWeight(octave, inverse_footprints[u]);
        if (weight > 0) octave_sums[u] += weight * octaveNoise(table, octave, points[u]);
      }
    }
    for (int u = 0; u < camera_.width; ++u) {
      if (ranges[u] == RayCaster::kNoHit) continue;
      const double gray_level = std::clamp(gray(points[u], octave_sums[u]), 0.0, 255.0);
      image[v * camera_.width + u] = static_cast<uint8_t>(gray_level + 0.5);
    }
  }
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
  const double inverse_footprint = 1.0 / footprint_m;
  double octave_sum = 0;
  for (int octave = 0; octave < kOctaves; ++octave) {
    const double weight = octaveWeight(octave, inverse_footprint);
    if (weight > 0) octave_sum += weight * octaveNoise(latticeTable(), octave, point);
  }
  return gray(point, octave_sum);
}

std::string StereoRenderer::calibrationYaml(const std::string& id) const {
  const bool id_ok = !id.empty() && std::all_of(id.begin(), id.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '-';
  });
  if (!id_ok) {
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

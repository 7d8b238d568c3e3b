// RayCaster and its View: exact ray casting against a World's ground, walls and cylinders.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "pseudo_angle.h"
#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

using Surface = SurfaceHit::Surface;

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

int azimuthBin(double pseudo_angle) {
  return std::min(static_cast<int>(pseudo_angle * (kAzimuthBins / 4.0)), kAzimuthBins - 1);
}

}  // namespace

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
  // The length of a ray's xy part when it is in the fan, and 0 when it is (almost) vertical: in
  // every fan. Without a square root: the xy part is within 1e-9 rad of the azimuth, so that its
  // length is its dot product with the azimuth, up to rounding.
  const auto xyInFan = [ax, ay](const Eigen::Vector3d& d) {
    const double along = d.x() * ax + d.y() * ay;
    const double across = d.x() * ay - d.y() * ax;
    if (along > 1e-9 && std::abs(across) <= 1e-9 * along) return along;
    if (!(along * along + across * across <= 1e-18)) {
      throw std::invalid_argument("RayCaster::View::castFan: a ray is not in the fan");
    }
    return 0.0;
  };
  if (!startCasting("RayCaster::View::castFan", unit_dirs.size(), ranges, hits)) {
    for (const Eigen::Vector3d& d : unit_dirs) xyInFan(d);
    return;
  }
  // Where the fan's vertical half-plane crosses each cylinder footprint, as xy travel s from the
  // eye: the ray of slope m = dz / |dxy| is at height eye.z + m * s there. It enters the side
  // where the footprint starts (from outside it), or the cap from above in between.
  struct Crossing {
    double s_in, s_out, height;
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
    if (s_in <= max_range_) crossings.push_back({s_in, far, c.height, outside > 0, j});
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
    const double xy = xyInFan(d);
    if (xy == 0) {
      ranges[i] = cast(d, hit);
      continue;
    }
    const double inverse_xy = 1 / xy;
    const double slope = d.z() * inverse_xy;
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
      const double z_in = z0 + slope * c.s_in;
      if (c.from_outside && z_in >= 0 && z_in <= c.height) {
        best.offer(c.s_in, Surface::kCylinderSide, c.index);
      } else if (slope < 0 && z0 > c.height) {
        const double s_cap = (c.height - z0) / slope;
        if (s_cap >= c.s_in && s_cap <= c.s_out) best.offer(s_cap, Surface::kCylinderCap, c.index);
      }
    }
    best.t *= inverse_xy;
    ranges[i] = report(best, makeRay(eye_, d), max_range_, hit);
  }
}

}  // namespace thicket::sim

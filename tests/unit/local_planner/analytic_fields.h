// Exact signed distance fields with exact gradients, as DistanceFields for the loco tests, and an
// independent check of a planned trajectory against them (every 0.01 s, not the planner's Δt).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>

#include "thicket/common/esdf_query.h"
#include "thicket/common/polynomial_trajectory.h"
#include "thicket/local_planner/loco.h"

namespace thicket::local_planner::testing {

/// Everything known and far from obstacles (beyond any collision potential's reach).
inline DistanceField freeSpace(double distance = 10.0) {
  return [distance](const Eigen::Vector3d&) {
    return EsdfSample{true, distance, Eigen::Vector3d::Zero()};
  };
}

/// An infinite vertical cylinder: d = ||(p - c)_xy|| - r, gradient the unit xy direction away
/// from the axis (zero on the axis itself, where it is undefined).
inline EsdfSample cylinderSample(const Eigen::Vector2d& center, double radius,
                                 const Eigen::Vector3d& p) {
  const Eigen::Vector2d offset = p.head<2>() - center;
  const double r = offset.norm();
  EsdfSample s;
  s.known = true;
  s.distance = r - radius;
  if (r > 0) s.gradient.head<2>() = offset / r;
  return s;
}

inline DistanceField cylinderField(const Eigen::Vector2d& center, double radius) {
  return [center, radius](const Eigen::Vector3d& p) { return cylinderSample(center, radius, p); };
}

/// An axis-aligned box.
struct Box {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();
};

/// A box spanning [lo, hi] per axis.
inline Box boxFromCorners(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return {(lo + hi) / 2, (hi - lo) / 2};
}

/// The exact signed distance to one box and its gradient. q = |p - c| - h: outside (some q > 0)
/// the distance is ||max(q, 0)|| with gradient sign(p - c) * max(q, 0) / ||max(q, 0)||; inside the
/// largest (least negative) q, with gradient along that axis.
inline EsdfSample boxSample(const Box& box, const Eigen::Vector3d& p) {
  const Eigen::Vector3d offset = p - box.center;
  const Eigen::Vector3d sign = offset.unaryExpr([](double x) { return x < 0 ? -1.0 : 1.0; });
  const Eigen::Vector3d q = offset.cwiseAbs() - box.half_extents;
  EsdfSample s;
  s.known = true;
  const Eigen::Vector3d outside = q.cwiseMax(0.0);
  const double norm = outside.norm();
  if (norm > 0) {
    s.distance = norm;
    s.gradient = sign.cwiseProduct(outside) / norm;
  } else {
    Eigen::Index axis = 0;
    s.distance = q.maxCoeff(&axis);
    s.gradient[axis] = sign[axis];
  }
  return s;
}

/// The union of boxes: the minimum of their distances, with the gradient of the nearest. Exact
/// outside the union; inside it is exact as long as the boxes do not overlap.
inline DistanceField boxesField(std::vector<Box> boxes) {
  if (boxes.empty()) throw std::invalid_argument("boxesField: no boxes");
  return [boxes = std::move(boxes)](const Eigen::Vector3d& p) {
    EsdfSample best;
    best.distance = std::numeric_limits<double>::infinity();
    for (const Box& b : boxes) {
      const EsdfSample s = boxSample(b, p);
      if (s.distance < best.distance) best = s;
    }
    return best;
  };
}

/// `field` where `unknown` is false; elsewhere unknown (known false, distance and gradient 0, as
/// sampleEsdf reports it).
inline DistanceField withUnknown(DistanceField field,
                                 std::function<bool(const Eigen::Vector3d&)> unknown) {
  return [field = std::move(field), unknown = std::move(unknown)](const Eigen::Vector3d& p) {
    if (unknown(p)) return EsdfSample{};
    return field(p);
  };
}

/// `field` with every point beyond x = `x` unknown.
inline DistanceField unknownBeyondX(DistanceField field, double x) {
  return withUnknown(std::move(field), [x](const Eigen::Vector3d& p) { return p.x() > x; });
}

/// The trajectory of a loco result.
inline PolynomialTrajectory trajectoryOf(const std::vector<PolynomialSegment>& segments) {
  auto t = PolynomialTrajectory::create(0, segments);
  if (!t) throw std::runtime_error("not a valid trajectory: " + t.error());
  return *t;
}

/// What a trajectory does against an analytic field, sampled every dt (and at the very end).
struct TrajectoryReport {
  double min_distance = std::numeric_limits<double>::infinity();  ///< unknown reads 0 [m]
  double min_distance_time = 0;                                   ///< where it is [s]
  bool all_known = true;
  double max_speed = 0;         ///< maxSpeed(dt) [m/s]
  double max_acceleration = 0;  ///< maxAcceleration(dt) [m/s²]
};

inline TrajectoryReport inspectTrajectory(const PolynomialTrajectory& trajectory,
                                          const DistanceField& field, double dt = 0.01) {
  TrajectoryReport report;
  for (const auto& [t, state] : trajectory.sample(dt)) {
    const EsdfSample s = field(state.position);
    if (!s.known) report.all_known = false;
    const double d = s.known ? s.distance : 0.0;
    if (d < report.min_distance) {
      report.min_distance = d;
      report.min_distance_time = t;
    }
  }
  report.max_speed = trajectory.maxSpeed(dt);
  report.max_acceleration = trajectory.maxAcceleration(dt);
  return report;
}

/// Expects `trajectory` to start in `start` (position, velocity and acceleration) and to end at
/// rest, just before its end (after it, it holds still anyway).
inline void expectFromStartToRest(const PolynomialTrajectory& trajectory,
                                  const TrajectoryState& start) {
  EXPECT_LT((trajectory.evaluate(0, 0) - start.position).norm(), 1e-9);
  EXPECT_LT((trajectory.evaluate(0, 1) - start.velocity).norm(), 1e-9);
  EXPECT_LT((trajectory.evaluate(0, 2) - start.acceleration).norm(), 1e-9);
  const double end = trajectory.duration() - 1e-12;
  EXPECT_LT(trajectory.evaluate(end, 1).norm(), 1e-8);
  EXPECT_LT(trajectory.evaluate(end, 2).norm(), 1e-8);
}

/// Checks the result's trajectory every 0.01 s: valid, known everywhere, within v_max and a_max
/// (+1e-6). Returns the smallest analytic distance along it (for the caller to compare with the
/// robot radius).
inline double checkTrajectory(const LocoResult& result, const DistanceField& field,
                              const LocoOptions& options) {
  auto trajectory = PolynomialTrajectory::create(0, result.segments);
  EXPECT_TRUE(trajectory.ok()) << trajectory.error();
  if (!trajectory) return -std::numeric_limits<double>::infinity();
  const TrajectoryReport report = inspectTrajectory(*trajectory, field, 0.01);
  EXPECT_TRUE(report.all_known);
  EXPECT_LE(report.max_speed, options.v_max + 1e-6);
  EXPECT_LE(report.max_acceleration, options.a_max + 1e-6);
  return report.min_distance;
}

}  // namespace thicket::local_planner::testing

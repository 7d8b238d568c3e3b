// The local planner's trajectory space (docs/design.md §1, loco): a spline of polynomial segments
// of order 9 (10 coefficients), continuous up to the 4th derivative (snap), parametrized after
// Richter et al. by the derivatives at the segment ends rather than by coefficients:
//
//   c = A⁻¹ M [d_F; d_P]
//
// c: every segment's coefficients; A maps a segment's coefficients to its end derivatives
// (orders 0..4 at tau = 0 and at tau = T); M copies the derivatives at the shared vertices into
// both segments that meet there (this is continuity); d_F: the fixed derivatives (start position,
// velocity and acceleration; end velocity and acceleration 0, and the end position unless it is
// free); d_P: the free rest, the optimizer's decision variables. The three axes share A and M and
// are independent, so derivatives are (rows) x (x, y, z) matrices.
//
// The jerk cost J_d = ∫ ||jerk||² dt is quadratic in d_P with the closed form
//   J_d = d_F' R_FF d_F + 2 d_F' R_FP d_P + d_P' R_PP d_P,  R = (A⁻¹ M)' Q (A⁻¹ M)
// (Q: the integral of the squared jerk basis), summed over the axes.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "thicket/common/polynomial_trajectory.h"

namespace thicket::local_planner {

/// Derivatives of the three axes, one row per derivative, columns x, y, z.
using Derivatives = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// The time a rest-to-rest move of `distance` takes at speed v_max and acceleration a_max: a
/// trapezoidal velocity profile, or a triangular one when v_max is not reached [s]. Throws
/// std::invalid_argument unless distance >= 0 and the limits are positive, all finite.
double velocityRampTime(double distance, double v_max, double a_max);

/// Segment durations for a move of `distance` (docs/design.md §1): `scale` times the velocity-ramp
/// time (at least `min_total` seconds), split evenly over `segments`. Throws as velocityRampTime,
/// and std::invalid_argument unless segments >= 1 and scale, min_total > 0.
std::vector<double> segmentTimes(double distance, double v_max, double a_max, int segments = 3,
                                 double scale = 1.2, double min_total = 0.1);

/// Where the spline starts and must end.
struct SplineEnds {
  Eigen::Vector3d start_position = Eigen::Vector3d::Zero();
  Eigen::Vector3d start_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d start_acceleration = Eigen::Vector3d::Zero();
  /// The goal; ignored when the end position is free. The spline ends at rest (velocity and
  /// acceleration 0).
  Eigen::Vector3d end_position = Eigen::Vector3d::Zero();
};

class JerkSpline {
 public:
  static constexpr int kCoefficients = 10;      ///< order 9
  static constexpr int kVertexDerivatives = 5;  ///< orders 0..4 at every vertex

  /// segment_times: one positive, finite duration per segment [s]. free_end_position: the end
  /// position is a decision variable (the soft goal of docs/design.md §1) instead of fixed. Throws
  /// std::invalid_argument on an empty list or a bad duration.
  JerkSpline(std::vector<double> segment_times, bool free_end_position);

  int numSegments() const { return static_cast<int>(times_.size()); }
  const std::vector<double>& segmentTimes() const { return times_; }
  double duration() const;
  bool freeEndPosition() const { return free_end_; }
  int numFixed() const { return num_fixed_; }
  int numFree() const { return num_free_; }
  /// The row of the end position in the free derivatives (free end only), else -1.
  int endPositionRow() const { return free_end_ ? end_position_row_ : -1; }
  /// The row of vertex `vertex`'s derivative of order `order` in the free derivatives, or -1 when
  /// it is fixed. Vertex 0 is the start, numSegments() the end.
  int freeRow(int vertex, int order) const;

  /// d_F for these ends. Throws std::invalid_argument if a value is not finite.
  Derivatives fixedDerivatives(const SplineEnds& ends) const;

  /// The jerk cost of the spline, summed over the axes; with `gradient`, d J_d / d d_P (same
  /// shape as d_P). Throws std::invalid_argument on wrongly sized inputs.
  double jerkCost(const Derivatives& fixed, const Derivatives& free,
                  Derivatives* gradient = nullptr) const;

  /// The free derivatives that minimise the jerk cost alone (the unconstrained optimum). With a
  /// free end position the end stays where `initial_end` puts it (the jerk cost alone would
  /// shrink the move to nothing), so pass the goal there.
  Derivatives minimumJerkFree(const Derivatives& fixed, const Eigen::Vector3d& initial_end) const;

  /// The free derivatives that minimise the jerk cost alone with the end position free too (free
  /// end only; throws std::logic_error otherwise): the smoothest way for a moving start to come to
  /// rest within the spline's duration, wherever that ends.
  Derivatives minimumJerkStop(const Derivatives& fixed) const;

  /// The segments of the spline, to build a PolynomialTrajectory from.
  std::vector<PolynomialSegment> segments(const Derivatives& fixed, const Derivatives& free) const;

  /// The linear map from [d_F; d_P] to segment s's coefficients (kCoefficients rows; the columns
  /// of d_F first): a point of segment s at local time tau is basis(tau, k)' * map * [d_F; d_P]
  /// for its k-th derivative. For chaining gradients through samples of the spline.
  const Eigen::MatrixXd& coefficientMap(int segment) const { return coefficient_maps_[segment]; }

  /// The k-th derivative of [1, tau, ..., tau^9] with respect to tau.
  static Eigen::Matrix<double, kCoefficients, 1> basis(double tau, int derivative);

 private:
  void checkSizes(Eigen::Index fixed_rows, Eigen::Index free_rows) const;

  std::vector<double> times_;
  bool free_end_;
  int num_fixed_ = 0;
  int num_free_ = 0;
  int end_position_row_ = -1;
  std::vector<int> free_rows_;  // per vertex derivative 5 v + r: its free row, or -1
  std::vector<Eigen::MatrixXd> coefficient_maps_;  // per segment: [d_F; d_P] -> coefficients
  Eigen::MatrixXd r_ff_, r_fp_, r_pp_;             // the partitions of R
};

}  // namespace thicket::local_planner

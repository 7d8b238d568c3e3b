#include "thicket/local_planner/spline.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace thicket::local_planner {

namespace {

bool positiveFinite(double x) {
  return std::isfinite(x) && x > 0;
}

// The integral over [0, T] of (d³/dtau³ of tau^i)(d³/dtau³ of tau^j).
Eigen::MatrixXd jerkGram(double duration) {
  constexpr int n = JerkSpline::kCoefficients;
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(n, n);
  for (int i = 3; i < n; ++i) {
    for (int j = 3; j < n; ++j) {
      const double falling = i * (i - 1.0) * (i - 2.0) * j * (j - 1.0) * (j - 2.0);
      const int power = i + j - 5;
      q(i, j) = falling * std::pow(duration, power) / power;
    }
  }
  return q;
}

}  // namespace

double velocityRampTime(double distance, double v_max, double a_max) {
  if (!(std::isfinite(distance) && distance >= 0) || !positiveFinite(v_max) ||
      !positiveFinite(a_max)) {
    throw std::invalid_argument("velocityRampTime: distance must be >= 0 and limits positive");
  }
  // Accelerating to v_max and braking from it covers v_max² / a_max.
  if (distance >= v_max * v_max / a_max) return distance / v_max + v_max / a_max;
  return 2 * std::sqrt(distance / a_max);
}

std::vector<double> segmentTimes(double distance, double v_max, double a_max, int segments,
                                 double scale, double min_total) {
  if (segments < 1 || !positiveFinite(scale) || !positiveFinite(min_total)) {
    throw std::invalid_argument("segmentTimes: needs segments >= 1 and positive scale, minimum");
  }
  const double total = std::max(min_total, scale * velocityRampTime(distance, v_max, a_max));
  return std::vector<double>(static_cast<size_t>(segments), total / segments);
}

Eigen::Matrix<double, JerkSpline::kCoefficients, 1> JerkSpline::basis(double tau, int derivative) {
  Eigen::Matrix<double, kCoefficients, 1> b = Eigen::Matrix<double, kCoefficients, 1>::Zero();
  for (int i = derivative; i < kCoefficients; ++i) {
    double falling = 1;
    for (int k = 0; k < derivative; ++k) falling *= i - k;
    b(i) = falling * std::pow(tau, i - derivative);
  }
  return b;
}

JerkSpline::JerkSpline(std::vector<double> segment_times, bool free_end_position)
    : times_(std::move(segment_times)), free_end_(free_end_position) {
  if (times_.empty()) throw std::invalid_argument("JerkSpline: no segments");
  for (double t : times_) {
    if (!positiveFinite(t)) {
      throw std::invalid_argument("JerkSpline: segment time " + std::to_string(t) +
                                  " is not positive and finite");
    }
  }
  // Each vertex derivative (vertex v, order r, unique index u = 5 v + r) becomes a column of d_F
  // or of d_P, both in increasing u.
  const int vertices = numSegments() + 1;
  const int last = vertices - 1;
  std::vector<int> column(static_cast<size_t>(vertices * kVertexDerivatives));
  std::vector<bool> fixed(column.size());
  for (int v = 0; v < vertices; ++v) {
    for (int r = 0; r < kVertexDerivatives; ++r) {
      const size_t u = static_cast<size_t>(v * kVertexDerivatives + r);
      fixed[u] = (v == 0 && r <= 2) || (v == last && (r == 1 || r == 2)) ||
                 (v == last && r == 0 && !free_end_);
      if (fixed[u]) column[u] = num_fixed_++;
    }
  }
  free_rows_.assign(column.size(), -1);
  for (size_t u = 0; u < column.size(); ++u) {
    if (fixed[u]) continue;
    if (u == static_cast<size_t>(last * kVertexDerivatives)) end_position_row_ = num_free_;
    free_rows_[u] = num_free_;
    column[u] = num_fixed_ + num_free_++;
  }

  const int all = num_fixed_ + num_free_;
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(all, all);
  for (int s = 0; s < numSegments(); ++s) {
    const double t = times_[static_cast<size_t>(s)];
    Eigen::Matrix<double, kCoefficients, kCoefficients> a;
    Eigen::MatrixXd select = Eigen::MatrixXd::Zero(kCoefficients, all);
    for (int k = 0; k < kVertexDerivatives; ++k) {
      a.row(k) = basis(0, k).transpose();
      a.row(kVertexDerivatives + k) = basis(t, k).transpose();
      select(k, column[static_cast<size_t>(s * kVertexDerivatives + k)]) = 1;
      select(kVertexDerivatives + k,
             column[static_cast<size_t>((s + 1) * kVertexDerivatives + k)]) = 1;
    }
    coefficient_maps_.push_back(a.fullPivLu().solve(select));
    const Eigen::MatrixXd& map = coefficient_maps_.back();
    r += map.transpose() * jerkGram(t) * map;
  }
  r_ff_ = r.topLeftCorner(num_fixed_, num_fixed_);
  r_fp_ = r.topRightCorner(num_fixed_, num_free_);
  r_pp_ = r.bottomRightCorner(num_free_, num_free_);
}

int JerkSpline::freeRow(int vertex, int order) const {
  if (vertex < 0 || vertex > numSegments() || order < 0 || order >= kVertexDerivatives) return -1;
  return free_rows_[static_cast<size_t>(vertex * kVertexDerivatives + order)];
}

double JerkSpline::duration() const {
  double total = 0;
  for (double t : times_) total += t;
  return total;
}

Derivatives JerkSpline::fixedDerivatives(const SplineEnds& ends) const {
  if (!ends.start_position.allFinite() || !ends.start_velocity.allFinite() ||
      !ends.start_acceleration.allFinite() || (!free_end_ && !ends.end_position.allFinite())) {
    throw std::invalid_argument("JerkSpline: the start state and goal must be finite");
  }
  // In column order: start position, velocity, acceleration; [end position]; end velocity and
  // acceleration, which are 0.
  Derivatives d = Derivatives::Zero(num_fixed_, 3);
  d.row(0) = ends.start_position.transpose();
  d.row(1) = ends.start_velocity.transpose();
  d.row(2) = ends.start_acceleration.transpose();
  if (!free_end_) d.row(3) = ends.end_position.transpose();
  return d;
}

void JerkSpline::checkSizes(Eigen::Index fixed_rows, Eigen::Index free_rows) const {
  if (fixed_rows != num_fixed_ || free_rows != num_free_) {
    throw std::invalid_argument("JerkSpline: expected " + std::to_string(num_fixed_) +
                                " fixed and " + std::to_string(num_free_) +
                                " free derivatives, got " + std::to_string(fixed_rows) + " and " +
                                std::to_string(free_rows));
  }
}

double JerkSpline::jerkCost(const Derivatives& fixed, const Derivatives& free,
                            Derivatives* gradient) const {
  checkSizes(fixed.rows(), free.rows());
  const Derivatives fp = r_fp_.transpose() * fixed;  // R_FP' d_F
  const Derivatives pp = r_pp_ * free;
  if (gradient) *gradient = 2 * (fp + pp);
  return (fixed.transpose() * r_ff_ * fixed).trace() + 2 * (fp.transpose() * free).trace() +
         (free.transpose() * pp).trace();
}

Derivatives JerkSpline::minimumJerkFree(const Derivatives& fixed,
                                        const Eigen::Vector3d& initial_end) const {
  checkSizes(fixed.rows(), num_free_);
  // Stationary in the optimized rows S: R_SS d_S = -(R_FS' d_F + R_S,end d_end).
  Derivatives rhs = -r_fp_.transpose() * fixed;
  Eigen::MatrixXd r_ss = r_pp_;
  if (free_end_) {
    rhs -= r_pp_.col(end_position_row_) * initial_end.transpose();
    // Pin the end row: 1 * d_end = initial_end.
    r_ss.row(end_position_row_).setZero();
    r_ss.col(end_position_row_).setZero();
    r_ss(end_position_row_, end_position_row_) = 1;
    rhs.row(end_position_row_) = initial_end.transpose();
  }
  return r_ss.ldlt().solve(rhs);
}

Derivatives JerkSpline::minimumJerkStop(const Derivatives& fixed) const {
  if (!free_end_) throw std::logic_error("JerkSpline::minimumJerkStop: the end position is fixed");
  checkSizes(fixed.rows(), num_free_);
  // Stationary in every free row: R_PP d_P = -R_FP' d_F.
  return r_pp_.ldlt().solve(-r_fp_.transpose() * fixed);
}

std::vector<PolynomialSegment> JerkSpline::segments(const Derivatives& fixed,
                                                    const Derivatives& free) const {
  checkSizes(fixed.rows(), free.rows());
  Derivatives all(num_fixed_ + num_free_, 3);
  all << fixed, free;
  std::vector<PolynomialSegment> result;
  for (int s = 0; s < numSegments(); ++s) {
    result.push_back({times_[static_cast<size_t>(s)],
                      (coefficient_maps_[static_cast<size_t>(s)] * all).transpose()});
  }
  return result;
}

}  // namespace thicket::local_planner

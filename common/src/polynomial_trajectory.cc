#include "thicket/common/polynomial_trajectory.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace thicket {
namespace {

// Caps on received messages: far beyond anything the planner sends, small enough that a corrupt
// or hostile count cannot make a receiver allocate or evaluate absurd amounts.
constexpr int32_t kMaxLcmSegments = 1000;
constexpr int32_t kMaxLcmCoefficients = 32;

// A grid sample this close to the end of a sampled interval is replaced by the end itself.
constexpr double kOnGridTolerance = 1e-9;

constexpr const char* kAxisNames[] = {"x", "y", "z"};

using Samples = std::vector<std::pair<double, TrajectoryState>>;

template <class... Args>
std::string concat(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

void checkDerivative(int derivative) {
  if (derivative < 0) {
    throw std::invalid_argument(concat("derivative order ", derivative, " is negative"));
  }
}

// Horner's scheme on the derivative polynomial: the r-th derivative of c_k tau^k is
// c_k k (k-1) ... (k-r+1) tau^(k-r), so orders above the degree give exactly zero.
Eigen::Vector3d evaluateSegment(const PolynomialSegment& segment, double tau, int derivative) {
  Eigen::Vector3d result = Eigen::Vector3d::Zero();
  for (Eigen::Index k = segment.coefficients.cols() - 1; k >= derivative; --k) {
    double falling_factorial = 1;
    for (int i = 0; i < derivative; ++i) falling_factorial *= static_cast<double>(k - i);
    result = result * tau + falling_factorial * segment.coefficients.col(k);
  }
  return result;
}

// Empty when the yaw metadata of a message is valid.
std::string yawError(int8_t yaw_policy, double yaw) {
  if (yaw_policy != polynomial_trajectory_t::YAW_ALONG_VELOCITY &&
      yaw_policy != polynomial_trajectory_t::YAW_CONSTANT) {
    return concat("unknown yaw_policy ", static_cast<int>(yaw_policy));
  }
  if (!std::isfinite(yaw)) return concat("yaw ", yaw, " rad is not finite");
  return {};
}

double maxNorm(const Samples& samples, Eigen::Vector3d TrajectoryState::*derivative) {
  double max_norm = 0;
  for (const auto& [t, state] : samples) max_norm = std::max(max_norm, (state.*derivative).norm());
  return max_norm;
}

}  // namespace

PolynomialTrajectory::PolynomialTrajectory(int64_t start_utime,
                                           std::vector<PolynomialSegment> segments)
    : start_utime_(start_utime), segments_(std::move(segments)), segment_starts_{0.0} {
  for (const PolynomialSegment& segment : segments_) {
    segment_starts_.push_back(segment_starts_.back() + segment.duration);
  }
}

Expected<PolynomialTrajectory> PolynomialTrajectory::create(
    int64_t start_utime, std::vector<PolynomialSegment> segments) {
  if (segments.empty()) return unexpected("a trajectory needs at least one segment");
  const Eigen::Index num_coefficients = segments.front().coefficients.cols();
  for (size_t s = 0; s < segments.size(); ++s) {
    const PolynomialSegment& segment = segments[s];
    const auto fail = [s](const auto&... what) {
      return unexpected(concat("segment ", s, ": ", what...));
    };
    if (!std::isfinite(segment.duration)) {
      return fail("duration ", segment.duration, " s is not finite");
    }
    if (segment.duration <= 0) return fail("duration ", segment.duration, " s is not positive");
    const Eigen::Index cols = segment.coefficients.cols();
    if (cols == 0) return fail("has no coefficients");
    if (cols != num_coefficients) {
      return fail(cols, " coefficients per axis, but segment 0 has ", num_coefficients);
    }
    for (Eigen::Index a = 0; a < 3; ++a) {
      for (Eigen::Index k = 0; k < cols; ++k) {
        const double c = segment.coefficients(a, k);
        if (!std::isfinite(c)) {
          return fail("coefficient of tau^", k, " on axis ", kAxisNames[a], " is not finite (", c,
                      ")");
        }
      }
    }
  }
  return PolynomialTrajectory(start_utime, std::move(segments));
}

PolynomialTrajectory PolynomialTrajectory::hover(int64_t start_utime,
                                                 const Eigen::Vector3d& position, double duration) {
  Expected<PolynomialTrajectory> trajectory =
      create(start_utime, {PolynomialSegment{duration, position}});
  if (!trajectory) throw std::invalid_argument("hover: " + trajectory.error());
  return std::move(trajectory).value();
}

Expected<PolynomialTrajectory> PolynomialTrajectory::fromLcm(const polynomial_trajectory_t& msg) {
  const int32_t num_segments = msg.num_segments;
  const int32_t num_coefficients = msg.num_coefficients;
  if (num_segments <= 0 || num_segments > kMaxLcmSegments) {
    return unexpected(
        concat("num_segments ", num_segments, " is outside [1, ", kMaxLcmSegments, "]"));
  }
  if (num_coefficients <= 0 || num_coefficients > kMaxLcmCoefficients) {
    return unexpected(concat("num_coefficients ", num_coefficients, " is outside [1, ",
                             kMaxLcmCoefficients, "]"));
  }
  if (msg.durations.size() != static_cast<size_t>(num_segments)) {
    return unexpected(concat("durations has ", msg.durations.size(),
                             " entries but num_segments is ", num_segments));
  }
  if (msg.coefficients.size() != static_cast<size_t>(num_segments)) {
    return unexpected(concat("coefficients has ", msg.coefficients.size(),
                             " segments but num_segments is ", num_segments));
  }
  if (std::string error = yawError(msg.yaw_policy, msg.yaw); !error.empty()) {
    return unexpected(std::move(error));
  }
  std::vector<PolynomialSegment> segments(num_segments);
  for (int32_t s = 0; s < num_segments; ++s) {
    const auto& axes = msg.coefficients[s];
    if (axes.size() != 3) {
      return unexpected(concat("segment ", s, ": coefficients has ", axes.size(), " axes, not 3"));
    }
    segments[s].duration = msg.durations[s];
    segments[s].coefficients.resize(3, num_coefficients);
    for (int a = 0; a < 3; ++a) {
      if (axes[a].size() != static_cast<size_t>(num_coefficients)) {
        return unexpected(concat("segment ", s, ": axis ", kAxisNames[a], " has ", axes[a].size(),
                                 " coefficients but num_coefficients is ", num_coefficients));
      }
      segments[s].coefficients.row(a) =
          Eigen::Map<const Eigen::RowVectorXd>(axes[a].data(), num_coefficients);
    }
  }
  return create(msg.utime, std::move(segments));
}

polynomial_trajectory_t PolynomialTrajectory::toLcm(int64_t cycle, int64_t goal_id,
                                                    int8_t yaw_policy, double yaw) const {
  if (const std::string error = yawError(yaw_policy, yaw); !error.empty()) {
    throw std::invalid_argument(error);
  }
  polynomial_trajectory_t msg{};
  msg.utime = start_utime_;
  msg.cycle = cycle;
  msg.goal_id = goal_id;
  msg.yaw_policy = yaw_policy;
  msg.yaw = yaw;
  msg.num_segments = numSegments();
  msg.num_coefficients = numCoefficients();
  for (const PolynomialSegment& segment : segments_) {
    msg.durations.push_back(segment.duration);
    auto& axes = msg.coefficients.emplace_back(3);
    for (int a = 0; a < 3; ++a) {
      const auto row = segment.coefficients.row(a);
      axes[a].assign(row.begin(), row.end());
    }
  }
  return msg;
}

Eigen::Vector3d PolynomialTrajectory::evaluate(double t, int derivative) const {
  checkDerivative(derivative);
  if (std::isnan(t)) throw std::invalid_argument("trajectory evaluated at a NaN time");
  if (t > duration() && derivative > 0) return Eigen::Vector3d::Zero();
  const double clamped = std::clamp(t, 0.0, duration());
  // Search the interior boundaries only; upper_bound sends a time exactly on one to the later
  // segment, and the end of the trajectory to the last segment.
  const auto interior_begin = segment_starts_.begin() + 1;
  const auto interior_end = segment_starts_.end() - 1;
  const auto s = std::upper_bound(interior_begin, interior_end, clamped) - interior_begin;
  return evaluateSegment(segments_[s], clamped - segment_starts_[s], derivative);
}

TrajectoryState PolynomialTrajectory::state(double t) const {
  return {evaluate(t, 0), evaluate(t, 1), evaluate(t, 2), evaluate(t, 3)};
}

TrajectoryState PolynomialTrajectory::stateAtUtime(int64_t utime) const {
  return state(static_cast<double>(utime - start_utime_) / 1e6);
}

Samples PolynomialTrajectory::sample(double dt, double t0, double t1) const {
  if (!(dt > 0) || !std::isfinite(dt)) {
    throw std::invalid_argument(concat("sample step ", dt, " s is not positive and finite"));
  }
  if (!std::isfinite(t0) || !std::isfinite(t1) || t0 > t1) {
    throw std::invalid_argument(
        concat("sample interval [", t0, ", ", t1, "] s is not finite and ordered"));
  }
  Samples samples;
  // Times are t0 + i dt rather than accumulated, so that long samplings do not drift.
  for (int64_t i = 0;; ++i) {
    const double t = t0 + static_cast<double>(i) * dt;
    if (t >= t1 - kOnGridTolerance) break;
    samples.emplace_back(t, state(t));
  }
  samples.emplace_back(t1, state(t1));
  return samples;
}

Samples PolynomialTrajectory::sample(double dt) const {
  return sample(dt, 0, duration());
}

double PolynomialTrajectory::maxSpeed(double dt) const {
  return maxNorm(sample(dt), &TrajectoryState::velocity);
}

double PolynomialTrajectory::maxAcceleration(double dt) const {
  return maxNorm(sample(dt), &TrajectoryState::acceleration);
}

double PolynomialTrajectory::maxDiscontinuity(int derivative) const {
  checkDerivative(derivative);
  double max_jump = 0;
  for (size_t s = 0; s + 1 < segments_.size(); ++s) {
    const Eigen::Vector3d end = evaluateSegment(segments_[s], segments_[s].duration, derivative);
    const Eigen::Vector3d start = evaluateSegment(segments_[s + 1], 0, derivative);
    max_jump = std::max(max_jump, (end - start).norm());
  }
  return max_jump;
}

}  // namespace thicket

#include "thicket/common/geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "thicket/common/time.h"

namespace thicket {
namespace {

// How far from unit norm a quaternion handed to PoseHistory may be before it is refused.
constexpr double kPoseHistoryUnitTolerance = 1e-3;

std::string toText(const Eigen::VectorXd& v) {
  std::ostringstream out;
  out << v.transpose().format(
      Eigen::IOFormat(Eigen::StreamPrecision, Eigen::DontAlignCols, ", ", ", ", "", "", "(", ")"));
  return out.str();
}

// Why a position and a w, x, y, z quaternion do not make a valid pose; nullopt when they do.
std::optional<std::string> poseError(const Eigen::Vector3d& position, const Eigen::Vector4d& wxyz,
                                     double unit_tolerance) {
  if (!position.allFinite()) return "position " + toText(position) + " is not finite";
  if (position.cwiseAbs().maxCoeff() > kMaxCoordinate) {
    return "position " + toText(position) + " is beyond +-" +
           std::to_string(static_cast<int64_t>(kMaxCoordinate / 1e3)) +
           " km: not a pose in a local map";
  }
  if (!wxyz.allFinite()) return "quaternion (w, x, y, z) " + toText(wxyz) + " is not finite";
  const double norm = wxyz.norm();
  if (std::abs(norm - 1.0) > unit_tolerance) {
    std::ostringstream out;
    out << "quaternion norm " << norm << " differs from 1 by more than " << unit_tolerance;
    return out.str();
  }
  return std::nullopt;
}

Eigen::Vector4d wxyzOf(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}

}  // namespace

Pose Pose::inverse() const {
  const Eigen::Quaterniond parent_to_child = orientation.conjugate();
  return Pose{-(parent_to_child * position), parent_to_child};
}

Pose Pose::operator*(const Pose& other) const {
  // Renormalized so that long chains of compositions do not drift off the unit sphere.
  return Pose{transform(other.position), (orientation * other.orientation).normalized()};
}

double Pose::yaw() const {
  const Eigen::Vector3d x_axis = orientation * Eigen::Vector3d::UnitX();
  return wrapAngle(std::atan2(x_axis.y(), x_axis.x()));
}

Pose Pose::fromYaw(const Eigen::Vector3d& position, double yaw) {
  return Pose{position, Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()))};
}

Eigen::Isometry3d Pose::isometry() const {
  Eigen::Isometry3d result = Eigen::Isometry3d::Identity();
  result.linear() = orientation.toRotationMatrix();
  result.translation() = position;
  return result;
}

Expected<Pose> poseFromArrays(const double position[3], const double orientation_wxyz[4],
                              double unit_tolerance) {
  const Eigen::Vector3d p(position[0], position[1], position[2]);
  const Eigen::Vector4d q(orientation_wxyz[0], orientation_wxyz[1], orientation_wxyz[2],
                          orientation_wxyz[3]);
  if (auto error = poseError(p, q, unit_tolerance)) return unexpected(*error);
  return Pose{p, Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized()};
}

void poseToArrays(const Pose& pose, double position[3], double orientation_wxyz[4]) {
  Eigen::Vector3d::Map(position) = pose.position;
  Eigen::Vector4d::Map(orientation_wxyz) = wxyzOf(pose.orientation);
}

Pose interpolate(const Pose& a, const Pose& b, double alpha) {
  if (!(alpha >= 0.0 && alpha <= 1.0)) {
    throw std::invalid_argument("interpolate: alpha " + std::to_string(alpha) +
                                " is outside [0, 1]");
  }
  // Eigen's slerp flips the sign of one quaternion when needed, so it takes the shorter arc.
  return Pose{(1.0 - alpha) * a.position + alpha * b.position,
              a.orientation.slerp(alpha, b.orientation).normalized()};
}

double wrapAngle(double angle) {
  const double wrapped = std::remainder(angle, 2.0 * std::numbers::pi);  // in [-pi, pi]
  return wrapped <= -std::numbers::pi ? wrapped + 2.0 * std::numbers::pi : wrapped;
}

PoseHistory::PoseHistory(PoseHistoryOptions options)
    : options_(options), timeline_("pose", options.clock_reset_after) {}

Timeline::Result PoseHistory::add(int64_t utime, const Pose& pose) {
  if (auto error = poseError(pose.position, wxyzOf(pose.orientation), kPoseHistoryUnitTolerance)) {
    return {Timeline::Verdict::kRefused, "pose at " + formatUtime(utime) + " refused: " + *error};
  }
  Timeline::Result time = timeline_.offer(utime);
  if (!time.accepted()) {
    time.reason = "pose at " + formatUtime(utime) + " refused: " + time.reason;
    return time;
  }
  if (time.verdict == Timeline::Verdict::kReanchored) poses_.clear();
  poses_.push_back({utime, Pose{pose.position, pose.orientation.normalized()}});
  while (poses_.back().utime - poses_.front().utime > options_.max_age_us) poses_.pop_front();
  return time;
}

PoseLookup PoseHistory::lookup(int64_t utime) const {
  using Status = PoseLookup::Status;
  const auto ok = [](const Pose& pose) { return PoseLookup{Status::kOk, pose, {}}; };
  const std::string query = "pose at " + formatUtime(utime);
  if (poses_.empty()) return {Status::kEmpty, {}, query + ": no pose stored yet"};
  if (utime < 0 || utime > kMaxUtime) return {Status::kTooOld, {}, query + ": not a time"};

  const auto after =
      std::lower_bound(poses_.begin(), poses_.end(), utime,
                       [](const Stamped& stamped, int64_t t) { return stamped.utime < t; });
  if (after != poses_.end() && after->utime == utime) return ok(after->pose);

  if (after == poses_.end()) {
    const Stamped& newest = poses_.back();
    if (utime - newest.utime <= options_.tolerance_us) return ok(newest.pose);
    return {Status::kNotYet,
            {},
            query + " not known yet: the newest is at " + formatUtime(newest.utime)};
  }
  if (after == poses_.begin()) {
    if (after->utime - utime <= options_.tolerance_us) return ok(after->pose);
    return {
        Status::kTooOld, {}, query + " is before the oldest kept, at " + formatUtime(after->utime)};
  }

  const Stamped& before = *std::prev(after);
  const int64_t gap = after->utime - before.utime;
  if (gap <= options_.max_interpolation_gap_us) {
    const double alpha = static_cast<double>(utime - before.utime) / static_cast<double>(gap);
    return ok(interpolate(before.pose, after->pose, alpha));
  }
  const bool before_is_nearer = utime - before.utime <= after->utime - utime;
  const Stamped& nearest = before_is_nearer ? before : *after;
  if (std::abs(utime - nearest.utime) <= options_.tolerance_us) return ok(nearest.pose);
  return {Status::kGap,
          {},
          query + " falls in a gap between poses at " + formatUtime(before.utime) + " and " +
              formatUtime(after->utime) + ", wider than max_interpolation_gap_us = " +
              std::to_string(options_.max_interpolation_gap_us)};
}

std::optional<int64_t> PoseHistory::newestUtime() const {
  if (poses_.empty()) return std::nullopt;
  return poses_.back().utime;
}

std::optional<int64_t> PoseHistory::oldestUtime() const {
  if (poses_.empty()) return std::nullopt;
  return poses_.front().utime;
}

}  // namespace thicket

// Rigid-body poses and a time-indexed pose buffer. Frames follow docs/design.md §3: world z up,
// body x forward / y left / z up; a Pose maps its child frame into its parent (body-to-world for a
// vehicle pose). Messages carry quaternions as w, x, y, z; poseFromArrays/poseToArrays adapt them.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "thicket/common/expected.h"
#include "thicket/common/time.h"

namespace thicket {

/// A rigid transform from a child frame to its parent, e.g. body-to-world.
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< child origin in the parent [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< child-to-parent rotation

  /// A point given in the child frame, expressed in the parent frame.
  Eigen::Vector3d transform(const Eigen::Vector3d& p_child) const {
    return position + orientation * p_child;
  }
  /// The parent-to-child transform.
  Pose inverse() const;
  /// Composition: (a * b) maps b's child frame into a's parent (world_T_camera =
  /// world_T_body * body_T_camera).
  Pose operator*(const Pose& other) const;
  /// Heading of the child x axis projected on the parent xy plane [rad], in (-pi, pi]; 0 when
  /// the x axis points straight up or down.
  double yaw() const;
  /// A level pose (no roll or pitch) with the given heading.
  static Pose fromYaw(const Eigen::Vector3d& position, double yaw);
  Eigen::Isometry3d isometry() const;
};

/// The largest coordinate a pose may have [m]: a vehicle's local map spans kilometres, and a
/// finite but absurd position (1e18 m) would overflow voxel indices downstream.
inline constexpr double kMaxCoordinate = 1e6;

/// A pose from message arrays (position [m]; unit quaternion w, x, y, z). Refuses non-finite
/// values, coordinates beyond ±kMaxCoordinate and quaternions whose norm differs from 1 by more
/// than unit_tolerance; renormalizes the rest.
Expected<Pose> poseFromArrays(const double position[3], const double orientation_wxyz[4],
                              double unit_tolerance = 1e-3);
/// Writes a pose into message arrays (quaternion as w, x, y, z).
void poseToArrays(const Pose& pose, double position[3], double orientation_wxyz[4]);

/// Linear in position, slerp on the shorter arc in orientation; alpha = 0 gives a, 1 gives b.
/// Throws std::invalid_argument when alpha is outside [0, 1].
Pose interpolate(const Pose& a, const Pose& b, double alpha);

/// The same angle in (-pi, pi].
double wrapAngle(double angle);

/// How PoseHistory answers lookups and how much it keeps.
struct PoseHistoryOptions {
  /// Widest gap between two stored poses that lookup interpolates across [µs]. A wider gap means
  /// the pose stream dropped out, and interpolating across it would invent motion.
  int64_t max_interpolation_gap_us = 200'000;
  /// A query within this distance of a stored pose, where interpolation cannot answer (past the
  /// newest, before the oldest, inside a gap), gets that pose [µs]. 0 (the default) keeps lookups
  /// deterministic: with a tolerance, the answer past the newest depends on message arrival order.
  int64_t tolerance_us = 0;
  /// Poses older than the newest by more than this are dropped [µs].
  int64_t max_age_us = 10'000'000;
  /// This many consecutive poses before the newest, each after the one before, start a new
  /// timeline: the history is cleared (Timeline in time.h). 0 never re-anchors.
  int clock_reset_after = Timeline::kDefaultResetAfter;
};

/// The answer to PoseHistory::lookup.
struct PoseLookup {
  enum class Status {
    kOk,
    kEmpty,   ///< nothing stored yet
    kNotYet,  ///< newer than the newest pose: wait for more
    kTooOld,  ///< before the oldest pose kept: will never be answerable
    kGap,     ///< the bracketing poses are too far apart to interpolate
  };
  Status status = Status::kEmpty;
  Pose pose;           ///< valid when status is kOk
  std::string reason;  ///< why not, for an operator; empty when kOk

  bool ok() const { return status == Status::kOk; }
};

/// Time-stamped poses in strictly increasing utime, answering "the pose at time t" by
/// interpolation. This is how a node pairs a depth frame with the pose at its utime (docs/design.md
/// §2): on kNotYet it keeps the frame pending until a newer pose arrives, never using the latest
/// pose.
class PoseHistory {
 public:
  explicit PoseHistory(PoseHistoryOptions options = {});

  /// Stores a pose (with its quaternion renormalized) and drops those older than max_age_us. On
  /// refusal nothing changes and the reason says why: utime not strictly after the newest pose
  /// or outside [0, kMaxUtime], non-finite values or coordinates beyond kMaxCoordinate, or a
  /// quaternion norm more than 1e-3 away from 1. A run of earlier poses re-anchors (kReanchored,
  /// with the reason): the history then holds only this pose.
  Timeline::Result add(int64_t utime, const Pose& pose);
  /// The pose at utime: exact hits return the stored pose, times between two poses interpolate.
  PoseLookup lookup(int64_t utime) const;

  size_t size() const { return poses_.size(); }
  bool empty() const { return poses_.empty(); }
  std::optional<int64_t> newestUtime() const;
  std::optional<int64_t> oldestUtime() const;
  const PoseHistoryOptions& options() const { return options_; }

 private:
  struct Stamped {
    int64_t utime;
    Pose pose;
  };
  PoseHistoryOptions options_;
  Timeline timeline_;
  std::deque<Stamped> poses_;
};

}  // namespace thicket

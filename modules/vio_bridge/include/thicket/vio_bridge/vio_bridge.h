// The VIO bridge's core: turns a visual-inertial odometry estimate, given in the VIO's own frames,
// into thicket's state estimate (docs/design.md §3: world z up; body x forward, y left, z up) and
// gates it. No LCM inside: odometry_t is used here only as the plain struct lcm-gen generates.
//
// Frames. The VIO reports the pose of its body frame B' (an IMU or a camera) in its world frame
// W'. Two fixed transforms, from configuration, bring that into thicket's frames:
//
//   T_world_body = T_world_vioworld · T_vioworld_viobody · T_viobody_body
//
// where T_world_vioworld is `vio_world_in_world` (the VIO's world frame in thicket's world) and
// T_viobody_body is `body_in_vio_body` (thicket's body frame in the VIO's body frame). Each is a
// position [m] and a unit quaternion w, x, y, z (the LCM convention), so a camera-like VIO frame
// (z forward, x right, y down) is written without Euler-angle ambiguities.
//
// Gate, decided from the message contents and utime only (never the wall clock). In this order:
//   1. any non-finite number → dropped (FLAG_NOT_FINITE);
//   2. |‖q‖ − 1| beyond quaternion_max_error → dropped; beyond quaternion_tolerance →
//      renormalized and flagged (FLAG_QUATERNION_NOT_UNIT, QUALITY_DEGRADED);
//   3. utime not after the previous accepted estimate → dropped (FLAG_TIME_BACKWARDS), unless
//      it completes a clock reset (below);
//   4. more than max_gap since the previous accepted estimate → FLAG_STALE, QUALITY_DEGRADED;
//   5. a step beyond the position or orientation bounds → FLAG_POSITION_JUMP /
//      FLAG_ORIENTATION_JUMP, QUALITY_LOST;
//   6. the estimator's own quality not GOOD → at least its quality, its flags and reason, and
//      FLAG_SOURCE_REPORTED.
// Non-finite values, far-from-unit quaternions and time going backwards are always dropped (there
// is nothing sound to publish); the other kinds are published with their flags, or dropped when
// their `on_*` option says "drop".
//
// Re-anchoring. Every estimate that passes checks 1–3 ("accepted") becomes the reference the next
// one is judged against, whether it was published or dropped by an `on_*` option, and even when it
// jumped: a VIO that resets jumps once, is flagged once, and is trusted again from the next
// consistent estimate. A jump or stale gap that was dropped is not hidden: its flags, its
// QUALITY and its reason are carried onto the next published estimate.
//
// Clock resets. A VIO that restarts, or a log that loops, starts a new timeline earlier than the
// reference, and a gate that only compared with the reference would drop it forever. When
// `clock_reset_after` consecutive estimates are all earlier than the reference and each is after
// the one before, the last of them starts the new timeline: it becomes the reference without being
// judged against the old one and is published LOST with FLAG_TIME_BACKWARDS and a reason saying
// the clock was reset; the next consistent estimate is GOOD again.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <thicket/odometry_t.hpp>

#include "thicket/common/geometry.h"
#include "thicket/common/params.h"
#include "thicket/common/time.h"

namespace thicket::vio_bridge {

/// A fixed transform from configuration: the child frame's origin and orientation in its parent.
struct Extrinsic {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< [m]
  std::vector<double> orientation = {1, 0, 0, 0};      ///< unit quaternion w, x, y, z

  void declare(Params& p);
  /// The transform; throws std::invalid_argument unless orientation holds 4 numbers whose norm
  /// is 1 within 1e-6 (`name` prefixes the message).
  Pose pose(const std::string& name) const;
};

struct VioBridgeOptions {
  /// T_world_vioworld: the VIO's world frame in thicket's world.
  Extrinsic vio_world_in_world;
  /// T_viobody_body: thicket's body frame (x forward, y left, z up) in the VIO's body frame.
  Extrinsic body_in_vio_body;
  /// How the VIO reports linear velocity: "world" (its world frame, as odometry_t says) or
  /// "body" (its body frame, as some VIOs do). Angular velocity is always in its body frame.
  std::string input_linear_velocity_frame = "world";

  /// A step between consecutive accepted estimates is a position jump when it exceeds
  /// max_speed · dt + position_slack, or max_position_step whatever dt.
  double max_speed = 10.0;         ///< [m/s]
  double position_slack = 0.05;    ///< position noise allowed on top of max_speed · dt [m]
  double max_position_step = 1.0;  ///< [m]
  /// A rotation between consecutive accepted estimates is a jump when its angle exceeds
  /// max_angular_rate · dt + orientation_slack.
  double max_angular_rate = 6.0;    ///< [rad/s]
  double orientation_slack = 0.02;  ///< [rad]
  /// |‖q‖ − 1| up to quaternion_tolerance: renormalized silently; up to quaternion_max_error:
  /// renormalized and flagged; beyond: dropped.
  double quaternion_tolerance = 1e-3;
  double quaternion_max_error = 0.05;
  /// A gap between consecutive accepted estimates longer than this makes the stream stale [s].
  double max_gap = 0.5;
  /// This many consecutive estimates earlier than the reference, each after the one before, are a
  /// clock reset (see the file comment); 0 never re-anchors.
  int clock_reset_after = 10;

  /// "flag" (publish with the flag) or "drop", for each kind that can be published.
  std::string on_quaternion_not_unit = "flag";
  std::string on_stale = "flag";
  std::string on_position_jump = "flag";
  std::string on_orientation_jump = "flag";
  std::string on_source_not_good = "flag";

  void declare(Params& p);
};

/// T_world_body = T_world_vioworld · T_vioworld_viobody · T_viobody_body applied to a whole
/// estimate (see convert()).
class FrameConversion {
 public:
  /// Throws std::invalid_argument on a malformed extrinsic or velocity frame.
  explicit FrameConversion(const VioBridgeOptions& options);

  /// The estimate in thicket's frames. `vio` must be finite with a unit quaternion (the gate
  /// checks first). Quality, flags, reason, utime and sequence are copied unchanged.
  ///  - position, orientation: of the body frame in thicket's world;
  ///  - linear velocity of the body origin in thicket's world, with the lever-arm term:
  ///    v_body = v_viobody + ω × r, ω and r = R_vioworld_viobody · t_viobody_body both in the
  ///    VIO's world frame, then rotated into thicket's world;
  ///  - angular velocity in thicket's body frame: R_viobody_body⁻¹ · ω_viobody;
  ///  - covariances propagated to first order, Σ' = J Σ Jᵀ, in the conventions of odometry_t
  ///    (position, then rotation as a small-angle perturbation in the world frame; the input's
  ///    in the VIO's world). Pose: J = [R_a, −R_a [R_v t]×; 0, R_a], R_a = R_world_vioworld,
  ///    R_v = R_vioworld_viobody, t the lever arm; the −[R_v t]× block is how an orientation error
  ///    moves a body origin that is off the VIO's origin. Twist: J = [R_a·R_in, −R_a R_v [t]×;
  ///    0, R_viobody_body⁻¹] (R_in = I, or R_v for body-frame velocities), the orientation taken
  ///    as exact. An all-zero covariance ("not provided") stays all zero.
  odometry_t convert(const odometry_t& vio) const;

  const Pose& worldFromVioWorld() const { return world_T_vioworld_; }
  const Pose& vioBodyFromBody() const { return viobody_T_body_; }

 private:
  Pose world_T_vioworld_;
  Pose viobody_T_body_;
  bool velocity_in_body_ = false;
};

/// The bit index of each odometry_t::FLAG_* (1 << i), for per-flag counters.
inline constexpr int kNumFlags = 7;
/// "not_finite", "quaternion_not_unit", "position_jump", "orientation_jump", "time_backwards",
/// "stale", "source_reported".
const char* flagName(int bit);
/// The names of the flags set in `flags`, joined by '+'; "none" when there are none.
std::string describeFlags(int32_t flags);

/// What the bridge did with one estimate.
struct GateResult {
  bool publish = false;  ///< false: dropped
  /// The estimate in thicket's frames with quality, flags and reason set (reason empty when
  /// GOOD, as odometry_t asks); meaningful only when publish. The sequence is the input's: the
  /// publisher numbers its own output.
  odometry_t estimate{};
  /// Why the estimate was published as it was, or dropped; never empty ("good" when nothing is
  /// wrong).
  std::string reason;
  int8_t quality = odometry_t::QUALITY_GOOD;  ///< what it was judged, also when dropped
  int32_t flags = odometry_t::FLAG_NONE;      ///< every problem found, also when dropped
};

/// What the bridge has seen, for an operator and for tests.
struct VioBridgeHealth {
  int64_t received = 0;
  int64_t published = 0;
  int64_t dropped = 0;
  std::array<int64_t, 3> published_by_quality{};  ///< indexed by QUALITY_*
  /// Published estimates carrying each flag bit (see flagName).
  std::array<int64_t, kNumFlags> flagged{};
  /// Dropped estimates by the flag that dropped them (the first of the gate order).
  std::array<int64_t, kNumFlags> dropped_by_flag{};
  int64_t clock_resets = 0;  ///< new timelines started (see the file comment)
  std::string last_reason;   ///< of the latest estimate that was not GOOD, or "" if none
  int64_t last_problem_utime = 0;

  /// One line: "N in, P published (G good, D degraded, L lost), X dropped (not_finite 1, ...);
  /// clock resets R; flagged: stale 1, ...; last problem: ..." (zero counts left out).
  std::string summary() const;
};

/// The gate and the conversion, with the state that judging consecutive estimates needs.
class VioBridge {
 public:
  /// Throws std::invalid_argument on inconsistent options (see VioBridgeOptions).
  explicit VioBridge(const VioBridgeOptions& options);

  /// Judges and converts one VIO estimate (see the file comment for the rules).
  GateResult process(const odometry_t& vio);

  const VioBridgeHealth& health() const { return health_; }
  const VioBridgeOptions& options() const { return options_; }

 private:
  struct Reference {
    int64_t utime = 0;
    Pose world_T_body;
  };
  struct Carried {
    int8_t quality = odometry_t::QUALITY_GOOD;
    int32_t flags = odometry_t::FLAG_NONE;
    std::string reason;
  };

  GateResult drop(int32_t flag, GateResult result);

  VioBridgeOptions options_;
  FrameConversion conversion_;
  bool has_reference_ = false;
  Reference reference_;
  Carried carried_;
  /// The estimates' stamps: strictly increasing, re-anchored after a clock reset.
  Timeline timeline_;
  VioBridgeHealth health_;
};

}  // namespace thicket::vio_bridge

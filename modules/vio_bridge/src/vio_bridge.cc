#include "thicket/vio_bridge/vio_bridge.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <Eigen/Geometry>

#include "thicket/common/time.h"

namespace thicket::vio_bridge {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using RowMajor6d = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;

constexpr int32_t kKnownFlags = (1 << kNumFlags) - 1;
// A jump or a stale gap is a discontinuity of the stream: when the estimate showing it is
// dropped, the next published one says so.
constexpr int32_t kDiscontinuityFlags = int32_t{odometry_t::FLAG_STALE} |
                                        int32_t{odometry_t::FLAG_POSITION_JUMP} |
                                        int32_t{odometry_t::FLAG_ORIENTATION_JUMP};

const char* const kQualityNames[] = {"good", "degraded", "lost"};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Vector3d vec3(const double a[3]) {
  return {a[0], a[1], a[2]};
}

void store(const Eigen::Vector3d& v, double a[3]) {
  for (int i = 0; i < 3; ++i) a[i] = v[i];
}

// Σ' = J Σ Jᵀ on a row-major 6x6 array.
void propagate(const Matrix6d& jacobian, double covariance[36]) {
  Eigen::Map<RowMajor6d> sigma(covariance);
  const RowMajor6d rotated = jacobian * sigma * jacobian.transpose();
  sigma = rotated;
}

// The first non-finite value of the message, named, or "".
std::string firstNonFinite(const odometry_t& m) {
  const auto check = [](const char* name, const double* values, int n) -> std::string {
    for (int i = 0; i < n; ++i) {
      if (!std::isfinite(values[i])) {
        char text[96];
        std::snprintf(text, sizeof text, "%s[%d] is %g", name, i, values[i]);
        return text;
      }
    }
    return {};
  };
  for (const std::string& found :
       {check("position", m.position, 3), check("orientation", m.orientation, 4),
        check("linear_velocity", m.linear_velocity, 3),
        check("angular_velocity", m.angular_velocity, 3),
        check("pose_covariance", m.pose_covariance, 36),
        check("twist_covariance", m.twist_covariance, 36)}) {
    if (!found.empty()) return found;
  }
  return {};
}

std::string format(const char* pattern, double a, double b = 0, double c = 0) {
  char text[160];
  std::snprintf(text, sizeof text, pattern, a, b, c);
  return text;
}

void addProblem(GateResult& result, int32_t flag, int8_t quality, const std::string& reason) {
  result.flags |= flag;
  result.quality = std::max(result.quality, quality);
  if (!result.reason.empty()) result.reason += "; ";
  result.reason += reason;
}

void declareAction(Params& p, const std::string& key, std::string& value, const char* what) {
  p.choice(key, value, {"flag", "drop"},
           std::string("what to do with ") + what + ": publish it flagged, or drop it");
}

void checkAction(const std::string& key, const std::string& value) {
  if (value != "flag" && value != "drop") {
    throw std::invalid_argument("vio_bridge: " + key + " must be 'flag' or 'drop', not '" + value +
                                "'");
  }
}

}  // namespace

// ---- options ----------------------------------------------------------------------------------

void Extrinsic::declare(Params& p) {
  p("position", position, "origin of the child frame in the parent frame [m]");
  p("orientation", orientation, "child-to-parent rotation, unit quaternion w, x, y, z",
    Range::between(-1, 1));
}

Pose Extrinsic::pose(const std::string& name) const {
  if (!position.allFinite()) {
    throw std::invalid_argument("vio_bridge: " + name + ".position must be finite");
  }
  if (orientation.size() != 4) {
    throw std::invalid_argument("vio_bridge: " + name +
                                ".orientation must have 4 elements (w, x, y, z), not " +
                                std::to_string(orientation.size()));
  }
  const Eigen::Quaterniond q(orientation[0], orientation[1], orientation[2], orientation[3]);
  if (!(std::abs(q.norm() - 1) <= 1e-3)) {
    throw std::invalid_argument("vio_bridge: " + name +
                                ".orientation must be a unit quaternion (norm " +
                                std::to_string(q.norm()) + ")");
  }
  Pose pose;
  pose.position = position;
  pose.orientation = q.normalized();
  return pose;
}

void VioBridgeOptions::declare(Params& p) {
  p.group("vio_world_in_world", vio_world_in_world,
          "T_world_vioworld: the VIO's world frame in thicket's world (z up)");
  p.group("body_in_vio_body", body_in_vio_body,
          "T_viobody_body: thicket's body frame (x forward, y left, z up) in the VIO's body frame "
          "(its IMU or camera)");
  p.choice("input_linear_velocity_frame", input_linear_velocity_frame, {"world", "body"},
           "frame of the VIO's linear velocity: its world frame, or its body frame");
  p("max_speed", max_speed, "a faster step between estimates is a position jump [m/s]",
    Range::positive());
  p("position_slack", position_slack, "position noise allowed on top of max_speed * dt [m]",
    Range::atLeast(0));
  p("max_position_step", max_position_step,
    "a longer step between estimates is a position jump, whatever the time between them [m]",
    Range::positive());
  p("max_angular_rate", max_angular_rate,
    "a faster rotation between estimates is an orientation jump [rad/s]", Range::positive());
  p("orientation_slack", orientation_slack,
    "orientation noise allowed on top of max_angular_rate * dt [rad]", Range::atLeast(0));
  p("quaternion_tolerance", quaternion_tolerance,
    "| |q| - 1 | up to this is renormalized silently, above it the estimate is flagged",
    Range::between(0, 0.5));
  p("quaternion_max_error", quaternion_max_error,
    "| |q| - 1 | above this drops the estimate (>= quaternion_tolerance)", Range::between(0, 0.5));
  p("max_gap", max_gap, "a longer gap between estimates makes the next one stale [s]",
    Range::positive());
  p("clock_reset_after", clock_reset_after,
    "this many consecutive estimates earlier than the last accepted one, each after the one "
    "before, mean the VIO's clock was reset: the last starts the new timeline, published lost "
    "(0: never)",
    Range::atLeast(0));
  declareAction(p, "on_quaternion_not_unit", on_quaternion_not_unit,
                "a renormalized quaternion (between the tolerance and the max error)");
  declareAction(p, "on_stale", on_stale, "the first estimate after a gap longer than max_gap");
  declareAction(p, "on_position_jump", on_position_jump, "a position jump");
  declareAction(p, "on_orientation_jump", on_orientation_jump, "an orientation jump");
  declareAction(p, "on_source_not_good", on_source_not_good,
                "an estimate its estimator reports degraded or lost");
}

// ---- flags and health -------------------------------------------------------------------------

const char* flagName(int bit) {
  static const char* const kNames[kNumFlags] = {
      "not_finite", "quaternion_not_unit", "position_jump", "orientation_jump", "time_backwards",
      "stale",      "source_reported"};
  return bit >= 0 && bit < kNumFlags ? kNames[bit] : "unknown";
}

std::string describeFlags(int32_t flags) {
  std::string text;
  for (int bit = 0; bit < kNumFlags; ++bit) {
    if ((flags & (1 << bit)) == 0) continue;
    if (!text.empty()) text += "+";
    text += flagName(bit);
  }
  return text.empty() ? "none" : text;
}

std::string VioBridgeHealth::summary() const {
  const auto counts = [](const std::array<int64_t, kNumFlags>& by_flag) {
    std::string text;
    for (int bit = 0; bit < kNumFlags; ++bit) {
      if (by_flag[bit] == 0) continue;
      if (!text.empty()) text += ", ";
      text += std::string(flagName(bit)) + " " + std::to_string(by_flag[bit]);
    }
    return text;
  };
  std::string text = std::to_string(received) + " estimates in, " + std::to_string(published) +
                     " published (" + std::to_string(published_by_quality[0]) + " good, " +
                     std::to_string(published_by_quality[1]) + " degraded, " +
                     std::to_string(published_by_quality[2]) + " lost), " +
                     std::to_string(dropped) + " dropped";
  if (dropped > 0) text += " (" + counts(dropped_by_flag) + ")";
  if (clock_resets > 0) text += "; clock resets " + std::to_string(clock_resets);
  const std::string flagged_text = counts(flagged);
  if (!flagged_text.empty()) text += "; flagged: " + flagged_text;
  if (!last_reason.empty()) {
    text += "; last problem at " + formatUtime(last_problem_utime) + ": " + last_reason;
  }
  return text;
}

// ---- frame conversion -------------------------------------------------------------------------

FrameConversion::FrameConversion(const VioBridgeOptions& options)
    : world_T_vioworld_(options.vio_world_in_world.pose("vio_world_in_world")),
      viobody_T_body_(options.body_in_vio_body.pose("body_in_vio_body")) {
  if (options.input_linear_velocity_frame != "world" &&
      options.input_linear_velocity_frame != "body") {
    throw std::invalid_argument(
        "vio_bridge: input_linear_velocity_frame must be 'world' or 'body', not '" +
        options.input_linear_velocity_frame + "'");
  }
  velocity_in_body_ = options.input_linear_velocity_frame == "body";
}

odometry_t FrameConversion::convert(const odometry_t& vio) const {
  odometry_t out = vio;
  Pose vioworld_T_viobody;
  vioworld_T_viobody.position = vec3(vio.position);
  vioworld_T_viobody.orientation = Eigen::Quaterniond(vio.orientation[0], vio.orientation[1],
                                                      vio.orientation[2], vio.orientation[3]);
  const Pose world_T_body = world_T_vioworld_ * vioworld_T_viobody * viobody_T_body_;
  poseToArrays(world_T_body, out.position, out.orientation);

  const Eigen::Matrix3d r_a = world_T_vioworld_.orientation.toRotationMatrix();
  const Eigen::Matrix3d r_v = vioworld_T_viobody.orientation.toRotationMatrix();
  const Eigen::Matrix3d r_e = viobody_T_body_.orientation.toRotationMatrix();
  const Eigen::Vector3d& lever = viobody_T_body_.position;  // body origin in the VIO body frame
  const Eigen::Vector3d lever_vioworld = r_v * lever;

  // Velocities: ω in the VIO's world frame, then v_body = v_viobody + ω × r.
  const Eigen::Matrix3d r_velocity = velocity_in_body_ ? r_v : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d omega_viobody = vec3(vio.angular_velocity);
  const Eigen::Vector3d v_viobody = r_velocity * vec3(vio.linear_velocity);
  const Eigen::Vector3d v_body = v_viobody + (r_v * omega_viobody).cross(lever_vioworld);
  store(r_a * v_body, out.linear_velocity);
  store(r_e.transpose() * omega_viobody, out.angular_velocity);

  Matrix6d pose_jacobian = Matrix6d::Zero();
  pose_jacobian.topLeftCorner<3, 3>() = r_a;
  pose_jacobian.topRightCorner<3, 3>() = -r_a * skew(lever_vioworld);
  pose_jacobian.bottomRightCorner<3, 3>() = r_a;
  propagate(pose_jacobian, out.pose_covariance);

  Matrix6d twist_jacobian = Matrix6d::Zero();
  twist_jacobian.topLeftCorner<3, 3>() = r_a * r_velocity;
  twist_jacobian.topRightCorner<3, 3>() = -r_a * r_v * skew(lever);
  twist_jacobian.bottomRightCorner<3, 3>() = r_e.transpose();
  propagate(twist_jacobian, out.twist_covariance);
  return out;
}

// ---- the gate ---------------------------------------------------------------------------------

VioBridge::VioBridge(const VioBridgeOptions& options)
    : options_(options),
      conversion_(options),
      timeline_("estimate", std::max(0, options.clock_reset_after)) {  // checked below
  const auto positive = [](const char* key, double value) {
    if (!(value > 0) || !std::isfinite(value)) {
      throw std::invalid_argument(std::string("vio_bridge: ") + key + " must be positive");
    }
  };
  const auto non_negative = [](const char* key, double value) {
    if (!(value >= 0) || !std::isfinite(value)) {
      throw std::invalid_argument(std::string("vio_bridge: ") + key + " must be >= 0");
    }
  };
  positive("max_speed", options.max_speed);
  positive("max_position_step", options.max_position_step);
  positive("max_angular_rate", options.max_angular_rate);
  positive("max_gap", options.max_gap);
  if (options.clock_reset_after < 0) {
    throw std::invalid_argument("vio_bridge: clock_reset_after must be >= 0");
  }
  non_negative("position_slack", options.position_slack);
  non_negative("orientation_slack", options.orientation_slack);
  non_negative("quaternion_tolerance", options.quaternion_tolerance);
  if (!(options.quaternion_max_error >= options.quaternion_tolerance) ||
      !(options.quaternion_max_error <= 0.5)) {
    throw std::invalid_argument(
        "vio_bridge: quaternion_max_error must lie in [quaternion_tolerance, 0.5]");
  }
  checkAction("on_quaternion_not_unit", options.on_quaternion_not_unit);
  checkAction("on_stale", options.on_stale);
  checkAction("on_position_jump", options.on_position_jump);
  checkAction("on_orientation_jump", options.on_orientation_jump);
  checkAction("on_source_not_good", options.on_source_not_good);
}

GateResult VioBridge::drop(int32_t flag, GateResult result) {
  result.publish = false;
  ++health_.dropped;
  for (int bit = 0; bit < kNumFlags; ++bit) {
    if (flag == (1 << bit)) ++health_.dropped_by_flag[bit];
  }
  result.reason = "dropped: " + result.reason;
  health_.last_reason = result.reason;
  return result;
}

GateResult VioBridge::process(const odometry_t& vio) {
  ++health_.received;
  GateResult result;
  const int64_t utime = vio.utime;

  // 1. Every number finite.
  if (const std::string bad = firstNonFinite(vio); !bad.empty()) {
    addProblem(result, odometry_t::FLAG_NOT_FINITE, odometry_t::QUALITY_LOST, "not finite: " + bad);
    health_.last_problem_utime = utime;
    return drop(odometry_t::FLAG_NOT_FINITE, result);
  }

  // 2. A unit quaternion, or close enough to renormalize.
  odometry_t unit = vio;
  const Eigen::Quaterniond q(vio.orientation[0], vio.orientation[1], vio.orientation[2],
                             vio.orientation[3]);
  const double norm_error = std::abs(q.norm() - 1);
  if (!(norm_error <= options_.quaternion_max_error)) {
    addProblem(result, odometry_t::FLAG_QUATERNION_NOT_UNIT, odometry_t::QUALITY_LOST,
               format("quaternion norm %.6g is too far from 1 (max error %g)", q.norm(),
                      options_.quaternion_max_error));
    health_.last_problem_utime = utime;
    return drop(odometry_t::FLAG_QUATERNION_NOT_UNIT, result);
  }
  const Eigen::Quaterniond q_unit = q.normalized();
  unit.orientation[0] = q_unit.w();
  unit.orientation[1] = q_unit.x();
  unit.orientation[2] = q_unit.y();
  unit.orientation[3] = q_unit.z();
  if (norm_error > options_.quaternion_tolerance) {
    addProblem(result, odometry_t::FLAG_QUATERNION_NOT_UNIT, odometry_t::QUALITY_DEGRADED,
               format("quaternion norm %.6g renormalized (tolerance %g)", q.norm(),
                      options_.quaternion_tolerance));
  }

  // 3. Time strictly increasing, unless the clock was reset (Timeline).
  const Timeline::Result time = timeline_.offer(utime);
  if (time.verdict != Timeline::Verdict::kAccepted) {
    health_.last_problem_utime = utime;
    addProblem(result, odometry_t::FLAG_TIME_BACKWARDS, odometry_t::QUALITY_LOST, time.reason);
    if (!time.accepted()) return drop(odometry_t::FLAG_TIME_BACKWARDS, result);
    ++health_.clock_resets;
    has_reference_ = false;
  }

  // Accepted: convert, judge against the reference, and make it the next reference.
  result.estimate = conversion_.convert(unit);
  Pose world_T_body;
  world_T_body.position = vec3(result.estimate.position);
  world_T_body.orientation =
      Eigen::Quaterniond(result.estimate.orientation[0], result.estimate.orientation[1],
                         result.estimate.orientation[2], result.estimate.orientation[3]);
  if (has_reference_) {
    const double dt = toSeconds(utime - reference_.utime);
    // 4. Stale: the stream resumes after a gap.
    if (dt > options_.max_gap) {
      addProblem(
          result, odometry_t::FLAG_STALE, odometry_t::QUALITY_DEGRADED,
          format("resumed after %.3f s without an estimate (max gap %g s)", dt, options_.max_gap));
    }
    // 5. Jumps.
    const double step = (world_T_body.position - reference_.world_T_body.position).norm();
    const double allowed_step =
        std::min(options_.max_speed * dt + options_.position_slack, options_.max_position_step);
    if (step > allowed_step) {
      addProblem(
          result, odometry_t::FLAG_POSITION_JUMP, odometry_t::QUALITY_LOST,
          format("position jumped %.3f m in %.3f s (allowed %.3f m)", step, dt, allowed_step));
    }
    const double angle =
        world_T_body.orientation.angularDistance(reference_.world_T_body.orientation);
    const double allowed_angle = options_.max_angular_rate * dt + options_.orientation_slack;
    if (angle > allowed_angle) {
      addProblem(result, odometry_t::FLAG_ORIENTATION_JUMP, odometry_t::QUALITY_LOST,
                 format("orientation jumped %.3f rad in %.3f s (allowed %.3f rad)", angle, dt,
                        allowed_angle));
    }
  }
  // 6. What the estimator says about itself. A quality outside QUALITY_* counts as lost.
  if (vio.quality != odometry_t::QUALITY_GOOD) {
    const bool known =
        vio.quality == odometry_t::QUALITY_DEGRADED || vio.quality == odometry_t::QUALITY_LOST;
    const int8_t source_quality = known ? vio.quality : odometry_t::QUALITY_LOST;
    std::string said = known ? std::string("the estimator reports it ") +
                                   kQualityNames[static_cast<int>(vio.quality)]
                             : "the estimator reports an unknown quality " +
                                   std::to_string(static_cast<int>(vio.quality));
    if (!vio.reason.empty()) said += ": " + vio.reason;
    addProblem(result, odometry_t::FLAG_SOURCE_REPORTED | (vio.flags & kKnownFlags), source_quality,
               said);
  }
  has_reference_ = true;
  reference_ = {utime, world_T_body};
  if (result.flags != odometry_t::FLAG_NONE) health_.last_problem_utime = utime;

  // Dropped by an on_* option: the first kind, in gate order, whose option says so.
  const std::pair<int32_t, const std::string*> actions[] = {
      {odometry_t::FLAG_QUATERNION_NOT_UNIT, &options_.on_quaternion_not_unit},
      {odometry_t::FLAG_STALE, &options_.on_stale},
      {odometry_t::FLAG_POSITION_JUMP, &options_.on_position_jump},
      {odometry_t::FLAG_ORIENTATION_JUMP, &options_.on_orientation_jump},
      {odometry_t::FLAG_SOURCE_REPORTED, &options_.on_source_not_good}};
  for (const auto& [flag, action] : actions) {
    if ((result.flags & flag) == 0 || *action != "drop") continue;
    if ((result.flags & kDiscontinuityFlags) != 0) {
      const int32_t discontinuity = result.flags & kDiscontinuityFlags;
      carried_.flags |= discontinuity;
      const int8_t quality = discontinuity == odometry_t::FLAG_STALE
                                 ? int8_t{odometry_t::QUALITY_DEGRADED}
                                 : int8_t{odometry_t::QUALITY_LOST};
      carried_.quality = std::max(carried_.quality, quality);
      if (!carried_.reason.empty()) carried_.reason += "; ";
      carried_.reason +=
          "after an estimate dropped at " + formatUtime(utime) + " (" + result.reason + ")";
    }
    return drop(flag, result);
  }

  if (carried_.flags != odometry_t::FLAG_NONE) {
    addProblem(result, carried_.flags, carried_.quality, carried_.reason);
    carried_ = {};
  }
  result.publish = true;
  result.estimate.quality = result.quality;
  result.estimate.flags = result.flags;
  result.estimate.reason = result.reason;
  ++health_.published;
  ++health_.published_by_quality[static_cast<size_t>(result.quality)];
  for (int bit = 0; bit < kNumFlags; ++bit) {
    if ((result.flags & (1 << bit)) != 0) ++health_.flagged[bit];
  }
  if (result.flags == odometry_t::FLAG_NONE) {
    result.reason = "good";
  } else {
    health_.last_reason = result.reason;
  }
  return result;
}

}  // namespace thicket::vio_bridge

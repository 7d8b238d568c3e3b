// The VIO bridge's frame conversion against poses, velocities and covariances computed by hand:
// a VIO whose world is rotated 90° about z and shifted, tracking a camera-like frame (z forward,
// x right, y down) mounted 10 cm ahead of thicket's body origin.
#include <cmath>

#include <gtest/gtest.h>

#include <thicket/odometry_t.hpp>

#include "thicket/vio_bridge/vio_bridge.h"

namespace thicket::vio_bridge {
namespace {

const double c = std::sqrt(0.5);

// T_world_vioworld: the VIO's world is thicket's world turned +90° about z (its x is thicket's
// y, its y is thicket's -x) with its origin at (10, 20, 1).
// T_viobody_body: the camera C sits at (0.1, 0, 0) in the body with R_body_cam columns
// x_c = (0, -1, 0), y_c = (0, 0, -1), z_c = (1, 0, 0), i.e. R_body_cam = Rz(-90°)·Rx(-90°),
// q_body_cam = (½, -½, ½, -½). Its inverse: the body origin is 10 cm behind the camera along its
// optical axis, t = (0, 0, -0.1), and q_cam_body = (½, ½, -½, ½).
VioBridgeOptions cameraOptions() {
  VioBridgeOptions o;
  o.vio_world_in_world.position = {10, 20, 1};
  o.vio_world_in_world.orientation = {c, 0, 0, c};
  o.body_in_vio_body.position = {0, 0, -0.1};
  o.body_in_vio_body.orientation = {0.5, 0.5, -0.5, 0.5};
  return o;
}

// The vehicle, level and yawed +90° in the VIO's world (facing the VIO's +y), rotating at
// ω_body = (0.2, 0.3, 1) rad/s and moving at (0, 0.5, 0) m/s in the VIO's world at the camera.
// The camera's orientation in the VIO world: R_v = Rz(90°)·R_body_cam; its axes are
// x_c = (1, 0, 0), y_c = (0, 0, -1), z_c = (0, 1, 0), i.e. R_v = Rx(-90°), q_v = (c, -c, 0, 0).
// ω in the VIO world: Rz(90°)·(0.2, 0.3, 1) = (-0.3, 0.2, 1); in the camera frame (dot products
// with x_c, y_c, z_c): (-0.3, -1, 0.2).
odometry_t cameraEstimate() {
  odometry_t m{};
  m.utime = 5'000'000;
  m.sequence = 17;
  m.position[0] = 1, m.position[1] = 2, m.position[2] = 3;
  m.orientation[0] = c, m.orientation[1] = -c, m.orientation[2] = 0, m.orientation[3] = 0;
  m.linear_velocity[0] = 0, m.linear_velocity[1] = 0.5, m.linear_velocity[2] = 0;
  m.angular_velocity[0] = -0.3, m.angular_velocity[1] = -1, m.angular_velocity[2] = 0.2;
  return m;
}

TEST(FrameConversion, CameraVioInARotatedWorldGivesTheHandComputedState) {
  const odometry_t out = FrameConversion(cameraOptions()).convert(cameraEstimate());
  // Body origin in the VIO world: camera + R_v·t = (1, 2, 3) + (-0.1)·z_c = (1, 1.9, 3).
  // In thicket's world: Rz(90°)·(1, 1.9, 3) + (10, 20, 1) = (-1.9, 1, 3) + (10, 20, 1).
  EXPECT_NEAR(out.position[0], 8.1, 1e-12);
  EXPECT_NEAR(out.position[1], 21.0, 1e-12);
  EXPECT_NEAR(out.position[2], 4.0, 1e-12);
  // R_world_body = Rz(90°)·Rz(90°) = Rz(180°): q = ±(0, 0, 0, 1).
  const double sign = out.orientation[3] < 0 ? -1 : 1;
  EXPECT_NEAR(sign * out.orientation[0], 0, 1e-12);
  EXPECT_NEAR(sign * out.orientation[1], 0, 1e-12);
  EXPECT_NEAR(sign * out.orientation[2], 0, 1e-12);
  EXPECT_NEAR(sign * out.orientation[3], 1, 1e-12);
  // Lever arm r = body - camera = (0, -0.1, 0) in the VIO world;
  // ω × r = (-0.3, 0.2, 1) × (0, -0.1, 0) = (0.1, 0, 0.03): the yaw rate swings the body origin,
  // 10 cm behind the camera, sideways, and the pitch rate moves it up.
  // v_body (VIO world) = (0, 0.5, 0) + (0.1, 0, 0.03) = (0.1, 0.5, 0.03);
  // in thicket's world Rz(90°)·v = (-0.5, 0.1, 0.03).
  EXPECT_NEAR(out.linear_velocity[0], -0.5, 1e-12);
  EXPECT_NEAR(out.linear_velocity[1], 0.1, 1e-12);
  EXPECT_NEAR(out.linear_velocity[2], 0.03, 1e-12);
  // ω back in the body frame: R_body_cam·(-0.3, -1, 0.2) = (0.2, 0.3, 1).
  EXPECT_NEAR(out.angular_velocity[0], 0.2, 1e-12);
  EXPECT_NEAR(out.angular_velocity[1], 0.3, 1e-12);
  EXPECT_NEAR(out.angular_velocity[2], 1.0, 1e-12);
  // Everything else passes through.
  EXPECT_EQ(out.utime, 5'000'000);
  EXPECT_EQ(out.sequence, 17);
}

TEST(FrameConversion, BodyFrameVelocityInputGivesTheSameState) {
  VioBridgeOptions options = cameraOptions();
  options.input_linear_velocity_frame = "body";
  odometry_t in = cameraEstimate();
  // (0, 0.5, 0) in the VIO world is 0.5 along z_c: (0, 0, 0.5) in the camera frame.
  in.linear_velocity[0] = 0, in.linear_velocity[1] = 0, in.linear_velocity[2] = 0.5;
  const odometry_t out = FrameConversion(options).convert(in);
  EXPECT_NEAR(out.linear_velocity[0], -0.5, 1e-12);
  EXPECT_NEAR(out.linear_velocity[1], 0.1, 1e-12);
  EXPECT_NEAR(out.linear_velocity[2], 0.03, 1e-12);
}

TEST(FrameConversion, CovariancesAreRotatedAndTheLeverArmCouplesYawToPosition) {
  odometry_t in = cameraEstimate();
  // Pose: position variances 1, 4, 9 along the VIO world's axes; yaw variance 0.01.
  in.pose_covariance[0] = 1, in.pose_covariance[7] = 4, in.pose_covariance[14] = 9;
  in.pose_covariance[35] = 0.01;
  // Twist: velocity variances 0.01, 0.02, 0.03 (VIO world); ω variances 0.1, 0.2, 0.3 (camera).
  in.twist_covariance[0] = 0.01, in.twist_covariance[7] = 0.02, in.twist_covariance[14] = 0.03;
  in.twist_covariance[21] = 0.1, in.twist_covariance[28] = 0.2, in.twist_covariance[35] = 0.3;
  const odometry_t out = FrameConversion(cameraOptions()).convert(in);
  const auto expect_pose = [&](const double expected[36]) {
    for (int i = 0; i < 36; ++i) EXPECT_NEAR(out.pose_covariance[i], expected[i], 1e-12) << i;
  };
  const auto expect_twist = [&](const double expected[36]) {
    for (int i = 0; i < 36; ++i) EXPECT_NEAR(out.twist_covariance[i], expected[i], 1e-12) << i;
  };
  // Rz(90°) swaps the x and y variances. A yaw error δψ (about z, the same in both worlds)
  // swings the body origin about the camera: δθ × r = (0, 0, δψ) × (0, -0.1, 0) =
  // (0.1 δψ, 0, 0) in the VIO world, (0, 0.1 δψ, 0) in thicket's. So var(y) gains
  // 0.1² · 0.01 = 1e-4 and cov(y, yaw) = 0.1 · 0.01 = 1e-3.
  double pose[36] = {};
  pose[0] = 4, pose[7] = 1 + 1e-4, pose[14] = 9, pose[35] = 0.01;
  pose[1 * 6 + 5] = pose[5 * 6 + 1] = 1e-3;
  expect_pose(pose);
  // ω in the body: wx = ω_cz, wy = -ω_cx, wz = -ω_cy: variances 0.3, 0.1, 0.2.
  // v (VIO world) gains R_v (ω_c × t) = R_v (-0.1 ω_cy, 0.1 ω_cx, 0) = (-0.1 ω_cy, 0, -0.1 ω_cx);
  // in thicket's world (-y, x, z): (0, -0.1 ω_cy, -0.1 ω_cx). With R_a swapping x and y:
  // var(vx) = 0.02, var(vy) = 0.01 + 0.01·0.2 = 0.012, var(vz) = 0.03 + 0.01·0.1 = 0.031,
  // cov(vy, wz) = cov(-0.1 ω_cy, -ω_cy) = 0.02, cov(vz, wy) = cov(-0.1 ω_cx, -ω_cx) = 0.01.
  double twist[36] = {};
  twist[0] = 0.02, twist[7] = 0.012, twist[14] = 0.031;
  twist[21] = 0.3, twist[28] = 0.1, twist[35] = 0.2;
  twist[1 * 6 + 5] = twist[5 * 6 + 1] = 0.02;
  twist[2 * 6 + 4] = twist[4 * 6 + 2] = 0.01;
  expect_twist(twist);
}

TEST(FrameConversion, AllZeroCovariancesStayNotProvided) {
  const odometry_t out = FrameConversion(cameraOptions()).convert(cameraEstimate());
  for (int i = 0; i < 36; ++i) {
    EXPECT_EQ(out.pose_covariance[i], 0) << i;
    EXPECT_EQ(out.twist_covariance[i], 0) << i;
  }
}

TEST(FrameConversion, IdentityOptionsReproduceTheInputExactly) {
  odometry_t in{};
  in.utime = 123;
  in.sequence = 4;
  const double position[3] = {1.25, -3.5, 0.75};
  // A unit quaternion exactly: 0.5² + 0.5² + 0.5² + 0.5² = 1.
  const double orientation[4] = {0.5, -0.5, 0.5, 0.5};
  for (int i = 0; i < 3; ++i) {
    in.position[i] = position[i];
    in.linear_velocity[i] = 0.1 * (i + 1);
    in.angular_velocity[i] = -0.2 * (i + 1);
  }
  for (int i = 0; i < 4; ++i) in.orientation[i] = orientation[i];
  for (int i = 0; i < 36; ++i) {
    in.pose_covariance[i] = 0.01 * i;
    in.twist_covariance[i] = 0.02 * i;
  }
  in.quality = odometry_t::QUALITY_DEGRADED;
  in.flags = odometry_t::FLAG_SOURCE_REPORTED;
  in.reason = "few features";
  const odometry_t out = FrameConversion(VioBridgeOptions{}).convert(in);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(out.position[i], in.position[i]);
    EXPECT_EQ(out.linear_velocity[i], in.linear_velocity[i]);
    EXPECT_EQ(out.angular_velocity[i], in.angular_velocity[i]);
  }
  for (int i = 0; i < 4; ++i) EXPECT_EQ(out.orientation[i], in.orientation[i]);
  for (int i = 0; i < 36; ++i) {
    EXPECT_EQ(out.pose_covariance[i], in.pose_covariance[i]);
    EXPECT_EQ(out.twist_covariance[i], in.twist_covariance[i]);
  }
  EXPECT_EQ(out.utime, in.utime);
  EXPECT_EQ(out.sequence, in.sequence);
  EXPECT_EQ(out.quality, in.quality);
  EXPECT_EQ(out.flags, in.flags);
  EXPECT_EQ(out.reason, in.reason);
}

TEST(FrameConversion, RefusesMalformedExtrinsics) {
  VioBridgeOptions options;
  options.body_in_vio_body.orientation = {1, 0, 0};
  EXPECT_THROW(FrameConversion{options}, std::invalid_argument);
  options.body_in_vio_body.orientation = {0.9, 0, 0, 0};
  EXPECT_THROW(FrameConversion{options}, std::invalid_argument);
  options.body_in_vio_body.orientation = {1, 0, 0, 0};
  options.input_linear_velocity_frame = "camera";
  EXPECT_THROW(FrameConversion{options}, std::invalid_argument);
  // A hand-typed quaternion a little off unit is fine (and renormalized).
  options.input_linear_velocity_frame = "world";
  options.vio_world_in_world.orientation = {0.7071, 0, 0, 0.7071};
  EXPECT_NO_THROW(FrameConversion{options});
}

}  // namespace
}  // namespace thicket::vio_bridge

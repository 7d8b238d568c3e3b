#include "thicket/common/camera.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace thicket {
namespace {

using std::numbers::pi;

constexpr double kMinDepth = 0.5;
constexpr double kMaxDepth = 5.0;

PinholeCamera paperCamera() {
  return PinholeCamera::fromHorizontalFov(320, 240, pi / 2);
}

void expectVectorNear(const Eigen::Vector3d& actual, const Eigen::Vector3d& expected) {
  EXPECT_LT((actual - expected).norm(), 1e-12)
      << actual.transpose() << " vs " << expected.transpose();
}

TEST(PinholeCamera, FromHorizontalFovPutsImageEdgesAtHalfTheFov) {
  const PinholeCamera camera = paperCamera();
  EXPECT_EQ(camera.width, 320);
  EXPECT_EQ(camera.height, 240);
  EXPECT_NEAR(camera.fx, 160.0, 1e-12);
  EXPECT_EQ(camera.fy, camera.fx);
  EXPECT_EQ(camera.cx, 159.5);
  EXPECT_EQ(camera.cy, 119.5);
  EXPECT_NEAR(camera.horizontalFov(), pi / 2, 1e-12);
  EXPECT_NEAR(camera.verticalFov(), 2.0 * std::atan(120.0 / 160.0), 1e-12);
  EXPECT_TRUE(camera.validated().ok());
}

TEST(PinholeCamera, ProjectAndBackProjectRoundTrip) {
  const PinholeCamera camera = paperCamera();
  for (double u = -0.5; u < 320.0; u += 13.25) {
    for (double v = -0.5; v < 240.0; v += 11.75) {
      for (double depth : {0.3, 1.0, 4.7}) {
        const Eigen::Vector3d p = camera.backProject(u, v, depth);
        EXPECT_DOUBLE_EQ(p.z(), depth);
        const auto uv = camera.project(p);
        ASSERT_TRUE(uv.has_value());
        EXPECT_NEAR(uv->x(), u, 1e-9);
        EXPECT_NEAR(uv->y(), v, 1e-9);
      }
    }
  }
}

TEST(PinholeCamera, LeftEdgeRayProjectsToLeftEdgeOfImage) {
  const PinholeCamera camera = paperCamera();
  // 45° left of the optical axis (optical x is right) for a 90° horizontal field of view.
  const auto uv = camera.project(Eigen::Vector3d(-2.0, 0.0, 2.0));
  ASSERT_TRUE(uv.has_value());
  EXPECT_NEAR(uv->x(), -0.5, 1e-12);
  EXPECT_NEAR(uv->y(), camera.cy, 1e-12);
  EXPECT_TRUE(camera.inImage({-0.5, -0.5}));
  EXPECT_FALSE(camera.inImage({319.5, 100.0}));
  EXPECT_FALSE(camera.inImage({100.0, 239.5}));
}

TEST(PinholeCamera, ProjectRefusesPointsNotInFront) {
  const PinholeCamera camera = paperCamera();
  EXPECT_FALSE(camera.project(Eigen::Vector3d(0.0, 0.0, 0.0)).has_value());
  EXPECT_FALSE(camera.project(Eigen::Vector3d(0.1, 0.0, -1.0)).has_value());
}

TEST(PinholeCamera, InFrustumAtEachBoundary) {
  const PinholeCamera camera = paperCamera();
  const double z = 2.0, eps = 1e-6;
  const double half_width = z * 160.0 / camera.fx;   // 45° each side
  const double half_height = z * 120.0 / camera.fy;  // the edges of the outer rows
  EXPECT_TRUE(camera.inFrustum({0.0, 0.0, z}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({-half_width + eps, 0.0, z}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({-half_width - eps, 0.0, z}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({half_width - eps, 0.0, z}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({half_width + eps, 0.0, z}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({0.0, -half_height + eps, z}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({0.0, -half_height - eps, z}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({0.0, half_height - eps, z}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({0.0, half_height + eps, z}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({0.0, 0.0, kMinDepth}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({0.0, 0.0, kMinDepth - eps}, kMinDepth, kMaxDepth));
  EXPECT_TRUE(camera.inFrustum({0.0, 0.0, kMaxDepth}, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.inFrustum({0.0, 0.0, kMaxDepth + eps}, kMinDepth, kMaxDepth));
}

Eigen::Vector3d randomPointInBall(std::mt19937& rng, const Eigen::Vector3d& center, double radius) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  while (true) {
    const Eigen::Vector3d offset(unit(rng), unit(rng), unit(rng));
    if (offset.squaredNorm() <= 1.0) return center + radius * offset;
  }
}

TEST(PinholeCamera, SphereTestNeverMissesASphereReachingIntoTheFrustum) {
  const PinholeCamera camera = paperCamera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lateral(-7.0, 7.0), depth(-2.0, 8.0), radius(0.05, 1.5);
  int reaching = 0, accepted = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const Eigen::Vector3d center(lateral(rng), lateral(rng), depth(rng));
    const double r = radius(rng);
    bool any_inside = camera.inFrustum(center, kMinDepth, kMaxDepth);
    for (int sample = 0; sample < 300 && !any_inside; ++sample) {
      any_inside = camera.inFrustum(randomPointInBall(rng, center, r), kMinDepth, kMaxDepth);
    }
    const bool intersects = camera.sphereIntersectsFrustum(center, r, kMinDepth, kMaxDepth);
    if (any_inside) {
      EXPECT_TRUE(intersects) << "center " << center.transpose() << " radius " << r;
    }
    reaching += any_inside;
    accepted += intersects;
  }
  // The sample must exercise both answers. Spheres near the frustum's edges and corners may be
  // accepted without reaching in (about 1 in 6 of the accepted ones here), but not many more.
  EXPECT_GT(reaching, 400);
  EXPECT_LT(accepted, 4000 - 400);
  EXPECT_LT(accepted - reaching, reaching / 3);
}

TEST(PinholeCamera, SphereTestRejectsSpheresFarOutside) {
  const PinholeCamera camera = paperCamera();
  const double r = 0.5;
  EXPECT_TRUE(camera.sphereIntersectsFrustum({0.0, 0.0, 3.0}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({0.0, 0.0, -1.0}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({0.0, 0.0, 5.6}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({-4.0, 0.0, 2.0}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({4.0, 0.0, 2.0}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({0.0, -3.0, 2.0}, r, kMinDepth, kMaxDepth));
  EXPECT_FALSE(camera.sphereIntersectsFrustum({0.0, 3.0, 2.0}, r, kMinDepth, kMaxDepth));
  // Just outside the left plane at 2 m (x = -2), by less than the radius: must count.
  EXPECT_TRUE(camera.sphereIntersectsFrustum({-2.3, 0.0, 2.0}, r, kMinDepth, kMaxDepth));
}

TEST(CameraMount, OpticalToBodyMapsAxes) {
  const Eigen::Quaterniond body_R_optical = opticalToBody();
  expectVectorNear(body_R_optical * Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX());
  expectVectorNear(body_R_optical * Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitY());
  expectVectorNear(body_R_optical * Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitZ());
}

TEST(CameraMount, PitchedDownNinetyDegreesLooksAlongWorldMinusZ) {
  const Eigen::Vector3d position_in_body(0.1, 0.0, -0.05);
  const Pose mount = cameraMount(position_in_body, pi / 2);
  const Pose camera_in_world = Pose{} * mount;
  expectVectorNear(camera_in_world.position, position_in_body);
  expectVectorNear(camera_in_world.orientation * Eigen::Vector3d::UnitZ(),
                   -Eigen::Vector3d::UnitZ());
  // Image right is still body right; the top of the image now points forward.
  expectVectorNear(camera_in_world.orientation * Eigen::Vector3d::UnitX(),
                   -Eigen::Vector3d::UnitY());
  expectVectorNear(camera_in_world.orientation * -Eigen::Vector3d::UnitY(),
                   Eigen::Vector3d::UnitX());
  EXPECT_LT(cameraMount(position_in_body, 0.0).orientation.angularDistance(opticalToBody()), 1e-12);
}

TEST(PinholeCamera, ValidatedRefusesUnusableIntrinsics) {
  const PinholeCamera good = paperCamera();
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  const auto refuses = [](PinholeCamera camera, const char* expected_word) {
    const auto result = camera.validated();
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.error().find(expected_word), std::string::npos) << result.error();
  };
  auto camera = good;
  camera.width = 0;
  refuses(camera, "size");
  camera = good;
  camera.height = -1;
  refuses(camera, "size");
  // A message claiming a huge image would make its decoder allocate (or decompress into) it.
  camera = good;
  camera.width = 46341;
  camera.height = 46341;  // the product overflows an int
  refuses(camera, "exceeds the 16777216 pixels");
  camera.width = 4097;
  camera.height = 4096;
  refuses(camera, "exceeds");
  camera.width = 4096;
  EXPECT_TRUE(camera.validated().ok());
  camera = good;
  camera.fx = nan;
  refuses(camera, "focal");
  camera = good;
  camera.fy = 0.0;
  refuses(camera, "focal");
  camera = good;
  camera.cx = inf;
  refuses(camera, "principal");
  refuses(PinholeCamera::fromHorizontalFov(320, 240, 0.0), "focal");
  refuses(PinholeCamera::fromHorizontalFov(320, 240, 1.2 * pi), "focal");
}

}  // namespace
}  // namespace thicket

#include "thicket/common/camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace thicket {

PinholeCamera PinholeCamera::fromHorizontalFov(int width, int height, double horizontal_fov_rad) {
  const double focal = (width / 2.0) / std::tan(horizontal_fov_rad / 2.0);
  return PinholeCamera{width, height, focal, focal, (width - 1) / 2.0, (height - 1) / 2.0};
}

Expected<PinholeCamera> PinholeCamera::validated() const {
  std::ostringstream problem;
  if (width <= 0 || height <= 0) {
    problem << "image size " << width << "x" << height << " is not positive";
  } else if (int64_t{width} * height > kMaxPixels) {
    problem << "image size " << width << "x" << height << " exceeds the " << kMaxPixels
            << " pixels thicket accepts";
  } else if (!(std::isfinite(fx) && fx > 0.0 && std::isfinite(fy) && fy > 0.0)) {
    problem << "focal lengths fx = " << fx << ", fy = " << fy << " are not finite and positive";
  } else if (!(std::isfinite(cx) && std::isfinite(cy))) {
    problem << "principal point (" << cx << ", " << cy << ") is not finite";
  } else {
    return *this;
  }
  return unexpected("invalid pinhole camera: " + problem.str());
}

double PinholeCamera::horizontalFov() const {
  return std::atan((cx + 0.5) / fx) + std::atan((width - 0.5 - cx) / fx);
}

double PinholeCamera::verticalFov() const {
  return std::atan((cy + 0.5) / fy) + std::atan((height - 0.5 - cy) / fy);
}

std::optional<Eigen::Vector2d> PinholeCamera::project(const Eigen::Vector3d& p_camera) const {
  if (!(p_camera.z() > 0.0)) return std::nullopt;
  return Eigen::Vector2d(fx * p_camera.x() / p_camera.z() + cx,
                         fy * p_camera.y() / p_camera.z() + cy);
}

bool PinholeCamera::inImage(const Eigen::Vector2d& uv) const {
  return uv.x() >= -0.5 && uv.x() < width - 0.5 && uv.y() >= -0.5 && uv.y() < height - 0.5;
}

Eigen::Vector3d PinholeCamera::backProject(double u, double v, double depth) const {
  return Eigen::Vector3d((u - cx) / fx * depth, (v - cy) / fy * depth, depth);
}

bool PinholeCamera::inFrustum(const Eigen::Vector3d& p_camera, double min_depth,
                              double max_depth) const {
  if (!(p_camera.z() >= min_depth && p_camera.z() <= max_depth)) return false;
  const auto uv = project(p_camera);
  return uv.has_value() && inImage(*uv);
}

bool PinholeCamera::sphereIntersectsFrustum(const Eigen::Vector3d& center_camera, double radius,
                                            double min_depth, double max_depth) const {
  if (center_camera.z() < min_depth - radius || center_camera.z() > max_depth + radius) {
    return false;
  }
  // Inward normals of the side planes through the optical centre along the image edges
  // (u = -0.5, u = width - 0.5, v = -0.5, v = height - 0.5). A point of the frustum is on the
  // inner side of each, so a sphere reaching into it has its centre no further than its radius
  // outside any of them. Testing planes one at a time is what lets spheres near corners through.
  const std::array<Eigen::Vector3d, 4> inward_normals = {
      Eigen::Vector3d(fx, 0.0, cx + 0.5), Eigen::Vector3d(-fx, 0.0, width - 0.5 - cx),
      Eigen::Vector3d(0.0, fy, cy + 0.5), Eigen::Vector3d(0.0, -fy, height - 0.5 - cy)};
  return std::all_of(inward_normals.begin(), inward_normals.end(),
                     [&](const Eigen::Vector3d& normal) {
                       return normal.normalized().dot(center_camera) >= -radius;
                     });
}

Eigen::Quaterniond opticalToBody() {
  Eigen::Matrix3d body_R_optical;
  body_R_optical.col(0) = -Eigen::Vector3d::UnitY();  // optical x (image right) = body right
  body_R_optical.col(1) = -Eigen::Vector3d::UnitZ();  // optical y (image down) = body down
  body_R_optical.col(2) = Eigen::Vector3d::UnitX();   // optical axis = body forward
  return Eigen::Quaterniond(body_R_optical);
}

Pose cameraMount(const Eigen::Vector3d& position_in_body, double pitch_down_rad) {
  // A positive rotation about body y (left) tips body x toward -z, i.e. down.
  const Eigen::AngleAxisd pitch(pitch_down_rad, Eigen::Vector3d::UnitY());
  return Pose{position_in_body, (pitch * opticalToBody()).normalized()};
}

}  // namespace thicket

// The mapping libraries a user might pick instead of thicket's mapper, on the same flight frames
// as bench_mapper.cc: OctoMap's OcTree::insertPointCloud (occupancy, ray casting to every point)
// and Open3D's ScalableTSDFVolume::Integrate (a hashed TSDF, voxel-centric). Both get the same
// 5 m integration range and 4-voxel truncation where the notion applies, and one core.
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>
#include <octomap/octomap.h>
#include <omp.h>
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>

#include "bench_worlds.h"

namespace thicket::bench {

namespace {

constexpr double kMaxRange = 5.0;  // [m], thicket's max_integration_range

// The frame's returns as world points, as OctoMap takes them (pixels without a return dropped).
octomap::Pointcloud worldPoints(const FlightFrame& frame) {
  octomap::Pointcloud cloud;
  const PinholeCamera& camera = frame.image.camera;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const float depth = frame.image.depth[static_cast<size_t>(v) * camera.width + u];
      if (depth <= 0) continue;
      const Eigen::Vector3d p = frame.world_T_camera.transform(camera.backProject(u, v, depth));
      cloud.push_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                      static_cast<float>(p.z()));
    }
  }
  return cloud;
}

// Arg: voxel size in mm. The point cloud conversion is untimed.
void BM_OctomapInsert(benchmark::State& state) {
  const double voxel = state.range(0) * 1e-3;
  octomap::OcTree tree(voxel);
  const std::vector<double> ms = flyFlight(state, [&](const FlightFrame& frame) {
    const octomap::Pointcloud cloud = worldPoints(frame);
    const Eigen::Vector3d& o = frame.world_T_camera.position;
    const octomap::point3d origin(static_cast<float>(o.x()), static_cast<float>(o.y()),
                                  static_cast<float>(o.z()));
    return timeMs([&] { tree.insertPointCloud(cloud, origin, kMaxRange); });
  });
  reportFrameTimes(state, ms, tree.memoryUsage());
}
BENCHMARK(BM_OctomapInsert)
    ->Arg(200)
    ->Arg(100)
    ->Arg(50)
    ->Iterations(kFlightFrames)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// Arg: voxel size in mm. Building Open3D's images is untimed.
void BM_Open3dTsdfInsert(benchmark::State& state) {
  namespace o3d = open3d;
  omp_set_num_threads(1);  // one core, like every other benchmark here
  const double voxel = state.range(0) * 1e-3;
  o3d::pipelines::integration::ScalableTSDFVolume volume(
      voxel, 4 * voxel, o3d::pipelines::integration::TSDFVolumeColorType::NoColor);
  const PinholeCamera& camera = flightFrames().front().image.camera;
  const o3d::camera::PinholeCameraIntrinsic intrinsic(camera.width, camera.height, camera.fx,
                                                      camera.fy, camera.cx, camera.cy);
  const std::vector<double> ms = flyFlight(state, [&](const FlightFrame& frame) {
    o3d::geometry::Image depth, color;
    depth.Prepare(camera.width, camera.height, 1, 4);
    color.Prepare(camera.width, camera.height, 1, 1);
    std::copy(frame.image.depth.begin(), frame.image.depth.end(), depth.PointerAs<float>());
    const auto rgbd = o3d::geometry::RGBDImage::CreateFromColorAndDepth(
        color, depth, /*depth_scale=*/1.0, /*depth_trunc=*/kMaxRange,
        /*convert_rgb_to_intensity=*/false);
    const Eigen::Matrix4d camera_T_world = frame.world_T_camera.inverse().isometry().matrix();
    return timeMs([&] { volume.Integrate(*rgbd, intrinsic, camera_T_world); });
  });
  // Open3D does not report its memory; its voxels are (tsdf, weight) floats in 16^3 blocks.
  reportFrameTimes(state, ms, 0);
}
BENCHMARK(BM_Open3dTsdfInsert)
    ->Arg(200)
    ->Arg(100)
    ->Arg(50)
    ->Iterations(kFlightFrames)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace thicket::bench

#include "thicket/explorer/gain.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

namespace thicket::explorer {

namespace {

// Bounding boxes of the frustum with more grid points than this are refused: the grid would not
// fit in memory, or its indices would overflow.
constexpr double kMaxBoxPoints = 1e8;
// Grid points along one axis of the bounding box: Morton codes take 21 bits per axis.
constexpr double kMaxAxisPoints = 1 << 21;
// Voxel indices of looked-up points stay below this in magnitude, far from int overflow.
constexpr double kMaxVoxelIndex = 1 << 30;

bool finitePositive(double x) {
  return std::isfinite(x) && x > 0;
}

// The bits of v (< 2^21) spread out to every third bit.
uint64_t spreadBits(uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffff;
  v = (v | v << 16) & 0x1f0000ff0000ff;
  v = (v | v << 8) & 0x100f00f00f00f00f;
  v = (v | v << 4) & 0x10c30c30c30c30c3;
  v = (v | v << 2) & 0x1249249249249249;
  return v;
}

// The Z-order (Morton) position of grid point (i, j, k), each < 2^21: x in the lowest bit.
uint64_t mortonCode(int64_t i, int64_t j, int64_t k) {
  return spreadBits(static_cast<uint64_t>(i)) | spreadBits(static_cast<uint64_t>(j)) << 1 |
         spreadBits(static_cast<uint64_t>(k)) << 2;
}

// The pose as a rotation matrix and a translation, after checking it.
struct CheckedPose {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
};

CheckedPose checkPose(const Pose& world_T_camera, double voxel_size, double max_range,
                      const char* caller) {
  const Eigen::Vector3d& t = world_T_camera.position;
  const Eigen::Vector4d q = world_T_camera.orientation.coeffs();
  if (!t.allFinite() || !q.allFinite() || std::abs(q.norm() - 1.0) > 1e-3) {
    throw std::invalid_argument(std::string(caller) +
                                ": the pose must be finite with a unit quaternion");
  }
  if ((t.cwiseAbs().maxCoeff() + max_range) / voxel_size > kMaxVoxelIndex) {
    throw std::invalid_argument(std::string(caller) +
                                ": the pose is too far out for the voxel indices");
  }
  return {world_T_camera.orientation.normalized().toRotationMatrix(), t};
}

void checkQuery(const TsdfLayer& tsdf, double voxel_size, int stride, const char* caller) {
  if (stride < 1) {
    throw std::invalid_argument(std::string(caller) + ": the stride must be at least 1");
  }
  if (std::abs(tsdf.voxelSize() - voxel_size) > 1e-9 * voxel_size) {
    throw std::invalid_argument(std::string(caller) + ": the TSDF's voxel size " +
                                std::to_string(tsdf.voxelSize()) + " is not the gain's " +
                                std::to_string(voxel_size));
  }
}

bool isUnknown(const TsdfVoxel* voxel, double min_weight) {
  return voxel == nullptr || voxel->weight < min_weight;
}

// Whether an observed voxel at or behind a surface (TSDF distance <= 0) lies on the segment from
// `from` (in voxel `current`) to `to` (in voxel `target`), `target` itself excluded. Walks the
// voxels the segment passes through (Amanatides & Woo), taking exactly as many steps along each
// axis as separate the two voxels, so that the walk ends in `target` whatever the rounding.
bool occluded(VoxelLookup<TsdfVoxel>& lookup, const Eigen::Vector3d& from,
              const Eigen::Vector3d& to, VoxelIndex current, const VoxelIndex& target,
              double voxel_size, double min_weight) {
  const Eigen::Vector3d start = from / voxel_size;
  const Eigen::Vector3d direction = to / voxel_size - start;  // t in [0, 1] along the segment
  int remaining[3];
  int step[3];
  double t_max[3];
  double t_delta[3];
  int total = 0;
  for (int a = 0; a < 3; ++a) {
    remaining[a] = std::abs(target[a] - current[a]);
    step[a] = target[a] >= current[a] ? 1 : -1;
    total += remaining[a];
    if (direction[a] != 0.0) {
      const double boundary = current[a] + (step[a] > 0 ? 1.0 : 0.0);
      t_max[a] = (boundary - start[a]) / direction[a];
      t_delta[a] = 1.0 / std::abs(direction[a]);
    } else {
      t_max[a] = std::numeric_limits<double>::infinity();
      t_delta[a] = 0.0;
    }
  }
  // The walk's voxel as its block, looked up again only where the walk leaves it, and its index
  // in the block.
  constexpr int kStrides[3] = {1, kVoxelsPerSide, kVoxelsPerSide * kVoxelsPerSide};
  const TsdfLayer::BlockType* block = lookup.block(blockOfVoxel(current));
  int lin = linearIndexInBlock(current);
  for (int n = 0; n < total; ++n) {
    if (block != nullptr) {
      const TsdfVoxel& voxel = block->voxels[lin];
      if (voxel.weight >= min_weight && voxel.distance <= 0.0f) return true;
    }
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (remaining[a] > 0 && (axis < 0 || t_max[a] < t_max[axis])) axis = a;
    }
    current[axis] += step[axis];
    // Into the next block where the coordinate wraps within a block's side.
    if ((current[axis] & (kVoxelsPerSide - 1)) == (step[axis] > 0 ? 0 : kVoxelsPerSide - 1)) {
      block = lookup.block(blockOfVoxel(current));
      lin = linearIndexInBlock(current);
    } else {
      lin += step[axis] * kStrides[axis];
    }
    t_max[axis] += t_delta[axis];
    --remaining[axis];
  }
  return false;
}

}  // namespace

void GainOptions::declare(Params& p) {
  p("width", width, "image width of the gain's camera [pixels]", Range::atLeast(1));
  p("height", height, "image height of the gain's camera [pixels]", Range::atLeast(1));
  p("hfov_deg", hfov_deg, "horizontal field of view of the gain's camera [deg]",
    Range::between(1, 179));
  p("min_range", min_range, "the frustum starts at this optical depth [m]", Range::atLeast(0));
  p("max_range", max_range, "... and ends at this one (> min_range) [m]", Range::positive());
  p("min_weight", min_weight, "TSDF voxels with less weight are unknown", Range::positive());
}

ExplorationGain::ExplorationGain(GainOptions options, double voxel_size)
    : options_(options), voxel_size_(voxel_size) {
  const GainOptions& o = options_;
  // The rules of GainOptions::declare, and the one between two fields it cannot state.
  if (const std::string error = paramsError(o); !error.empty()) {
    throw std::invalid_argument("ExplorationGain: " + error);
  }
  if (!(o.max_range > o.min_range)) {
    throw std::invalid_argument("ExplorationGain: max_range must exceed min_range");
  }
  if (!finitePositive(voxel_size_)) {
    throw std::invalid_argument("ExplorationGain: the voxel size must be positive and finite");
  }
  const auto camera =
      PinholeCamera::fromHorizontalFov(o.width, o.height, o.hfov_deg * std::numbers::pi / 180.0)
          .validated();
  if (!camera) throw std::invalid_argument("ExplorationGain: " + camera.error());
  camera_ = *camera;

  // The frustum's bounding box in the optical frame: its far face is its widest cross-section.
  const double x_lo = (-0.5 - camera_.cx) / camera_.fx * o.max_range;
  const double x_hi = (camera_.width - 0.5 - camera_.cx) / camera_.fx * o.max_range;
  const double y_lo = (-0.5 - camera_.cy) / camera_.fy * o.max_range;
  const double y_hi = (camera_.height - 0.5 - camera_.cy) / camera_.fy * o.max_range;
  // Grid point i sits at (i + 0.5) * voxel_size; these bounds include one point beyond each side.
  const auto first = [&](double lo) { return std::floor(lo / voxel_size_ - 0.5); };
  const auto last = [&](double hi) { return std::ceil(hi / voxel_size_ - 0.5); };
  const double nx = last(x_hi) - first(x_lo) + 1;
  const double ny = last(y_hi) - first(y_lo) + 1;
  const double nz = last(o.max_range) - first(o.min_range) + 1;
  if (!(nx * ny * nz <= kMaxBoxPoints)) {
    throw std::invalid_argument(
        "ExplorationGain: the frustum grid is too large for this voxel size and range");
  }
  if (std::max({nx, ny, nz}) > kMaxAxisPoints) {
    throw std::invalid_argument(
        "ExplorationGain: the frustum grid is too long along an axis for this voxel size");
  }
  const auto x0 = static_cast<int64_t>(first(x_lo));
  const auto y0 = static_cast<int64_t>(first(y_lo));
  const auto z0 = static_cast<int64_t>(first(o.min_range));
  struct Keyed {
    uint64_t key;
    Eigen::Vector3f point;
  };
  std::vector<Keyed> keyed;
  for (int64_t k = 0; k < static_cast<int64_t>(nz); ++k) {
    for (int64_t j = 0; j < static_cast<int64_t>(ny); ++j) {
      for (int64_t i = 0; i < static_cast<int64_t>(nx); ++i) {
        const Eigen::Vector3d p((x0 + i + 0.5) * voxel_size_, (y0 + j + 0.5) * voxel_size_,
                                (z0 + k + 0.5) * voxel_size_);
        // Points on a side plane of the frustum (the 90-degree default puts a grid column on
        // each) belong to it as pixel (u, v) does to the half-open image: the left and top
        // planes in, the right and bottom ones out, whatever the rounding of the focal length.
        const Eigen::Vector3d nudged =
            p + Eigen::Vector3d(1e-6 * p.z() / camera_.fx, 1e-6 * p.z() / camera_.fy, 0.0);
        if (camera_.inFrustum(nudged, o.min_range, o.max_range)) {
          keyed.push_back({mortonCode(i, j, k), p.cast<float>()});
        }
      }
    }
  }
  // Z-order: any run of consecutive points is a compact cluster, so every stride-th point is a
  // stratified sample of the frustum (one point per cluster of `stride`), and consecutive
  // lookups stay in one TSDF block.
  std::sort(keyed.begin(), keyed.end(),
            [](const Keyed& a, const Keyed& b) { return a.key < b.key; });
  points_.reserve(keyed.size());
  for (const Keyed& k : keyed) points_.push_back(k.point);
}

int64_t ExplorationGain::frustumPoints() const {
  return static_cast<int64_t>(points_.size());
}

Gain ExplorationGain::unknownFraction(const TsdfLayer& tsdf, const Pose& world_T_camera,
                                      int stride) const {
  checkQuery(tsdf, voxel_size_, stride, "ExplorationGain::unknownFraction");
  const CheckedPose pose = checkPose(world_T_camera, voxel_size_, options_.max_range,
                                     "ExplorationGain::unknownFraction");
  VoxelLookup lookup(tsdf);
  Gain gain;
  const size_t step = static_cast<size_t>(stride);
  for (size_t n = 0; n < points_.size(); n += step) {
    const Eigen::Vector3d p = pose.rotation * points_[n].cast<double>() + pose.translation;
    ++gain.checked;
    if (isUnknown(lookup.voxel(tsdf.voxelIndex(p)), options_.min_weight)) ++gain.unknown;
  }
  gain.unknown_fraction =
      gain.checked > 0 ? static_cast<double>(gain.unknown) / static_cast<double>(gain.checked) : 0;
  return gain;
}

Gain ExplorationGain::visibleUnknownFraction(const TsdfLayer& tsdf, const Pose& world_T_camera,
                                             int stride) const {
  // Every fraction is at least 0 and more than -1: nothing stops the walk.
  return *visibleUnknownFractionIfAbove(tsdf, world_T_camera, stride, 0.0, -1.0);
}

std::optional<Gain> ExplorationGain::visibleUnknownFractionIfAbove(const TsdfLayer& tsdf,
                                                                   const Pose& world_T_camera,
                                                                   int stride, double at_least,
                                                                   double more_than) const {
  checkQuery(tsdf, voxel_size_, stride, "ExplorationGain::visibleUnknownFraction");
  const CheckedPose pose = checkPose(world_T_camera, voxel_size_, options_.max_range,
                                     "ExplorationGain::visibleUnknownFraction");
  VoxelLookup lookup(tsdf);
  const VoxelIndex origin_voxel = tsdf.voxelIndex(pose.translation);
  const size_t step = static_cast<size_t>(stride);
  const auto total = static_cast<int64_t>((points_.size() + step - 1) / step);
  // The fraction if every point not yet checked were visible and unknown: it only falls.
  const auto reachable = [&](int64_t unknown, int64_t checked) {
    const double best =
        total > 0 ? static_cast<double>(unknown + total - checked) / static_cast<double>(total) : 0;
    return best >= at_least && best > more_than;
  };
  if (!reachable(0, 0)) return std::nullopt;
  Gain gain;
  for (size_t n = 0; n < points_.size(); n += step) {
    const Eigen::Vector3d p = pose.rotation * points_[n].cast<double>() + pose.translation;
    ++gain.checked;
    const VoxelIndex v = tsdf.voxelIndex(p);
    // Observed points are not unknown whether hidden or not: only unknown ones need the walk.
    if (isUnknown(lookup.voxel(v), options_.min_weight) &&
        !occluded(lookup, pose.translation, p, origin_voxel, v, voxel_size_, options_.min_weight)) {
      ++gain.unknown;
    } else if (!reachable(gain.unknown, gain.checked)) {
      return std::nullopt;
    }
  }
  gain.unknown_fraction =
      gain.checked > 0 ? static_cast<double>(gain.unknown) / static_cast<double>(gain.checked) : 0;
  return gain;
}

Pose ExplorationGain::cameraAt(const Eigen::Vector3d& position, double yaw) {
  const Eigen::Quaterniond heading(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return Pose{position, (heading * opticalToBody()).normalized()};
}

}  // namespace thicket::explorer

// Export through PCL, the one file of the mapper that includes it.
#include <array>
#include <stdexcept>
#include <unordered_map>

#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "thicket/mapper/map_io.h"

namespace thicket::mapper {
namespace {

// The cube between 8 voxel centres, corner c at offset (c & 1, (c >> 1) & 1, c >> 2), is split
// into six tetrahedra around its diagonal 0-7. Neighbouring cubes split their shared faces along
// the same diagonal, so the mesh has no cracks.
constexpr std::array<std::array<int, 4>, 6> kTetrahedra = {
    {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7}, {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}}};

class MeshBuilder {
 public:
  explicit MeshBuilder(double voxel_size) : voxel_size_(voxel_size) {}

  void addCube(const VoxelIndex& base, const std::array<float, 8>& d) {
    for (const auto& tet : kTetrahedra) {
      std::array<int, 4> inside{}, outside{};
      int n_in = 0, n_out = 0;
      for (int corner : tet) {
        if (d[corner] < 0) {
          inside[n_in++] = corner;
        } else {
          outside[n_out++] = corner;
        }
      }
      if (n_in == 0 || n_out == 0) continue;
      const auto vertex = [&](int a, int b) { return edgeVertex(base, a, b, d); };
      const Eigen::Vector3d free_point = cornerPoint(base, outside[0]);
      if (n_in == 1 || n_out == 1) {
        // One corner on its own side: a triangle across the three edges leaving it.
        const bool lone_inside = n_in == 1;
        const int lone = lone_inside ? inside[0] : outside[0];
        const auto& others = lone_inside ? outside : inside;
        addTriangle(vertex(lone, others[0]), vertex(lone, others[1]), vertex(lone, others[2]),
                    lone_inside ? free_point : cornerPoint(base, lone));
      } else {
        // Two and two: a quad across the four crossing edges, as two triangles.
        const int a = vertex(inside[0], outside[0]);
        const int b = vertex(inside[0], outside[1]);
        const int c = vertex(inside[1], outside[1]);
        const int e = vertex(inside[1], outside[0]);
        addTriangle(a, b, c, free_point);
        addTriangle(a, c, e, free_point);
      }
    }
  }

  size_t save(const std::string& path) const {
    pcl::PolygonMesh mesh;
    pcl::toPCLPointCloud2(points_, mesh.cloud);
    mesh.polygons = triangles_;
    if (pcl::io::savePLYFileBinary(path, mesh) != 0) {
      throw std::runtime_error("cannot write " + path);
    }
    return triangles_.size();
  }

 private:
  Eigen::Vector3d cornerPoint(const VoxelIndex& base, int corner) const {
    const VoxelIndex v = base + VoxelIndex(corner & 1, (corner >> 1) & 1, corner >> 2);
    return (v.cast<double>().array() + 0.5).matrix() * voxel_size_;
  }

  // The zero crossing on the edge between two corners, shared by every triangle that uses it.
  int edgeVertex(const VoxelIndex& base, int a, int b, const std::array<float, 8>& d) {
    const VoxelIndex va = base + VoxelIndex(a & 1, (a >> 1) & 1, a >> 2);
    const VoxelIndex vb = base + VoxelIndex(b & 1, (b >> 1) & 1, b >> 2);
    const auto key = [](const VoxelIndex& v) {
      return (static_cast<uint64_t>(static_cast<uint32_t>(v.x()) & 0x1fffff) << 42) |
             (static_cast<uint64_t>(static_cast<uint32_t>(v.y()) & 0x1fffff) << 21) |
             (static_cast<uint64_t>(static_cast<uint32_t>(v.z()) & 0x1fffff));
    };
    const bool a_first = key(va) < key(vb);
    const std::pair<uint64_t, uint64_t> edge =
        a_first ? std::pair(key(va), key(vb)) : std::pair(key(vb), key(va));
    const auto [it, inserted] = vertices_.try_emplace(edge, static_cast<int>(points_.size()));
    if (inserted) {
      const double t = d[a] / (d[a] - d[b]);
      const Eigen::Vector3d p =
          cornerPoint(base, a) + t * (cornerPoint(base, b) - cornerPoint(base, a));
      points_.push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                      static_cast<float>(p.z())));
    }
    return it->second;
  }

  // Oriented so that the normal points to the free side, where free_point is.
  void addTriangle(int a, int b, int c, const Eigen::Vector3d& free_point) {
    const auto at = [&](int i) { return points_[i].getVector3fMap().cast<double>(); };
    const Eigen::Vector3d normal = (at(b) - at(a)).cross(at(c) - at(a));
    if (normal.squaredNorm() == 0) return;  // degenerate where the surface passes a corner
    pcl::Vertices triangle;
    triangle.vertices =
        normal.dot(free_point - at(a)) >= 0 ? pcl::Indices{a, b, c} : pcl::Indices{a, c, b};
    triangles_.push_back(std::move(triangle));
  }

  struct PairHash {
    size_t operator()(const std::pair<uint64_t, uint64_t>& p) const {
      return std::hash<uint64_t>()(p.first * 0x9e3779b97f4a7c15ULL ^ p.second);
    }
  };
  double voxel_size_;
  pcl::PointCloud<pcl::PointXYZ> points_;
  std::vector<pcl::Vertices> triangles_;
  std::unordered_map<std::pair<uint64_t, uint64_t>, int, PairHash> vertices_;
};

}  // namespace

size_t exportMeshPly(const TsdfLayer& tsdf, const std::string& path) {
  MeshBuilder mesh(tsdf.voxelSize());
  for (const BlockIndex& index : tsdf.blockIndices()) {
    const Block<TsdfVoxel>& block = *tsdf.block(index);
    for (int i = 0; i < kVoxelsPerBlock; ++i) {
      const VoxelIndex base = voxelOfBlock(index, i);
      std::array<float, 8> d;
      bool observed = true, positive = false, negative = false;
      for (int corner = 0; corner < 8 && observed; ++corner) {
        const VoxelIndex v = base + VoxelIndex(corner & 1, (corner >> 1) & 1, corner >> 2);
        const TsdfVoxel* voxel = corner == 0 ? &block.voxels[i] : tsdf.voxel(v);
        observed = voxel != nullptr && voxel->weight > 0;
        if (observed) {
          d[corner] = voxel->distance;
          (d[corner] < 0 ? negative : positive) = true;
        }
      }
      if (observed && positive && negative) mesh.addCube(base, d);
    }
  }
  return mesh.save(path);
}

size_t exportOccupiedPcd(const TsdfLayer& tsdf, const std::string& path) {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  for (const BlockIndex& index : tsdf.blockIndices()) {
    const Block<TsdfVoxel>& block = *tsdf.block(index);
    for (int i = 0; i < kVoxelsPerBlock; ++i) {
      const TsdfVoxel& voxel = block.voxels[i];
      if (voxel.weight > 0 && voxel.distance <= 0) {
        const Eigen::Vector3d p = tsdf.voxelCenter(voxelOfBlock(index, i));
        cloud.push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                      static_cast<float>(p.z())));
      }
    }
  }
  if (cloud.empty()) {
    // PCL refuses to write an empty cloud; an empty map is still a valid answer.
    cloud.width = 0;
    cloud.height = 1;
  }
  if (pcl::io::savePCDFileBinary(path, cloud) != 0)
    throw std::runtime_error("cannot write " + path);
  return cloud.size();
}

}  // namespace thicket::mapper

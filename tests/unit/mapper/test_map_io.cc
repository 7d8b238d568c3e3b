// Maps on disk: the saved file loads back bit for bit and refuses what it cannot read; the
// exported mesh lies on the surface and faces the free side; the cloud holds the occupied voxels.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>

#include <thicket/map_update_t.hpp>

#include "thicket/mapper/map_io.h"

namespace thicket::mapper {
namespace {

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "thicket_map_io_" + name;
}

// A TSDF of a sphere of radius 1 m around `centre`, truncated at 4 voxels, every voxel observed.
TsdfLayer sphereTsdf(double voxel, const Eigen::Vector3d& centre) {
  TsdfLayer tsdf(voxel);
  const int n = static_cast<int>(std::ceil(1.6 / voxel));
  const VoxelIndex c = tsdf.voxelIndex(centre);
  for (int x = -n; x <= n; ++x) {
    for (int y = -n; y <= n; ++y) {
      for (int z = -n; z <= n; ++z) {
        const VoxelIndex v = c + VoxelIndex(x, y, z);
        const double d = (tsdf.voxelCenter(v) - centre).norm() - 1.0;
        tsdf.allocateVoxel(v) = {static_cast<float>(std::clamp(d, -4 * voxel, 4 * voxel)), 1.0f};
      }
    }
  }
  return tsdf;
}

SavedMap sampleMap() {
  SavedMap map;
  map.tsdf = sphereTsdf(0.1, {0.3, -0.2, 1.0});
  map.esdf = EsdfLayer(0.1);
  EsdfVoxel& voxel = map.esdf.allocateVoxel({1, 2, 3});
  voxel = {0.7f, true, false};
  map.map_id = 77;
  map.revision = 12;
  map.utime = 123456;
  map.start = Eigen::Vector3d(0.1 / 3, -2.5, 1.75);
  return map;
}

TEST(MapFile, SavesAndLoadsBothLayersBitForBit) {
  const SavedMap map = sampleMap();
  const std::string path = tempPath("roundtrip.map");
  saveMap(path, map);
  auto loaded = loadMap(path);
  ASSERT_TRUE(loaded) << loaded.error();
  EXPECT_TRUE(identicalLayers(loaded->tsdf, map.tsdf));
  EXPECT_TRUE(identicalLayers(loaded->esdf, map.esdf));
  EXPECT_EQ(loaded->map_id, 77);
  EXPECT_EQ(loaded->revision, 12);
  EXPECT_EQ(loaded->utime, 123456);
  ASSERT_TRUE(loaded->start.has_value());
  EXPECT_EQ(*loaded->start, *map.start);                  // to the last bit
  EXPECT_FALSE(std::filesystem::exists(path + ".part"));  // written beside it, then renamed
  SavedMap unstarted = map;
  unstarted.start.reset();
  saveMap(path, unstarted);
  loaded = loadMap(path);
  ASSERT_TRUE(loaded) << loaded.error();
  EXPECT_FALSE(loaded->start.has_value());
}

TEST(MapFile, RefusesWhatItCannotRead) {
  const std::string good = tempPath("good.map");
  saveMap(good, sampleMap());
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto write = [](const std::string& name, const std::string& content) {
    const std::string path = tempPath(name);
    std::ofstream(path, std::ios::binary) << content;
    return path;
  };
  const auto refusal = [](const std::string& path) {
    auto loaded = loadMap(path);
    return loaded ? std::string() : loaded.error();
  };
  EXPECT_NE(refusal(tempPath("missing.map")).find("cannot read"), std::string::npos);
  EXPECT_NE(refusal(write("text.map", "hello\n")).find("not a thicket map"), std::string::npos);
  std::string newer = bytes;
  newer.replace(0, newer.find('\n'), "THICKET-MAP 3");
  EXPECT_NE(refusal(write("newer.map", newer)).find("version 3"), std::string::npos);
  std::string bad_start = bytes;
  bad_start.replace(0, bad_start.find('\n'), "THICKET-MAP 2 start 1 nan 2");
  EXPECT_NE(refusal(write("bad_start.map", bad_start)).find("bad start"), std::string::npos);
  // Version 1 (before the start position) still reads, without a start.
  std::string old = bytes;
  old.replace(0, old.find('\n'), "THICKET-MAP 1");
  const auto v1 = loadMap(write("v1.map", old));
  ASSERT_TRUE(v1.ok()) << v1.error();
  EXPECT_FALSE(v1->start.has_value());
  EXPECT_NE(refusal(write("truncated.map", bytes.substr(0, bytes.size() - 100))).find("truncated"),
            std::string::npos);
  std::string corrupt = bytes;
  corrupt[corrupt.size() - 50] ^= 0x5a;
  EXPECT_NE(refusal(write("corrupt.map", corrupt)).find("corrupt"), std::string::npos);
  // Only the TSDF: the header line and the first record.
  const size_t first = bytes.find('\n') + 1;
  uint32_t size = 0;
  for (int i = 0; i < 4; ++i)
    size |= static_cast<uint32_t>(static_cast<uint8_t>(bytes[first + i])) << (8 * i);
  EXPECT_NE(refusal(write("half.map", bytes.substr(0, first + 12 + size))).find("lacks"),
            std::string::npos);
}

// A record with a valid checksum whose message claims -1 or 2^31 - 1 blocks: LCM's generated
// decoder would throw or allocate gigabytes (thicket-map aborted); the load names file and cause.
TEST(MapFile, ARecordClaimingImpossibleBlockCountsIsRefusedNamingTheFile) {
  for (const int32_t num_blocks : {-1, INT32_MAX}) {
    thicket::map_update_t update{};
    update.layer = thicket::map_update_t::LAYER_TSDF;
    std::vector<uint8_t> message(static_cast<size_t>(update.getEncodedSize()));
    update.encode(message.data(), 0, static_cast<int>(message.size()));
    // num_blocks and num_removed are the last two int32 fields of an update without blocks.
    const size_t at = message.size() - 8;
    for (int i = 0; i < 4; ++i) message[at + i] = static_cast<uint8_t>(num_blocks >> (24 - 8 * i));
    uint64_t checksum = 0xcbf29ce484222325ULL;  // FNV-1a, as the map file writes it
    for (uint8_t byte : message) checksum = (checksum ^ byte) * 0x100000001b3ULL;
    std::string file = "THICKET-MAP 1\n";
    for (int i = 0; i < 4; ++i) file += static_cast<char>((message.size() >> (8 * i)) & 0xff);
    for (int i = 0; i < 8; ++i) file += static_cast<char>((checksum >> (8 * i)) & 0xff);
    file.append(message.begin(), message.end());
    const std::string path = tempPath("blocks.map");
    std::ofstream(path, std::ios::binary) << file;
    const auto loaded = loadMap(path);
    ASSERT_FALSE(loaded.ok());
    EXPECT_NE(loaded.error().find(path + ": record 0: not a map update: malformed"),
              std::string::npos)
        << loaded.error();
    EXPECT_NE(loaded.error().find("num_blocks"), std::string::npos) << loaded.error();
  }
}

TEST(MapExport, MeshLiesOnTheSurfaceAndFacesTheFreeSide) {
  const Eigen::Vector3d centre(0.33, -0.21, 1.07);
  const TsdfLayer tsdf = sphereTsdf(0.1, centre);
  const std::string path = tempPath("sphere.ply");
  const size_t triangles = exportMeshPly(tsdf, path);
  pcl::PolygonMesh mesh;
  ASSERT_EQ(pcl::io::loadPLYFile(path, mesh), 0);
  ASSERT_EQ(mesh.polygons.size(), triangles);
  // A sphere of radius 1 m at 0.1 m voxels: about 4 pi / 0.01 = 1257 voxel faces' worth.
  EXPECT_GT(triangles, 1500u);
  pcl::PointCloud<pcl::PointXYZ> vertices;
  pcl::fromPCLPointCloud2(mesh.cloud, vertices);
  double worst = 0;
  for (const auto& p : vertices) {
    worst = std::max(worst, std::abs((p.getVector3fMap().cast<double>() - centre).norm() - 1.0));
  }
  EXPECT_LT(worst, 0.01);  // linear interpolation of a smooth field, 0.1 m voxels
  int outward = 0;
  Eigen::Vector3d area_weighted_sum = Eigen::Vector3d::Zero();
  for (const pcl::Vertices& t : mesh.polygons) {
    const Eigen::Vector3d a = vertices[t.vertices[0]].getVector3fMap().cast<double>();
    const Eigen::Vector3d b = vertices[t.vertices[1]].getVector3fMap().cast<double>();
    const Eigen::Vector3d c = vertices[t.vertices[2]].getVector3fMap().cast<double>();
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    outward += normal.dot((a + b + c) / 3 - centre) > 0;
    area_weighted_sum += normal;
  }
  EXPECT_EQ(outward, static_cast<int>(triangles));
  EXPECT_LT(area_weighted_sum.norm(), 1e-3);  // a closed surface: normals cancel
}

TEST(MapExport, CloudHoldsExactlyTheOccupiedVoxels) {
  TsdfLayer tsdf(0.2);
  tsdf.allocateVoxel({0, 0, 0}) = {-0.1f, 1};
  tsdf.allocateVoxel({5, -3, 2}) = {0.0f, 2};
  tsdf.allocateVoxel({1, 0, 0}) = {0.3f, 1};   // free
  tsdf.allocateVoxel({2, 0, 0}) = {-0.3f, 0};  // never observed
  const std::string path = tempPath("occupied.pcd");
  EXPECT_EQ(exportOccupiedPcd(tsdf, path), 2u);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path, cloud), 0);
  ASSERT_EQ(cloud.size(), 2u);
  // Block (0, -1, 0) comes first.
  EXPECT_LT((cloud[0].getVector3fMap() - Eigen::Vector3f(1.1f, -0.5f, 0.5f)).norm(), 1e-6);
  EXPECT_LT((cloud[1].getVector3fMap() - Eigen::Vector3f(0.1f, 0.1f, 0.1f)).norm(), 1e-6);
  EXPECT_EQ(exportOccupiedPcd(TsdfLayer(0.2), tempPath("empty.pcd")), 0u);
  EXPECT_THROW(exportOccupiedPcd(tsdf, "/nonexistent/dir/x.pcd"), std::runtime_error);
}

}  // namespace
}  // namespace thicket::mapper

// Maps on disk: save and load both layers (a versioned file that refuses what it cannot read),
// and export for viewers (pcl_viewer, CloudCompare, MeshLab): the TSDF's zero crossing as a PLY
// mesh, the occupied voxels as a PCD cloud.
#pragma once

#include <cstdint>
#include <string>

#include "thicket/common/expected.h"
#include "thicket/common/voxel_layer.h"

namespace thicket::mapper {

/// The version written by saveMap; loadMap reads this one only.
constexpr int kMapFileVersion = 1;

struct SavedMap {
  TsdfLayer tsdf{1.0};
  EsdfLayer esdf{1.0};
  int64_t map_id = 0;
  int64_t revision = 0;
  int64_t utime = 0;  ///< the newest integrated frame [µs]
};

/// Writes "THICKET-MAP <version>\n", then both layers as full-snapshot map_update_t messages,
/// each preceded by its length (uint32) and a 64-bit FNV-1a checksum of it (little-endian): the
/// wire format's validation applies to files too. Throws std::runtime_error when the file cannot be
/// written.
void saveMap(const std::string& path, const SavedMap& map);

/// Reads a file written by saveMap. Refuses, with the reason, a missing or unreadable file,
/// another format or version, a truncated or corrupt record, and a file without both layers.
Expected<SavedMap> loadMap(const std::string& path);

/// The TSDF's zero crossing (marching tetrahedra over the cubes between voxel centres whose
/// eight voxels are observed) as a binary PLY mesh; vertices shared between triangles are
/// merged. Returns the number of triangles; throws std::runtime_error when writing fails.
size_t exportMeshPly(const TsdfLayer& tsdf, const std::string& path);

/// The occupied voxels (observed, TSDF distance <= 0) as their centres in a binary PCD cloud.
/// Returns the number of points; throws std::runtime_error when writing fails.
size_t exportOccupiedPcd(const TsdfLayer& tsdf, const std::string& path);

}  // namespace thicket::mapper

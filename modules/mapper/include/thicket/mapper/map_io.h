// Maps on disk: save and load both layers (a versioned file that refuses what it cannot read),
// and export for viewers (pcl_viewer, CloudCompare, MeshLab): the TSDF's zero crossing as a PLY
// mesh, the occupied voxels as a PCD cloud.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "thicket/common/expected.h"
#include "thicket/common/voxel_layer.h"

namespace thicket::mapper {

/// The version written by saveMap; loadMap reads it and version 1 (which had no start position).
constexpr int kMapFileVersion = 2;

/// What a map file says besides its layers.
struct MapStamp {
  int64_t map_id = 0;
  int64_t revision = 0;
  int64_t utime = 0;  ///< the newest integrated frame [µs]
  /// Where the flight that built the map started: the centre of the ESDF's clear sphere (none
  /// before the first pose, and in version 1 files).
  std::optional<Eigen::Vector3d> start;
};

struct SavedMap : MapStamp {
  TsdfLayer tsdf{1.0};
  EsdfLayer esdf{1.0};
};

/// Writes "THICKET-MAP <version> start <x> <y> <z>\n" ("start none" without one), then both layers
/// as full-snapshot map_update_t messages, each preceded by its length (uint32) and a 64-bit FNV-1a
/// checksum of it (little-endian): the wire format's validation applies to files too. The file is
/// replaced atomically: written beside it, synced, then renamed over it, so that a crash leaves the
/// old file or the new one, never a torn one. Throws std::runtime_error when the file cannot be
/// written.
void saveMap(const std::string& path, const TsdfLayer& tsdf, const EsdfLayer& esdf,
             const MapStamp& stamp);
inline void saveMap(const std::string& path, const SavedMap& map) {
  saveMap(path, map.tsdf, map.esdf, map);
}

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

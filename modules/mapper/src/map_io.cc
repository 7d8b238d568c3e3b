#include "thicket/mapper/map_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include <thicket/map_update_t.hpp>

#include "thicket/common/map_update.h"
#include "thicket/common/node.h"

namespace thicket::mapper {
namespace {

constexpr const char* kMagic = "THICKET-MAP";

// FNV-1a, 64 bits: catches a corrupt record anywhere, headers included (the zstd checksums cover
// only the compressed voxel payloads).
uint64_t fnv1a(const uint8_t* data, size_t size) {
  uint64_t hash = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < size; ++i) hash = (hash ^ data[i]) * 0x100000001b3ULL;
  return hash;
}

void putLittleEndian(std::ofstream& out, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out.put(static_cast<char>((value >> (8 * i)) & 0xff));
}

uint64_t getLittleEndian(const uint8_t* in, int bytes) {
  uint64_t value = 0;
  for (int i = 0; i < bytes; ++i) value |= static_cast<uint64_t>(in[i]) << (8 * i);
  return value;
}

template <class Voxel>
void writeLayer(std::ofstream& out, const Layer<Voxel>& layer, const MapStamp& stamp) {
  for (const map_update_t& part :
       encodeMapUpdate(layer, {stamp.utime, stamp.map_id, stamp.revision, true}, {}, {})) {
    std::vector<uint8_t> bytes(part.getEncodedSize());
    part.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    putLittleEndian(out, bytes.size(), 4);
    putLittleEndian(out, fnv1a(bytes.data(), bytes.size()), 8);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
  }
}

template <class Voxel>
std::string applyRecord(MapMirror<Voxel>& mirror, const map_update_t& msg) {
  const auto result = mirror.apply(msg);
  using Outcome = typename MapMirror<Voxel>::Outcome;
  return result.outcome == Outcome::kApplied || result.outcome == Outcome::kPartial ? ""
                                                                                    : result.reason;
}

}  // namespace

void saveMap(const std::string& path, const TsdfLayer& tsdf, const EsdfLayer& esdf,
             const MapStamp& stamp) {
  const std::string temporary = path + ".part";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot write " + temporary);
    out << kMagic << ' ' << kMapFileVersion << " start";
    if (stamp.start) {
      char text[96];
      std::snprintf(text, sizeof(text), " %.17g %.17g %.17g", stamp.start->x(), stamp.start->y(),
                    stamp.start->z());
      out << text;
    } else {
      out << " none";
    }
    out << '\n';
    writeLayer(out, tsdf, stamp);
    writeLayer(out, esdf, stamp);
    out.close();
    if (!out) throw std::runtime_error("writing " + temporary + " failed");
  }
  const int fd = ::open(temporary.c_str(), O_RDONLY);
  const bool synced = fd >= 0 && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!synced || std::rename(temporary.c_str(), path.c_str()) != 0) {
    const std::string error = std::strerror(errno);
    std::remove(temporary.c_str());
    throw std::runtime_error("saving " + path + " failed: " + error);
  }
}

Expected<SavedMap> loadMap(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return unexpected("cannot read " + path);
  std::string header;
  std::getline(in, header);
  std::istringstream fields(header);
  std::string magic;
  int version = 0;
  if (!(fields >> magic >> version) || magic != kMagic) {
    return unexpected(path + " is not a thicket map");
  }
  if (version != 1 && version != kMapFileVersion) {
    return unexpected(path + " is a thicket map of version " + std::to_string(version) +
                      "; this build reads versions 1 to " + std::to_string(kMapFileVersion));
  }
  std::optional<Eigen::Vector3d> start;
  if (version >= 2) {
    std::string word, x;
    if (!(fields >> word >> x) || word != "start") return unexpected(path + ": bad header");
    if (x != "none") {
      double y = 0, z = 0;
      char* end = nullptr;
      const double px = std::strtod(x.c_str(), &end);
      if (*end != '\0' || !(fields >> y >> z) || !std::isfinite(px) || !std::isfinite(y) ||
          !std::isfinite(z)) {
        return unexpected(path + ": bad start position in the header");
      }
      start = Eigen::Vector3d(px, y, z);
    }
  }
  const std::vector<uint8_t> body((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  MapMirror<TsdfVoxel> tsdf;
  MapMirror<EsdfVoxel> esdf;
  size_t offset = 0;
  for (int record = 0; offset < body.size(); ++record) {
    const std::string where = path + ": record " + std::to_string(record) + ": ";
    if (body.size() - offset < 12) return unexpected(where + "truncated");
    const uint64_t size = getLittleEndian(&body[offset], 4);
    const uint64_t checksum = getLittleEndian(&body[offset + 4], 8);
    offset += 12;
    if (size > body.size() - offset) return unexpected(where + "truncated");
    if (fnv1a(&body[offset], size) != checksum) return unexpected(where + "corrupt (checksum)");
    map_update_t msg;
    if (const std::string error = decodeMessage(&body[offset], size, msg); !error.empty()) {
      return unexpected(where + "not a map update: " + error);
    }
    offset += size;
    const std::string problem = msg.layer == map_update_t::LAYER_TSDF ? applyRecord(tsdf, msg)
                                : msg.layer == map_update_t::LAYER_ESDF
                                    ? applyRecord(esdf, msg)
                                    : "unknown layer " + std::to_string(msg.layer);
    if (!problem.empty()) return unexpected(where + problem);
  }
  if (tsdf.layer() == nullptr || esdf.layer() == nullptr) {
    return unexpected(path + " lacks a complete " + (tsdf.layer() ? "ESDF" : "TSDF") + " layer");
  }
  if (tsdf.mapId() != esdf.mapId() || tsdf.revision() != esdf.revision()) {
    return unexpected(path + ": its TSDF and ESDF are from different maps or revisions");
  }
  SavedMap map;
  map.tsdf = *tsdf.layer();
  map.esdf = *esdf.layer();
  map.map_id = tsdf.mapId();
  map.revision = tsdf.revision();
  map.utime = tsdf.utime();
  map.start = start;
  return map;
}

}  // namespace thicket::mapper

// Voxel layers on the wire (docs/design.md §3): the mapper publishes the blocks that changed in
// each map revision as thicket::map_update_t (zstd-compressed, split so each message stays well
// under 1 MB); planner and explorer keep a MapMirror that applies them in revision order and asks
// for a full snapshot on MAP_REQUEST when it finds a gap or a restarted mapper.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <thicket/map_request_t.hpp>
#include <thicket/map_update_t.hpp>

#include "thicket/common/expected.h"
#include "thicket/common/voxel_layer.h"

namespace thicket {

/// Which layer and voxel format a voxel type travels as.
template <class Voxel>
struct VoxelWire;
template <>
struct VoxelWire<TsdfVoxel> {
  static constexpr int8_t kLayer = map_update_t::LAYER_TSDF;
  static constexpr int8_t kFormat = map_update_t::FORMAT_TSDF_F32_F32;
  static constexpr int8_t kChangesFormat = map_update_t::FORMAT_TSDF_F32_F32_CHANGES;
  static constexpr size_t kBytes = 8;  // float32 distance, float32 weight
};
template <>
struct VoxelWire<EsdfVoxel> {
  static constexpr int8_t kLayer = map_update_t::LAYER_ESDF;
  static constexpr int8_t kFormat = map_update_t::FORMAT_ESDF_F32_U8;
  static constexpr int8_t kChangesFormat = map_update_t::FORMAT_ESDF_F32_U8_CHANGES;
  static constexpr size_t kBytes = 5;  // float32 distance, uint8 flags (observed, fixed)
};

/// The header of one map revision.
struct MapRevision {
  int64_t utime = 0;     ///< the newest measurement in it [µs]
  int64_t map_id = 0;    ///< changes when the mapper restarts or resets
  int64_t revision = 0;  ///< +1 per integrated frame
  bool full_snapshot = false;
};

/// Most block bytes (as sent) in one message: a message holds at least one block, so it stays
/// under this plus one block (about 33 kB uncompressed at worst).
constexpr size_t kDefaultMaxMessageBytes = 256 * 1024;

/// The messages (parts) of one revision: the blocks listed in `changed` (that exist in the layer),
/// sorted, and the indices in `removed`; a full snapshot sends every block of the layer and
/// ignores both lists. Always at least one message, so that a revision without changes still
/// advances the mirrors. Blocks are zstd-compressed unless `compress` is false (raw blocks: for a
/// transport inside one process, where compressing costs more than copying).
/// With changed_voxels (one set per entry of `changed`; a delta's), a block carries only the
/// voxels of its set (the union, for an index listed twice) in the changes format: the set must
/// hold every voxel that differs from the revision before, or from zero in a block new to it.
/// Throws std::invalid_argument when the counts differ.
template <class Voxel>
std::vector<map_update_t> encodeMapUpdate(const Layer<Voxel>& layer, const MapRevision& revision,
                                          const std::vector<BlockIndex>& changed,
                                          const std::vector<BlockIndex>& removed,
                                          size_t max_message_bytes = kDefaultMaxMessageBytes,
                                          bool compress = true,
                                          const std::vector<BlockVoxels>& changed_voxels = {});

/// A block in the changes format: which of its voxels travel, and their values in index order.
template <class Voxel>
struct BlockChanges {
  BlockIndex index;
  BlockVoxels voxels;
  std::vector<Voxel> values;
};

/// One validated message: its blocks decoded.
template <class Voxel>
struct MapUpdatePart {
  MapRevision revision;
  double voxel_size = 0;
  int part_index = 0;
  int num_parts = 1;
  std::vector<std::unique_ptr<Block<Voxel>>> blocks;  ///< whole blocks
  std::vector<BlockChanges<Voxel>> changes;           ///< blocks in the changes format
  std::vector<BlockIndex> removed;
};

/// Decodes and validates one message: layer and voxel format of Voxel (whole blocks, or the
/// changes format in a delta), 16 voxels per side, a positive finite voxel size, consistent counts
/// and part numbers, known compression, exact payload sizes, finite distances, non-negative finite
/// weights, known flag bits, no block twice.
template <class Voxel>
Expected<MapUpdatePart<Voxel>> decodeMapUpdate(const map_update_t& msg);

/// A copy of a mapper's layer, kept up to date from its map_update_t stream.
template <class Voxel>
class MapMirror {
 public:
  enum class Outcome {
    kApplied,       ///< a whole revision was applied
    kPartial,       ///< a part was stored; the revision is not complete yet
    kIgnored,       ///< an old or duplicate revision, or deltas while waiting for a snapshot
    kNeedSnapshot,  ///< a gap, a new map or no map yet: ask for a full snapshot (request())
    kRefused,       ///< the message is malformed; nothing changed
  };
  struct Result {
    Outcome outcome;
    std::string reason;  ///< why, for anything but kApplied and kPartial
  };

  /// Applies one message. Parts of a revision are held until all have arrived, then applied
  /// together; a delta applies only on top of the revision before it, from the same map, and
  /// one that cannot is dropped on its header alone, before any block is decompressed.
  Result apply(const map_update_t& msg);

  /// The mirrored layer, or nullptr before the first full snapshot.
  const Layer<Voxel>* layer() const { return layer_.get(); }
  int64_t mapId() const { return map_id_; }
  /// The last applied revision, or -1.
  int64_t revision() const { return layer_ ? revision_ : -1; }
  /// Time of the newest measurement in the mirrored map [µs], or 0.
  int64_t utime() const { return utime_; }
  /// Whether the mirror needs a full snapshot (it has none, or it found a gap).
  bool needsSnapshot() const { return needs_snapshot_; }
  /// Why it needs one, e.g. "gap after revision 41".
  const std::string& snapshotReason() const { return snapshot_reason_; }

  /// The MAP_REQUEST asking for a full snapshot of this layer.
  map_request_t request(int64_t utime, const std::string& requester) const;

 private:
  Result needSnapshot(const std::string& reason);
  Result applyComplete();

  std::unique_ptr<Layer<Voxel>> layer_;
  // Blocks the layer let go of (replaced or removed), whose memory the next revision's blocks are
  // decoded into instead of fresh, zeroed allocations; at most as many as the last revision had.
  std::vector<std::unique_ptr<Block<Voxel>>> spare_blocks_;
  int64_t map_id_ = 0;
  int64_t revision_ = -1;
  int64_t utime_ = 0;
  bool needs_snapshot_ = true;
  std::string snapshot_reason_ = "start-up";
  // The parts of the revision being received, by part index.
  std::optional<MapUpdatePart<Voxel>> header_;
  std::map<int, MapUpdatePart<Voxel>> parts_;
};

extern template class MapMirror<TsdfVoxel>;
extern template class MapMirror<EsdfVoxel>;

}  // namespace thicket

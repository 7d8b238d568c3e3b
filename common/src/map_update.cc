#include "thicket/common/map_update.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "thicket/common/compression.h"

namespace thicket {
namespace {

static_assert(std::endian::native == std::endian::little, "payloads are little-endian");

constexpr uint8_t kObservedBit = 1;
constexpr uint8_t kFixedBit = 2;
// Far more parts than any map needs (a 16^3-block message is at least one block).
constexpr int32_t kMaxParts = 1 << 20;

void putFloat(uint8_t*& out, float value) {
  std::memcpy(out, &value, 4);
  out += 4;
}

float getFloat(const uint8_t*& in) {
  float value;
  std::memcpy(&value, in, 4);
  in += 4;
  return value;
}

void encodeVoxel(const TsdfVoxel& voxel, uint8_t*& out) {
  putFloat(out, voxel.distance);
  putFloat(out, voxel.weight);
}

void encodeVoxel(const EsdfVoxel& voxel, uint8_t*& out) {
  putFloat(out, voxel.distance);
  *out++ =
      static_cast<uint8_t>((voxel.observed ? kObservedBit : 0) | (voxel.fixed ? kFixedBit : 0));
}

// Decodes one voxel into `voxel`; what is wrong with it, or nullptr. A block holds 4096 voxels,
// so this stays free of allocations.
const char* validVoxel(const TsdfVoxel& voxel) {
  if (!std::isfinite(voxel.distance) || !(voxel.weight >= 0) || !std::isfinite(voxel.weight)) {
    return "a TSDF voxel has a non-finite distance or a bad weight";
  }
  return nullptr;
}

const char* decodeVoxel(const uint8_t*& in, TsdfVoxel& voxel) {
  voxel.distance = getFloat(in);
  voxel.weight = getFloat(in);
  return validVoxel(voxel);
}

const char* decodeVoxel(const uint8_t*& in, EsdfVoxel& voxel) {
  voxel.distance = getFloat(in);
  const uint8_t flags = *in++;
  if (!std::isfinite(voxel.distance)) return "an ESDF voxel has a non-finite distance";
  if ((flags & ~(kObservedBit | kFixedBit)) != 0) return "an ESDF voxel has unknown flag bits";
  voxel.observed = (flags & kObservedBit) != 0;
  voxel.fixed = (flags & kFixedBit) != 0;
  return nullptr;
}

// A TSDF voxel in memory is its bytes on the wire (float32 distance, then float32 weight,
// little-endian), so that whole blocks travel as they are.
static_assert(sizeof(TsdfVoxel) == VoxelWire<TsdfVoxel>::kBytes &&
                  offsetof(TsdfVoxel, distance) == 0 && offsetof(TsdfVoxel, weight) == 4,
              "TsdfVoxel's layout is the wire's");
template <class Voxel>
constexpr bool kSameAsWire = std::is_same_v<Voxel, TsdfVoxel>;

// The changes format's set of voxels on the wire: its 256 rows as little-endian uint16.
constexpr size_t kSetBytes = sizeof(BlockVoxels::rows);

// One block's payload: every voxel, or (changes format) the set `voxels` and its voxels.
template <class Voxel>
map_block_t encodeBlock(const Block<Voxel>& block, const BlockVoxels* voxels, bool compress) {
  const size_t bytes = voxels != nullptr ? kSetBytes + static_cast<size_t>(voxels->count()) *
                                                           VoxelWire<Voxel>::kBytes
                                         : kVoxelsPerBlock * VoxelWire<Voxel>::kBytes;
  std::vector<uint8_t> raw;
  if (voxels == nullptr && kSameAsWire<Voxel>) {
    // A TSDF block is its payload: one copy, with no zeroing of the buffer first.
    const auto* first = reinterpret_cast<const uint8_t*>(block.voxels.data());
    raw.assign(first, first + bytes);
  } else {
    raw.resize(bytes);
    uint8_t* out = raw.data();
    if (voxels != nullptr) {
      std::memcpy(out, voxels->rows.data(), kSetBytes);
      out += kSetBytes;
      voxels->forEach([&](int lin) { encodeVoxel(block.voxels[lin], out); });
    } else {
      for (const Voxel& voxel : block.voxels) encodeVoxel(voxel, out);
    }
  }
  map_block_t msg;
  for (int i = 0; i < 3; ++i) msg.index[i] = block.index[i];
  msg.compression = compress ? map_block_t::COMPRESSION_ZSTD : map_block_t::COMPRESSION_NONE;
  msg.raw_size = static_cast<int32_t>(raw.size());
  msg.data = compress ? zstdCompress(raw) : std::move(raw);
  msg.size = static_cast<int32_t>(msg.data.size());
  return msg;
}

// "block [x, y, z]: ", for errors only: decoding runs for every block of every map message.
std::string blockName(const map_block_t& msg) {
  return "block [" + std::to_string(msg.index[0]) + ", " + std::to_string(msg.index[1]) + ", " +
         std::to_string(msg.index[2]) + "]: ";
}

// A block's payload of raw_size bytes, within [min_size, max_size], after checking the sizes;
// decompressed into `buffer` if need be.
Expected<const uint8_t*> blockPayload(const map_block_t& msg, size_t min_size, size_t max_size,
                                      std::vector<uint8_t>& buffer) {
  if (msg.size < 0 || static_cast<size_t>(msg.size) != msg.data.size()) {
    return unexpected(blockName(msg) + "size field " + std::to_string(msg.size) + " but " +
                      std::to_string(msg.data.size()) + " bytes of data");
  }
  if (msg.raw_size < 0 || static_cast<size_t>(msg.raw_size) < min_size ||
      static_cast<size_t>(msg.raw_size) > max_size) {
    return unexpected(blockName(msg) + "raw size " + std::to_string(msg.raw_size) +
                      (min_size == max_size ? ", expected " + std::to_string(min_size)
                                            : ", outside " + std::to_string(min_size) + " to " +
                                                  std::to_string(max_size)));
  }
  const size_t raw_size = static_cast<size_t>(msg.raw_size);
  if (msg.compression == map_block_t::COMPRESSION_ZSTD) {
    auto content = zstdDecompress(msg.data, raw_size);
    if (!content) return unexpected(blockName(msg) + content.error());
    buffer = std::move(*content);
    return buffer.data();
  }
  if (msg.compression != map_block_t::COMPRESSION_NONE) {
    return unexpected(blockName(msg) + "unknown compression " + std::to_string(msg.compression));
  }
  if (msg.data.size() != raw_size) {
    return unexpected(blockName(msg) + std::to_string(msg.data.size()) + " bytes, expected " +
                      std::to_string(raw_size));
  }
  return msg.data.data();
}

// Decodes one whole block, into a block taken from `spare` when it has one (every voxel is
// written).
template <class Voxel>
Expected<std::unique_ptr<Block<Voxel>>> decodeBlock(
    const map_block_t& msg, std::vector<std::unique_ptr<Block<Voxel>>>* spare) {
  const size_t raw_size = kVoxelsPerBlock * VoxelWire<Voxel>::kBytes;
  std::vector<uint8_t> decompressed;
  auto payload = blockPayload(msg, raw_size, raw_size, decompressed);
  if (!payload) return unexpected(payload.error());
  const uint8_t* in = *payload;
  const BlockIndex index(msg.index[0], msg.index[1], msg.index[2]);
  std::unique_ptr<Block<Voxel>> block;
  if (spare != nullptr && !spare->empty()) {
    block = std::move(spare->back());
    spare->pop_back();
    block->index = index;
  } else {
    block = std::make_unique<Block<Voxel>>(index);
  }
  if constexpr (kSameAsWire<Voxel>) {
    std::memcpy(block->voxels.data(), in, raw_size);
    for (const Voxel& voxel : block->voxels) {
      if (const char* error = validVoxel(voxel)) return unexpected(blockName(msg) + error);
    }
  } else {
    for (Voxel& voxel : block->voxels) {
      if (const char* error = decodeVoxel(in, voxel)) return unexpected(blockName(msg) + error);
    }
  }
  return block;
}

// Decodes one block in the changes format.
template <class Voxel>
Expected<BlockChanges<Voxel>> decodeChanges(const map_block_t& msg) {
  std::vector<uint8_t> decompressed;
  auto payload = blockPayload(msg, kSetBytes,
                              kSetBytes + kVoxelsPerBlock * VoxelWire<Voxel>::kBytes, decompressed);
  if (!payload) return unexpected(payload.error());
  const uint8_t* in = *payload;
  BlockChanges<Voxel> changes;
  changes.index = BlockIndex(msg.index[0], msg.index[1], msg.index[2]);
  std::memcpy(changes.voxels.rows.data(), in, kSetBytes);
  in += kSetBytes;
  const size_t count = static_cast<size_t>(changes.voxels.count());
  if (static_cast<size_t>(msg.raw_size) != kSetBytes + count * VoxelWire<Voxel>::kBytes) {
    return unexpected(blockName(msg) + "raw size " + std::to_string(msg.raw_size) + " for " +
                      std::to_string(count) + " voxels");
  }
  changes.values.resize(count);
  for (Voxel& voxel : changes.values) {
    if (const char* error = decodeVoxel(in, voxel)) return unexpected(blockName(msg) + error);
  }
  return changes;
}

map_update_t emptyPart(const MapRevision& revision, int8_t layer, int8_t format,
                       double voxel_size) {
  map_update_t msg;
  msg.utime = revision.utime;
  msg.map_id = revision.map_id;
  msg.layer = layer;
  msg.voxel_format = format;
  msg.voxel_size = voxel_size;
  msg.voxels_per_side = kVoxelsPerSide;
  msg.revision = revision.revision;
  msg.full_snapshot = revision.full_snapshot;
  msg.part_index = 0;
  msg.num_parts = 1;
  msg.num_blocks = 0;
  msg.num_removed = 0;
  return msg;
}

}  // namespace

template <class Voxel>
std::vector<map_update_t> encodeMapUpdate(const Layer<Voxel>& layer, const MapRevision& revision,
                                          const std::vector<BlockIndex>& changed,
                                          const std::vector<BlockIndex>& removed,
                                          size_t max_message_bytes, bool compress,
                                          const std::vector<BlockVoxels>& changed_voxels) {
  const bool changes = !revision.full_snapshot && !changed_voxels.empty();
  if (changes && changed_voxels.size() != changed.size()) {
    throw std::invalid_argument("encodeMapUpdate: " + std::to_string(changed_voxels.size()) +
                                " voxel sets for " + std::to_string(changed.size()) +
                                " changed blocks");
  }
  // The blocks to send, sorted, each once; in the changes format, each with the union of its sets.
  std::vector<BlockIndex> blocks;
  std::vector<BlockVoxels> sets;
  if (revision.full_snapshot) {
    blocks = layer.blockIndices();
  } else {
    std::vector<size_t> order;
    for (size_t i = 0; i < changed.size(); ++i) {
      if (layer.block(changed[i]) != nullptr) order.push_back(i);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return indexLess(changed[a], changed[b]); });
    for (const size_t i : order) {
      const bool repeated = !blocks.empty() && blocks.back() == changed[i];
      if (!repeated) blocks.push_back(changed[i]);
      if (changes && repeated) sets.back() |= changed_voxels[i];
      if (changes && !repeated) sets.push_back(changed_voxels[i]);
    }
  }
  const map_update_t empty = emptyPart(
      revision, VoxelWire<Voxel>::kLayer,
      changes ? VoxelWire<Voxel>::kChangesFormat : VoxelWire<Voxel>::kFormat, layer.voxelSize());
  std::vector<map_update_t> parts = {empty};
  size_t part_bytes = 0;
  for (size_t i = 0; i < blocks.size(); ++i) {
    map_block_t block =
        encodeBlock(*layer.block(blocks[i]), changes ? &sets[i] : nullptr, compress);
    if (part_bytes > 0 && part_bytes + block.data.size() > max_message_bytes) {
      parts.push_back(empty);
      part_bytes = 0;
    }
    part_bytes += block.data.size();
    parts.back().blocks.push_back(std::move(block));
  }
  if (!revision.full_snapshot) {
    for (const BlockIndex& index : removed) {
      parts.back().removed.push_back({index.x(), index.y(), index.z()});
    }
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    parts[i].part_index = static_cast<int32_t>(i);
    parts[i].num_parts = static_cast<int32_t>(parts.size());
    parts[i].num_blocks = static_cast<int32_t>(parts[i].blocks.size());
    parts[i].num_removed = static_cast<int32_t>(parts[i].removed.size());
  }
  return parts;
}

namespace {

// decodeMapUpdate in two steps, so that the mirror can drop a delta it cannot apply before it
// decompresses any block: the header (every field but the blocks), then the blocks.
template <class Voxel>
Expected<MapUpdatePart<Voxel>> decodeHeader(const map_update_t& msg) {
  if (msg.layer != VoxelWire<Voxel>::kLayer) {
    return unexpected("layer " + std::to_string(msg.layer) + " where " +
                      std::to_string(VoxelWire<Voxel>::kLayer) + " was expected");
  }
  if (msg.voxel_format != VoxelWire<Voxel>::kFormat &&
      msg.voxel_format != VoxelWire<Voxel>::kChangesFormat) {
    return unexpected("voxel format " + std::to_string(msg.voxel_format) + " where " +
                      std::to_string(VoxelWire<Voxel>::kFormat) + " or " +
                      std::to_string(VoxelWire<Voxel>::kChangesFormat) + " was expected");
  }
  if (msg.voxel_format == VoxelWire<Voxel>::kChangesFormat && msg.full_snapshot) {
    return unexpected("a full snapshot in the changes format, which needs the blocks before");
  }
  if (msg.voxels_per_side != kVoxelsPerSide) {
    return unexpected(std::to_string(msg.voxels_per_side) + " voxels per side, expected " +
                      std::to_string(kVoxelsPerSide));
  }
  if (!(msg.voxel_size > 0 && std::isfinite(msg.voxel_size))) {
    return unexpected("voxel size " + std::to_string(msg.voxel_size) + " is not positive");
  }
  if (msg.num_parts < 1 || msg.num_parts > kMaxParts || msg.part_index < 0 ||
      msg.part_index >= msg.num_parts) {
    return unexpected("part " + std::to_string(msg.part_index) + " of " +
                      std::to_string(msg.num_parts) + " is not possible");
  }
  if (msg.revision < 0) return unexpected("negative revision " + std::to_string(msg.revision));
  if (msg.num_blocks < 0 || static_cast<size_t>(msg.num_blocks) != msg.blocks.size() ||
      msg.num_removed < 0 || static_cast<size_t>(msg.num_removed) != msg.removed.size()) {
    return unexpected("block counts disagree with the arrays");
  }
  MapUpdatePart<Voxel> part;
  part.revision = {msg.utime, msg.map_id, msg.revision, msg.full_snapshot != 0};
  part.voxel_size = msg.voxel_size;
  part.part_index = msg.part_index;
  part.num_parts = msg.num_parts;
  for (const auto& index : msg.removed) part.removed.emplace_back(index[0], index[1], index[2]);
  return part;
}

template <class Voxel>
std::optional<std::string> decodeBlocks(const map_update_t& msg, MapUpdatePart<Voxel>& part,
                                        std::vector<std::unique_ptr<Block<Voxel>>>* spare) {
  std::set<std::array<int32_t, 3>> seen;
  for (const map_block_t& block_msg : msg.blocks) {
    if (!seen.insert({block_msg.index[0], block_msg.index[1], block_msg.index[2]}).second) {
      return "a block appears twice";
    }
    if (msg.voxel_format == VoxelWire<Voxel>::kChangesFormat) {
      auto changes = decodeChanges<Voxel>(block_msg);
      if (!changes) return changes.error();
      part.changes.push_back(std::move(*changes));
      continue;
    }
    auto block = decodeBlock<Voxel>(block_msg, spare);
    if (!block) return block.error();
    part.blocks.push_back(std::move(*block));
  }
  return std::nullopt;
}

}  // namespace

template <class Voxel>
Expected<MapUpdatePart<Voxel>> decodeMapUpdate(const map_update_t& msg) {
  auto part = decodeHeader<Voxel>(msg);
  if (!part) return part;
  if (auto error = decodeBlocks<Voxel>(msg, *part, nullptr)) return unexpected(*error);
  return part;
}

template <class Voxel>
typename MapMirror<Voxel>::Result MapMirror<Voxel>::apply(const map_update_t& msg) {
  auto decoded = decodeHeader<Voxel>(msg);
  if (!decoded) return {Outcome::kRefused, decoded.error()};
  MapUpdatePart<Voxel>& part = *decoded;
  const MapRevision& r = part.revision;
  if (!r.full_snapshot) {
    if (!layer_) return needSnapshot("no map yet");
    if (r.map_id != map_id_) return needSnapshot("a new map id " + std::to_string(r.map_id));
    // The first revision of a map again: its mapper restarted empty under a fixed map id.
    if (r.revision == 1 && revision_ > 1) return needSnapshot("the mapper restarted");
    if (r.revision <= revision_) {
      return {Outcome::kIgnored, "revision " + std::to_string(r.revision) + " is not newer than " +
                                     std::to_string(revision_)};
    }
    if (r.revision != revision_ + 1) {
      return needSnapshot("gap after revision " + std::to_string(revision_));
    }
    if (part.voxel_size != layer_->voxelSize()) return needSnapshot("the voxel size changed");
  } else if (layer_ && !needs_snapshot_ && r.map_id == map_id_ && r.revision == revision_ &&
             part.voxel_size == layer_->voxelSize()) {
    // Another mirror's snapshot of what this one has: nothing to apply (nor to replan on).
    return {Outcome::kIgnored,
            "a snapshot of revision " + std::to_string(r.revision) + ", which the mirror has"};
  }
  if (auto error = decodeBlocks(msg, part, &spare_blocks_)) return {Outcome::kRefused, *error};
  // A part of another revision means the one being received lost a part: drop it. A lost delta
  // shows up as a gap when the next one arrives.
  if (header_ &&
      (header_->revision.map_id != r.map_id || header_->revision.revision != r.revision ||
       header_->revision.full_snapshot != r.full_snapshot || header_->num_parts != part.num_parts ||
       header_->voxel_size != part.voxel_size)) {
    header_.reset();
    parts_.clear();
  }
  if (parts_.count(part.part_index) > 0) {
    return {Outcome::kIgnored, "part " + std::to_string(part.part_index) + " arrived twice"};
  }
  if (!header_) {
    header_.emplace();
    header_->revision = r;
    header_->voxel_size = part.voxel_size;
    header_->num_parts = part.num_parts;
  }
  const int index = part.part_index;
  parts_.emplace(index, std::move(part));
  if (static_cast<int>(parts_.size()) < header_->num_parts) return {Outcome::kPartial, ""};
  return applyComplete();
}

template <class Voxel>
typename MapMirror<Voxel>::Result MapMirror<Voxel>::applyComplete() {
  const MapRevision r = header_->revision;
  if (r.full_snapshot) layer_ = std::make_unique<Layer<Voxel>>(header_->voxel_size);
  size_t blocks = 0;
  const auto keep = [this](std::unique_ptr<Block<Voxel>> block) {
    if (block) spare_blocks_.push_back(std::move(block));
  };
  for (auto& [index, part] : parts_) {
    blocks += part.blocks.size();
    for (std::unique_ptr<Block<Voxel>>& block : part.blocks) {
      keep(layer_->insertBlock(std::move(block)));
    }
    for (const BlockChanges<Voxel>& changes : part.changes) {
      Block<Voxel>& block = layer_->allocateBlock(changes.index);
      const Voxel* value = changes.values.data();
      changes.voxels.forEach([&](int lin) { block.voxels[lin] = *value++; });
    }
    for (const BlockIndex& removed : part.removed) keep(layer_->releaseBlock(removed));
  }
  if (spare_blocks_.size() > blocks) spare_blocks_.resize(blocks);
  header_.reset();
  parts_.clear();
  map_id_ = r.map_id;
  revision_ = r.revision;
  utime_ = r.utime;
  needs_snapshot_ = false;
  snapshot_reason_.clear();
  return {Outcome::kApplied, ""};
}

template <class Voxel>
typename MapMirror<Voxel>::Result MapMirror<Voxel>::needSnapshot(const std::string& reason) {
  needs_snapshot_ = true;
  snapshot_reason_ = reason;
  return {Outcome::kNeedSnapshot, reason};
}

template <class Voxel>
map_request_t MapMirror<Voxel>::request(int64_t utime, const std::string& requester) const {
  map_request_t msg;
  msg.utime = utime;
  msg.requester = requester;
  msg.layer = VoxelWire<Voxel>::kLayer;
  msg.map_id = map_id_;
  msg.last_revision = revision();
  msg.reason = snapshot_reason_;
  return msg;
}

template std::vector<map_update_t> encodeMapUpdate(const Layer<TsdfVoxel>&, const MapRevision&,
                                                   const std::vector<BlockIndex>&,
                                                   const std::vector<BlockIndex>&, size_t, bool,
                                                   const std::vector<BlockVoxels>&);
template std::vector<map_update_t> encodeMapUpdate(const Layer<EsdfVoxel>&, const MapRevision&,
                                                   const std::vector<BlockIndex>&,
                                                   const std::vector<BlockIndex>&, size_t, bool,
                                                   const std::vector<BlockVoxels>&);
template Expected<MapUpdatePart<TsdfVoxel>> decodeMapUpdate(const map_update_t&);
template Expected<MapUpdatePart<EsdfVoxel>> decodeMapUpdate(const map_update_t&);
template class MapMirror<TsdfVoxel>;
template class MapMirror<EsdfVoxel>;

}  // namespace thicket

#include "thicket/mapper/esdf_integrator.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "bucket_queue.h"

namespace thicket::mapper {
namespace {

// A voxel's class (the low bits of BlockNode::state); see the header.
enum : uint8_t { kUnknown = 0, kFree = 1, kInside = 2, kSurface = 3, kOccupied = 4 };
constexpr uint8_t kClassMask = 7;
// Set while the voxel is in the running call's touched list.
constexpr uint8_t kTouched = 8;
// Set while the queue holds the voxel in the bucket of its value, not yet passed on.
constexpr uint8_t kQueued = 16;
constexpr uint8_t kNoParent = 26;

// Which children a raise reaches: those on the free side, those on the inside side; and whether
// they keep their parent with a value recomputed from it (a site's value grew) rather than lose it.
constexpr uint8_t kRaiseFree = 1;
constexpr uint8_t kRaiseInside = 2;
constexpr uint8_t kReevaluate = 4;

bool isSite(uint8_t cls) {
  return cls >= kSurface;
}
bool propagates(uint8_t cls) {
  return cls == kFree || cls == kInside;
}
// Whether the ESDF layer shows the voxel as observed; the rest (occupied sites and unknown voxels)
// it shows as unknown.
bool published(uint8_t cls) {
  return cls == kFree || cls == kInside || cls == kSurface;
}
uint8_t sideOf(uint8_t cls) {
  return cls == kFree ? kRaiseFree : cls == kInside ? kRaiseInside : 0;
}

// The 26 neighbour directions, z slowest and x fastest, (0, 0, 0) left out: so the opposite of
// direction d is 25 - d. A voxel's neighbours depend on where it lies in its block along each
// axis (0: the first layer, 1: between, 2: the last), its class x + 3 y + 9 z: per class and
// direction, the neighbour's block as a slot in BlockNode::neighbours (kMiddle: the voxel's own)
// and its offset from the voxel's linear index into that block.
// The middle of 3 x 3 x 3 (x = y = z = 1): among position classes, the voxels all of whose
// neighbours lie in their block; among a block's neighbour slots, the block itself.
constexpr int kMiddle = 13;
struct Neighbourhood {
  std::array<int, 26> steps{};  // non-zero components: the edge is sqrt(steps) voxels long
  std::array<std::array<uint8_t, 26>, 27> slot{};
  std::array<std::array<int16_t, 26>, 27> offset{};
};

constexpr Neighbourhood makeNeighbourhood() {
  Neighbourhood n;
  for (int c = 0; c < 27; ++c) {
    const int where[3] = {c % 3, c / 3 % 3, c / 9};
    int d = 0;
    for (int z = -1; z <= 1; ++z) {
      for (int y = -1; y <= 1; ++y) {
        for (int x = -1; x <= 1; ++x) {
          if (x == 0 && y == 0 && z == 0) continue;
          const int step[3] = {x, y, z};
          int slot = 0;
          int offset = 0;
          for (int a = 0, slot_stride = 1, stride = 1; a < 3;
               ++a, slot_stride *= 3, stride *= kVoxelsPerSide) {
            // Off the first layer backwards or the last forwards: the next block, wrapped.
            const int block = (where[a] == 0 && step[a] < 0)   ? -1
                              : (where[a] == 2 && step[a] > 0) ? 1
                                                               : 0;
            slot += (block + 1) * slot_stride;
            offset += (step[a] - block * kVoxelsPerSide) * stride;
          }
          n.steps[d] = (x != 0) + (y != 0) + (z != 0);
          n.slot[c][d] = static_cast<uint8_t>(slot);
          n.offset[c][d] = static_cast<int16_t>(offset);
          ++d;
        }
      }
    }
  }
  return n;
}
constexpr Neighbourhood kNeighbours = makeNeighbourhood();

// Per row of three neighbours, each lane's direction (-1: the voxel itself, or the fourth lane),
// and the parent byte a neighbour has when the voxel is its parent, 25 - direction, four to a
// word (0xFF, which no parent byte holds, for the voxel itself and the fourth lane).
constexpr std::array<std::array<int, 4>, 9> kRowDirections = [] {
  std::array<std::array<int, 4>, 9> directions{};
  for (int row = 0, d = 0; row < 9; ++row) {
    for (int lane = 0; lane < 4; ++lane) {
      directions[row][lane] = lane == 3 || (row == 4 && lane == 1) ? -1 : d++;
    }
  }
  return directions;
}();
constexpr std::array<uint32_t, 9> kRowParents = [] {
  std::array<uint32_t, 9> words{};
  for (int row = 0; row < 9; ++row) {
    for (int lane = 0; lane < 4; ++lane) {
      const int d = kRowDirections[row][lane];
      words[row] |= static_cast<uint32_t>(d < 0 ? 0xFF : 25 - d) << (8 * lane);
    }
  }
  return words;
}();

// The rows of three neighbours of a voxel that is neither on its block's first nor on its last
// layer along x (rowsInBlocks): each row (x - 1, x, x + 1 at y + dy, z + dz; rows in direction
// order, dz slowest) lies in one block. Per position class and row, that block as a slot in
// BlockNode::neighbours and the offset of the row's first voxel from the voxel's linear index. A
// row is read as four voxels: the fourth may lie one past the block's last voxel, which
// BlockNode's arrays hold for that.
struct RowTables {
  std::array<std::array<uint8_t, 9>, 27> slot{};
  std::array<std::array<int16_t, 9>, 27> offset{};
};
constexpr RowTables kRows = [] {
  RowTables rows;
  for (int c = 0; c < 27; ++c) {
    for (int row = 0; row < 9; ++row) {
      rows.slot[c][row] = kNeighbours.slot[c][kRowDirections[row][0]];
      rows.offset[c][row] = kNeighbours.offset[c][kRowDirections[row][0]];
    }
  }
  return rows;
}();

// Four floats, and four comparison results, compared lane by lane (GCC vector extensions).
using Floats4 = float __attribute__((vector_size(16)));
using Ints4 = int32_t __attribute__((vector_size(16)));

double square(double x) {
  return x * x;
}

double centre(int i, double voxel_size) {
  return (i + 0.5) * voxel_size;
}

// Voxel x indices lo..hi of one row of voxels; empty when lo > hi.
struct Span {
  int lo = 0;
  int hi = -1;
  bool empty() const { return lo > hi; }
  bool contains(int x) const { return lo <= x && x <= hi; }
};

// The voxels of row (y, z) whose centres lie within sqrt(r2) of p. The one definition of sphere
// membership: classification and the search for voxels that entered or left the occupied sphere
// both ask it, and it is not inlined, so that no caller can round differently.
[[gnu::noinline]] Span rowSpan(const Eigen::Vector3d& p, double r2, int y, int z, double vs) {
  const double ry2 = square(centre(y, vs) - p.y()) + square(centre(z, vs) - p.z());
  if (!(ry2 <= r2)) return {};
  const double h = std::sqrt(r2 - ry2);
  return {static_cast<int>(std::ceil((p.x() - h) / vs - 0.5)),
          static_cast<int>(std::floor((p.x() + h) / vs - 0.5))};
}

// rowSpan of every row through one sphere, computed once per sphere: the occupied sphere's rows
// are asked by the classification and twice by the sphere's pass (as the current sphere, then the
// previous one), the clear sphere's, which does not move, by both at every call.
class SphereRows {
 public:
  void assign(const Eigen::Vector3d& p, double r2, double vs) {
    // Every row whose centre can be within reach, with a voxel to spare against rounding; rowSpan
    // decides.
    const double r = std::sqrt(r2);
    y0_ = static_cast<int>(std::floor((p.y() - r) / vs)) - 1;
    z0_ = static_cast<int>(std::floor((p.z() - r) / vs)) - 1;
    ny_ = static_cast<int>(std::floor((p.y() + r) / vs)) + 2 - y0_;
    nz_ = static_cast<int>(std::floor((p.z() + r) / vs)) + 2 - z0_;
    spans_.resize(static_cast<size_t>(ny_) * static_cast<size_t>(nz_));
    for (int z = 0; z < nz_; ++z) {
      for (int y = 0; y < ny_; ++y) spans_[y + ny_ * z] = rowSpan(p, r2, y0_ + y, z0_ + z, vs);
    }
  }
  // rowSpan(p, r2, y, z, vs) of the sphere assigned.
  Span span(int y, int z) const {
    const unsigned dy = static_cast<unsigned>(y - y0_);
    const unsigned dz = static_cast<unsigned>(z - z0_);
    if (dy >= static_cast<unsigned>(ny_) || dz >= static_cast<unsigned>(nz_)) return {};
    return spans_[dy + static_cast<unsigned>(ny_) * dz];
  }
  size_t memoryBytes() const { return spans_.capacity() * sizeof(Span); }

 private:
  int y0_ = 0, z0_ = 0, ny_ = 0, nz_ = 0;
  std::vector<Span> spans_;
};

// Calls f(lo, hi) for the ranges of a that are not in b.
template <class F>
void forEachInDifference(const Span& a, const Span& b, F&& f) {
  if (a.empty()) return;
  if (b.empty()) {
    f(a.lo, a.hi);
    return;
  }
  if (a.lo < b.lo) f(a.lo, std::min(a.hi, b.lo - 1));
  if (a.hi > b.hi) f(std::max(a.lo, b.hi + 1), a.hi);
}

// The integrator's side of one ESDF block: each voxel's class, value and shortest-path parent.
struct BlockNode {
  // none: the stand-in for blocks that are not allocated, whose classes a new node starts with.
  BlockNode(const BlockIndex& block_index, BlockNode* none) : index(block_index) {
    neighbours.fill(none);
    neighbours[kMiddle] = this;
    parent.fill(kNoParent);
    if (none != nullptr) {
      state = none->state;
      known = none->known;
    }
  }
  BlockIndex index;
  uint32_t id = 0;  // the integrator's short name for the node
  // The 3x3x3 blocks around this one, x fastest; cached so that neighbour lookups across block
  // faces need no hashing. Missing blocks are the integrator's empty stand-in, all unknown.
  std::array<BlockNode*, 27> neighbours;
  int known = 0;        // voxels that are not unknown; the node exists exactly when known > 0
  int published = 0;    // published voxels; the ESDF block exists exactly when published > 0
  int propagating = 0;  // free and inside voxels
  uint64_t changed_in_call = 0;
  BlockVoxels changed;  // the voxels changed in the call (valid while it writes them out)
  EsdfLayer::BlockType* out = nullptr;  // valid while a call writes its changes out
  // Per voxel, and one element more: a row of three neighbours is read as four at once, the
  // fourth up to one past the last voxel (kRows).
  // Sites: their distance; free and inside voxels: the magnitude; unknown: 0.
  std::array<float, kVoxelsPerBlock + 1> value{};
  std::array<uint8_t, kVoxelsPerBlock + 1> state{};  // class | kTouched | kQueued
  std::array<uint8_t, kVoxelsPerBlock + 1> parent;   // direction to the parent, or kNoParent
};

struct Classified {
  uint8_t cls;
  float value;  // sites: their distance; free and inside voxels: max_distance (unreached)
};

// A block's array stride along x, y and z.
constexpr int kStride[3] = {1, kVoxelsPerSide, kVoxelsPerSide* kVoxelsPerSide};

// The position class of each voxel of a block (see Neighbourhood), by linear index.
constexpr std::array<uint8_t, kVoxelsPerBlock> kPositionClasses = [] {
  std::array<uint8_t, kVoxelsPerBlock> classes{};
  const auto where = [](int coordinate) {
    return (coordinate != 0) + (coordinate == kVoxelsPerSide - 1);
  };
  for (int lin = 0; lin < kVoxelsPerBlock; ++lin) {
    classes[lin] =
        static_cast<uint8_t>(where(lin & 15) + 3 * where((lin >> 4) & 15) + 9 * where(lin >> 8));
  }
  return classes;
}();
inline int positionClass(int lin) {
  return kPositionClasses[lin];
}

// Whether voxel lin has all 26 neighbours in its block (the class of the middle along every axis).
inline bool interior(int lin) {
  return positionClass(lin) == kMiddle;
}

// Whether voxel lin's rows of neighbours each lie in one block (kRows): x neither 0 nor 15.
inline bool rowsInBlocks(int lin) {
  return static_cast<unsigned>((lin & (kVoxelsPerSide - 1)) - 1) < kVoxelsPerSide - 2;
}

// Calls f(row, node, linear index of the row's first voxel) for the nine rows of neighbours of
// voxel lin, which must be rowsInBlocks. Unrolled, and for interior voxels with the rows' block
// and offsets as constants.
template <class F>
inline void forEachRow(BlockNode* node, int lin, F&& f) {
  const int c = positionClass(lin);
  if (c == kMiddle) {
#pragma GCC unroll 9
    for (int row = 0; row < 9; ++row) f(row, node, lin + kRows.offset[kMiddle][row]);
    return;
  }
#pragma GCC unroll 9
  for (int row = 0; row < 9; ++row) {
    f(row, node->neighbours[kRows.slot[c][row]], lin + kRows.offset[c][row]);
  }
}

// Whether the block or one of its neighbours holds a free or inside voxel.
inline bool blockNearPropagating(const BlockNode* node) {
  return std::any_of(node->neighbours.begin(), node->neighbours.end(),
                     [](const BlockNode* n) { return n->propagating > 0; });
}

// Whether a free or inside voxel may be among the neighbours of voxel lin: false skips the scan
// of sites deep in unobserved space, which the moving occupied sphere creates and removes.
inline bool nearPropagating(const BlockNode* node, int lin) {
  return node->propagating > 0 || (!interior(lin) && blockNearPropagating(node));
}

// Calls f(direction, node, linear index) for each neighbour (in the empty stand-in if its block is
// not allocated), in direction order. Unrolled, with a block per row of three neighbours where the
// rows lie each in one block (seven eighths of a block's voxels), and constant offsets for
// interior voxels: the scans of the changed voxels' neighbourhoods are most of an update.
template <class F>
inline void forEachNeighbour(BlockNode* node, int lin, F&& f) {
  if (rowsInBlocks(lin)) {
    forEachRow(node, lin, [&](int row, BlockNode* n, int first) {
#pragma GCC unroll 3
      for (int lane = 0; lane < 3; ++lane) {
        if (kRowDirections[row][lane] >= 0) f(kRowDirections[row][lane], n, first + lane);
      }
    });
    return;
  }
  const int c = positionClass(lin);
  const std::array<uint8_t, 26>& slot = kNeighbours.slot[c];
  const std::array<int16_t, 26>& offset = kNeighbours.offset[c];
#pragma GCC unroll 26
  for (int d = 0; d < 26; ++d) f(d, node->neighbours[slot[d]], lin + offset[d]);
}

// Per row of three neighbours, the bit 0 of each lane's byte that counts (not the voxel's own).
constexpr std::array<uint32_t, 9> kRowLanes = [] {
  std::array<uint32_t, 9> masks{};
  for (int row = 0; row < 9; ++row) {
    for (int lane = 0; lane < 3; ++lane) {
      if (kRowDirections[row][lane] >= 0) masks[row] |= 1u << (8 * lane);
    }
  }
  return masks;
}();

// Calls f(direction, node, linear index) for each free or inside neighbour of voxel lin, in
// direction order, as forEachNeighbour does for all. Where the rows of neighbours lie each in one
// block, a row's three classes are tested at once (four state bytes in a word): next to a new site
// most neighbours are sites or unknown.
template <class F>
inline void forEachPropagatingNeighbour(BlockNode* node, int lin, F&& f) {
  if (!rowsInBlocks(lin)) {
    forEachNeighbour(node, lin, [&](int d, BlockNode* n, int l) {
      if (propagates(n->state[l] & kClassMask)) f(d, n, l);
    });
    return;
  }
  forEachRow(node, lin, [&](int row, BlockNode* n, int first) {
    uint32_t states;
    std::memcpy(&states, &n->state[first], sizeof(states));
    // Bit 0 of a lane's byte: free (1) or inside (2), the class's bits 0 and 1 differing and its
    // bit 2 clear.
    for (uint32_t lanes = (states ^ (states >> 1)) & ~(states >> 2) & kRowLanes[row]; lanes != 0;
         lanes &= lanes - 1) {
      const int lane = std::countr_zero(lanes) / 8;
      f(kRowDirections[row][lane], n, first + lane);
    }
  });
}

// Whether a free or inside voxel is among the neighbours of voxel lin: nearPropagating, then the
// neighbours themselves. Most voxels that the occupied sphere's surface passes have none, even in
// blocks that hold free space.
inline bool hasPropagatingNeighbour(BlockNode* node, int lin) {
  bool found = false;
  if (nearPropagating(node, lin)) {
    forEachPropagatingNeighbour(node, lin, [&](int, BlockNode*, int) { found = true; });
  }
  return found;
}

// Sixteen bytes, compared byte by byte (GCC vector extensions).
using Bytes16 = uint8_t __attribute__((vector_size(16)));

// The bytes' bit 0 as bits 0-15: each half's bits gathered by a product whose partial products
// do not overlap, so nothing carries.
inline uint32_t packBytes(Bytes16 bytes) {
  uint64_t half[2];
  std::memcpy(half, &bytes, sizeof(half));
  const auto pack = [](uint64_t b) {
    return static_cast<uint32_t>(((b & 0x0101010101010101u) * 0x0102040810204080u) >> 56);
  };
  return pack(half[0]) | pack(half[1]) << 8;
}

// For the voxels of the row through voxel `first` (x = 0) of node: bit x + 1 set where the column
// at x (in -1 .. 16: the neighbouring blocks' edge voxels included) holds a free or inside voxel
// among the rows y - 1 .. y + 1, z - 1 .. z + 1. Voxel x has a free or inside neighbour exactly
// when bits x .. x + 2 hold one, its own class not counting: hasPropagatingNeighbour for a run of
// the row at once, the nine rows read once for all its voxels rather than for each. Where the
// voxels are themselves neither free nor inside (the occupied sphere's edge), their own bits are
// clear. Without with_edges, bits 0 and 17 (the neighbouring blocks') stay clear.
inline uint32_t rowPropagatingColumns(BlockNode* node, int first, bool with_edges) {
  // The rows of neighbours of the row's voxel x = 1, which lie each in one block, from x = 0.
  const int one = first + 1;
  const int c = positionClass(one);
  Bytes16 any{};
  uint32_t edges = 0;
#pragma GCC unroll 9
  for (int row = 0; row < 9; ++row) {
    const int slot = kRows.slot[c][row];
    const int start = one + kRows.offset[c][row];
    Bytes16 states;
    std::memcpy(&states, node->neighbours[slot]->state.data() + start, sizeof(states));
    const Bytes16 cls = states & kClassMask;
    any |= reinterpret_cast<Bytes16>((cls == uint8_t{kFree}) | (cls == uint8_t{kInside}));
    if (with_edges) {
      // The blocks before and after along x (their slots are next to it): their voxels 15 and 0.
      edges |=
          propagates(node->neighbours[slot - 1]->state[start + kVoxelsPerSide - 1] & kClassMask);
      edges |=
          static_cast<uint32_t>(propagates(node->neighbours[slot + 1]->state[start] & kClassMask))
          << 17;
    }
  }
  return packBytes(any) << 1 | edges;
}

// A list of the wavefront's work, appended to with the common case (room left) inlined: the
// callers in propagate() are large enough that GCC left std::vector::push_back out of line there,
// and the element, passed through memory, stalled on reloading what narrower stores had just
// written (perf: 2 % of a benchmark trial in that call). Grown without zeroing the new room.
template <class T>
class WorkList {
 public:
  using value_type = T;
  [[gnu::always_inline]] void push_back(const T& item) {
    if (size_ == capacity_) [[unlikely]] {
      grow();
    }
    items_[size_++] = item;
  }
  size_t size() const { return size_; }
  size_t capacity() const { return capacity_; }
  void clear() { size_ = 0; }
  void swap(WorkList& other) noexcept {
    items_.swap(other.items_);
    std::swap(size_, other.size_);
    std::swap(capacity_, other.capacity_);
  }
  const T& operator[](size_t i) const { return items_[i]; }
  const T* begin() const { return items_.get(); }
  const T* end() const { return items_.get() + size_; }

 private:
  [[gnu::noinline]] void grow() {
    const size_t capacity = std::max<size_t>(256, 2 * capacity_);
    std::unique_ptr<T[]> items = std::make_unique_for_overwrite<T[]>(capacity);
    std::copy(begin(), end(), items.get());
    items_ = std::move(items);
    capacity_ = capacity;
  }
  std::unique_ptr<T[]> items_;
  size_t size_ = 0;
  size_t capacity_ = 0;
};

constexpr int kLast = kVoxelsPerSide - 1;
constexpr float kNoSite = std::numeric_limits<float>::infinity();

// A TSDF block and its six face neighbours (nullptr where not allocated): enough to look up a
// voxel of the block and each of its face neighbours without hashing.
class TsdfStar {
 public:
  TsdfStar(const TsdfLayer& tsdf, const BlockIndex& b) {
    blocks_[0] = tsdf.block(b);
    for (int face = 0; face < 6; ++face) {
      blocks_[face + 1] = tsdf.block(b + (face % 2 ? 1 : -1) * BlockIndex::Unit(face / 2));
    }
  }
  const TsdfLayer::BlockType* centre() const { return blocks_[0]; }
  // The voxel at local (x, y, z), at most one coordinate a step outside [0, 15].
  const TsdfVoxel* voxel(int x, int y, int z) const {
    int slot = 0;
    if (x < 0 || x > kLast) slot = x < 0 ? 1 : 2;
    if (y < 0 || y > kLast) slot = y < 0 ? 3 : 4;
    if (z < 0 || z > kLast) slot = z < 0 ? 5 : 6;
    const TsdfLayer::BlockType* block = blocks_[slot];
    if (block == nullptr) return nullptr;
    return &block->voxels[(x & 15) + kVoxelsPerSide * ((y & 15) + kVoxelsPerSide * (z & 15))];
  }

 private:
  std::array<const TsdfLayer::BlockType*, 7> blocks_;
};

void checkPosition(const Eigen::Vector3d& p, const char* what) {
  // The bound keeps voxel indices far from int overflow at any sensible voxel size.
  if (!(p.array().abs() <= 1e6).all()) {
    throw std::invalid_argument(std::string("EsdfIntegrator: the ") + what +
                                " must be finite and within 1e6 m of the origin");
  }
}

}  // namespace

void EsdfIntegratorOptions::declare(Params& p) {
  p("max_distance", max_distance, "distances saturate at +-this [m]", Range::positive());
  p("clear_radius", clear_radius,
    "r_c: unobserved voxels this close to the initial position are free [m]", Range::positive());
  p("occupied_radius", occupied_radius,
    "r_o: with occupied_everywhere false, unobserved voxels this close to the vehicle are "
    "occupied [m]",
    Range::positive());
  p("occupied_everywhere", occupied_everywhere,
    "unobserved voxels outside the clear sphere are occupied wherever they are; false: only "
    "within occupied_radius (the paper's sphere, moving with the vehicle). The distances within "
    "occupied_radius - max_distance of the vehicle are the same either way");
  p("surface_band_voxels", surface_band_voxels,
    "observed voxels with |TSDF distance| <= this * voxel size are fixed sites [voxels]",
    Range::positive());
  p("min_weight", min_weight, "TSDF voxels with less weight are unobserved", Range::positive());
  p("crossing_sites", crossing_sites,
    "observed voxels next to a TSDF sign change are sites no farther than the interpolated zero "
    "crossing");
}

class EsdfIntegrator::Impl {
 public:
  explicit Impl(EsdfIntegratorOptions options) : options_(options) {
    const double values[] = {options.max_distance, options.clear_radius, options.occupied_radius,
                             options.surface_band_voxels, options.min_weight};
    for (const double v : values) {
      if (!(v > 0 && std::isfinite(v))) {
        throw std::invalid_argument("EsdfIntegrator: every option must be positive and finite");
      }
    }
    max_ = static_cast<float>(options.max_distance);
    min_weight_ = static_cast<float>(options.min_weight);
    if (options.occupied_everywhere) {
      none_->state.fill(kOccupied);
      none_->known = kVoxelsPerBlock;
    }
  }

  const EsdfIntegratorOptions& options() const { return options_; }

  void setInitialPosition(const Eigen::Vector3d& p) {
    checkPosition(p, "initial position");
    if (has_initial_ && p != initial_) built_ = false;
    initial_ = p;
    has_initial_ = true;
  }

  EsdfUpdateResult update(const TsdfLayer& tsdf, const std::vector<BlockIndex>& changed_tsdf_blocks,
                          const Eigen::Vector3d& position, EsdfLayer& esdf) {
    return incremental(tsdf, position, esdf, [&] {
      for (const BlockIndex& b : changed_tsdf_blocks) addWork(tsdf, b, BlockVoxels::all());
    });
  }

  EsdfUpdateResult update(const TsdfLayer& tsdf, const TsdfIntegrationResult& integration,
                          const Eigen::Vector3d& position, EsdfLayer& esdf) {
    const bool reported = integration.observed_weight == min_weight_;
    return incremental(tsdf, position, esdf, [&] {
      // Thrown here, the next call recomputes, as after any throw.
      if (integration.changed_voxels.size() != integration.changed_blocks.size()) {
        throw std::invalid_argument(
            "EsdfIntegrator::update: the integration reports " +
            std::to_string(integration.changed_voxels.size()) + " voxel sets for " +
            std::to_string(integration.changed_blocks.size()) + " changed blocks");
      }
      for (size_t i = 0; i < integration.changed_blocks.size(); ++i) {
        const BlockIndex& b = integration.changed_blocks[i];
        addWork(tsdf, b,
                reported && tsdf.block(b) != nullptr ? integration.changed_voxels[i]
                                                     : BlockVoxels::all());
      }
    });
  }

  // An incremental update: collect() lists the TSDF voxels that changed (addWork), then their
  // voxels, those whose sphere membership changed, and every distance that depends on them are
  // updated.
  template <class Collect>
  EsdfUpdateResult incremental(const TsdfLayer& tsdf, const Eigen::Vector3d& position,
                               EsdfLayer& esdf, Collect&& collect) {
    // Until the end, should anything throw (bad inputs, std::bad_alloc too): the next call then
    // recomputes, so that no change the TSDF took is lost.
    const bool built = built_;
    built_ = false;
    checkInputs(tsdf, position, esdf);
    if (!built || tsdf.voxelSize() != voxel_size_) return recompute(tsdf, position, esdf);
    if (esdf.numBlocks() != blocks_) {
      throw std::logic_error(
          "EsdfIntegrator::update: esdf is not the layer of the previous call (blocks differ)");
    }
    beginCall();
    const Eigen::Vector3d previous = position_;
    position_ = position;
    const bool sphere_moved = previous != position && !options_.occupied_everywhere;
    if (sphere_moved) {
      std::swap(previous_rows_, occupied_rows_);
      occupied_rows_.assign(position_, ro2_, voxel_size_);
    }
    collect();
    // Block by block in index order, each block once with the union of its sets.
    std::sort(work_.begin(), work_.end(), [](const Work& a, const Work& b) {
      return indexLess(a.block, b.block) || (a.block == b.block && a.set < b.set);
    });
    for (size_t i = 0; i < work_.size();) {
      const BlockIndex b = work_[i].block;
      BlockVoxels& voxels = work_sets_[work_[i].set];
      for (++i; i < work_.size() && work_[i].block == b; ++i) voxels |= work_sets_[work_[i].set];
      const TsdfStar star(tsdf, b);
      BlockNode* node = find(b);
      // Without either, every voxel was unknown and stays so, except where the occupied sphere
      // arrived, which sphereMoved handles.
      if (star.centre() != nullptr || node != nullptr) classifyVoxels(b, star, node, voxels);
    }
    if (sphere_moved) sphereMoved(previous);
    propagate(/*incremental=*/true);
    EsdfUpdateResult result = finish(esdf, /*whole_blocks=*/false);
    built_ = true;
    return result;
  }

  // Lists the voxels of block b whose TSDF voxels changed for classification, with the voxels
  // whose class reads them: with crossing_sites, their face neighbours, in this block or the next.
  void addWork(const TsdfLayer& tsdf, const BlockIndex& b, const BlockVoxels& changed) {
    if (!options_.crossing_sites) {
      pushWork(b, changed);
      return;
    }
    BlockVoxels within;
    std::array<BlockVoxels, 6> across;
    for (int z = 0; z < kVoxelsPerSide; ++z) {
      for (int y = 0; y < kVoxelsPerSide; ++y) {
        const int r = y + kVoxelsPerSide * z;
        const uint16_t row = changed.rows[r];
        if (row == 0) continue;
        within.rows[r] |= row | static_cast<uint16_t>(row << 1) | static_cast<uint16_t>(row >> 1);
        if (y > 0) within.rows[r - 1] |= row;
        if (y < kLast) within.rows[r + 1] |= row;
        if (z > 0) within.rows[r - kVoxelsPerSide] |= row;
        if (z < kLast) within.rows[r + kVoxelsPerSide] |= row;
        // Faces -x, +x, -y, +y, -z, +z: the neighbour's voxel on the other side of the face.
        if (row & 1) across[0].rows[r] |= 1u << kLast;
        if (row >> kLast) across[1].rows[r] |= 1u;
        if (y == 0) across[2].rows[kLast + kVoxelsPerSide * z] = row;
        if (y == kLast) across[3].rows[kVoxelsPerSide * z] = row;
        if (z == 0) across[4].rows[y + kVoxelsPerSide * kLast] = row;
        if (z == kLast) across[5].rows[y] = row;
      }
    }
    pushWork(b, within);
    for (int face = 0; face < 6; ++face) {
      const BlockIndex n = b + (face % 2 ? 1 : -1) * BlockIndex::Unit(face / 2);
      // Unobserved voxels' classes read no neighbour: without a TSDF block, nothing there does.
      if (!across[face].empty() && tsdf.block(n) != nullptr) pushWork(n, across[face]);
    }
  }
  void pushWork(const BlockIndex& b, const BlockVoxels& voxels) {
    work_.push_back({b, static_cast<uint32_t>(work_sets_.size())});
    work_sets_.push_back(voxels);
  }

  size_t memoryBytes() const {
    // A node per allocated block (with its hash-map entry), and the lists' capacities.
    const size_t nodes =
        nodes_.size() * (sizeof(BlockNode) + sizeof(BlockIndex) + 2 * sizeof(void*)) +
        nodes_.bucket_count() * sizeof(void*);
    return nodes + by_id_.capacity() * sizeof(BlockNode*) +
           free_ids_.capacity() * sizeof(uint32_t) + touched_.capacity() * sizeof(Touched) +
           (raise_.capacity() + seeds_.capacity() + tentative_.capacity()) * sizeof(VoxelRef) +
           queue_.memoryBytes() +
           (changed_nodes_.capacity() + emptied_.capacity()) * sizeof(BlockNode*) +
           work_.capacity() * sizeof(Work) + work_sets_.capacity() * sizeof(BlockVoxels) +
           clear_rows_.memoryBytes() + occupied_rows_.memoryBytes() + previous_rows_.memoryBytes();
  }

  EsdfUpdateResult recompute(const TsdfLayer& tsdf, const Eigen::Vector3d& position,
                             EsdfLayer& esdf) {
    checkInputs(tsdf, position, esdf);
    const std::vector<BlockIndex> before = esdf.blockIndices();
    built_ = false;  // until the end, should anything throw
    esdf.clear();
    nodes_.clear();
    by_id_.clear();
    free_ids_.clear();
    voxel_size_ = tsdf.voxelSize();
    band_ = static_cast<float>(options_.surface_band_voxels * voxel_size_);
    voxel_size_f_ = static_cast<float>(voxel_size_);
    rc2_ = square(options_.clear_radius);
    ro2_ = square(options_.occupied_radius);
    for (int d = 0; d < 26; ++d) {
      edge_[d] =
          static_cast<float>(voxel_size_ * std::sqrt(static_cast<double>(kNeighbours.steps[d])));
    }
    // Per row of three neighbours (x - 1, x, x + 1), its edges; the voxel itself and a fourth
    // lane, read along, at infinity: never shorter.
    for (int row = 0; row < 9; ++row) {
      for (int lane = 0; lane < 4; ++lane) {
        const int d = kRowDirections[row][lane];
        row_edges_[row][lane] = d < 0 ? std::numeric_limits<float>::infinity() : edge_[d];
      }
    }
    position_ = position;
    clear_rows_.assign(initial_, rc2_, voxel_size_);
    if (!options_.occupied_everywhere) occupied_rows_.assign(position_, ro2_, voxel_size_);
    beginCall();

    std::vector<BlockIndex> blocks = tsdf.blockIndices();
    appendSphereBlocks(initial_, options_.clear_radius, blocks);
    if (!options_.occupied_everywhere) {
      appendSphereBlocks(position, options_.occupied_radius, blocks);
    }
    std::sort(blocks.begin(), blocks.end(), indexLess);
    blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
    for (const BlockIndex& b : blocks) {
      classifyVoxels(b, TsdfStar(tsdf, b), nullptr, BlockVoxels::all(), /*from_empty=*/true);
    }
    // Of the occupied sites, only those next to free or inside voxels seed the wavefront: no
    // distance reads the rest, most of the occupied sphere.
    for (const BlockIndex& b : blocks) {
      BlockNode* node = find(b);
      if (node == nullptr || !blockNearPropagating(node)) continue;
      for (int lin = 0; lin < kVoxelsPerBlock; ++lin) {
        if (node->state[lin] == kOccupied && hasPropagatingNeighbour(node, lin)) {
          seeds_.push_back({node, lin, 0});
        }
      }
    }
    propagate(/*incremental=*/false);

    EsdfUpdateResult result = finish(esdf, /*whole_blocks=*/true);
    built_ = true;
    for (const BlockIndex& b : before) {
      if (esdf.block(b) == nullptr) result.removed_blocks.push_back(b);
    }
    return result;
  }

 private:
  struct Touched {
    BlockNode* node;
    int lin;
    uint8_t cls;  // before the call
    float value;  // before the call
  };
  struct VoxelRef {
    BlockNode* node;
    int lin;
    uint8_t raise;  // kRaiseFree | kRaiseInside | kReevaluate
  };

  void checkInputs(const TsdfLayer& tsdf, const Eigen::Vector3d& position,
                   const EsdfLayer& esdf) const {
    if (!has_initial_) {
      throw std::logic_error("EsdfIntegrator: setInitialPosition() must be called first");
    }
    if (tsdf.voxelSize() != esdf.voxelSize()) {
      throw std::invalid_argument("EsdfIntegrator: the TSDF and ESDF voxel sizes differ");
    }
    checkPosition(position, "current position");
  }

  // A work list whose last call used under a quarter of it, and that holds more than 1 MiB, is
  // freed (the next call grows it again): a large call, such as the first with its whole occupied
  // sphere, does not keep its peak for the rest of the flight.
  template <class List>
  static void clearList(List& list) {
    using T = typename List::value_type;
    if (list.capacity() * sizeof(T) > (size_t{1} << 20) && list.size() * 4 < list.capacity()) {
      List().swap(list);
    }
    list.clear();
  }

  void beginCall() {
    ++call_;
    clearList(touched_);
    clearList(raise_);
    clearList(seeds_);
    clearList(tentative_);
    // Buckets of half a voxel: narrower than every edge, so each voxel leaves the queue final.
    queue_.reset(0.5f * voxel_size_f_, max_);
    clearList(changed_nodes_);
    clearList(emptied_);
    clearList(work_);
    clearList(work_sets_);
  }

  BlockNode* find(const BlockIndex& b) const {
    const auto it = nodes_.find(b);
    return it == nodes_.end() ? nullptr : it->second.get();
  }

  BlockNode* allocate(const BlockIndex& b) {
    auto owned = std::make_unique<BlockNode>(b, none_.get());
    BlockNode* node = owned.get();
    for (int i = 0; i < 27; ++i) {
      if (i == kMiddle) continue;
      BlockNode* other = find(b + BlockIndex(i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1));
      if (other == nullptr) continue;
      node->neighbours[i] = other;
      other->neighbours[26 - i] = node;
    }
    if (free_ids_.empty()) {
      // Queue entries hold the id in 20 bits: a million blocks, 24 GB of integrator state.
      if (by_id_.size() >= (size_t{1} << 20)) {
        built_ = false;  // the state is half updated: the next update() recomputes
        throw std::length_error("EsdfIntegrator: more than 2^20 ESDF blocks");
      }
      node->id = static_cast<uint32_t>(by_id_.size());
      by_id_.push_back(node);
    } else {
      node->id = free_ids_.back();
      free_ids_.pop_back();
      by_id_[node->id] = node;
    }
    nodes_.emplace(b, std::move(owned));
    return node;
  }

  void erase(BlockNode* node) {
    for (int i = 0; i < 27; ++i) {
      if (i != kMiddle && node->neighbours[i] != none_.get()) {
        node->neighbours[i]->neighbours[26 - i] = none_.get();
      }
    }
    by_id_[node->id] = nullptr;
    free_ids_.push_back(node->id);
    nodes_.erase(node->index);
  }

  void appendSphereBlocks(const Eigen::Vector3d& p, double r,
                          std::vector<BlockIndex>& blocks) const {
    // One voxel of margin: a centre within r lies in a voxel whose index floor() may round away.
    const double reach = r + voxel_size_;
    const BlockIndex lo = blockOfVoxel(voxelOf((p.array() - reach).matrix()));
    const BlockIndex hi = blockOfVoxel(voxelOf((p.array() + reach).matrix()));
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const BlockIndex b(x, y, z);
          if (nearestSquared(b, p) <= square(reach)) blocks.push_back(b);
        }
      }
    }
  }

  VoxelIndex voxelOf(const Eigen::Vector3d& p) const {
    return (p / voxel_size_).array().floor().cast<int>().matrix();
  }

  // The squared distances from p to the nearest and the farthest voxel centre of block b.
  double nearestSquared(const BlockIndex& b, const Eigen::Vector3d& p) const {
    double sum = 0;
    for (int a = 0; a < 3; ++a) {
      const double lo = centre(kVoxelsPerSide * b[a], voxel_size_);
      const double hi = lo + (kVoxelsPerSide - 1) * voxel_size_;
      sum += square(std::max({0.0, lo - p[a], p[a] - hi}));
    }
    return sum;
  }
  double farthestSquared(const BlockIndex& b, const Eigen::Vector3d& p) const {
    double sum = 0;
    for (int a = 0; a < 3; ++a) {
      const double lo = centre(kVoxelsPerSide * b[a], voxel_size_);
      const double hi = lo + (kVoxelsPerSide - 1) * voxel_size_;
      sum += square(std::max(std::abs(p[a] - lo), std::abs(p[a] - hi)));
    }
    return sum;
  }

  bool observed(const TsdfVoxel* t) const {
    return t != nullptr && t->weight >= min_weight_ && !std::isnan(t->distance);
  }

  // The class of voxel (x, y, z) of star's centre block (local coordinates), at global x in a row
  // with the clear and the occupied sphere's spans. An observed voxel within the surface band is a
  // site carrying its distance; with crossing_sites, so is one whose face neighbour was observed
  // on the other side of the surface, at no more than the distance to the zero crossing
  // interpolated between them. That crossing is where the TSDF puts the surface, whatever the
  // distances on either side claim: line-of-sight distances stretch at a slant, and a projective
  // TSDF paints free space behind a thin tree as inside, leaving free voxels next to inside ones
  // with no site between them, so the free side's distances came from sites far away.
  Classified classify(const TsdfStar& star, int x, int y, int z, int global_x, const Span& clear,
                      const Span& occupied) const {
    const int lin = x + kVoxelsPerSide * (y + kVoxelsPerSide * z);
    const TsdfVoxel* t = star.centre() != nullptr ? &star.centre()->voxels[lin] : nullptr;
    if (observed(t)) {
      const float d = t->distance;
      const float magnitude = std::abs(d);
      float site = magnitude <= band_ ? magnitude : kNoSite;
      if (options_.crossing_sites && magnitude > 0) {
        const auto crossing = [&](const TsdfVoxel* n) __attribute__((always_inline)) {
          // The sign first: most neighbours are on the same side (a NaN fails either test).
          if (n == nullptr || !(d > 0 ? n->distance <= 0 : n->distance >= 0) || !observed(n)) {
            return;
          }
          // A signed distance changes by at most the voxel size between neighbours: a larger
          // sum means one side is stretched (a slant) or truncated, and which is unknown, so the
          // crossing is taken midway rather than interpolated toward the smaller value.
          const float sum = magnitude + std::abs(n->distance);
          site = std::min(
              site, sum > voxel_size_f_ ? 0.5f * voxel_size_f_ : voxel_size_f_ * magnitude / sum);
        };
        // Faces -x, +x, -y, +y, -z, +z: at constant strides for a voxel off its block's faces.
        if (interior(lin)) {
          for (const int stride : kStride) {
            crossing(t - stride);
            crossing(t + stride);
          }
        } else {
          for (int face = 0; face < 6; ++face) {
            const int step = face % 2 ? 1 : -1;
            crossing(star.voxel(x + (face / 2 == 0 ? step : 0), y + (face / 2 == 1 ? step : 0),
                                z + (face / 2 == 2 ? step : 0)));
          }
        }
      }
      if (site != kNoSite) return {kSurface, std::copysign(std::min(site, max_), d)};
      return d > 0 ? Classified{kFree, max_} : Classified{kInside, max_};
    }
    return unobservedClass(global_x, clear, occupied);
  }

  // The class of an unobserved voxel at x in a row with the spheres' spans.
  Classified unobservedClass(int x, const Span& clear, const Span& occupied) const {
    if (clear.contains(x)) return {kFree, max_};
    if (occupied.contains(x)) return {kOccupied, 0};
    return {kUnknown, 0};
  }

  // The node of a block, or the stand-in whose classes a block has while it is not allocated.
  const BlockNode* orNone(const BlockNode* node) const {
    return node != nullptr ? node : none_.get();
  }

  // Whether voxel lin already has class c (a site: and its value). Propagated values do not count.
  bool unchanged(const BlockNode* node, int lin, const Classified& c) const {
    const BlockNode* n = orNone(node);
    const uint8_t old = n->state[lin] & kClassMask;
    return old == c.cls && (!isSite(old) || std::bit_cast<uint32_t>(n->value[lin]) ==
                                                std::bit_cast<uint32_t>(c.value));
  }

  // Counts a voxel of node going from class old to cls in the node's known and observed voxels; a
  // node left with none known is erased at the end of the call.
  void count(BlockNode* node, uint8_t old, uint8_t cls) {
    node->known += (cls != kUnknown) - (old != kUnknown);
    node->published += published(cls) - published(old);
    if (node->known == 0 && old != kUnknown) emptied_.push_back(node);
  }

  // Gives voxel lin, unknown or occupied, the other of those classes, cls, where no distance reads
  // it: the layer shows both as unknown, and both have value 0 and no parent, so only the class
  // and the counts change, outside the wavefront's lists.
  void flipUnpublished(BlockNode* node, int lin, uint8_t cls) {
    uint8_t& state = node->state[lin];
    count(node, state & kClassMask, cls);
    state = static_cast<uint8_t>((state & kTouched) | cls);
  }

  // Records the voxel's state before the call, once.
  void touch(BlockNode* node, int lin) {
    if (!(node->state[lin] & kTouched)) record(node, lin);
  }
  void record(BlockNode* node, int lin) {
    uint8_t& state = node->state[lin];
    touched_.push_back({node, lin, static_cast<uint8_t>(state & kClassMask), node->value[lin]});
    state |= kTouched;
  }

  // Gives voxel lin of block b (node: nullptr if not allocated yet) its new class c, not the one it
  // has. It drops its parent and raises the children that the change can lengthen; sites become
  // seeds of the lower wavefront, free and inside voxels look for a new parent.
  void reclassify(BlockNode*& node, const BlockIndex& b, int lin, const Classified& c) {
    const uint8_t cls = c.cls;
    const float value = c.value;
    if (node == nullptr) node = allocate(b);
    const uint8_t old = node->state[lin] & kClassMask;
    touch(node, lin);
    const float old_value = node->value[lin];
    uint8_t raise = 0;
    if (propagates(old) || (isSite(old) && !isSite(cls))) {
      raise = kRaiseFree | kRaiseInside;
    } else if (isSite(old)) {
      // A site is the free side's source at +value and the inside's at -value: the side whose
      // source grew keeps its paths, only longer.
      raise = value > old_value   ? kRaiseFree | kReevaluate
              : value < old_value ? kRaiseInside | kReevaluate
                                  : 0;
    }
    if (raise != 0) raise_.push_back({node, lin, raise});
    count(node, old, cls);
    node->propagating += propagates(cls) - propagates(old);
    node->state[lin] = kTouched | cls;
    node->value[lin] = value;
    node->parent[lin] = kNoParent;
    if (isSite(cls) && raise == 0) {
      seeds_.push_back({node, lin, 0});
    } else if (propagates(cls)) {
      tentative_.push_back({node, lin, 0});
    }
  }

  // Classifies the voxels `which` of block b (node: nullptr if not allocated yet), reclassifying
  // those whose class changed; from_empty: for recompute(), every block's first classification.
  void classifyVoxels(const BlockIndex& b, const TsdfStar& star, BlockNode* node,
                      const BlockVoxels& which, bool from_empty = false) {
    const VoxelIndex origin = b * kVoxelsPerSide;
    const Span whole{origin.x(), origin.x() + kVoxelsPerSide - 1};
    // Blocks clear of a sphere's surface by a voxel take their spans without asking rowSpan.
    enum Relation { kClearOf, kWithin, kCrossing };
    auto relation = [&](const Eigen::Vector3d& p, double r) {
      if (nearestSquared(b, p) > square(r + voxel_size_)) return kClearOf;
      if (r > voxel_size_ && farthestSquared(b, p) < square(r - voxel_size_)) return kWithin;
      return kCrossing;
    };
    const Relation to_clear = relation(initial_, options_.clear_radius);
    const Relation to_occupied =
        options_.occupied_everywhere ? kWithin : relation(position_, options_.occupied_radius);
    auto spanOf = [&](Relation relation, const SphereRows& rows, int y, int z) {
      return relation == kClearOf ? Span{} : relation == kWithin ? whole : rows.span(y, z);
    };
    for (int z = 0; z < kVoxelsPerSide; ++z) {
      for (int y = 0; y < kVoxelsPerSide; ++y) {
        unsigned row = which.rows[y + kVoxelsPerSide * z];
        if (row == 0) continue;
        const Span clear = spanOf(to_clear, clear_rows_, origin.y() + y, origin.z() + z);
        const Span occupied = spanOf(to_occupied, occupied_rows_, origin.y() + y, origin.z() + z);
        for (; row != 0; row &= row - 1) {
          const int x = std::countr_zero(row);
          const int lin = x + kVoxelsPerSide * (y + kVoxelsPerSide * z);
          const Classified c = classify(star, x, y, z, origin.x() + x, clear, occupied);
          if (unchanged(node, lin, c)) continue;
          if (from_empty && c.cls == kOccupied) {
            // From scratch, an occupied site is neither published nor a parent yet: recompute()
            // seeds the wavefront with those next to free or inside voxels once all are
            // classified.
            if (node == nullptr) node = allocate(b);
            flipUnpublished(node, lin, kOccupied);
          } else {
            reclassify(node, b, lin, c);
          }
        }
      }
    }
  }

  // Reclassifies the voxels that left the occupied sphere (around `previous`) or entered it
  // (around position_), in one pass over the rows through either sphere.
  void sphereMoved(const Eigen::Vector3d& previous) {
    const Eigen::Vector3d& current = position_;
    const double reach = options_.occupied_radius + voxel_size_;
    const BlockIndex lo =
        blockOfVoxel(voxelOf((previous.cwiseMin(current).array() - reach).matrix()));
    const BlockIndex hi =
        blockOfVoxel(voxelOf((previous.cwiseMax(current).array() + reach).matrix()));
    const int width = hi.x() - lo.x() + 1;
    for (int bz = lo.z(); bz <= hi.z(); ++bz) {
      for (int by = lo.y(); by <= hi.y(); ++by) {
        // The blocks along x, looked up once for their 256 rows of voxels.
        bool looked_up = false;
        for (int z = kVoxelsPerSide * bz; z < kVoxelsPerSide * (bz + 1); ++z) {
          for (int y = kVoxelsPerSide * by; y < kVoxelsPerSide * (by + 1); ++y) {
            // Rows through neither sphere have two empty spans.
            const Span before = previous_rows_.span(y, z);
            const Span now = occupied_rows_.span(y, z);
            if ((before.empty() && now.empty()) || (before.lo == now.lo && before.hi == now.hi)) {
              continue;
            }
            if (!looked_up) {
              row_nodes_.resize(width);
              for (int i = 0; i < width; ++i) {
                row_nodes_[i] = find(BlockIndex(lo.x() + i, by, bz));
              }
              looked_up = true;
            }
            const SphereRow row{y, z, clear_rows_.span(y, z), now};
            // The run that left, then the one that entered, block by block.
            const auto reclassifyRun = [&](int x0, int x1) {
              for (int s0 = x0, s1; s0 <= x1; s0 = s1 + 1) {
                s1 = std::min(x1, s0 | kLast);
                reclassifyStretch(row, row_nodes_[(s0 >> 4) - lo.x()], s0, s1);
              }
            };
            forEachInDifference(before, now, reclassifyRun);
            forEachInDifference(now, before, reclassifyRun);
          }
        }
      }
    }
  }

  // A row (y, z) of voxels through the sphere's pass, with the spans of the clear and the occupied
  // sphere.
  struct SphereRow {
    int y, z;
    Span clear, occupied;
  };

  // Reclassifies voxels s0..s1 of the row, which left or entered the occupied sphere and lie in
  // one block (node: nullptr if not allocated yet).
  void reclassifyStretch(const SphereRow& row, BlockNode*& node, int s0, int s1) {
    const BlockIndex b(s0 >> 4, row.y >> 4, row.z >> 4);
    const int first = kVoxelsPerSide * ((row.y & 15) + kVoxelsPerSide * (row.z & 15));
    // The neighbour test of a stretch of three or more reads the nine rows once, when the first
    // voxel needs it (rowPropagatingColumns).
    const bool by_columns = s1 - s0 >= 2;
    uint32_t columns = 0;
    bool have_columns = false;
    const auto hasNeighbour = [&](int x, int lin) {
      if (!by_columns) return hasPropagatingNeighbour(node, lin);
      if (!have_columns) {
        columns = node->propagating > 0 || blockNearPropagating(node)
                      ? rowPropagatingColumns(node, first, (s0 & 15) == 0 || (s1 & 15) == kLast)
                      : 0;
        have_columns = true;
      }
      return (columns >> (x & 15) & 7) != 0;
    };
    for (int x = s0; x <= s1; ++x) {
      const int lin = (x & 15) + first;
      const uint8_t old = orNone(node)->state[lin] & kClassMask;
      // A published class is that of an observed voxel, which the spheres do not change (and
      // which was classified with its block if its TSDF changed), or of an unobserved one in the
      // clear sphere, which does not move: free, as it stays. Either way nothing changes, and the
      // TSDF need not tell which.
      if (published(old)) continue;
      const Classified c = unobservedClass(x, row.clear, row.occupied);
      if (unchanged(node, lin, c)) continue;
      if (node == nullptr) node = allocate(b);
      // Between unknown and occupied with no free or inside neighbour (most of the sphere's
      // edge), in place. Only here: the classification is done, so the neighbours' classes are
      // final (this pass changes only unknown and occupied ones).
      if (!published(c.cls) && !hasNeighbour(x, lin)) {
        flipUnpublished(node, lin, c.cls);
        continue;
      }
      reclassify(node, b, lin, c);
      // Should the voxel now propagate, its neighbours' columns changed.
      have_columns = have_columns && !propagates(c.cls);
    }
  }

  // Gives a free or inside voxel a shorter value (in [0, max_distance]) through the neighbour in
  // direction `dir` and queues it: unless the queue holds it in that value's bucket already, where
  // the entry stands for the lower value too (in a T1 flight a seventh of the lowerings, half the
  // entries that went stale). Inlined, as the queue's push, into both callers: out of line they
  // ran 1-3 % more instructions (BM_EsdfUpdateFaster/200/4).
  [[gnu::always_inline]] void shorten(BlockNode* node, int lin, float value, int dir) {
    uint8_t& state = node->state[lin];
    const bool queued =
        (state & kQueued) && queue_.bucketOf(value) == queue_.bucketOf(node->value[lin]);
    node->value[lin] = value;
    node->parent[lin] = static_cast<uint8_t>(dir);
    if (queued) return;
    state |= kQueued;
    queue_.push(value, node->id << 12 | static_cast<uint32_t>(lin));
  }

  // Offers a free or inside voxel a path of length `candidate` (not negative) through the
  // neighbour in direction `dir` (seen from the voxel). Only sites can have negative values, so
  // only paths from a site need clamping at 0 first.
  [[gnu::always_inline]] void offer(BlockNode* node, int lin, float candidate, int dir) {
    if (candidate < node->value[lin]) lower(node, lin, candidate, dir);
  }
  void lower(BlockNode* node, int lin, float candidate, int dir) {
    touch(node, lin);
    shorten(node, lin, candidate, dir);
  }

  // Dijkstra's offers from voxel lin, whose rows of neighbours lie each in one block, to those of
  // class cls: the same offers in the same order as one by one, but a row of three neighbours is
  // compared at once, since few offers succeed (under 4 %).
  void offerToRowNeighbours(BlockNode* node, int lin, float value, uint8_t cls) {
    const Floats4 from = {value, value, value, value};
    forEachRow(node, lin, [&](int row, BlockNode* n, int first) {
      Floats4 neighbours;
      std::memcpy(&neighbours, &n->value[first], sizeof(neighbours));
      const Floats4 candidates = from + row_edges_[row];
      const Ints4 shorter = candidates < neighbours;
      if ((shorter[0] | shorter[1] | shorter[2]) == 0) return;
      for (int lane = 0; lane < 3; ++lane) {
        if (shorter[lane] != 0 && (n->state[first + lane] & kClassMask) == cls) {
          lower(n, first + lane, candidates[lane], 25 - kRowDirections[row][lane]);
        }
      }
    });
  }

  // raiseChild for each child of voxel r, whose rows of neighbours lie each in one block, in
  // direction order as one by one, but a row of three neighbours' parents is compared at once
  // (four bytes in a word), since most voxels are no child of r.
  void raiseRowChildren(const VoxelRef& r, float source) {
    forEachRow(r.node, r.lin, [&](int row, BlockNode* n, int first) {
      uint32_t parents;
      std::memcpy(&parents, &n->parent[first], sizeof(parents));
      // Zero bytes where a neighbour's parent is r: the classic test for a zero byte in a word
      // can flag a byte above a real zero too, never miss one; the lanes are checked below.
      const uint32_t x = parents ^ kRowParents[row];
      if (((x - 0x01010101u) & ~x & 0x80808080u) == 0) return;
      for (int lane = 0; lane < 3; ++lane) {
        if ((x >> (8 * lane) & 0xFF) == 0) {
          raiseChild(r, kRowDirections[row][lane], n, first + lane, source);
        }
      }
    });
  }

  // Invalidates child n of raised voxel r, in direction d from r, or re-evaluates it from r's
  // value as a source (`source`).
  void raiseChild(const VoxelRef& r, int d, BlockNode* n, int l, float source) {
    float value = max_;
    if (r.raise & kReevaluate) {
      value = std::min(max_, std::max(0.0f, source + edge_[d]));
      // Not longer: the same (and so is the subtree), or shorter, because a changed site's offer
      // lowered r after its parent had queued it for raising. r is in the queue then, and the
      // lower wavefront shortens n and passes that on to all of n's neighbours; shortening n
      // here, outside the queue, would pass it on to n's children only.
      if (value <= n->value[l]) return;
    }
    touch(n, l);
    n->value[l] = value;
    // kQueued promises an entry in the bucket of the value: any entry n has lies below it now.
    n->state[l] &= ~kQueued;
    if (value == max_) n->parent[l] = kNoParent;
    raise_.push_back(
        {n, l, static_cast<uint8_t>(sideOf(n->state[l] & kClassMask) | (r.raise & kReevaluate))});
    tentative_.push_back({n, l, 0});
  }

  void propagate(bool incremental) {
    // Raise: every free or inside voxel whose shortest path ran through a changed voxel loses it
    // (invalidated: no parent, max_distance) or, below a site whose value grew, keeps it with the
    // longer length. Parents come before children, and an invalidated voxel drops its parent, so
    // none is visited twice.
    // A changed site also seeds the lower wavefront here, in the same pass over its neighbours.
    for (size_t i = 0; i < raise_.size(); ++i) {
      const VoxelRef r = raise_[i];
      if (!nearPropagating(r.node, r.lin)) continue;
      const float from_value = r.node->value[r.lin];
      if (isSite(r.node->state[r.lin] & kClassMask)) {
        forEachPropagatingNeighbour(r.node, r.lin, [&](int d, BlockNode* n, int l) {
          const uint8_t cls = n->state[l] & kClassMask;
          const float source = cls == kInside ? -from_value : from_value;
          if ((sideOf(cls) & r.raise) != 0 && n->parent[l] == 25 - d) {
            raiseChild(r, d, n, l, source);
          } else {
            offer(n, l, std::max(0.0f, source + edge_[d]), 25 - d);
          }
        });
      } else {
        // Only free and inside voxels have parents, and a child is on its parent's side.
        if (rowsInBlocks(r.lin)) {
          raiseRowChildren(r, from_value);
        } else {
          forEachNeighbour(r.node, r.lin, [&](int d, BlockNode* n, int l) {
            if (n->parent[l] == 25 - d) raiseChild(r, d, n, l, from_value);
          });
        }
      }
    }
    // Lower, seeded by the other new sites...
    for (const VoxelRef& s : seeds_) {
      if (!nearPropagating(s.node, s.lin)) continue;
      const float v = s.node->value[s.lin];
      forEachPropagatingNeighbour(s.node, s.lin, [&](int d, BlockNode* n, int l) {
        const float source = (n->state[l] & kClassMask) == kFree ? v : -v;
        offer(n, l, std::max(0.0f, source + edge_[d]), 25 - d);
      });
    }
    // ... and by the best neighbour of every invalidated, re-evaluated or reclassified voxel: once
    // the raise is done, every value is the length of a real path (from scratch, none is). From
    // scratch with occupied_everywhere too: every free or inside voxel, for the occupied sites of
    // blocks not allocated, which no seed stands for.
    if (incremental || options_.occupied_everywhere) {
      for (const VoxelRef& t : tentative_) {
        const uint8_t cls = t.node->state[t.lin] & kClassMask;
        float best = t.node->value[t.lin];
        int best_dir = -1;
        forEachNeighbour(t.node, t.lin, [&](int d, BlockNode* n, int l) {
          const uint8_t other = n->state[l] & kClassMask;
          float candidate;
          if (other == cls) {
            candidate = n->value[l] + edge_[d];
          } else if (isSite(other)) {
            candidate = std::max(0.0f, (cls == kFree ? n->value[l] : -n->value[l]) + edge_[d]);
          } else {
            return;
          }
          if (candidate < best) {
            best = candidate;
            best_dir = d;
          }
        });
        // Touched already: reclassified or raised.
        if (best_dir >= 0) shorten(t.node, t.lin, best, best_dir);
      }
    }
    // Dijkstra: a voxel leaves the queue with its final value and passes it on; its entries in
    // higher buckets, left from before it was lowered, are dropped.
    while (!queue_.empty()) {
      float key;
      const uint32_t voxel = queue_.pop(key);
      BlockNode* node = by_id_[voxel >> 12];
      const int lin = static_cast<int>(voxel & 4095);
      uint8_t& state = node->state[lin];
      const float value = node->value[lin];
      if (!(state & kQueued) || queue_.bucketOf(value) != queue_.bucketOf(key)) continue;
      state &= ~kQueued;
      const uint8_t cls = state & kClassMask;
      if (rowsInBlocks(lin)) {
        offerToRowNeighbours(node, lin, value, cls);
        continue;
      }
      forEachNeighbour(node, lin, [&](int d, BlockNode* n, int l) {
        if ((n->state[l] & kClassMask) == cls) offer(n, l, value + edge_[d], 25 - d);
      });
    }
  }

  static EsdfVoxel esdfVoxel(uint8_t cls, float value) {
    // Unknown and occupied voxels alike: unobserved space to every reader.
    if (!published(cls)) return {};
    return cls == kFree     ? EsdfVoxel{value, true, false}
           : cls == kInside ? EsdfVoxel{-value, true, false}
                            : EsdfVoxel{value, true, true};  // a surface site
  }

  // Writes the voxels whose published state changed to esdf, allocating and removing blocks, and
  // reports them, with the voxels that changed per block (whole_blocks: all, as after a rebuild
  // from empty). Erases the nodes left with no voxel known.
  EsdfUpdateResult finish(EsdfLayer& esdf, bool whole_blocks) {
    EsdfUpdateResult result;
    // One pass: a node's first changed voxel allocates its ESDF block (unless none of its voxels
    // is published any more), and every changed voxel is written out at once.
    for (const Touched& t : touched_) {
      BlockNode* node = t.node;
      uint8_t& state = node->state[t.lin];
      state &= ~kTouched;
      const float value = node->value[t.lin];
      // A published voxel shows its class and value (esdfVoxel tells them apart), the rest none.
      if ((state == t.cls && std::bit_cast<uint32_t>(value) == std::bit_cast<uint32_t>(t.value)) ||
          (!published(state) && !published(t.cls))) {
        continue;
      }
      const EsdfVoxel voxel = esdfVoxel(state, value);
      ++result.voxels_updated;
      if (node->changed_in_call != call_) {
        node->changed_in_call = call_;
        node->changed = BlockVoxels{};
        node->out = node->published > 0 ? &esdf.allocateBlock(node->index) : nullptr;
        changed_nodes_.push_back(node);
      }
      node->changed.insert(t.lin);
      if (node->out != nullptr) node->out->voxels[t.lin] = voxel;
    }
    const auto by_index = [](const BlockNode* a, const BlockNode* b) {
      return indexLess(a->index, b->index);
    };
    std::sort(changed_nodes_.begin(), changed_nodes_.end(), by_index);
    for (BlockNode* node : changed_nodes_) {
      if (node->published == 0) {
        // It had a block: one of its voxels was published before the call.
        esdf.removeBlock(node->index);
        result.removed_blocks.push_back(node->index);
      } else {
        result.changed_blocks.push_back(node->index);
        result.changed_voxels.push_back(whole_blocks ? BlockVoxels::all() : node->changed);
      }
    }
    std::sort(emptied_.begin(), emptied_.end(), by_index);
    emptied_.erase(std::unique(emptied_.begin(), emptied_.end()), emptied_.end());
    for (BlockNode* node : emptied_) {
      if (node->known == 0) erase(node);
    }
    blocks_ = esdf.numBlocks();
    return result;
  }

  EsdfIntegratorOptions options_;
  float max_ = 0;
  float min_weight_ = 0;
  // Set by recompute() from the voxel size.
  double voxel_size_ = 0;
  float band_ = 0;  // [m], compared with float TSDF distances
  float voxel_size_f_ = 0;
  double rc2_ = 0;
  double ro2_ = 0;
  // The rows through the clear sphere, the occupied sphere around position_, and around the
  // previous call's position (valid in sphereMoved).
  SphereRows clear_rows_, occupied_rows_, previous_rows_;
  std::array<float, 26> edge_{};
  std::array<Floats4, 9> row_edges_{};

  bool has_initial_ = false;
  Eigen::Vector3d initial_ = Eigen::Vector3d::Zero();
  bool built_ = false;  // nodes_ hold the state of the last call's result
  Eigen::Vector3d position_ = Eigen::Vector3d::Zero();
  std::unordered_map<BlockIndex, std::unique_ptr<BlockNode>, IndexHash> nodes_;
  const std::unique_ptr<BlockNode> none_ = std::make_unique<BlockNode>(BlockIndex::Zero(), nullptr);
  // Nodes by id (queue entries name them so), and the ids of erased nodes for reuse.
  std::vector<BlockNode*> by_id_;
  std::vector<uint32_t> free_ids_;

  // Per-call work lists, kept to reuse their memory.
  uint64_t call_ = 0;
  WorkList<Touched> touched_;
  WorkList<VoxelRef> raise_;
  WorkList<VoxelRef> seeds_;
  WorkList<VoxelRef> tentative_;
  BucketQueue queue_;
  std::vector<BlockNode*> changed_nodes_;
  std::vector<BlockNode*> emptied_;  // nodes whose last known voxel became unknown in the call
  size_t blocks_ = 0;                // the ESDF blocks after the last call
  struct Work {
    BlockIndex block;
    uint32_t set;  // in work_sets_
  };
  std::vector<Work> work_;
  std::vector<BlockVoxels> work_sets_;
  std::vector<BlockNode*> row_nodes_;
};

EsdfIntegrator::EsdfIntegrator(EsdfIntegratorOptions options)
    : impl_(std::make_unique<Impl>(options)) {}
EsdfIntegrator::~EsdfIntegrator() = default;
EsdfIntegrator::EsdfIntegrator(EsdfIntegrator&&) noexcept = default;
EsdfIntegrator& EsdfIntegrator::operator=(EsdfIntegrator&&) noexcept = default;

const EsdfIntegratorOptions& EsdfIntegrator::options() const {
  return impl_->options();
}

void EsdfIntegrator::setInitialPosition(const Eigen::Vector3d& p) {
  impl_->setInitialPosition(p);
}

EsdfUpdateResult EsdfIntegrator::update(const TsdfLayer& tsdf,
                                        const std::vector<BlockIndex>& changed_tsdf_blocks,
                                        const Eigen::Vector3d& current_position, EsdfLayer& esdf) {
  return impl_->update(tsdf, changed_tsdf_blocks, current_position, esdf);
}

EsdfUpdateResult EsdfIntegrator::update(const TsdfLayer& tsdf,
                                        const TsdfIntegrationResult& integration,
                                        const Eigen::Vector3d& current_position, EsdfLayer& esdf) {
  return impl_->update(tsdf, integration, current_position, esdf);
}

size_t EsdfIntegrator::memoryBytes() const {
  return impl_->memoryBytes();
}

EsdfUpdateResult EsdfIntegrator::recompute(const TsdfLayer& tsdf,
                                           const Eigen::Vector3d& current_position,
                                           EsdfLayer& esdf) {
  return impl_->recompute(tsdf, current_position, esdf);
}

}  // namespace thicket::mapper

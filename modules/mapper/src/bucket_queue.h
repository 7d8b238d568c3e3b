// The ESDF's priority queue (esdf_integrator.cc): buckets of a fixed width of keys (Dial's
// algorithm). Internal to the mapper; tested on its own.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace thicket::mapper {

// A min-queue of float keys in [0, max_key] with 32-bit payloads, kept in buckets of `width`:
// pop() gives an entry of the lowest non-empty bucket, the last pushed there first, not
// necessarily the smallest key. That is exact for Dijkstra's algorithm when every edge is longer
// than the width: no entry can lower another of the same bucket, so any of them is final when
// popped. Pushing below the bucket of the last pop is allowed (the queue goes back to it).
// Deterministic: the same pushes and pops give the same order.
class BucketQueue {
 public:
  // Empties the queue and sets its buckets: width and max_key positive and finite. A bucket that
  // holds more than 1 MiB and more than four times the most entries the queue held since the last
  // reset() is freed.
  void reset(float width, float max_key) {
    if (!(width > 0 && max_key > 0 && std::isfinite(width) && std::isfinite(max_key))) {
      throw std::invalid_argument("BucketQueue: width and max_key must be positive and finite");
    }
    inverse_width_ = 1.0f / width;
    max_key_ = max_key;
    for (std::vector<uint64_t>& b : buckets_) {
      if (b.capacity() * sizeof(uint64_t) > (size_t{1} << 20) && peak_ * 4 < b.capacity()) {
        std::vector<uint64_t>().swap(b);
      }
      b.clear();
    }
    buckets_.resize(index(max_key) + 1);
    cursor_ = 0;
    size_ = 0;
    peak_ = 0;
  }

  bool empty() const { return size_ == 0; }

  // The buckets' capacity [bytes].
  size_t memoryBytes() const {
    size_t bytes = buckets_.capacity() * sizeof(std::vector<uint64_t>);
    for (const std::vector<uint64_t>& b : buckets_) bytes += b.capacity() * sizeof(uint64_t);
    return bytes;
  }

  // key in [0, max_key] (checked: std::out_of_range otherwise). Inlined: the ESDF's wavefront
  // pushes millions of entries a second, and GCC leaves it out of line there otherwise.
  [[gnu::always_inline]] void push(float key, uint32_t payload) {
    if (!(key >= 0 && key <= max_key_)) {
      throw std::out_of_range("BucketQueue: a key outside [0, max_key]");
    }
    const size_t b = index(key);
    cursor_ = std::min(cursor_, b);
    buckets_[b].push_back(uint64_t{std::bit_cast<uint32_t>(key)} << 32 | payload);
    peak_ = std::max(peak_, ++size_);
  }

  // The bucket of a key in [0, max_key]: keys in one bucket are popped in no particular order.
  size_t bucketOf(float key) const { return index(key); }

  // The payload of an entry of the lowest non-empty bucket, and its key. Not on an empty queue.
  uint32_t pop(float& key) {
    while (buckets_[cursor_].empty()) ++cursor_;
    std::vector<uint64_t>& bucket = buckets_[cursor_];
    const uint64_t e = bucket.back();
    bucket.pop_back();
    --size_;
    key = std::bit_cast<float>(static_cast<uint32_t>(e >> 32));
    return static_cast<uint32_t>(e);
  }

 private:
  size_t index(float key) const { return static_cast<size_t>(key * inverse_width_); }

  std::vector<std::vector<uint64_t>> buckets_;
  float inverse_width_ = 1;
  float max_key_ = 0;
  size_t cursor_ = 0;  // no bucket below holds entries
  size_t size_ = 0;
  size_t peak_ = 0;  // the most entries held since reset()
};

}  // namespace thicket::mapper

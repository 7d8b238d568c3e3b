// The ESDF's priority queue (esdf_integrator.cc): a radix heap of 32-bit keys with 32-bit
// payloads, exact for Dijkstra's algorithm. Internal to the mapper; tested on its own.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace thicket::mapper {

// A monotone min-queue of 32-bit keys with 32-bit payloads (a radix heap): exact, for Dijkstra's
// algorithm, where no key pushed is below the last one popped. A key waits in the bucket of the
// highest bit in which it differs from the last key popped (bucket 0: equal to it); when bucket 0
// runs empty, the lowest non-empty bucket is spread over the lower ones, around its minimum.
// Equal keys leave last in, first out: deterministic.
class MonotoneQueue {
 public:
  bool empty() const { return size_ == 0; }

  // The buckets' capacity [bytes].
  size_t memoryBytes() const {
    size_t bytes = 0;
    for (const std::vector<uint64_t>& b : buckets_) bytes += b.capacity() * sizeof(uint64_t);
    return bytes;
  }

  // Empties the queue; a bucket that holds more than 1 MiB and more than four times the most
  // entries the queue held since the last clear() is freed.
  void clear() {
    for (std::vector<uint64_t>& b : buckets_) {
      if (b.capacity() * sizeof(uint64_t) > (size_t{1} << 20) && peak_ * 4 < b.capacity()) {
        std::vector<uint64_t>().swap(b);
      }
      b.clear();
    }
    nonempty_ = 0;
    size_ = 0;
    peak_ = 0;
    last_ = 0;
  }

  void push(uint32_t key, uint32_t payload) {
    insert(uint64_t{key} << 32 | payload);
    peak_ = std::max(peak_, ++size_);
  }

  // The payload of an entry with the smallest key, and that key.
  uint32_t pop(uint32_t& key) {
    if (buckets_[0].empty()) {
      const int i = std::countr_zero(nonempty_ & ~uint64_t{1});
      std::vector<uint64_t>& from = buckets_[i];
      nonempty_ &= ~(uint64_t{1} << i);
      last_ = min_[i];
      for (const uint64_t e : from) insert(e);
      from.clear();
    }
    const uint64_t e = buckets_[0].back();
    buckets_[0].pop_back();
    if (buckets_[0].empty()) nonempty_ &= ~uint64_t{1};
    --size_;
    key = static_cast<uint32_t>(e >> 32);
    return static_cast<uint32_t>(e);
  }

 private:
  int bucket(uint32_t key) const { return 32 - std::countl_zero(key ^ last_); }

  void insert(uint64_t e) {
    const uint32_t key = static_cast<uint32_t>(e >> 32);
    const int b = bucket(key);
    const uint64_t bit = uint64_t{1} << b;
    min_[b] = (nonempty_ & bit) ? std::min(min_[b], key) : key;
    nonempty_ |= bit;
    buckets_[b].push_back(e);
  }

  std::array<std::vector<uint64_t>, 33> buckets_;
  std::array<uint32_t, 33> min_{};  // the smallest key in each non-empty bucket
  uint64_t nonempty_ = 0;           // bit b: bucket b holds entries
  uint32_t last_ = 0;
  size_t size_ = 0;
  size_t peak_ = 0;  // the most entries held since clear()
};

}  // namespace thicket::mapper

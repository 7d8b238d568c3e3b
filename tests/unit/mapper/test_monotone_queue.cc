// The ESDF's radix heap against a reference: every pop gives the smallest key pushed and not yet
// popped, under the monotone rule Dijkstra's algorithm keeps (no key below the last one popped),
// and equal keys leave last in, first out.
#include "monotone_queue.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace thicket::mapper {
namespace {

TEST(MonotoneQueue, PopsInKeyOrderUnderTheMonotoneRule) {
  std::mt19937 random(3);
  MonotoneQueue queue;
  std::multimap<uint32_t, uint32_t> reference;  // key -> payload
  uint32_t last = 0;
  uint32_t payload = 0;
  for (int round = 0; round < 20000; ++round) {
    if (reference.empty() || random() % 3 != 0) {
      // Keys near the last one popped and far from it, up to the top of the 32-bit range.
      const uint32_t room = 0xFFFFFFFFu - last;
      const uint32_t span = random() % 2 ? std::min(1000u, room) : room;
      const uint32_t key = last + (span == 0 ? 0 : random() % span);
      queue.push(key, payload);
      reference.emplace(key, payload++);
    } else {
      uint32_t key = 0;
      const uint32_t got = queue.pop(key);
      ASSERT_EQ(key, reference.begin()->first) << round;
      // The popped payload is one pushed with that key.
      const auto [lo, hi] = reference.equal_range(key);
      auto it = lo;
      while (it != hi && it->second != got) ++it;
      ASSERT_NE(it, hi) << round;
      reference.erase(it);
      last = key;
    }
    ASSERT_EQ(queue.empty(), reference.empty());
  }
}

TEST(MonotoneQueue, EqualKeysLeaveLastInFirstOutAndClearEmptiesIt) {
  MonotoneQueue queue;
  for (uint32_t p = 0; p < 5; ++p) queue.push(7, p);
  uint32_t key = 0;
  for (uint32_t p = 5; p-- > 0;) {
    EXPECT_EQ(queue.pop(key), p);
    EXPECT_EQ(key, 7u);
  }
  EXPECT_TRUE(queue.empty());
  queue.push(9, 1);
  queue.push(0xFFFFFFFF, 2);
  queue.clear();
  EXPECT_TRUE(queue.empty());
  queue.push(3, 4);  // after clear the keys start over from 0
  EXPECT_EQ(queue.pop(key), 4u);
  EXPECT_EQ(key, 3u);
}

}  // namespace
}  // namespace thicket::mapper

// The ESDF's bucket queue: pops come from the lowest non-empty bucket (bucketOf's), last in first
// out within it, and Dijkstra's algorithm on it gives the distances a binary heap gives when every
// edge is longer than the bucket width.
#include "bucket_queue.h"

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <queue>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace thicket::mapper {
namespace {

TEST(BucketQueue, PopsFromTheLowestBucketUnderTheMonotoneRule) {
  constexpr float kWidth = 0.05f;
  constexpr float kMax = 2.0f;
  std::mt19937 random(3);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  BucketQueue queue;
  queue.reset(kWidth, kMax);
  std::multimap<float, uint32_t> reference;  // key -> payload
  float last = 0;
  uint32_t payload = 0;
  const auto bucket = [&](float key) { return static_cast<int>(key * (1.0f / kWidth)); };
  for (int round = 0; round < 20000; ++round) {
    if (reference.empty() || random() % 3 != 0) {
      // At or above the last key popped (Dijkstra's rule), near it or anywhere up to kMax.
      const float room = kMax - last;
      const float key = last + (random() % 2 ? std::min(room, 0.1f) : room) * uniform(random);
      queue.push(key, payload);
      reference.emplace(key, payload++);
      // bucketOf, which the ESDF compares keys with, names the bucket pops go by.
      ASSERT_EQ(queue.bucketOf(key), static_cast<size_t>(bucket(key)));
    } else {
      float key = -1;
      const uint32_t got = queue.pop(key);
      ASSERT_EQ(bucket(key), bucket(reference.begin()->first)) << round;
      const auto [lo, hi] = reference.equal_range(key);
      auto it = lo;
      while (it != hi && it->second != got) ++it;
      ASSERT_NE(it, hi) << "round " << round << ": a payload not pushed with key " << key;
      reference.erase(it);
      last = key;
    }
    ASSERT_EQ(queue.empty(), reference.empty());
  }
}

TEST(BucketQueue, LastInFirstOutWithinABucketAndBackBelowTheLastPop) {
  BucketQueue queue;
  queue.reset(0.5f, 10.0f);
  for (uint32_t p = 0; p < 4; ++p) queue.push(1.0f + 0.1f * static_cast<float>(p), p);
  queue.push(7.0f, 9);
  float key = 0;
  for (uint32_t p = 4; p-- > 0;) EXPECT_EQ(queue.pop(key), p);
  EXPECT_FLOAT_EQ(key, 1.0f);
  queue.push(0.2f, 5);  // below the bucket of the last pop
  EXPECT_EQ(queue.pop(key), 5u);
  EXPECT_EQ(queue.pop(key), 9u);
  EXPECT_EQ(key, 7.0f);
  EXPECT_TRUE(queue.empty());
  queue.push(10.0f, 1);  // max_key itself is in range
  queue.reset(0.5f, 10.0f);
  EXPECT_TRUE(queue.empty());

  EXPECT_THROW(queue.push(10.5f, 0), std::out_of_range);
  EXPECT_THROW(queue.push(-0.1f, 0), std::out_of_range);
  EXPECT_THROW(queue.push(std::numeric_limits<float>::quiet_NaN(), 0), std::out_of_range);
  EXPECT_THROW(queue.reset(0.0f, 1.0f), std::invalid_argument);
  EXPECT_THROW(queue.reset(0.1f, std::numeric_limits<float>::infinity()), std::invalid_argument);
}

// Shortest paths on random grids with float edges of 1 to 1.8 (the ESDF's 1, sqrt 2, sqrt 3 voxel
// sizes and more), summed in float as the ESDF does, from a few sources: Dijkstra with buckets of
// half the shortest edge gives exactly what it gives with a binary heap.
TEST(BucketQueue, DijkstraWithBucketsNarrowerThanEveryEdgeIsExact) {
  constexpr int kSide = 40;
  constexpr int kNodes = kSide * kSide;
  constexpr float kMax = 80.0f;
  std::mt19937 random(11);
  for (int graph = 0; graph < 5; ++graph) {
    std::vector<std::vector<std::pair<int, float>>> edges(kNodes);
    std::uniform_real_distribution<float> weight(1.0f, 1.8f);
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        const int i = x + kSide * y;
        for (const auto& [dx, dy] : {std::pair{1, 0}, {0, 1}, {1, 1}, {1, -1}}) {
          if (x + dx >= kSide || y + dy < 0 || y + dy >= kSide) continue;
          const int j = (x + dx) + kSide * (y + dy);
          const float w = weight(random);
          edges[i].push_back({j, w});
          edges[j].push_back({i, w});
        }
      }
    }
    std::vector<float> sources(kNodes, kMax);
    for (int s = 0; s < 4; ++s) sources[random() % kNodes] = static_cast<float>(random() % 3);

    std::vector<float> expected = sources;
    using Entry = std::pair<float, int>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
    for (int i = 0; i < kNodes; ++i) {
      if (sources[i] < kMax) heap.push({sources[i], i});
    }
    while (!heap.empty()) {
      const auto [d, i] = heap.top();
      heap.pop();
      if (d != expected[i]) continue;
      for (const auto& [j, w] : edges[i]) {
        if (d + w < expected[j]) heap.push({expected[j] = d + w, j});
      }
    }

    // Dijkstra on buckets of `width`; the number of pops that passed a distance on.
    const auto run = [&](float width, std::vector<float>& got) {
      got = sources;
      BucketQueue queue;
      queue.reset(width, kMax);
      int pops = 0;
      for (int i = 0; i < kNodes; ++i) {
        if (sources[i] < kMax) queue.push(sources[i], static_cast<uint32_t>(i));
      }
      while (!queue.empty()) {
        float d = 0;
        const int i = static_cast<int>(queue.pop(d));
        if (d != got[i]) continue;
        ++pops;
        for (const auto& [j, w] : edges[i]) {
          if (d + w < got[j]) queue.push(got[j] = d + w, static_cast<uint32_t>(j));
        }
      }
      return pops;
    };
    std::vector<float> got;
    // Each node is final when it leaves the queue: it passes its distance on once.
    EXPECT_EQ(run(0.5f, got), kNodes) << "graph " << graph;
    ASSERT_EQ(got, expected) << "graph " << graph;
    // Buckets wider than the edges still converge, but pass distances on that were not final.
    EXPECT_GT(run(4.0f, got), kNodes) << "graph " << graph;
    ASSERT_EQ(got, expected) << "graph " << graph;
  }
}

}  // namespace
}  // namespace thicket::mapper

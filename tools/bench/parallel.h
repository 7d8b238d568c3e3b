// The benchmark's one worker pool: independent tasks (trials, maps, flights) on a few threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <thread>
#include <vector>

namespace thicket::bench {

/// Runs task(i) once for every i in [0, count) on min(jobs, count) threads, which take the
/// indices in increasing order as they become free; returns when every task has returned. The
/// tasks must not throw, and whatever they share they must guard themselves.
inline void parallelFor(size_t count, int jobs, const std::function<void(size_t)>& task) {
  std::atomic<size_t> next{0};
  const auto worker = [&] {
    for (size_t i = next++; i < count; i = next++) task(i);
  };
  const size_t threads_wanted = std::min(static_cast<size_t>(std::max(jobs, 1)), count);
  std::vector<std::thread> threads;
  threads.reserve(threads_wanted);
  for (size_t j = 0; j < threads_wanted; ++j) threads.emplace_back(worker);
  for (std::thread& thread : threads) thread.join();
}

}  // namespace thicket::bench

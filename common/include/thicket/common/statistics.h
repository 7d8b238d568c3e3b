// Summaries of measured durations (timing lines, MODULE_TIMING tables, benchmarks).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace thicket {

/// The q-quantile (q clamped to [0, 1]) of `values`, interpolated linearly between the two
/// closest ranks (rank q·(n-1) of the sorted values, as numpy's default): the minimum at 0, the
/// maximum at 1. 0 when empty.
inline double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const double rank = std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  const auto below = static_cast<size_t>(std::floor(rank));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(below),
                   values.end());
  const double low = values[below];
  if (below + 1 == values.size()) return low;
  // The next rank is the smallest value after `below` (nth_element put the larger ones there).
  const double high =
      *std::min_element(values.begin() + static_cast<std::ptrdiff_t>(below) + 1, values.end());
  return low + (rank - static_cast<double>(below)) * (high - low);
}

/// The middle value; for an even count, the mean of the two middle ones.
inline double median(std::vector<double> values) {
  return quantile(std::move(values), 0.5);
}

}  // namespace thicket

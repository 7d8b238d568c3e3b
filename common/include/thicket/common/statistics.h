// Summaries of measured durations (timing lines, MODULE_TIMING tables, benchmarks).
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace thicket {

/// The q-quantile (0 <= q <= 1) of `values` by the nearest lower rank; 0 when empty.
inline double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k =
      static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1) + 0.5);
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

inline double median(std::vector<double> values) {
  return quantile(std::move(values), 0.5);
}

}  // namespace thicket

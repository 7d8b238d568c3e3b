// Numbers read from text that must be nothing else: a command-line value, a CSV cell.
#pragma once

#include <charconv>
#include <cmath>
#include <optional>
#include <string>

namespace thicket {

/// `text`, all of it, as a finite number; nothing when it is not one (also for an empty text,
/// surrounding spaces, a trailing unit, "nan" or "inf").
inline std::optional<double> finiteNumber(const std::string& text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

/// `text`, all of it, as a decimal integer of type Int; nothing when it is not one or out of
/// range.
template <class Int>
std::optional<Int> integerNumber(const std::string& text) {
  Int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
    return std::nullopt;
  }
  return value;
}

}  // namespace thicket

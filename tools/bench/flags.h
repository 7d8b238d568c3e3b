// The command-line flags of thicket-bench's subcommands: "--flag value" or "--flag=value", each
// flag applied by a setter that validates its value and says what is wrong with it.
#pragma once

#include <charconv>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::bench {

/// Why a flag's value was refused, or nothing.
using FlagError = std::optional<std::string>;

template <class Options>
using FlagSetter = std::function<FlagError(Options&, const std::string&)>;

/// `text`, all of it, as a finite number; nothing when it is not one (also for an empty text,
/// surrounding spaces or a trailing unit). Flags and the benchmark's CSV cells read numbers
/// through these two.
inline std::optional<double> finiteNumber(const std::string& text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

/// `text`, all of it, as an integer of type Int; nothing when it is not one or out of range.
template <class Int>
std::optional<Int> integerNumber(const std::string& text) {
  Int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
    return std::nullopt;
  }
  return value;
}

/// A finite number >= 0.
inline FlagError parseNumber(double& value, const std::string& flag, const std::string& text) {
  const std::optional<double> parsed = finiteNumber(text);
  if (parsed && *parsed >= 0) {
    value = *parsed;
    return {};
  }
  return flag + " '" + text + "' is not a non-negative number";
}

/// A finite number of either sign, for flags whose range is checked with the other options.
inline FlagError parseAnyNumber(double& value, const std::string& flag, const std::string& text) {
  const std::optional<double> parsed = finiteNumber(text);
  if (parsed) {
    value = *parsed;
    return {};
  }
  return flag + " '" + text + "' is not a number";
}

template <class Int>
FlagError parseInteger(Int& value, const std::string& flag, const std::string& text, Int min) {
  const std::optional<Int> parsed = integerNumber<Int>(text);
  if (parsed && *parsed >= min) {
    value = *parsed;
    return {};
  }
  return flag + " must be an integer >= " + std::to_string(min) + ", not '" + text + "'";
}

/// Applies `args` to `options` through `setters`. "--help" or "-h" sets options.help and stops.
/// Arguments that are not flags go to `positional`, or are refused when it is null. Returns the
/// flags given, or the message for the user.
template <class Options>
Expected<std::set<std::string>> applyFlags(
    const std::vector<std::string>& args, const std::map<std::string, FlagSetter<Options>>& setters,
    Options& options, std::vector<std::string>* positional = nullptr) {
  std::set<std::string> given;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--help" || args[i] == "-h") {
      options.help = true;
      return given;
    }
    if (args[i].rfind("--", 0) != 0) {
      if (positional == nullptr) return unexpected("unexpected argument '" + args[i] + "'");
      positional->push_back(args[i]);
      continue;
    }
    const size_t equals = args[i].find('=');
    const std::string flag = args[i].substr(0, equals);
    const auto setter = setters.find(flag);
    if (setter == setters.end()) return unexpected("unknown option " + flag);
    std::string value;
    if (equals != std::string::npos) {
      value = args[i].substr(equals + 1);
    } else if (i + 1 < args.size()) {
      value = args[++i];
    }
    if (value.empty()) return unexpected(flag + " needs a value");
    if (FlagError error = setter->second(options, value)) return unexpected(*error);
    given.insert(flag);
  }
  return given;
}

}  // namespace thicket::bench

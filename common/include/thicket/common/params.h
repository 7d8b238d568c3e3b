// Typed, validated module parameters from YAML. Every options struct keeps its defaults in the
// struct and lists its fields once, in declare(); the same declaration loads a YAML file and
// documents the parameters, so the file format and the documentation cannot drift apart.
//
//   struct TsdfOptions {
//     int truncation_voxels = 4;
//     void declare(thicket::Params& p) {
//       p("truncation_voxels", truncation_voxels, "[voxels]", thicket::Range::atLeast(1));
//     }
//   };
//   TsdfOptions o = thicket::loadParams<TsdfOptions>("config/params/tsdf.yaml");
//
// Loading is strict: unknown keys, wrong types, non-finite numbers and out-of-range values are
// errors, so a typo in a config file fails loudly instead of silently leaving a default in place.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace thicket {

/// A parameter file that cannot be read, parsed or validated. The message reads
/// "source:line:col: key 'a.b': what is wrong" (line/col when known, key when there is one).
/// line:col point at the offending value, or at its key when the value is empty or unknown.
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The interval a numeric parameter must lie in; applies to every element of vectors.
/// Default-constructed: unbounded. Bounds are inclusive except for positive().
struct Range {
  std::optional<double> lo;
  std::optional<double> hi;
  bool lo_exclusive = false;

  /// > 0.
  static Range positive() { return {0.0, std::nullopt, true}; }
  /// >= lo.
  static Range atLeast(double lo) { return {lo, std::nullopt, false}; }
  /// <= hi.
  static Range atMost(double hi) { return {std::nullopt, hi, false}; }
  /// lo <= value <= hi; throws std::logic_error if lo > hi.
  static Range between(double lo, double hi) {
    if (lo > hi) throw std::logic_error("Range::between: lower bound above upper bound");
    return {lo, hi, false};
  }

  bool contains(double value) const;
  /// Human-readable bound, e.g. "> 0", ">= 1", "in [0.01, 1]"; empty when unbounded.
  std::string describe() const;
};

class Params;

namespace detail {
template <class T>
inline constexpr bool kIsRangedParam =
    std::is_same_v<T, int> || std::is_same_v<T, std::int64_t> || std::is_same_v<T, double> ||
    std::is_same_v<T, std::vector<double>> || std::is_same_v<T, Eigen::Vector3d>;
template <class T>
inline constexpr bool kIsParam =
    kIsRangedParam<T> || std::is_same_v<T, bool> || std::is_same_v<T, std::string>;

// Type-erased "options.declare(params)" so the loading machinery lives in params.cc.
using DeclareFn = void (*)(void* options, Params& params);
void loadInto(const std::string& yaml, const std::string& source, void* options, DeclareFn declare);
std::string describe(void* options, DeclareFn declare);
std::string readFile(const std::string& path);
}  // namespace detail

/// What an options struct's declare() talks to: each call names one field, its documentation and
/// its constraints. Depending on how the Params was created, a call either loads the field from
/// YAML (after validating it) or writes the field's default and documentation out as YAML.
/// Keys are [A-Za-z0-9_]+. Declaring the same key twice in one declare() throws std::logic_error,
/// as does a default that its own declaration would reject (so describeParams output loads back).
class Params {
 public:
  Params(const Params&) = delete;
  Params& operator=(const Params&) = delete;
  ~Params();

  /// A bool, int, int64_t, double, std::string, std::vector<double> or Eigen::Vector3d field.
  template <class T>
  void operator()(const std::string& key, T& value, const std::string& doc) {
    static_assert(detail::kIsParam<T>,
                  "parameter type must be bool, int, int64_t, double, std::string, "
                  "std::vector<double> or Eigen::Vector3d");
    if constexpr (detail::kIsRangedParam<T>) {
      field(key, value, doc, Range{});
    } else {
      field(key, value, doc);
    }
  }

  /// A numeric field (int, int64_t, double, std::vector<double>, Eigen::Vector3d) that must lie
  /// in `range`; for vectors, every element must.
  template <class T>
  void operator()(const std::string& key, T& value, const std::string& doc, const Range& range) {
    static_assert(detail::kIsRangedParam<T>,
                  "a Range applies only to int, int64_t, double, std::vector<double> and "
                  "Eigen::Vector3d");
    field(key, value, doc, range);
  }

  /// A string that must be one of `allowed`.
  void choice(const std::string& key, std::string& value, const std::vector<std::string>& allowed,
              const std::string& doc);

  /// A nested options struct, written as a YAML map under `key`; its fields get the dotted prefix
  /// "key." in messages. A missing or empty map keeps the group's defaults.
  template <class Group>
  void group(const std::string& key, Group& value, const std::string& doc) {
    enterGroup(key, doc);
    value.declare(*this);
    leaveGroup();
  }

 private:
  struct Impl;
  explicit Params(std::unique_ptr<Impl> impl);

  void field(const std::string& key, bool& value, const std::string& doc);
  void field(const std::string& key, std::string& value, const std::string& doc);
  void field(const std::string& key, int& value, const std::string& doc, const Range& range);
  void field(const std::string& key, std::int64_t& value, const std::string& doc,
             const Range& range);
  void field(const std::string& key, double& value, const std::string& doc, const Range& range);
  void field(const std::string& key, std::vector<double>& value, const std::string& doc,
             const Range& range);
  void field(const std::string& key, Eigen::Vector3d& value, const std::string& doc,
             const Range& range);
  void enterGroup(const std::string& key, const std::string& doc);
  void leaveGroup();

  friend void detail::loadInto(const std::string&, const std::string&, void*, detail::DeclareFn);
  friend std::string detail::describe(void*, detail::DeclareFn);

  std::unique_ptr<Impl> impl_;
};

/// Loads the keys present in the YAML text over `options`; the others keep their values. `source`
/// names the text in error messages. Throws ParamError, and then `options` is unchanged.
template <class Options>
void overrideParams(Options& options, const std::string& yaml, const std::string& source) {
  Options copy = options;
  detail::loadInto(yaml, source, &copy,
                   [](void* o, Params& p) { static_cast<Options*>(o)->declare(p); });
  options = std::move(copy);
}

/// Options parsed from YAML text; `source` names the text in error messages. Keys absent from the
/// text keep their defaults; an empty document gives all defaults. Throws ParamError. The result
/// is either fully loaded or not returned at all.
template <class Options>
Options loadParamsFromString(const std::string& yaml, const std::string& source) {
  Options options;
  overrideParams(options, yaml, source);
  return options;
}

/// Options loaded from the YAML file at `path`; see loadParamsFromString. Throws ParamError.
template <class Options>
Options loadParams(const std::string& path) {
  return loadParamsFromString<Options>(detail::readFile(path), path);
}

/// Every parameter of `options` with its value, as YAML with the documentation in comments.
/// Loading this text back gives `options`; two options structs run alike exactly when their texts
/// are equal.
template <class Options>
std::string describeParams(const Options& options) {
  Options copy = options;
  return detail::describe(&copy, [](void* o, Params& p) { static_cast<Options*>(o)->declare(p); });
}

/// Why `options`, built or changed in code, break a rule of their own declaration (a range, a
/// choice, a finite number): the rules loading from YAML enforces, checked in the one place they
/// are written. Empty when every field keeps them. For constructors, as Ceres's Options::IsValid.
template <class Options>
std::string paramsError(const Options& options) {
  try {
    (void)describeParams(options);
  } catch (const std::logic_error& e) {
    return e.what();
  }
  return {};
}

/// Every parameter of Options with its default (what `thicket-<module> params` prints).
template <class Options>
std::string describeParams() {
  return describeParams(Options{});
}

}  // namespace thicket

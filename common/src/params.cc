#include "thicket/common/params.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <string_view>

#include <yaml-cpp/yaml.h>

namespace thicket {
namespace {

// What an error message points at: the source, the dotted key, and the key's position, used when
// the offending value has no position of its own (an empty value's mark is on the next line).
struct Where {
  std::string source;
  std::string key;
  YAML::Mark mark;
};

std::string location(const std::string& source, const YAML::Mark& mark) {
  if (mark.is_null()) return source;
  return source + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

[[noreturn]] void fail(const Where& where, const YAML::Node& at, const std::string& what) {
  const bool own_mark = at.IsDefined() && !at.IsNull() && !at.Mark().is_null();
  std::string message;  // no source: a default being checked, which has no location
  if (!where.source.empty()) {
    message = location(where.source, own_mark ? at.Mark() : where.mark) + ": ";
  }
  if (!where.key.empty()) message += "key '" + where.key + "': ";
  throw ParamError(message + what);
}

// Shortest text that parses back to exactly `value`.
std::string formatNumber(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

// As formatNumber, but "5.0" rather than "5" so a reader sees the field is not an integer.
std::string formatDouble(double value) {
  std::string text = formatNumber(value);
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

// The "got ..." half of a type error.
std::string describeNode(const YAML::Node& node) {
  if (node.IsScalar()) {
    return (node.Tag() == "!" ? "the quoted string '" : "'") + node.Scalar() + "'";
  }
  if (node.IsSequence()) return "a sequence";
  if (node.IsMap()) return "a map";
  return "no value";
}

// Numbers and bools must be plain scalars: quoting makes a YAML value a string.
const std::string& plainScalar(const Where& where, const YAML::Node& node, const char* expected) {
  if (!node.IsScalar() || node.Tag() == "!") {
    fail(where, node, std::string("expected ") + expected + ", got " + describeNode(node));
  }
  return node.Scalar();
}

bool parseBool(const Where& where, const YAML::Node& node) {
  const std::string& text = plainScalar(where, node, "true or false");
  // yaml-cpp would also take y/n/on/off; those are too easy to write by accident.
  for (const char* t : {"true", "True", "TRUE", "yes", "Yes", "YES"}) {
    if (text == t) return true;
  }
  for (const char* f : {"false", "False", "FALSE", "no", "No", "NO"}) {
    if (text == f) return false;
  }
  fail(where, node, "expected true or false, got '" + text + "'");
}

// `text` without a leading '+', which YAML allows and std::from_chars does not.
std::string_view withoutPlus(const std::string& text) {
  std::string_view view = text;
  if (view.size() > 1 && view[0] == '+' && view[1] != '-') view.remove_prefix(1);
  return view;
}

void checkRange(const Where& where, const YAML::Node& node, double value, const std::string& text,
                const Range& range) {
  if (!range.contains(value)) {
    fail(where, node, text + " is out of range: must be " + range.describe());
  }
}

template <class Int>
Int parseInt(const Where& where, const YAML::Node& node, const Range& range) {
  const std::string& text = plainScalar(where, node, "an integer");
  const std::string_view digits = withoutPlus(text);
  Int value{};
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (digits.empty() || end != digits.data() + digits.size()) {
    fail(where, node, "expected an integer, got '" + text + "'");
  }
  if (error == std::errc::result_out_of_range) {
    fail(where, node,
         text + " is out of range for a " + std::to_string(std::numeric_limits<Int>::digits + 1) +
             "-bit integer");
  }
  checkRange(where, node, static_cast<double>(value), std::to_string(value), range);
  return value;
}

double parseDouble(const Where& where, const YAML::Node& node, const Range& range) {
  const std::string& text = plainScalar(where, node, "a number");
  const std::string_view number = withoutPlus(text);
  double value = 0.0;
  const auto [end, error] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (number.empty() || end != number.data() + number.size()) {
    const std::string_view unsigned_text = number.substr(number.starts_with('-') ? 1 : 0);
    for (const char* yaml_non_finite : {".inf", ".Inf", ".INF", ".nan", ".NaN", ".NAN"}) {
      if (unsigned_text == yaml_non_finite) fail(where, node, "non-finite value '" + text + "'");
    }
    fail(where, node, "expected a number, got '" + text + "'");
  }
  if (error == std::errc::result_out_of_range) {
    fail(where, node, text + " is out of the range of a double");
  }
  if (!std::isfinite(value)) fail(where, node, "non-finite value '" + text + "'");
  checkRange(where, node, value, formatNumber(value), range);
  return value;
}

std::string parseString(const Where& where, const YAML::Node& node) {
  if (!node.IsScalar()) {
    fail(where, node,
         "expected a string, got " + describeNode(node) +
             (node.IsNull() ? " (write \"\" for an empty string)" : ""));
  }
  return node.Scalar();
}

std::string formatDoubles(const double* values, std::size_t size) {
  std::string text = "[";
  for (std::size_t i = 0; i < size; ++i) text += (i ? ", " : "") + formatDouble(values[i]);
  return text + "]";
}

std::string formatString(const std::string& value) {
  // yaml-cpp quotes what would not parse back as this string; also quote what YAML would read as
  // a bool or a number, so readers and other tools see a string.
  const YAML::Node plain(value);
  bool as_bool = false;
  double as_number = 0.0;
  YAML::Emitter emitter;
  if (YAML::convert<bool>::decode(plain, as_bool) ||
      YAML::convert<double>::decode(plain, as_number)) {
    emitter << YAML::DoubleQuoted;
  }
  emitter << value;
  return emitter.c_str();
}

std::vector<double> parseDoubles(const Where& where, const YAML::Node& node, const Range& range) {
  if (!node.IsSequence()) {
    fail(where, node, "expected a sequence of numbers, got " + describeNode(node));
  }
  std::vector<double> values;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const Where element{where.source, where.key + "[" + std::to_string(i) + "]", where.mark};
    values.push_back(parseDouble(element, node[i], range));
  }
  return values;
}

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitution = diagonal + (a[i - 1] == b[j - 1] ? 0 : 1);
      diagonal = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, substitution});
    }
  }
  return row[b.size()];
}

std::string join(const std::vector<std::string>& items) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : ", ") + item;
  return text;
}

}  // namespace

// One instance per load or describe; a stack of map levels, one per group being declared.
struct Params::Impl {
  struct Entry {
    YAML::Node key;
    YAML::Node value;
  };
  struct Level {
    std::string prefix;                  // "" at the top, "tsdf." inside group "tsdf"
    std::map<std::string, Entry> given;  // keys present in the YAML at this level
    std::set<std::string> declared;      // keys declare() has named so far at this level
  };

  std::string source;
  bool describing = false;
  std::vector<Level> levels;
  std::string text;  // describeParams output

  Where where(const std::string& key, const YAML::Mark& mark) const {
    return {source, levels.back().prefix + key, mark};
  }

  void push(std::string prefix, const YAML::Node& map) {
    Level level{std::move(prefix), {}, {}};
    if (map.IsMap()) {
      for (const auto& pair : map) {
        if (!pair.first.IsScalar()) {
          fail({source, "", pair.first.Mark()}, pair.first, "parameter names must be strings");
        }
        const std::string& name = pair.first.Scalar();
        const auto [it, inserted] = level.given.emplace(name, Entry{pair.first, pair.second});
        if (!inserted) {
          fail({source, level.prefix + name, pair.first.Mark()}, pair.first,
               "duplicate key (first given on line " +
                   std::to_string(it->second.key.Mark().line + 1) + ")");
        }
      }
    }
    levels.push_back(std::move(level));
  }

  // Rejects the first (in file order) key at this level that declare() did not name.
  void pop() {
    const Level& level = levels.back();
    const Entry* unknown = nullptr;
    for (const auto& [name, entry] : level.given) {
      if (level.declared.count(name) == 0 &&
          (!unknown || entry.key.Mark().pos < unknown->key.Mark().pos)) {
        unknown = &entry;
      }
    }
    if (unknown) {
      const std::string& name = unknown->key.Scalar();
      std::string message = "unknown parameter";
      std::size_t best = 3;  // suggest only within edit distance 2
      for (const std::string& candidate : level.declared) {
        const std::size_t distance = editDistance(name, candidate);
        if (distance < best) {
          best = distance;
          message = "unknown parameter (did you mean '" + level.prefix + candidate + "'?)";
        }
      }
      fail(where(name, unknown->key.Mark()), unknown->key, message);
    }
    levels.pop_back();
  }

  // Registers `key` at the current level; returns its YAML entry, or nullptr when absent.
  const Entry* declare(const std::string& key) {
    const bool valid = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
    const std::string full_key = levels.back().prefix + key;
    if (!valid) throw std::logic_error("parameter name '" + full_key + "' is not [A-Za-z0-9_]+");
    if (!levels.back().declared.insert(key).second) {
      throw std::logic_error("parameter '" + full_key + "' declared twice");
    }
    const auto it = levels.back().given.find(key);
    return it == levels.back().given.end() ? nullptr : &it->second;
  }

  void emit(const std::string& key, const std::string& value, const std::string& doc,
            const std::string& constraint) {
    std::string comment = doc;
    if (!constraint.empty()) comment += (comment.empty() ? "(" : " (") + constraint + ")";
    std::replace(comment.begin(), comment.end(), '\n', ' ');
    text += std::string(2 * (levels.size() - 1), ' ') + key + ":";
    if (!value.empty()) text += " " + value;
    if (!comment.empty()) text += "  # " + comment;
    text += "\n";
  }

  // The one path every field takes. `parse` turns YAML into a valid T or throws ParamError;
  // `format` writes T as YAML. The value in the struct (the default, or what code set) is checked
  // by parsing its own YAML form, which proves both that it satisfies the declaration and that
  // describeParams output loads back.
  template <class T, class Parse, class Format>
  void field(const std::string& key, T& value, const std::string& doc,
             const std::string& constraint, Parse parse, Format format) {
    const Entry* given = declare(key);
    const std::string default_text = format(value);
    try {
      parse(Where{"", levels.back().prefix + key, YAML::Mark::null_mark()},
            YAML::Load(default_text));
    } catch (const ParamError& e) {
      throw std::logic_error(std::string("invalid value: ") + e.what());
    }
    if (describing) {
      emit(key, default_text, doc, constraint);
    } else if (given) {
      value = parse(where(key, given->key.Mark()), given->value);
    }
  }
};

bool Range::contains(double value) const {
  const bool above_lo = !lo || (lo_exclusive ? value > *lo : value >= *lo);
  return above_lo && (!hi || value <= *hi);
}

std::string Range::describe() const {
  if (lo && hi) {
    return std::string("in ") + (lo_exclusive ? "(" : "[") + formatNumber(*lo) + ", " +
           formatNumber(*hi) + "]";
  }
  if (lo) return (lo_exclusive ? "> " : ">= ") + formatNumber(*lo);
  if (hi) return "<= " + formatNumber(*hi);
  return "";
}

Params::Params(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Params::~Params() = default;

void Params::field(const std::string& key, bool& value, const std::string& doc) {
  impl_->field(key, value, doc, "", parseBool,
               [](bool b) { return std::string(b ? "true" : "false"); });
}

void Params::field(const std::string& key, std::string& value, const std::string& doc) {
  impl_->field(key, value, doc, "", parseString, formatString);
}

void Params::field(const std::string& key, int& value, const std::string& doc, const Range& range) {
  impl_->field(
      key, value, doc, range.describe(),
      [&](const Where& where, const YAML::Node& node) { return parseInt<int>(where, node, range); },
      [](int i) { return std::to_string(i); });
}

void Params::field(const std::string& key, std::int64_t& value, const std::string& doc,
                   const Range& range) {
  impl_->field(
      key, value, doc, range.describe(),
      [&](const Where& where, const YAML::Node& node) {
        return parseInt<std::int64_t>(where, node, range);
      },
      [](std::int64_t i) { return std::to_string(i); });
}

void Params::field(const std::string& key, double& value, const std::string& doc,
                   const Range& range) {
  impl_->field(
      key, value, doc, range.describe(),
      [&](const Where& where, const YAML::Node& node) { return parseDouble(where, node, range); },
      formatDouble);
}

void Params::field(const std::string& key, std::vector<double>& value, const std::string& doc,
                   const Range& range) {
  impl_->field(
      key, value, doc, range.describe(),
      [&](const Where& where, const YAML::Node& node) { return parseDoubles(where, node, range); },
      [](const std::vector<double>& v) { return formatDoubles(v.data(), v.size()); });
}

void Params::field(const std::string& key, Eigen::Vector3d& value, const std::string& doc,
                   const Range& range) {
  impl_->field(
      key, value, doc, range.describe(),
      [&](const Where& where, const YAML::Node& node) {
        const std::vector<double> parsed = parseDoubles(where, node, range);
        if (parsed.size() != 3) {
          fail(where, node, "expected 3 numbers [x, y, z], got " + std::to_string(parsed.size()));
        }
        return Eigen::Vector3d(parsed[0], parsed[1], parsed[2]);
      },
      [](const Eigen::Vector3d& v) { return formatDoubles(v.data(), 3); });
}

void Params::choice(const std::string& key, std::string& value,
                    const std::vector<std::string>& allowed, const std::string& doc) {
  if (allowed.empty()) throw std::logic_error("choice '" + key + "' allows no values");
  const std::string list = join(allowed);
  impl_->field(
      key, value, doc, "one of: " + list,
      [&](const Where& where, const YAML::Node& node) {
        std::string parsed = parseString(where, node);
        if (std::find(allowed.begin(), allowed.end(), parsed) == allowed.end()) {
          fail(where, node, "'" + parsed + "' is not one of: " + list);
        }
        return parsed;
      },
      formatString);
}

void Params::enterGroup(const std::string& key, const std::string& doc) {
  const Impl::Entry* given = impl_->declare(key);
  if (impl_->describing) impl_->emit(key, "", doc, "");
  YAML::Node map;  // null: the group keeps its defaults
  if (given) {
    if (!given->value.IsMap() && !given->value.IsNull()) {
      fail(impl_->where(key, given->key.Mark()), given->value,
           "expected a map of parameters, got " + describeNode(given->value));
    }
    map = given->value;
  }
  impl_->push(impl_->levels.back().prefix + key + ".", map);
}

void Params::leaveGroup() {
  impl_->pop();
}

namespace detail {

void loadInto(const std::string& yaml, const std::string& source, void* options,
              DeclareFn declare) {
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(yaml);
  } catch (const YAML::Exception& e) {
    throw ParamError(location(source, e.mark) + ": invalid YAML: " + e.msg);
  }
  const Where top{source, "", YAML::Mark::null_mark()};
  if (documents.size() > 1) {
    fail(top, documents[1], "expected one YAML document, got " + std::to_string(documents.size()));
  }
  // An empty file, or one with only comments or "~", means "all defaults".
  const YAML::Node root = documents.empty() ? YAML::Node() : documents[0];
  if (!root.IsMap() && !root.IsNull()) {
    fail(top, root, "expected a map of parameters, got " + describeNode(root));
  }
  Params params(std::make_unique<Params::Impl>());
  params.impl_->source = source;
  params.impl_->push("", root);
  declare(options, params);
  params.impl_->pop();
}

std::string describe(void* options, DeclareFn declare) {
  Params params(std::make_unique<Params::Impl>());
  params.impl_->describing = true;
  params.impl_->push("", YAML::Node());
  declare(options, params);
  params.impl_->pop();
  return std::move(params.impl_->text);
}

std::string readFile(const std::string& path) {
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ParamError(path + ": cannot open: " + std::strerror(errno));
  try {
    return std::string(std::istreambuf_iterator<char>(in), {});
  } catch (const std::ios_base::failure&) {  // e.g. a directory: opening works, reading fails
    throw ParamError(path + ": cannot read: " + std::strerror(errno));
  }
}

}  // namespace detail
}  // namespace thicket

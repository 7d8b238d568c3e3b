#include "diff.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <cstring>

namespace thicket::replay {

const std::vector<ExcludedField>& excludedFields() {
  static const std::vector<ExcludedField> fields = {
      {"thicket.module_timing_t", "durations_ms", "wall-clock stage durations"},
      {"thicket.planner_status_t", "solve_time_ms", "wall-clock time of the optimization"},
  };
  return fields;
}

namespace {

bool excluded(const LcmStruct& type, const std::string& field) {
  const std::string name = type.fullName();
  return std::any_of(excludedFields().begin(), excludedFields().end(),
                     [&](const ExcludedField& e) { return name == e.type && field == e.field; });
}

// Shortest text that reads back as the same number, so two different values never print alike.
template <class Real>
std::string realText(Real value) {
  char text[64];
  const auto result = std::to_chars(text, text + sizeof text, value);
  return std::string(text, result.ptr);
}

// An integer, with the name of the constant it equals among those named after its field
// ("state" -> STATE_*), so "2 (STATE_GOAL_REACHED)" reads without the .lcm file at hand.
std::string integerText(int64_t value, const LcmStruct* parent, const std::string& field) {
  std::string text = std::to_string(value);
  if (parent == nullptr) return text;
  std::string prefix = field + "_";
  for (char& c : prefix) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  for (const LcmConstant& constant : parent->constants) {
    if (constant.name.rfind(prefix, 0) != 0) continue;
    try {
      if (std::stoll(constant.value, nullptr, 0) == value) return text + " (" + constant.name + ")";
    } catch (const std::exception&) {
    }
  }
  return text;
}

std::string quoted(const std::string& text) {
  constexpr size_t kMaxShown = 160;
  std::string out = "\"";
  for (size_t i = 0; i < text.size() && i < kMaxShown; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20 || c == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", c);
      out += escaped;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += "\"";
  if (text.size() > kMaxShown) out += " (" + std::to_string(text.size()) + " characters)";
  return out;
}

std::string scalarText(const LcmValue& value, const LcmStruct* parent, const std::string& field) {
  switch (value.primitive) {
    case Primitive::kFloat:
      return realText(static_cast<float>(value.real()));
    case Primitive::kDouble:
      return realText(value.real());
    case Primitive::kBoolean:
      return value.bits ? "true" : "false";
    default:
      return integerText(value.integer(), parent, field);
  }
}

std::string elements(size_t n) {
  return std::to_string(n) + (n == 1 ? " element" : " elements");
}

class Differ {
 public:
  explicit Differ(size_t keep, std::vector<FieldDifference>& kept) : keep_(keep), kept_(kept) {}
  size_t total() const { return total_; }

  void structs(const std::string& path, const LcmValue& a, const LcmValue& b) {
    if (a.type != b.type || a.items.size() != b.items.size()) {
      add(path.empty() ? "type" : path, a.type ? a.type->fullName() : "?",
          b.type ? b.type->fullName() : "?");
      return;
    }
    for (size_t i = 0; i < a.items.size(); ++i) {
      const std::string& name = a.type->fields[i].name;
      if (excluded(*a.type, name)) continue;
      value(path.empty() ? name : path + "." + name, a.items[i], b.items[i], a.type, name);
    }
  }

 private:
  void add(const std::string& path, std::string recorded, std::string replayed) {
    if (kept_.size() < keep_) kept_.push_back({path, std::move(recorded), std::move(replayed)});
    ++total_;
  }

  void value(const std::string& path, const LcmValue& a, const LcmValue& b, const LcmStruct* parent,
             const std::string& field) {
    if (a.kind != b.kind) {
      add(path, "a value of another shape", "");
      return;
    }
    switch (a.kind) {
      case LcmValue::Kind::kScalar:
        if (a.bits != b.bits || a.primitive != b.primitive) {
          add(path, scalarText(a, parent, field), scalarText(b, parent, field));
        }
        return;
      case LcmValue::Kind::kString:
        if (a.text != b.text) add(path, quoted(a.text), quoted(b.text));
        return;
      case LcmValue::Kind::kBytes:
        bytes(path, a.bytes, b.bytes);
        return;
      case LcmValue::Kind::kStruct:
        structs(path, a, b);
        return;
      case LcmValue::Kind::kArray: {
        if (a.items.size() != b.items.size()) {
          add(path, elements(a.items.size()), elements(b.items.size()));
        }
        const size_t common = std::min(a.items.size(), b.items.size());
        for (size_t i = 0; i < common; ++i) {
          value(path + "[" + std::to_string(i) + "]", a.items[i], b.items[i], parent, field);
        }
        return;
      }
    }
  }

  // Payloads (compressed voxels, encoded images) are compared as a whole: where they first
  // differ says more than every byte after it.
  void bytes(const std::string& path, const std::vector<uint8_t>& a,
             const std::vector<uint8_t>& b) {
    if (a == b) return;
    const auto first = std::mismatch(a.begin(), a.end(), b.begin(), b.end());
    const size_t at = static_cast<size_t>(first.first - a.begin());
    auto describe = [at](const std::vector<uint8_t>& bytes) {
      std::string text = std::to_string(bytes.size()) + " bytes";
      if (at < bytes.size()) {
        char byte[64];
        std::snprintf(byte, sizeof byte, " (byte %zu = 0x%02x)", at, bytes[at]);
        text += byte;
      }
      return text;
    };
    add(path, describe(a), describe(b));
  }

  size_t keep_;
  std::vector<FieldDifference>& kept_;
  size_t total_ = 0;
};

// The message's own time, for people matching a diff line to a moment of the flight.
std::string utimeText(const Expected<LcmValue>& recorded, const Expected<LcmValue>& replayed) {
  for (const Expected<LcmValue>* message : {&recorded, &replayed}) {
    if (!*message) continue;
    const LcmValue* utime = (*message)->field("utime");
    if (utime != nullptr && utime->isInteger())
      return " (utime " + std::to_string(utime->integer()) + ")";
  }
  return "";
}

}  // namespace

size_t diffMessages(const LcmValue& recorded, const LcmValue& replayed, size_t keep,
                    std::vector<FieldDifference>& kept) {
  Differ differ(keep, kept);
  differ.structs("", recorded, replayed);
  return differ.total();
}

bool Comparison::equal() const {
  return std::all_of(channels.begin(), channels.end(),
                     [](const ChannelComparison& c) { return c.equal(); });
}

std::string Comparison::text() const {
  std::string out;
  for (const ChannelComparison& c : channels) {
    if (c.equal()) continue;
    out += c.channel + ": recorded " + std::to_string(c.recorded) + " messages, replayed " +
           std::to_string(c.replayed);
    if (c.differing > 0) {
      out += ", " + std::to_string(c.differing) + (c.differing == 1 ? " differs" : " differ");
    }
    out += "\n";
  }
  for (const std::string& line : lines) out += line + "\n";
  if (differences > lines.size()) {
    out += "... and " + std::to_string(differences - lines.size()) + " more differences\n";
  }
  return out;
}

Comparison compareChannels(const LcmTypeSet& types, const ChannelMessages& recorded,
                           const ChannelMessages& replayed, size_t max_lines) {
  Comparison comparison;
  std::map<std::string, std::pair<const std::vector<std::vector<uint8_t>>*,
                                  const std::vector<std::vector<uint8_t>>*>>
      sides;
  for (const auto& [channel, messages] : recorded) sides[channel].first = &messages;
  for (const auto& [channel, messages] : replayed) sides[channel].second = &messages;
  static const std::vector<std::vector<uint8_t>> kNone;

  for (const auto& [channel, pair] : sides) {
    const auto& a = pair.first ? *pair.first : kNone;
    const auto& b = pair.second ? *pair.second : kNone;
    ChannelComparison result{channel, a.size(), b.size(), 0};
    const std::string of = " of " + std::to_string(a.size());
    auto line = [&](const std::string& text) {
      ++comparison.differences;
      if (comparison.lines.size() < max_lines) comparison.lines.push_back(text);
    };
    for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      if (a[i] == b[i]) continue;
      const Expected<LcmValue> x = types.decode(a[i].data(), a[i].size());
      const Expected<LcmValue> y = types.decode(b[i].data(), b[i].size());
      const std::string where =
          channel + " message " + std::to_string(i + 1) + of + utimeText(x, y) + ": ";
      if (!x || !y) {
        ++result.differing;
        if (!x) line(where + "the recorded message " + x.error());
        if (!y) line(where + "the replayed message " + y.error());
        continue;
      }
      std::vector<FieldDifference> kept;
      const size_t keep =
          max_lines > comparison.lines.size() ? max_lines - comparison.lines.size() : 0;
      const size_t n = diffMessages(*x, *y, keep, kept);
      if (n == 0) continue;  // only excluded fields differ
      ++result.differing;
      for (const FieldDifference& d : kept) {
        line(where + d.path + ": recorded " + d.recorded + " replayed " + d.replayed);
      }
      comparison.differences += n - kept.size();  // the ones not kept, counted unprinted
    }
    // Messages of one side only.
    const bool more_recorded = a.size() > b.size();
    const auto& longer = more_recorded ? a : b;
    for (size_t i = std::min(a.size(), b.size()); i < longer.size(); ++i) {
      const Expected<LcmValue> x = types.decode(longer[i].data(), longer[i].size());
      const Expected<LcmValue> none = unexpected("");
      line(channel + " message " + std::to_string(i + 1) + (more_recorded ? of : "") +
           utimeText(x, none) +
           (more_recorded ? ": recorded, not replayed" : ": replayed, not recorded"));
    }
    comparison.channels.push_back(result);
  }
  return comparison;
}

}  // namespace thicket::replay

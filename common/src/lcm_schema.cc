#include "thicket/common/lcm_schema.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>

namespace thicket {
namespace {

struct PrimitiveInfo {
  Primitive primitive;
  const char* name;
  size_t size;  // encoded bytes; 0 for strings
};
constexpr PrimitiveInfo kPrimitives[] = {
    {Primitive::kInt8, "int8_t", 1},   {Primitive::kInt16, "int16_t", 2},
    {Primitive::kInt32, "int32_t", 4}, {Primitive::kInt64, "int64_t", 8},
    {Primitive::kByte, "byte", 1},     {Primitive::kBoolean, "boolean", 1},
    {Primitive::kFloat, "float", 4},   {Primitive::kDouble, "double", 8},
    {Primitive::kString, "string", 0},
};

static_assert(
    [] {
      for (size_t i = 0; i < std::size(kPrimitives); ++i) {
        if (static_cast<size_t>(kPrimitives[i].primitive) != i) return false;
      }
      return true;
    }(),
    "kPrimitives is indexed by Primitive");

const PrimitiveInfo& info(Primitive primitive) {
  return kPrimitives[static_cast<size_t>(primitive)];
}

bool isSizeType(Primitive p) {
  return p == Primitive::kInt8 || p == Primitive::kInt16 || p == Primitive::kInt32 ||
         p == Primitive::kInt64 || p == Primitive::kByte;
}

// ---- the .lcm grammar ----

struct Token {
  std::string text;
  int line = 0;
};

// Words (identifiers, dotted type names, numbers) and single-character punctuation; comments
// dropped.
Expected<std::vector<Token>> tokenize(const std::string& source, const std::string& file) {
  std::vector<Token> tokens;
  int line = 1;
  for (size_t i = 0; i < source.size();) {
    const char c = source[i];
    if (c == '\n') {
      ++line;
      ++i;
    } else if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (source.compare(i, 2, "//") == 0) {
      while (i < source.size() && source[i] != '\n') ++i;
    } else if (source.compare(i, 2, "/*") == 0) {
      const size_t end = source.find("*/", i + 2);
      if (end == std::string::npos) {
        return unexpected(file + ":" + std::to_string(line) + ": unterminated comment");
      }
      line += static_cast<int>(std::count(source.begin() + static_cast<long>(i),
                                          source.begin() + static_cast<long>(end), '\n'));
      i = end + 2;
    } else if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
               c == '+') {
      const size_t start = i;
      while (i < source.size() && (std::isalnum(static_cast<unsigned char>(source[i])) ||
                                   std::strchr("_.-+", source[i]) != nullptr)) {
        ++i;
      }
      tokens.push_back({source.substr(start, i - start), line});
    } else if (std::strchr("{}[];,=", c) != nullptr) {
      tokens.push_back({std::string(1, c), line});
      ++i;
    } else {
      return unexpected(file + ":" + std::to_string(line) + ": unexpected character '" +
                        std::string(1, c) + "'");
    }
  }
  return tokens;
}

bool isIdentifier(const std::string& text) {
  if (text.empty() || std::isdigit(static_cast<unsigned char>(text[0]))) return false;
  return std::all_of(text.begin(), text.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

// A struct as parsed, before nested type names are resolved.
struct ParsedStruct {
  std::unique_ptr<LcmStruct> type;
  std::vector<int> field_lines;
  std::string file;
};

class Parser {
 public:
  Parser(std::vector<Token> tokens, std::string file)
      : tokens_(std::move(tokens)), file_(std::move(file)) {}

  Expected<std::vector<ParsedStruct>> parseFile() {
    std::vector<ParsedStruct> structs;
    std::string package;
    while (!atEnd()) {
      const Token& keyword = next();
      if (keyword.text == "package") {
        if (!package.empty()) return fail("a second package line");
        package = peek().text;
        if (!isIdentifier(package)) return fail("expected a package name");
        ++pos_;
        if (auto e = expect(";")) return fail(*e);
      } else if (keyword.text == "struct") {
        auto parsed = parseStruct(package);
        if (!parsed) return unexpected(parsed.error());
        structs.push_back(std::move(*parsed));
      } else {
        return failAt(keyword, "expected 'package' or 'struct', found '" + keyword.text + "'");
      }
    }
    return structs;
  }

 private:
  bool atEnd() const { return pos_ >= tokens_.size(); }
  const Token& peek() const {
    static const Token end{"end of file", 0};
    return atEnd() ? end : tokens_[pos_];
  }
  const Token& next() {
    const Token& token = peek();
    if (!atEnd()) ++pos_;
    return token;
  }
  int line() const { return atEnd() ? (tokens_.empty() ? 1 : tokens_.back().line) : peek().line; }
  Unexpected failAt(const Token& token, const std::string& message) const {
    return unexpected(file_ + ":" + std::to_string(token.line ? token.line : line()) + ": " +
                      message);
  }
  Unexpected fail(const std::string& message) const { return failAt(peek(), message); }
  std::optional<std::string> expect(const std::string& text) {
    if (peek().text != text) return "expected '" + text + "', found '" + peek().text + "'";
    ++pos_;
    return std::nullopt;
  }

  Expected<ParsedStruct> parseStruct(const std::string& package) {
    if (package.empty()) return fail("a struct before the package line");
    ParsedStruct parsed;
    parsed.file = file_;
    parsed.type = std::make_unique<LcmStruct>();
    parsed.type->package = package;
    parsed.type->name = next().text;
    if (!isIdentifier(parsed.type->name)) return fail("expected a struct name");
    if (auto e = expect("{")) return fail(*e);
    std::set<std::string> names;
    while (peek().text != "}") {
      if (atEnd()) return fail("missing '}' of struct " + parsed.type->name);
      const bool is_const = peek().text == "const";
      if (is_const) ++pos_;
      const Token& type_token = next();
      std::string type_name = type_token.text;
      if (!isIdentifier(type_name)) {
        // A dotted name is a type of another package.
        const size_t dot = type_name.find('.');
        if (dot == std::string::npos || !isIdentifier(type_name.substr(0, dot)) ||
            !isIdentifier(type_name.substr(dot + 1))) {
          return failAt(type_token, "expected a type, found '" + type_name + "'");
        }
      }
      // One or more names, each with its dimensions (fields) or value (constants).
      while (true) {
        const Token& name_token = next();
        if (!isIdentifier(name_token.text)) {
          return failAt(name_token, "expected a name, found '" + name_token.text + "'");
        }
        if (!names.insert(name_token.text).second) {
          return failAt(name_token, "'" + name_token.text + "' declared twice");
        }
        if (is_const) {
          LcmConstant constant;
          constant.name = name_token.text;
          if (!parsePrimitive(type_name, constant.primitive) ||
              constant.primitive == Primitive::kString) {
            return failAt(type_token, "a constant must have a numeric type, not " + type_name);
          }
          if (auto e = expect("=")) return fail(*e);
          constant.value = next().text;
          parsed.type->constants.push_back(constant);
        } else {
          LcmField field;
          field.name = name_token.text;
          field.type_name = type_name;
          while (peek().text == "[") {
            ++pos_;
            const Token& size = next();
            LcmDimension dimension;
            if (std::isdigit(static_cast<unsigned char>(size.text[0]))) {
              try {
                size_t used = 0;
                dimension.size = std::stoll(size.text, &used, 0);
                if (used != size.text.size() || dimension.size <= 0) throw std::exception();
              } catch (const std::exception&) {
                return failAt(size, "bad array size '" + size.text + "'");
              }
            } else {
              dimension.variable = true;
              dimension.size_field = size.text;
            }
            if (auto e = expect("]")) return fail(*e);
            field.dimensions.push_back(dimension);
          }
          parsed.type->fields.push_back(field);
          parsed.field_lines.push_back(name_token.line);
        }
        if (peek().text == ",") {
          ++pos_;
          continue;
        }
        if (auto e = expect(";")) return fail(*e);
        break;
      }
    }
    ++pos_;  // '}'
    return parsed;
  }

  std::vector<Token> tokens_;
  std::string file_;
  size_t pos_ = 0;
};

// ---- fingerprints (lcm-gen's rule) ----

int64_t hashUpdate(int64_t v, char c) {
  return ((v << 8) ^ (v >> 55)) + c;
}

int64_t hashString(int64_t v, const std::string& s) {
  v = hashUpdate(v, static_cast<char>(s.size()));
  for (char c : s) v = hashUpdate(v, c);
  return v;
}

// The hash of a struct's own layout: member names, primitive type names and dimensions; nested
// types contribute through their own hash (so renaming a type keeps fingerprints).
int64_t baseHash(const LcmStruct& type) {
  int64_t v = 0x12345678;
  for (const LcmField& field : type.fields) {
    v = hashString(v, field.name);
    if (field.is_primitive) v = hashString(v, field.type_name);
    v = hashUpdate(v, static_cast<char>(field.dimensions.size()));
    for (const LcmDimension& dimension : field.dimensions) {
      v = hashUpdate(v, static_cast<char>(dimension.variable ? 1 : 0));
      v = hashString(v, dimension.variable ? dimension.size_field : std::to_string(dimension.size));
    }
  }
  return v;
}

// The generated _computeHash: the base hash plus every nested member's hash (0 for a type
// already being hashed further up), rotated left by one.
uint64_t computeHash(const LcmStruct& type, std::vector<const LcmStruct*>& parents) {
  if (std::find(parents.begin(), parents.end(), &type) != parents.end()) return 0;
  parents.push_back(&type);
  uint64_t hash = static_cast<uint64_t>(baseHash(type));
  for (const LcmField& field : type.fields) {
    if (!field.is_primitive) hash += computeHash(*field.type, parents);
  }
  parents.pop_back();
  return (hash << 1) + ((hash >> 63) & 1);
}

// ---- encoding ----

constexpr int kMaxNesting = 64;

class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  size_t remaining() const { return size_ - pos_; }
  size_t position() const { return pos_; }

  bool scalar(Primitive primitive, uint64_t& bits) {
    const size_t n = info(primitive).size;
    if (remaining() < n) return false;
    uint64_t value = 0;
    for (size_t i = 0; i < n; ++i) value = (value << 8) | data_[pos_ + i];
    pos_ += n;
    // Integers and booleans sign-extend; float keeps its 32 bits.
    if (primitive != Primitive::kFloat && primitive != Primitive::kDouble && n < 8) {
      const unsigned shift = static_cast<unsigned>(64 - 8 * n);
      value = static_cast<uint64_t>(static_cast<int64_t>(value << shift) >> shift);
    }
    bits = value;
    return true;
  }
  /// An encoded string: an int32 length that counts the NUL, the characters, the NUL. Nullopt
  /// when it is one (`text`, if given, gets the characters), else why not.
  std::optional<std::string> string(std::string* text) {
    uint64_t length = 0;
    if (!scalar(Primitive::kInt32, length)) return std::string("truncated");
    const int64_t n = static_cast<int64_t>(length);
    if (n < 1) return "string length " + std::to_string(n) + " (at least 1: the NUL)";
    if (static_cast<uint64_t>(n) > remaining()) {
      return "string length " + std::to_string(n) + " exceeds the " + std::to_string(remaining()) +
             " bytes left";
    }
    const auto* start = reinterpret_cast<const char*>(data_ + pos_);
    pos_ += static_cast<size_t>(n);
    if (start[n - 1] != 0) return std::string("string not NUL-terminated");
    if (text != nullptr) text->assign(start, static_cast<size_t>(n - 1));
    return std::nullopt;
  }
  bool skip(size_t n) {
    if (remaining() < n) return false;
    pos_ += n;
    return true;
  }
  bool bytes(size_t n, std::vector<uint8_t>& out) {
    if (remaining() < n) return false;
    out.assign(data_ + pos_, data_ + pos_ + n);
    pos_ += n;
    return true;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

void writeScalar(std::vector<uint8_t>& out, Primitive primitive, uint64_t bits) {
  const size_t n = info(primitive).size;
  for (size_t i = 0; i < n; ++i) out.push_back(static_cast<uint8_t>(bits >> (8 * (n - 1 - i))));
}

// The smallest number of bytes an element of `field` can take; bounds the element counts a
// decoder accepts from untrusted size fields.
size_t minimumSize(const LcmField& field, size_t dimension, int depth = 0);

size_t minimumStructSize(const LcmStruct& type, int depth) {
  if (depth > kMaxNesting) return 0;
  size_t total = 0;
  for (const LcmField& field : type.fields) total += minimumSize(field, 0, depth + 1);
  return total;
}

size_t minimumSize(const LcmField& field, size_t dimension, int depth) {
  for (size_t d = dimension; d < field.dimensions.size(); ++d) {
    if (field.dimensions[d].variable) return 0;
  }
  size_t count = 1;
  for (size_t d = dimension; d < field.dimensions.size(); ++d) {
    count *= static_cast<size_t>(field.dimensions[d].size);
  }
  if (!field.is_primitive) return count * minimumStructSize(*field.type, depth);
  return count * (field.primitive == Primitive::kString ? 4 : info(field.primitive).size);
}

// "segment: error", or "segment[i]..." when the error already starts with a deeper path.
std::string withPath(const std::string& segment, const std::string& error) {
  const bool deeper = !error.empty() && (error[0] == '[' || error[0] == '.');
  return segment + (deeper ? "" : ": ") + error;
}

// Decodes a message that Checker found well-formed (LcmTypeSet::decode checks first): every size
// is known to fit in the bytes, so nothing here allocates more than the message holds.
class Decoder {
 public:
  Decoder(const uint8_t* data, size_t size) : reader_(data, size) {}
  Reader& reader() { return reader_; }

  std::optional<std::string> decodeStruct(const LcmStruct& type, LcmValue& value, int depth) {
    if (depth > kMaxNesting) return "nesting deeper than " + std::to_string(kMaxNesting);
    value.kind = LcmValue::Kind::kStruct;
    value.type = &type;
    value.items.resize(type.fields.size());
    for (size_t f = 0; f < type.fields.size(); ++f) {
      const LcmField& field = type.fields[f];
      if (auto error = decodeField(type, value, field, 0, value.items[f], depth)) {
        return withPath(field.name, *error);
      }
    }
    return std::nullopt;
  }

 private:
  std::optional<std::string> decodeField(const LcmStruct& type, const LcmValue& parent,
                                         const LcmField& field, size_t dimension, LcmValue& value,
                                         int depth) {
    if (dimension == field.dimensions.size()) return decodeElement(field, value, depth);
    const LcmDimension& d = field.dimensions[dimension];
    const int64_t count = d.variable ? parent.items[d.size_field_index].integer() : d.size;
    if (count < 0) return std::string("negative size");  // (Checker refuses it first)
    const bool innermost_bytes = dimension + 1 == field.dimensions.size() && field.is_primitive &&
                                 field.primitive == Primitive::kByte;
    if (innermost_bytes) {
      value.kind = LcmValue::Kind::kBytes;
      if (!reader_.bytes(static_cast<size_t>(count), value.bytes)) return std::string("truncated");
      return std::nullopt;
    }
    value.kind = LcmValue::Kind::kArray;
    value.items.resize(static_cast<size_t>(count));
    for (int64_t i = 0; i < count; ++i) {
      if (auto error = decodeField(type, parent, field, dimension + 1,
                                   value.items[static_cast<size_t>(i)], depth)) {
        return withPath("[" + std::to_string(i) + "]", *error);
      }
    }
    return std::nullopt;
  }

  std::optional<std::string> decodeElement(const LcmField& field, LcmValue& value, int depth) {
    if (!field.is_primitive) {
      auto error = decodeStruct(*field.type, value, depth + 1);
      if (error) return "." + *error;
      return std::nullopt;
    }
    if (field.primitive == Primitive::kString) {
      value.kind = LcmValue::Kind::kString;
      return reader_.string(&value.text);
    }
    value.kind = LcmValue::Kind::kScalar;
    value.primitive = field.primitive;
    if (!reader_.scalar(field.primitive, value.bits)) return std::string("truncated");
    return std::nullopt;
  }

  Reader reader_;
};

// The wire size of one element of `field` below `dimension` when it is the same for every
// element (primitives other than strings, structs of such), given the values of the enclosing
// struct's size fields; nullopt otherwise. Saturates at UINT64_MAX.
std::optional<uint64_t> fixedWireSize(const LcmField& field, size_t dimension,
                                      std::span<const int64_t> sizes, int depth = 0);

std::optional<uint64_t> fixedStructSize(const LcmStruct& type, int depth) {
  if (depth > kMaxNesting) return std::nullopt;
  uint64_t total = 0;
  for (const LcmField& field : type.fields) {
    for (const LcmDimension& d : field.dimensions) {
      if (d.variable) return std::nullopt;
    }
    const auto size = fixedWireSize(field, 0, {}, depth + 1);  // no variable sizes to look up
    if (!size) return std::nullopt;
    total = (total > UINT64_MAX - *size) ? UINT64_MAX : total + *size;
  }
  return total;
}

std::optional<uint64_t> fixedWireSize(const LcmField& field, size_t dimension,
                                      std::span<const int64_t> sizes, int depth) {
  uint64_t element = 0;
  if (!field.is_primitive) {
    const auto size = fixedStructSize(*field.type, depth);
    if (!size) return std::nullopt;
    element = *size;
  } else if (field.primitive == Primitive::kString) {
    return std::nullopt;
  } else {
    element = info(field.primitive).size;
  }
  uint64_t total = element;
  for (size_t d = dimension; d < field.dimensions.size(); ++d) {
    const LcmDimension& dim = field.dimensions[d];
    const int64_t count = dim.variable ? sizes[dim.size_field_index] : dim.size;
    if (count < 0) return std::nullopt;  // the walk reports it where it is
    if (__builtin_mul_overflow(total, static_cast<uint64_t>(count), &total)) return UINT64_MAX;
  }
  return total;
}

// Walks an encoded message without allocating anything in proportion to what it declares.
class Checker {
 public:
  Checker(const uint8_t* data, size_t size) : reader_(data, size) {}
  Reader& reader() { return reader_; }

  std::optional<std::string> checkStruct(const LcmStruct& type, int depth) {
    if (depth > kMaxNesting) return "nesting deeper than " + std::to_string(kMaxNesting);
    std::vector<int64_t> sizes(type.fields.size(), 0);  // scalar values, for size fields
    for (size_t f = 0; f < type.fields.size(); ++f) {
      const LcmField& field = type.fields[f];
      if (field.dimensions.empty() && field.is_primitive && field.primitive != Primitive::kString) {
        uint64_t bits = 0;
        if (!reader_.scalar(field.primitive, bits)) return withPath(field.name, "truncated");
        sizes[f] = static_cast<int64_t>(bits);
        continue;
      }
      if (auto error = checkField(field, 0, sizes, depth)) return withPath(field.name, *error);
    }
    return std::nullopt;
  }

 private:
  std::optional<std::string> checkField(const LcmField& field, size_t dimension,
                                        std::span<const int64_t> sizes, int depth) {
    if (dimension == field.dimensions.size()) return checkElement(field, depth);
    const LcmDimension& d = field.dimensions[dimension];
    const int64_t count = d.variable ? sizes[d.size_field_index] : d.size;
    if (count < 0) {
      return "size field " + d.size_field + " is negative (" + std::to_string(count) + ")";
    }
    const auto exceeds = [&] {
      const std::string left = " the " + std::to_string(reader_.remaining()) + " bytes left";
      if (!d.variable) return "truncated: " + std::to_string(count) + " elements exceed" + left;
      return "size " + std::to_string(count) + " (" + d.size_field + ") exceeds" + left;
    };
    const uint64_t n = static_cast<uint64_t>(count);
    // Even elements of no bytes cost the decoder a container each: at most one per byte left.
    if (const auto element = fixedWireSize(field, dimension + 1, sizes, depth)) {
      const bool fits =
          *element == 0 ? n <= reader_.remaining() + 1 : n <= reader_.remaining() / *element;
      if (!fits) return exceeds();
      if (!reader_.skip(n * *element)) return std::string("truncated");
      return std::nullopt;
    }
    const size_t minimum = std::max<size_t>(minimumSize(field, dimension + 1), 1);
    if (n > reader_.remaining() / minimum + 1) return exceeds();
    for (uint64_t i = 0; i < n; ++i) {
      if (auto error = checkField(field, dimension + 1, sizes, depth)) {
        return withPath("[" + std::to_string(i) + "]", *error);
      }
    }
    return std::nullopt;
  }

  std::optional<std::string> checkElement(const LcmField& field, int depth) {
    if (!field.is_primitive) {
      auto error = checkStruct(*field.type, depth + 1);
      if (error) return "." + *error;
      return std::nullopt;
    }
    if (field.primitive == Primitive::kString) return reader_.string(nullptr);
    uint64_t bits = 0;
    if (!reader_.scalar(field.primitive, bits)) return std::string("truncated");
    return std::nullopt;
  }

  Reader reader_;
};

// A message body (after its fingerprint) against `type`: what is malformed (with its path), or
// the bytes left over after a well-formed one.
struct BodyCheck {
  std::optional<std::string> malformed;
  size_t left = 0;      // bytes after the end of a well-formed body
  size_t position = 0;  // where the body ended
};

BodyCheck checkBody(const LcmStruct& type, const void* data, size_t size) {
  Checker checker(static_cast<const uint8_t*>(data), size);
  checker.reader().skip(8);
  BodyCheck result;
  result.malformed = checker.checkStruct(type, 0);
  result.left = checker.reader().remaining();
  result.position = checker.reader().position();
  return result;
}

class Encoder {
 public:
  std::vector<uint8_t>& out() { return out_; }

  std::optional<std::string> encodeStruct(const LcmStruct& type, const LcmValue& value, int depth) {
    if (depth > kMaxNesting) return "nesting deeper than " + std::to_string(kMaxNesting);
    if (value.kind != LcmValue::Kind::kStruct || value.type != &type ||
        value.items.size() != type.fields.size()) {
      return "not a " + type.fullName() + " value";
    }
    for (size_t f = 0; f < type.fields.size(); ++f) {
      if (auto error = encodeField(value, type.fields[f], 0, value.items[f], depth)) {
        return type.fields[f].name + ": " + *error;
      }
    }
    return std::nullopt;
  }

 private:
  std::optional<std::string> encodeField(const LcmValue& parent, const LcmField& field,
                                         size_t dimension, const LcmValue& value, int depth) {
    if (dimension == field.dimensions.size()) return encodeElement(field, value, depth);
    const LcmDimension& d = field.dimensions[dimension];
    const int64_t count = d.variable ? parent.items[d.size_field_index].integer() : d.size;
    const bool innermost_bytes = dimension + 1 == field.dimensions.size() && field.is_primitive &&
                                 field.primitive == Primitive::kByte;
    const LcmValue::Kind kind = innermost_bytes ? LcmValue::Kind::kBytes : LcmValue::Kind::kArray;
    const size_t length = innermost_bytes ? value.bytes.size() : value.items.size();
    if (value.kind != kind || count < 0 || length != static_cast<size_t>(count)) {
      return "holds " + std::to_string(length) + " elements where its size says " +
             std::to_string(count);
    }
    if (innermost_bytes) {
      out_.insert(out_.end(), value.bytes.begin(), value.bytes.end());
      return std::nullopt;
    }
    for (const LcmValue& item : value.items) {
      if (auto error = encodeField(parent, field, dimension + 1, item, depth)) return error;
    }
    return std::nullopt;
  }

  std::optional<std::string> encodeElement(const LcmField& field, const LcmValue& value,
                                           int depth) {
    if (!field.is_primitive) return encodeStruct(*field.type, value, depth + 1);
    if (field.primitive == Primitive::kString) {
      if (value.kind != LcmValue::Kind::kString) return std::string("not a string");
      writeScalar(out_, Primitive::kInt32, value.text.size() + 1);
      out_.insert(out_.end(), value.text.begin(), value.text.end());
      out_.push_back(0);
      return std::nullopt;
    }
    if (value.kind != LcmValue::Kind::kScalar || value.primitive != field.primitive) {
      return std::string("not a ") + primitiveName(field.primitive);
    }
    writeScalar(out_, field.primitive, value.bits);
    return std::nullopt;
  }

  std::vector<uint8_t> out_;
};

}  // namespace

bool parsePrimitive(const std::string& name, Primitive& primitive) {
  for (const PrimitiveInfo& p : kPrimitives) {
    if (name == p.name) {
      primitive = p.primitive;
      return true;
    }
  }
  return false;
}

const char* primitiveName(Primitive primitive) {
  return info(primitive).name;
}

bool LcmValue::isInteger() const {
  return kind == Kind::kScalar && primitive != Primitive::kFloat && primitive != Primitive::kDouble;
}

double LcmValue::real() const {
  if (primitive == Primitive::kFloat) {
    const uint32_t narrow = static_cast<uint32_t>(bits);
    float f;
    std::memcpy(&f, &narrow, sizeof f);
    return f;
  }
  double d;
  std::memcpy(&d, &bits, sizeof d);
  return d;
}

const LcmValue* LcmValue::field(const std::string& name) const {
  if (kind != Kind::kStruct || type == nullptr) return nullptr;
  for (size_t i = 0; i < type->fields.size() && i < items.size(); ++i) {
    if (type->fields[i].name == name) return &items[i];
  }
  return nullptr;
}

const LcmTypeSet& builtinLcmTypes() {
  static const LcmTypeSet types = [] {
    const std::vector<std::pair<std::string, std::string>> sources = {
#include "lcm_sources.inc"
    };
    auto parsed = LcmTypeSet::parse(sources);
    // The build parsed the same files with lcm-gen; a failure here is a defect of this parser.
    if (!parsed) throw std::logic_error("thicket's own LCM types: " + parsed.error());
    return std::move(*parsed);
  }();
  return types;
}

bool readFingerprint(const void* data, size_t size, uint64_t& fingerprint) {
  if (size < 8) return false;
  Reader reader(static_cast<const uint8_t*>(data), size);
  return reader.scalar(Primitive::kInt64, fingerprint);
}

Expected<LcmTypeSet> LcmTypeSet::loadDirectory(const std::string& dir) {
  std::vector<std::pair<std::string, std::string>> files;
  std::error_code error;
  std::vector<std::filesystem::path> paths;
  for (const auto& entry : std::filesystem::directory_iterator(dir, error)) {
    if (entry.path().extension() == ".lcm") paths.push_back(entry.path());
  }
  if (error)
    return unexpected("cannot read the LCM type directory '" + dir + "': " + error.message());
  if (paths.empty()) return unexpected("no .lcm files in '" + dir + "'");
  std::sort(paths.begin(), paths.end());
  for (const auto& path : paths) {
    std::ifstream in(path, std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) return unexpected("cannot read " + path.string());
    files.emplace_back(path.string(), std::move(text));
  }
  return parse(files);
}

Expected<LcmTypeSet> LcmTypeSet::parse(
    const std::vector<std::pair<std::string, std::string>>& files) {
  std::vector<ParsedStruct> parsed;
  for (const auto& [name, text] : files) {
    auto tokens = tokenize(text, name);
    if (!tokens) return unexpected(tokens.error());
    auto structs = Parser(std::move(*tokens), name).parseFile();
    if (!structs) return unexpected(structs.error());
    for (ParsedStruct& s : *structs) parsed.push_back(std::move(s));
  }

  LcmTypeSet set;
  for (ParsedStruct& p : parsed) {
    const std::string full = p.type->fullName();
    if (set.by_name_.count(full)) return unexpected(p.file + ": " + full + " defined twice");
    set.by_name_[full] = p.type.get();
  }
  // Resolve field types and dimensions now that every struct is known.
  for (ParsedStruct& p : parsed) {
    LcmStruct& type = *p.type;
    for (size_t f = 0; f < type.fields.size(); ++f) {
      LcmField& field = type.fields[f];
      const std::string where = p.file + ":" + std::to_string(p.field_lines[f]) + ": " +
                                type.fullName() + "." + field.name;
      field.is_primitive = parsePrimitive(field.type_name, field.primitive);
      if (!field.is_primitive) {
        const std::string full = field.type_name.find('.') == std::string::npos
                                     ? type.package + "." + field.type_name
                                     : field.type_name;
        const auto found = set.by_name_.find(full);
        if (found == set.by_name_.end()) return unexpected(where + ": unknown type " + full);
        field.type_name = full;
        field.type = found->second;
      }
      for (LcmDimension& d : field.dimensions) {
        if (!d.variable) continue;
        const auto size_field =
            std::find_if(type.fields.begin(), type.fields.begin() + static_cast<long>(f),
                         [&](const LcmField& other) { return other.name == d.size_field; });
        if (size_field == type.fields.begin() + static_cast<long>(f)) {
          return unexpected(where + ": the size " + d.size_field + " is not an earlier field");
        }
        if (!size_field->is_primitive || !isSizeType(size_field->primitive) ||
            !size_field->dimensions.empty()) {
          return unexpected(where + ": the size " + d.size_field + " is not an integer field");
        }
        d.size_field_index = static_cast<size_t>(size_field - type.fields.begin());
      }
    }
  }
  for (ParsedStruct& p : parsed) {
    std::vector<const LcmStruct*> parents;
    p.type->fingerprint = computeHash(*p.type, parents);
    const auto [existing, inserted] =
        set.by_fingerprint_.emplace(p.type->fingerprint, p.type.get());
    if (!inserted) {
      return unexpected(p.type->fullName() + " and " + existing->second->fullName() +
                        " have the same fingerprint (the same layout): their messages could not "
                        "be told apart");
    }
    set.types_.push_back(std::move(p.type));
  }
  return set;
}

const LcmStruct* LcmTypeSet::find(const std::string& full_name) const {
  const auto it = by_name_.find(full_name);
  return it == by_name_.end() ? nullptr : it->second;
}

const LcmStruct* LcmTypeSet::findByFingerprint(uint64_t fingerprint) const {
  const auto it = by_fingerprint_.find(fingerprint);
  return it == by_fingerprint_.end() ? nullptr : it->second;
}

std::vector<const LcmStruct*> LcmTypeSet::types() const {
  std::vector<const LcmStruct*> all;
  for (const auto& type : types_) all.push_back(type.get());
  return all;
}

Expected<LcmValue> LcmTypeSet::decode(const void* data, size_t size) const {
  uint64_t fingerprint = 0;
  if (!readFingerprint(data, size, fingerprint)) {
    return unexpected(std::to_string(size) + " bytes: too short for a fingerprint");
  }
  const LcmStruct* type = findByFingerprint(fingerprint);
  if (type == nullptr) {
    char hex[32];
    std::snprintf(hex, sizeof hex, "0x%016llx", static_cast<unsigned long long>(fingerprint));
    return unexpected(std::string("unknown fingerprint ") + hex);
  }
  const BodyCheck body = checkBody(*type, data, size);
  if (body.malformed) {
    return unexpected("does not decode as " + type->fullName() + ": " + *body.malformed);
  }
  if (body.left != 0) {
    return unexpected("does not decode as " + type->fullName() + ": " + std::to_string(body.left) +
                      " bytes left over after " + std::to_string(body.position));
  }
  Decoder decoder(static_cast<const uint8_t*>(data), size);
  uint64_t skipped = 0;
  decoder.reader().scalar(Primitive::kInt64, skipped);
  LcmValue value;
  if (auto error = decoder.decodeStruct(*type, value, 0)) {
    return unexpected("does not decode as " + type->fullName() + ": " + *error);
  }
  return value;
}

std::string LcmTypeSet::check(const LcmStruct& type, const void* data, size_t size) {
  uint64_t fingerprint = 0;
  if (!readFingerprint(data, size, fingerprint)) {
    return std::to_string(size) + " bytes is too short for any " + type.fullName();
  }
  if (fingerprint != type.fingerprint) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "fingerprint 0x%016llx is not %s (0x%016llx): a message of another type",
                  static_cast<unsigned long long>(fingerprint), type.fullName().c_str(),
                  static_cast<unsigned long long>(type.fingerprint));
    return text;
  }
  const BodyCheck body = checkBody(type, data, size);
  if (body.malformed) {
    return "malformed " + type.fullName() + " (" + std::to_string(size) +
           " bytes): " + *body.malformed;
  }
  if (body.left != 0) {
    return type.fullName() + " followed by " + std::to_string(body.left) + " unexpected bytes";
  }
  return {};
}

Expected<std::vector<uint8_t>> LcmTypeSet::encode(const LcmValue& message) const {
  if (message.kind != LcmValue::Kind::kStruct || message.type == nullptr) {
    return unexpected("only a struct value encodes as a message");
  }
  Encoder encoder;
  writeScalar(encoder.out(), Primitive::kInt64, message.type->fingerprint);
  if (auto error = encoder.encodeStruct(*message.type, message, 0)) {
    return unexpected("cannot encode " + message.type->fullName() + ": " + *error);
  }
  return std::move(encoder.out());
}

}  // namespace thicket

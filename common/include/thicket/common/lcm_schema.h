// LCM types known at run time: the .lcm definitions in lcmtypes/ parsed into a schema, so that
// any logged message can be decoded field by field (and encoded back) without the generated
// code. thicket-replay compares recorded and replayed messages this way, whatever their type,
// and every subscriber checks a message against it before the generated decoder sees it
// (decodeMessage in node.h): LCM 1.3.1's decoders allocate whatever sizes a message declares
// and compute byte counts in an int, so a 50-byte message could make them allocate gigabytes
// or read past the buffer.
//
// The schema follows lcm-gen: primitive types, fixed and variable-length arrays (a variable
// dimension names an earlier integer field), nested types, constants, and LCM's fingerprint rule,
// so a message's type is found from its first 8 bytes exactly as the generated decoders check it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket {

enum class Primitive { kInt8, kInt16, kInt32, kInt64, kByte, kBoolean, kFloat, kDouble, kString };

/// The primitive named `name` as in a .lcm file ("int32_t", "double", ...), if it is one.
bool parsePrimitive(const std::string& name, Primitive& primitive);
const char* primitiveName(Primitive primitive);

struct LcmStruct;

struct LcmDimension {
  bool variable = false;
  int64_t size = 0;        ///< fixed dimensions
  std::string size_field;  ///< variable dimensions: the earlier integer field holding the size
  size_t size_field_index = 0;
};

struct LcmField {
  std::string name;
  std::string type_name;  ///< as written for primitives; "package.type" for structs
  bool is_primitive = true;
  Primitive primitive = Primitive::kInt8;
  const LcmStruct* type = nullptr;  ///< nested structs
  std::vector<LcmDimension> dimensions;
};

struct LcmConstant {
  std::string name;
  Primitive primitive = Primitive::kInt8;
  std::string value;  ///< as written
};

struct LcmStruct {
  std::string package;
  std::string name;
  std::vector<LcmField> fields;
  std::vector<LcmConstant> constants;
  /// What the generated getHash() returns: the fingerprint leading every encoded message.
  uint64_t fingerprint = 0;

  std::string fullName() const { return package + "." + name; }
};

/// A decoded value. Scalars keep their exact bits, so comparisons are exact (doubles bitwise).
struct LcmValue {
  enum class Kind { kScalar, kString, kBytes, kArray, kStruct };
  Kind kind = Kind::kScalar;
  Primitive primitive = Primitive::kInt8;  ///< kScalar
  /// kScalar: integers and booleans sign-extended; float and double as their IEEE-754 bits.
  uint64_t bits = 0;
  std::string text;                 ///< kString
  std::vector<uint8_t> bytes;       ///< kBytes: the innermost dimension of a byte array
  std::vector<LcmValue> items;      ///< kArray: elements; kStruct: fields in declaration order
  const LcmStruct* type = nullptr;  ///< kStruct

  bool isInteger() const;
  int64_t integer() const { return static_cast<int64_t>(bits); }
  double real() const;  ///< float and double
  /// The field named `name` of a struct value, or nullptr.
  const LcmValue* field(const std::string& name) const;
};

/// Every type of a set of .lcm files.
class LcmTypeSet {
 public:
  /// Parses every *.lcm file of `dir`; the error names the file and line of the first problem.
  static Expected<LcmTypeSet> loadDirectory(const std::string& dir);
  /// Parses .lcm sources given as (name for messages, text).
  static Expected<LcmTypeSet> parse(const std::vector<std::pair<std::string, std::string>>& files);

  LcmTypeSet(LcmTypeSet&&) = default;
  LcmTypeSet& operator=(LcmTypeSet&&) = default;

  /// "package.type", or nullptr.
  const LcmStruct* find(const std::string& full_name) const;
  /// The type whose messages start with `fingerprint`, or nullptr.
  const LcmStruct* findByFingerprint(uint64_t fingerprint) const;
  std::vector<const LcmStruct*> types() const;

  /// Decodes one whole message (fingerprint first), picking its type by the fingerprint. The
  /// error says why not: too short, an unknown fingerprint, truncated, trailing bytes.
  Expected<LcmValue> decode(const void* data, size_t size) const;
  /// Checks, without allocating, that `size` bytes hold exactly one encoded message of `type`
  /// (fingerprint first): every size a field declares is non-negative and fits in the bytes
  /// left, strings are NUL-terminated, nothing is left over. Empty when it holds; otherwise
  /// why not, naming the field. A message that passes makes the generated decoder allocate at
  /// most a few dozen bytes per encoded byte: no element count exceeds the bytes left + 1.
  static std::string check(const LcmStruct& type, const void* data, size_t size);
  /// Encodes a struct value as a whole message; the error names the field that does not fit
  /// its type (an array length that disagrees with its size field...).
  Expected<std::vector<uint8_t>> encode(const LcmValue& message) const;

 private:
  LcmTypeSet() = default;
  std::vector<std::unique_ptr<LcmStruct>> types_;
  std::map<std::string, const LcmStruct*> by_name_;
  std::map<uint64_t, const LcmStruct*> by_fingerprint_;
};

/// The types thicket was built with: lcmtypes/*.lcm, compiled in.
const LcmTypeSet& builtinLcmTypes();

/// The first 8 bytes of a message as a fingerprint (big-endian); false when there are fewer.
bool readFingerprint(const void* data, size_t size, uint64_t& fingerprint);

}  // namespace thicket

// Hostile LCM messages for any thicket type, built from the schema compiled into thicket_common:
// a valid sample, then the same with huge, negative and zero counts, truncated, with junk behind
// a valid fingerprint, with NaN, infinite and huge numbers, and with its time far ahead or back.
// The decode test (tests/unit/test_bounded_decode.cc) and the module fuzz test
// (tests/system/test_module_fuzz.cc) feed them to decoders and to running modules.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "thicket/common/lcm_schema.h"

namespace thicket::fuzz {

using Bytes = std::vector<uint8_t>;

/// A value of `type` with every integer `integer` (1: every variable array has one element),
/// every real `real` (as IEEE bits of a double; floats get the float of the same value) and every
/// string "ab".
inline LcmValue sampleValue(const LcmStruct& type, int64_t integer = 1, double real = 0.5);

inline LcmValue sampleElement(const LcmField& field, int64_t integer, double real) {
  if (!field.is_primitive) return sampleValue(*field.type, integer, real);
  LcmValue value;
  if (field.primitive == Primitive::kString) {
    value.kind = LcmValue::Kind::kString;
    value.text = "ab";
    return value;
  }
  value.primitive = field.primitive;
  if (field.primitive == Primitive::kDouble) {
    std::memcpy(&value.bits, &real, 8);
  } else if (field.primitive == Primitive::kFloat) {
    const float f = static_cast<float>(real);
    uint32_t bits = 0;
    std::memcpy(&bits, &f, 4);
    value.bits = bits;
  } else {
    value.bits = static_cast<uint64_t>(integer);
  }
  return value;
}

inline LcmValue sampleArray(const LcmField& field, size_t dimension, int64_t integer, double real) {
  if (dimension == field.dimensions.size()) return sampleElement(field, integer, real);
  const LcmDimension& d = field.dimensions[dimension];
  const int64_t count = d.variable ? 1 : d.size;
  LcmValue value;
  if (dimension + 1 == field.dimensions.size() && field.is_primitive &&
      field.primitive == Primitive::kByte) {
    value.kind = LcmValue::Kind::kBytes;
    value.bytes.assign(static_cast<size_t>(count), 7);
    return value;
  }
  value.kind = LcmValue::Kind::kArray;
  for (int64_t i = 0; i < count; ++i) {
    value.items.push_back(sampleArray(field, dimension + 1, integer, real));
  }
  return value;
}

inline LcmValue sampleValue(const LcmStruct& type, int64_t integer, double real) {
  LcmValue value;
  value.kind = LcmValue::Kind::kStruct;
  value.type = &type;
  for (const LcmField& field : type.fields) {
    // Size fields stay 1, whatever the other integers are, so the sample encodes.
    bool is_size = false;
    for (const LcmField& other : type.fields) {
      for (const LcmDimension& d : other.dimensions)
        is_size |= d.variable && d.size_field == field.name;
    }
    value.items.push_back(sampleArray(field, 0, is_size ? 1 : integer, real));
  }
  return value;
}

inline const LcmStruct& builtinType(const std::string& name) {
  const LcmStruct* type = builtinLcmTypes().find(name);
  if (type == nullptr) throw std::runtime_error("no built-in LCM type " + name);
  return *type;
}

inline Bytes encodeValue(const LcmValue& value) {
  auto bytes = builtinLcmTypes().encode(value);
  if (!bytes) throw std::runtime_error(bytes.error());
  return *bytes;
}

/// The encoded sample of the type "package.type".
inline Bytes sampleBytes(const std::string& name, int64_t integer = 1, double real = 0.5) {
  return encodeValue(sampleValue(builtinType(name), integer, real));
}

inline void writeBigEndian32(Bytes& bytes, size_t at, uint32_t value) {
  for (int i = 0; i < 4; ++i) {
    bytes[at + static_cast<size_t>(i)] = static_cast<uint8_t>(value >> (24 - 8 * i));
  }
}

/// Counts that break decoders: huge (overflowing 32-bit byte counts), negative, zero.
inline const std::vector<uint32_t>& hostileCounts() {
  static const std::vector<uint32_t> counts = {0x7FFFFFFF, 0x10000001, 0xFFFFFFFF, 0x80000000, 0};
  return counts;
}

/// `count` pairs of messages that no type decodes as `sample`'s: random bytes (up to 300), and
/// random bytes behind `sample`'s fingerprint.
inline std::vector<Bytes> junkMessages(const Bytes& sample, int count, std::mt19937& random) {
  std::vector<Bytes> all;
  for (int i = 0; i < count; ++i) {
    Bytes junk(random() % 300);
    for (uint8_t& b : junk) b = static_cast<uint8_t>(random());
    all.push_back(junk);
    Bytes behind(sample.begin(), sample.begin() + 8);  // a valid fingerprint, then junk
    behind.resize(8 + random() % 300);
    for (size_t b = 8; b < behind.size(); ++b) behind[b] = static_cast<uint8_t>(random());
    all.push_back(behind);
  }
  return all;
}

/// Every kind of hostile message for the type "package.type", `random_count` of each random kind.
inline std::vector<Bytes> hostileMessages(const std::string& name, int random_count,
                                          uint32_t seed) {
  const Bytes sample = sampleBytes(name);
  std::vector<Bytes> all;
  for (size_t at = 8; at + 4 <= sample.size(); ++at) {  // each 4-byte window a hostile count
    for (uint32_t count : hostileCounts()) {
      Bytes bytes = sample;
      writeBigEndian32(bytes, at, count);
      all.push_back(std::move(bytes));
    }
  }
  for (size_t size = 0; size < sample.size(); size += 1 + sample.size() / 40) {  // truncations
    all.emplace_back(sample.begin(), sample.begin() + static_cast<long>(size));
  }
  Bytes longer = sample;  // trailing bytes
  longer.push_back(0);
  all.push_back(longer);
  // Numbers no sensor gives: NaN, infinities, huge; integers (times, ids, enums) at the extremes.
  const double inf = std::numeric_limits<double>::infinity();
  for (double real : {std::nan(""), inf, -inf, 1e300, -1e300}) {
    all.push_back(sampleBytes(name, 1, real));
  }
  for (int64_t integer : {INT64_MAX, INT64_MIN, int64_t{-1}, int64_t{1'000'000'000'000}}) {
    all.push_back(sampleBytes(name, integer, 0.5));
  }
  std::mt19937 random(seed);
  for (Bytes& junk : junkMessages(sample, random_count, random)) all.push_back(std::move(junk));
  return all;
}

}  // namespace thicket::fuzz

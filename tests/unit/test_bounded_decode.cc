// Decoding untrusted bytes: decodeMessage checks every message against the built-in schema before
// LCM's generated decoder sees it, so no message makes a subscriber allocate in proportion to the
// sizes it claims, read past its bytes, or throw. Every type is fuzzed: each 4-byte window of a
// valid sample overwritten with huge, negative and zero counts, every truncation, and random bytes
// behind a valid fingerprint. This binary replaces operator new to measure what a decode
// allocates, and refuses any single allocation over 256 MB so a regression fails, not swaps.
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "known_lcm_types.h"
#include "lcm_fuzz.h"
#include "thicket/common/lcm_schema.h"
#include "thicket/common/node.h"

namespace {

std::atomic<uint64_t> g_allocated{0};  // bytes requested since the last reset
constexpr size_t kRefusedAllocation = size_t{256} << 20;

void* allocate(size_t size) {
  if (size > kRefusedAllocation) throw std::bad_alloc();
  g_allocated += size;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(size_t size) {
  return allocate(size);
}
void* operator new[](size_t size) {
  return allocate(size);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t) noexcept {
  std::free(p);
}

namespace thicket {
namespace {

using fuzz::sampleBytes;
using fuzz::writeBigEndian32;

// What one decode did: its error (empty when accepted) and the bytes it allocated.
struct Outcome {
  std::string error;
  uint64_t allocated = 0;
  bool threw = false;
};

template <class Msg>
Outcome decodeCounting(const std::vector<uint8_t>& bytes) {
  Outcome outcome;
  builtinLcmTypes();  // parsed once per process, not per message
  const uint64_t before = g_allocated;
  try {
    Msg msg;
    outcome.error = decodeMessage(bytes.data(), bytes.size(), msg);
  } catch (const std::exception& e) {
    outcome.threw = true;
    outcome.error = e.what();
  }
  outcome.allocated = g_allocated - before;
  return outcome;
}

// A decode of `size` bytes may allocate a container per byte and the bytes themselves, plus the
// refusal's text: never what the message claims.
uint64_t allocationBound(size_t size) {
  return 64 * static_cast<uint64_t>(size) + (64u << 10);
}

template <class Msg>
void fuzzType(const char* name) {
  SCOPED_TRACE(name);
  const std::vector<uint8_t> sample = sampleBytes(name);
  // The schema and the generated code agree on a valid message.
  const Outcome valid = decodeCounting<Msg>(sample);
  ASSERT_EQ(valid.error, "");

  int refused = 0;
  const auto expectSafe = [&](const std::vector<uint8_t>& bytes, const std::string& what) {
    const Outcome outcome = decodeCounting<Msg>(bytes);
    EXPECT_FALSE(outcome.threw) << what << ": " << outcome.error;
    EXPECT_LE(outcome.allocated, allocationBound(bytes.size())) << what << ": " << outcome.error;
    // The check refuses whatever the generated decoder would: it never gets to refuse itself.
    EXPECT_EQ(outcome.error.find("generated decoder"), std::string::npos) << what;
    if (!outcome.error.empty()) ++refused;
  };

  const std::vector<fuzz::Bytes> hostile = fuzz::hostileMessages(name, 300, 7);
  for (size_t i = 0; i < hostile.size(); ++i)
    expectSafe(hostile[i], "message " + std::to_string(i));
  for (size_t size = 0; size < sample.size(); ++size) {
    const std::vector<uint8_t> cut(sample.begin(), sample.begin() + static_cast<long>(size));
    const Outcome outcome = decodeCounting<Msg>(cut);
    EXPECT_NE(outcome.error, "") << "cut to " << size << " bytes";
    EXPECT_FALSE(outcome.threw);
  }
  std::vector<uint8_t> longer = sample;
  longer.push_back(0);
  EXPECT_NE(decodeCounting<Msg>(longer).error.find("1 unexpected bytes"), std::string::npos);
  EXPECT_GT(refused, 0);
}

TEST(BoundedDecode, EveryTypeSurvivesHugeCountsTruncationAndJunk) {
  int types = 0;
#define THICKET_FUZZ_TYPE(Cpp, name) \
  fuzzType<Cpp>(name);               \
  ++types;
  THICKET_KNOWN_LCM_TYPES(THICKET_FUZZ_TYPE)
#undef THICKET_FUZZ_TYPE
  EXPECT_EQ(static_cast<size_t>(types), builtinLcmTypes().types().size());
}

TEST(BoundedDecode, ATrajectoryClaimingTwoHundredMillionSegmentsIsRefusedNamingTheField) {
  // The packet that crashed the simulator: num_segments 2^28 + 1 makes LCM 1.3.1's int byte count
  // overflow to 8, so its length check passes and it reads 2 GiB past the buffer.
  thicket::polynomial_trajectory_t trajectory{};
  std::vector<uint8_t> bytes(static_cast<size_t>(trajectory.getEncodedSize()));
  trajectory.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const LcmStruct* type = builtinLcmTypes().find("thicket.polynomial_trajectory_t");
  ASSERT_NE(type, nullptr);
  size_t offset = 8;  // the size field's offset: the encoded fields before it
  for (const LcmField& field : type->fields) {
    if (field.name == "num_segments") break;
    ASSERT_TRUE(field.is_primitive && field.dimensions.empty()) << field.name;
    offset += field.primitive == Primitive::kInt64 || field.primitive == Primitive::kDouble  ? 8
              : field.primitive == Primitive::kInt32 || field.primitive == Primitive::kFloat ? 4
                                                                                             : 1;
  }
  writeBigEndian32(bytes, offset, (1u << 28) + 1);
  bytes.resize(49, 0);
  const Outcome outcome = decodeCounting<thicket::polynomial_trajectory_t>(bytes);
  EXPECT_NE(outcome.error.find("size 268435457 (num_segments) exceeds the"), std::string::npos)
      << outcome.error;
  EXPECT_LE(outcome.allocated, allocationBound(bytes.size()));
}

TEST(BoundedDecode, ADepthImageClaimingTwoGigabytesAllocatesNothingOfIt) {
  thicket::depth_image_t image{};
  image.size = 0;
  std::vector<uint8_t> bytes(static_cast<size_t>(image.getEncodedSize()));
  image.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  // size is the last integer before the (empty) data: the final 4 bytes.
  writeBigEndian32(bytes, bytes.size() - 4, 0x7FFFFFFF);
  const Outcome outcome = decodeCounting<thicket::depth_image_t>(bytes);
  EXPECT_NE(outcome.error.find("size 2147483647 (size) exceeds the 0 bytes left"),
            std::string::npos)
      << outcome.error;
  EXPECT_LT(outcome.allocated, 64u << 10);
}

TEST(BoundedDecode, AnEmptyStringLengthIsRefusedNotThrown) {
  // LCM's string decoder assigns length - 1 characters: 0 wraps to SIZE_MAX and throws.
  std::vector<uint8_t> bytes = sampleBytes("thicket.planner_status_t");
  const LcmStruct* type = builtinLcmTypes().find("thicket.planner_status_t");
  bool has_string = false;
  for (const LcmField& field : type->fields) has_string |= field.primitive == Primitive::kString;
  ASSERT_TRUE(has_string);
  int refused_as_empty = 0;
  for (size_t at = 8; at + 4 <= bytes.size(); ++at) {
    std::vector<uint8_t> damaged = bytes;
    writeBigEndian32(damaged, at, 0);
    const Outcome outcome = decodeCounting<thicket::planner_status_t>(damaged);
    EXPECT_FALSE(outcome.threw) << outcome.error;
    if (outcome.error.find("string length 0 (at least 1: the NUL)") != std::string::npos) {
      ++refused_as_empty;
    }
  }
  EXPECT_GT(refused_as_empty, 0);
}

}  // namespace
}  // namespace thicket

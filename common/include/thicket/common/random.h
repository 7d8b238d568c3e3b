// Seeding (docs/design.md §2, determinism): every random draw is seeded from the configuration and
// the message being answered, so the same inputs give the same outputs in any process layout.
#pragma once

#include <cstdint>

namespace thicket {

/// A seed for the draws answering `salt` (a cycle, a trial) under the configured `seed`: the
/// splitmix64 finalizer of the pair, so neighbouring salts get unrelated streams.
inline uint64_t mixSeed(int64_t seed, int64_t salt) {
  uint64_t z = static_cast<uint64_t>(seed) * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(salt);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace thicket

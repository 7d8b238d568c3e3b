// zstd compression of message payloads (depth images, map blocks), in one place.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket {

/// The zstd frame of raw, recording its content size and a checksum of the content. Throws
/// std::runtime_error if zstd fails, which only happens when memory runs out.
std::vector<uint8_t> zstdCompress(std::span<const uint8_t> raw, int level = 1);

/// The content of one zstd frame that must hold exactly expected_size bytes; anything else (no
/// valid frame, another size, corrupt data, a checksum mismatch) is refused with the reason.
Expected<std::vector<uint8_t>> zstdDecompress(std::span<const uint8_t> frame, size_t expected_size);

}  // namespace thicket

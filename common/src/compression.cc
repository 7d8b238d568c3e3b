#include "thicket/common/compression.h"

#include <memory>
#include <stdexcept>
#include <string>

#include <zstd.h>

namespace thicket {

namespace {

// One compression and one decompression context per thread, kept: creating a context allocates
// and clears its tables, which costs more than compressing a 16^3 map block. Each call sets every
// parameter it depends on, so nothing carries over from the previous frame.
template <class Context, Context* (*create)(), size_t (*destroy)(Context*)>
Context* threadContext() {
  thread_local const std::unique_ptr<Context, size_t (*)(Context*)> context(create(), destroy);
  if (!context) throw std::runtime_error("zstd: out of memory");
  return context.get();
}

}  // namespace

std::vector<uint8_t> zstdCompress(std::span<const uint8_t> raw, int level) {
  // The frame carries a checksum of its content, so that decompression catches corruption
  // (a flipped byte in a map file) instead of returning wrong voxels.
  ZSTD_CCtx* context = threadContext<ZSTD_CCtx, ZSTD_createCCtx, ZSTD_freeCCtx>();
  ZSTD_CCtx_reset(context, ZSTD_reset_session_and_parameters);
  ZSTD_CCtx_setParameter(context, ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(context, ZSTD_c_checksumFlag, 1);
  std::vector<uint8_t> frame(ZSTD_compressBound(raw.size()));
  const size_t size = ZSTD_compress2(context, frame.data(), frame.size(), raw.data(), raw.size());
  if (ZSTD_isError(size)) throw std::runtime_error(ZSTD_getErrorName(size));
  frame.resize(size);
  return frame;
}

Expected<std::vector<uint8_t>> zstdDecompress(std::span<const uint8_t> frame,
                                              size_t expected_size) {
  const unsigned long long content = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (content != expected_size) {
    return unexpected("zstd payload holds " +
                      (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN
                           ? std::string("no valid frame")
                           : std::to_string(content) + " bytes") +
                      ", expected " + std::to_string(expected_size));
  }
  std::vector<uint8_t> raw(expected_size);
  const size_t size =
      ZSTD_decompressDCtx(threadContext<ZSTD_DCtx, ZSTD_createDCtx, ZSTD_freeDCtx>(), raw.data(),
                          raw.size(), frame.data(), frame.size());
  if (ZSTD_isError(size) || size != expected_size) {
    return unexpected(std::string("zstd payload does not decompress: ") +
                      (ZSTD_isError(size) ? ZSTD_getErrorName(size) : "short"));
  }
  return raw;
}

}  // namespace thicket

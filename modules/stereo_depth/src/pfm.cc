// PFM: a text header "Pf\n<width> <height>\n<scale>\n" (a negative scale means little-endian),
// then float32 rows from the bottom of the image to the top.
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "thicket/stereo_depth/image.h"

namespace thicket::stereo_depth {
namespace {

uint32_t byteSwap(uint32_t x) {
  return (x >> 24) | ((x >> 8) & 0xff00u) | ((x << 8) & 0xff0000u) | (x << 24);
}

}  // namespace

std::string writePfm(const std::string& path, int width, int height,
                     const std::vector<float>& values) {
  if (width < 1 || height < 1 || values.size() != static_cast<size_t>(width) * height) {
    return "cannot write " + path + ": the image has the wrong size";
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) return "cannot write " + path;
  const bool little = std::endian::native == std::endian::little;
  out << "Pf\n" << width << " " << height << "\n" << (little ? "-1.0" : "1.0") << "\n";
  for (int v = height - 1; v >= 0; --v) {
    out.write(reinterpret_cast<const char*>(values.data() + static_cast<size_t>(v) * width),
              static_cast<std::streamsize>(sizeof(float) * static_cast<size_t>(width)));
  }
  out.close();
  if (!out) return "cannot write " + path;
  return {};
}

Expected<PfmImage> readPfm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return unexpected(path + ": cannot read");
  std::string magic;
  in >> magic;
  if (magic == "PF") return unexpected(path + ": a colour PFM; expected one channel (Pf)");
  if (magic != "Pf") return unexpected(path + ": not a PFM file");
  long long width = 0, height = 0;
  double scale = 0;
  in >> width >> height >> scale;
  if (!in || width < 1 || height < 1 || width > kMaxImageSide || height > kMaxImageSide ||
      !std::isfinite(scale) || scale == 0) {
    return unexpected(path + ": bad PFM header");
  }
  in.get();  // the single whitespace character after the scale
  const bool file_little = scale < 0;
  const bool swap = file_little != (std::endian::native == std::endian::little);
  PfmImage image;
  image.width = static_cast<int>(width);
  image.height = static_cast<int>(height);
  image.values.resize(static_cast<size_t>(width * height));
  for (long long v = height - 1; v >= 0; --v) {
    float* row = image.values.data() + static_cast<size_t>(v * width);
    in.read(reinterpret_cast<char*>(row), static_cast<std::streamsize>(sizeof(float) * width));
    if (!in) return unexpected(path + ": truncated PFM data");
    if (swap) {
      for (long long u = 0; u < width; ++u) {
        uint32_t bits;
        std::memcpy(&bits, row + u, 4);
        bits = byteSwap(bits);
        std::memcpy(row + u, &bits, 4);
      }
    }
  }
  return image;
}

}  // namespace thicket::stereo_depth

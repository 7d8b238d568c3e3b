// The stereo pair's procedural surface texture (mip-mapped value noise) and surfaceIntensity.
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "pseudo_angle.h"
#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

using Surface = SurfaceHit::Surface;
using std::numbers::pi;

// The texture is one periodic tile of value noise that every surface shows at its own offset:
// 2^kTileBits texels of 1 / kTexelsPerMetre square (10.24 m), the sum of seven octaves whose
// lattice cells measure 2 texels (2 cm) up to 128 texels (1.28 m). Coarse octaves vary the
// brightness of a surface, fine ones give the pixel-scale detail a matcher needs. Box-filtered mip
// levels, sampled trilinearly as a GPU does, low-pass it to a pixel's footprint: eight texel reads
// per pixel, near each other for neighbouring pixels. The tile repeats every 10.24 m on a surface,
// at least 36 times the disparity at any range (fx * 10.24 m / z against fx * 0.11 m / z), so a
// matcher never confuses a point with its repeat.
constexpr int kTileBits = 10;
constexpr int kTileTexels = 1 << kTileBits;
constexpr double kTexelsPerMetre = 100;
constexpr int kOctaves = 7;
constexpr int kLevels = kTileBits + 1;  // 1024 x 1024 texels down to 1 x 1
// Texel coordinates are shifted by this multiple of the tile at every level, so that they are
// positive for surfaces within 160 km of the origin and truncation floors them.
constexpr double kTexelShift = 1 << 24;
// Gray levels per unit of noise: a forest image has a standard deviation of about 30 gray
// levels, and under 0.1 % of its pixels saturate.
constexpr double kContrast = 60;

inline uint32_t hash32(uint32_t h) {  // "lowbias32" (C. Wellons): an avalanching 32-bit mix
  h ^= h >> 16;
  h *= 0x7feb352dU;
  h ^= h >> 15;
  h *= 0x846ca68bU;
  h ^= h >> 16;
  return h;
}

inline double smoothStep(double t) {
  return t * t * (3.0 - 2.0 * t);
}

class TextureTile {
 public:
  static const TextureTile& instance() {
    static const TextureTile tile;
    return tile;
  }

  // The noise (mean about 0, within +-3.5) around level-0 texel coordinates (x, y), filtered to
  // a footprint of footprint_texels: level log2(footprint_texels), linearly between levels.
  double sample(double x, double y, double footprint_texels) const {
    x += kTexelShift;
    y += kTexelShift;
    if (!(footprint_texels > 1)) return bilinear(0, x, y);
    // log2 by the exponent and a linear mantissa: exact at powers of two, monotonic between.
    const uint64_t bits = std::bit_cast<uint64_t>(footprint_texels);
    const int level = static_cast<int>(bits >> 52) - 1023;
    if (level >= kLevels - 1) return bilinear(kLevels - 1, x, y);
    const double blend = static_cast<double>(bits & ((uint64_t{1} << 52) - 1)) * 0x1.0p-52;
    const double fine = bilinear(level, x, y);
    return fine + blend * (bilinear(level + 1, x, y) - fine);
  }

 private:
  TextureTile() {
    std::vector<float>& base = levels_[0];
    base.assign(size_t{1} << (2 * kTileBits), 0.0f);
    std::vector<double> lattice;
    for (int octave = 0; octave < kOctaves; ++octave) {
      const int cell = 2 << octave;  // texels
      const int cells = kTileTexels / cell;
      lattice.resize(static_cast<size_t>(cells) * cells);
      for (int cy = 0; cy < cells; ++cy) {
        for (int cx = 0; cx < cells; ++cx) {
          const uint32_t key = static_cast<uint32_t>((octave << 20) | (cy << 10) | cx);
          lattice[static_cast<size_t>(cy) * cells + cx] = hash32(key) * 0x1.0p-32 - 0.5;
        }
      }
      const auto at = [&](int cx, int cy) {
        return lattice[static_cast<size_t>(cy % cells) * cells + cx % cells];
      };
      for (int y = 0; y < kTileTexels; ++y) {
        const double fy = (y + 0.5) / cell;
        const int cy = static_cast<int>(fy);
        const double ty = smoothStep(fy - cy);
        for (int x = 0; x < kTileTexels; ++x) {
          const double fx = (x + 0.5) / cell;
          const int cx = static_cast<int>(fx);
          const double tx = smoothStep(fx - cx);
          const double bottom = at(cx, cy) + tx * (at(cx + 1, cy) - at(cx, cy));
          const double top = at(cx, cy + 1) + tx * (at(cx + 1, cy + 1) - at(cx, cy + 1));
          base[texelIndex(kTileBits, x, y)] += static_cast<float>(bottom + ty * (top - bottom));
        }
      }
    }
    for (int level = 1; level < kLevels; ++level) {
      const std::vector<float>& fine = levels_[level - 1];
      const int size = kTileTexels >> level;
      std::vector<float>& coarse = levels_[level];
      coarse.resize(static_cast<size_t>(size) * size);
      const int fine_bits = kTileBits - level + 1;
      for (uint32_t y = 0; y < static_cast<uint32_t>(size); ++y) {
        for (uint32_t x = 0; x < static_cast<uint32_t>(size); ++x) {
          coarse[texelIndex(fine_bits - 1, x, y)] =
              0.25f * (fine[texelIndex(fine_bits, 2 * x, 2 * y)] +
                       fine[texelIndex(fine_bits, 2 * x + 1, 2 * y)] +
                       fine[texelIndex(fine_bits, 2 * x, 2 * y + 1)] +
                       fine[texelIndex(fine_bits, 2 * x + 1, 2 * y + 1)]);
        }
      }
    }
  }

  // Where texel (x, y) of a level 2^bits texels square is stored: in blocks of 4 x 4 texels,
  // one cache line of floats, so that walking the texture along a row or a column (an image
  // column may run either way on a surface) reads a new line every four texels, not every one.
  static size_t texelIndex(int bits, uint32_t x, uint32_t y) {
    if (bits < 2) return (static_cast<size_t>(y) << bits) + x;
    const size_t block = (static_cast<size_t>(y >> 2) << (bits - 2)) + (x >> 2);
    return (block << 4) + ((y & 3) << 2) + (x & 3);
  }

  // Bilinear between the texel centres of a level, at shifted level-0 coordinates.
  [[gnu::always_inline]] double bilinear(int level, double x, double y) const {
    const int bits = kTileBits - level;
    const uint32_t mask = (uint32_t{1} << bits) - 1;
    const double scale = kLevelScale[level];
    const double lx = x * scale - 0.5;
    const double ly = y * scale - 0.5;
    const int64_t x0 = static_cast<int64_t>(lx);
    const int64_t y0 = static_cast<int64_t>(ly);
    const double tx = lx - static_cast<double>(x0);
    const double ty = ly - static_cast<double>(y0);
    const uint32_t col0 = static_cast<uint32_t>(x0) & mask;
    const uint32_t col1 = (col0 + 1) & mask;
    const uint32_t row0 = static_cast<uint32_t>(y0) & mask;
    const uint32_t row1 = (row0 + 1) & mask;
    const float* t = levels_[level].data();
    const double t00 = t[texelIndex(bits, col0, row0)];
    const double t10 = t[texelIndex(bits, col1, row0)];
    const double t01 = t[texelIndex(bits, col0, row1)];
    const double t11 = t[texelIndex(bits, col1, row1)];
    const double bottom = t00 + tx * (t10 - t00);
    const double top = t01 + tx * (t11 - t01);
    return bottom + ty * (top - bottom);
  }

  static constexpr std::array<double, kLevels> kLevelScale = [] {
    std::array<double, kLevels> scale{};
    for (int level = 0; level < kLevels; ++level) scale[level] = 1.0 / (1 << level);
    return scale;
  }();

  std::array<std::vector<float>, kLevels> levels_;
};

// A surface point in texture space: level-0 texel coordinates in the tile (surface coordinates
// plus the surface's own offset) and the surface's mean gray level.
struct TexturePoint {
  double x = 0, y = 0;
  double mean = 0;
};

// Surfaces of one kind share a mean gray level; each surface has its own offset in the tile, and
// each cylinder a mean offset of up to +-20 gray levels, so that neighbouring trees differ.
TexturePoint texturePoint(const SurfaceHit& hit, const std::vector<Cylinder>& cylinders) {
  const Eigen::Vector3d& p = hit.point;
  const uint32_t seed =
      hash32((static_cast<uint32_t>(hit.surface) << 24) ^ static_cast<uint32_t>(hit.index));
  const double mean_offset = (seed >> 24) * (40.0 / 255.0) - 20.0;
  const auto point = [seed](double s, double w, double mean) {
    return TexturePoint{s * kTexelsPerMetre + (seed & (kTileTexels - 1)),
                        w * kTexelsPerMetre + ((seed >> kTileBits) & (kTileTexels - 1)), mean};
  };
  switch (hit.surface) {
    case Surface::kGround:
      return point(p.x(), p.y(), 105);
    case Surface::kWall:
      return point(hit.index < 2 ? p.y() : p.x(), p.z(), 150);
    case Surface::kCylinderCap:
      return point(p.x(), p.y(), 140 + mean_offset);
    case Surface::kCylinderSide: {
      // Around the trunk: pseudoAngle scaled to the circumference, 0.79-1.57 times the arc
      // length and much cheaper than atan2. The texture has a seam where it wraps (on the +x
      // side), like a crack in the bark: both cameras see it alike.
      const Cylinder& c = cylinders[hit.index];
      const double dx = p.x() - c.x;
      const double dy = p.y() - c.y;
      const double quarter_turns = (dx == 0 && dy == 0) ? 0 : pseudoAngle(dx, dy);
      return point(quarter_turns * (0.5 * pi * c.radius), p.z(), 85 + mean_offset);
    }
    case Surface::kNone:
      break;
  }
  throw std::invalid_argument("surfaceIntensity: the hit has no surface");
}

}  // namespace

double StereoRenderer::surfaceIntensity(const SurfaceHit& hit, double footprint_m) const {
  const TexturePoint point = texturePoint(hit, cylinders_);
  return point.mean + kContrast * TextureTile::instance().sample(point.x, point.y,
                                                                 footprint_m * kTexelsPerMetre);
}

}  // namespace thicket::sim

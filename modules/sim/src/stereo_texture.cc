// The stereo pair's procedural surface texture (mip-mapped value noise), surfaceIntensity and the
// shading of rendered pixels (StereoRenderer::shadeLine).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <span>
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
// levels low-pass it to a pixel's footprint, sampled as a GPU does with "brilinear" filtering
// (see TextureTile::sample): four texel reads for most pixels, eight for the others, near each
// other for neighbouring pixels. The tile repeats every 10.24 m on a surface,
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
// Texels hold the texture's gray level offset (kContrast * noise) as int16_t in steps of
// 1 / kTexelStepsPerGray gray levels, rounded to the nearest: a texel is within 1/128 gray level
// of the exact (float) mip level, and so is any interpolation of texels; half the memory of
// floats. The noise is within +-3.5 (seven octaves of +-0.5), so no texel clips.
using Texel = int16_t;
constexpr float kTexelStepsPerGray = 64;
static_assert(kContrast * 0.5 * kOctaves * kTexelStepsPerGray < 32767);
// Texels are stored in blocks of 2^kBlockBits texels square (see TextureTile::columnIndex).
constexpr int kBlockBits = 2;
constexpr uint32_t kBlock = 1u << kBlockBits;
// Texture coordinates in fixed point, kFractionBits below a level-0 texel: interpolation weights
// in steps of 1/65536, far below what an 8-bit pixel resolves.
constexpr int kFractionBits = 16;
constexpr uint32_t kFractionMask = (uint32_t{1} << kFractionBits) - 1;

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

  // The gray level offset (mean about 0, within +-210) around level-0 texel coordinates (x, y),
  // filtered to a footprint whose square is footprint_sq texels^2: about level log2(footprint).
  [[gnu::always_inline]] float sample(double x, double y, double footprint_sq) const {
    // Fixed point, modulo 2^32: a multiple of the tile's period at every level.
    const auto fixed = [](double c) {
      return static_cast<uint32_t>(static_cast<int64_t>((c + kTexelShift) * (1 << kFractionBits)));
    };
    const uint32_t fx = fixed(x);
    const uint32_t fy = fixed(y);
    if (!(footprint_sq > 1)) return bilinear(0, fx, fy);
    // log2 of the footprint as half that of its square, by the exponent and a linear mantissa:
    // exact at powers of two, continuous and monotonic between.
    const uint64_t bits = std::bit_cast<uint64_t>(footprint_sq);
    const int exponent = static_cast<int>(bits >> 52) - 1023;
    const int level = exponent >> 1;
    if (level >= kLevels - 1) return bilinear(kLevels - 1, fx, fy);
    const float mantissa = static_cast<float>(bits & ((uint64_t{1} << 52) - 1)) * 0x1.0p-52f;
    const float between = 0.5f * (mantissa + static_cast<float>(exponent & 1));
    // "Brilinear": linear between the two levels (trilinear) only in the middle quarter of the
    // octave between them, the nearer level alone elsewhere, so that most pixels read one level
    // (texels within about 2^(3/8) = 1.3 times their footprint) instead of two. Trilinear
    // everywhere takes a fifth longer for stereo depth within half a percentage point of this
    // beyond 5 m and the same nearer; the nearer level alone, without the blend, makes a step
    // where a surface point that the cameras see with slightly different footprints switches
    // level in one image and not in the other (test: TextureChangesSmoothlyWithTheFootprint).
    const float blend = std::clamp(4 * between - 1.5f, 0.0f, 1.0f);
    if (blend == 0) return bilinear(level, fx, fy);
    if (blend == 1) return bilinear(level + 1, fx, fy);
    const float fine = bilinear(level, fx, fy);
    return fine + blend * (bilinear(level + 1, fx, fy) - fine);
  }

 private:
  TextureTile() {
    std::array<std::vector<float>, kLevels> levels;
    std::vector<float>& base = levels[0];
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
          base[static_cast<size_t>(y) * kTileTexels + x] +=
              static_cast<float>(bottom + ty * (top - bottom));
        }
      }
    }
    for (int level = 1; level < kLevels; ++level) {
      const std::vector<float>& fine = levels[level - 1];
      const size_t size = kTileTexels >> level;
      std::vector<float>& coarse = levels[level];
      coarse.resize(size * size);
      for (size_t y = 0; y < size; ++y) {
        for (size_t x = 0; x < size; ++x) {
          coarse[y * size + x] =
              0.25f *
              (fine[2 * y * 2 * size + 2 * x] + fine[2 * y * 2 * size + 2 * x + 1] +
               fine[(2 * y + 1) * 2 * size + 2 * x] + fine[(2 * y + 1) * 2 * size + 2 * x + 1]);
        }
      }
    }
    texels_.resize(kLevelOffset[kLevels]);
    for (int level = 0; level < kLevels; ++level) {
      const int bits = kTileBits - level;
      const uint32_t size = uint32_t{1} << bits;
      for (uint32_t y = 0; y < size; ++y) {
        for (uint32_t x = 0; x < size; ++x) {
          const float gray = static_cast<float>(kContrast) * levels[level][y * size + x];
          texels_[kLevelOffset[level] + texelIndex(bits, x, y)] =
              static_cast<Texel>(std::lround(gray * kTexelStepsPerGray));
        }
      }
    }
  }

  // Where texel (x, y) of a level 2^bits texels square is stored: in blocks of 4 x 4 texels, so
  // that walking the texture along a row or a column (an image column may run either way on a
  // surface) reads a new cache line every four texels at most, not every one; a level smaller
  // than a block takes a whole block. The index is the sum of a column's part and a row's part,
  // so that a 2 x 2 neighbourhood takes two of each.
  static uint32_t columnIndex(uint32_t x) {
    return ((x & ~(kBlock - 1)) << kBlockBits) | (x & (kBlock - 1));
  }
  static uint32_t rowIndex(int bits, uint32_t y) {
    return ((y & ~(kBlock - 1)) << bits) | ((y & (kBlock - 1)) << kBlockBits);
  }
  static size_t texelIndex(int bits, uint32_t x, uint32_t y) {
    return columnIndex(x) + rowIndex(bits, y);
  }

  // Bilinear between the texel centres of a level, at fixed-point level-0 coordinates (fx, fy).
  [[gnu::always_inline]] float bilinear(int level, uint32_t fx, uint32_t fy) const {
    const int bits = kTileBits - level;
    const uint32_t mask = (uint32_t{1} << bits) - 1;
    // Level coordinates, half a texel back so that texel centres fall on whole numbers.
    constexpr uint32_t kHalf = uint32_t{1} << (kFractionBits - 1);
    const uint32_t lx = (fx >> level) - kHalf;
    const uint32_t ly = (fy >> level) - kHalf;
    const uint32_t col0 = (lx >> kFractionBits) & mask;
    const uint32_t col1 = (col0 + 1) & mask;
    const uint32_t row0 = (ly >> kFractionBits) & mask;
    const uint32_t row1 = (row0 + 1) & mask;
    const float tx = static_cast<float>(lx & kFractionMask) * (1.0f / (1 << kFractionBits));
    const float ty = static_cast<float>(ly & kFractionMask) * (1.0f / (1 << kFractionBits));
    const Texel* t = texels_.data() + kLevelOffset[level];
    const uint32_t x0 = columnIndex(col0), x1 = columnIndex(col1);
    const uint32_t y0 = rowIndex(bits, row0), y1 = rowIndex(bits, row1);
    const float t00 = t[x0 + y0];
    const float t10 = t[x1 + y0];
    const float t01 = t[x0 + y1];
    const float t11 = t[x1 + y1];
    const float bottom = t00 + tx * (t10 - t00);
    const float top = t01 + tx * (t11 - t01);
    return (bottom + ty * (top - bottom)) * (1.0f / kTexelStepsPerGray);
  }

  // Where each level starts in texels_, finest first; kLevelOffset[kLevels] is the total.
  static constexpr std::array<size_t, kLevels + 1> kLevelOffset = [] {
    std::array<size_t, kLevels + 1> offset{};
    for (int level = 0; level < kLevels; ++level) {
      offset[level + 1] =
          offset[level] + std::max(size_t{kBlock * kBlock}, size_t{1} << (2 * (kTileBits - level)));
    }
    return offset;
  }();

  std::vector<Texel> texels_;  // every level, finest first
};

// Grazing views stretch a pixel's footprint by 1 / cos(incidence), capped at 1 / this.
constexpr double kMinCosIncidence = 0.05;

// Where a surface point is in the texture: level-0 texel coordinates in the tile (surface
// coordinates plus the surface's own offset), and the surface's mean gray level. For the
// footprint, the surface normal's dot products with the ray (normal_dir) and with the image's x
// axis (normal_right).
struct TexturePoint {
  double x = 0, y = 0;
  double mean = 0;
  double normal_dir = 0, normal_right = 0;
};

// The texture point of a hit, with the normal's dot products with the world-frame unit vectors
// dir and right. Texture is StereoRenderer::SurfaceTexture, which is private to it.
template <class Texture>
[[gnu::always_inline]] inline TexturePoint texturePoint(const SurfaceHit& hit,
                                                        const std::vector<Texture>& textures,
                                                        const Eigen::Vector3d& dir,
                                                        const Eigen::Vector3d& right) {
  const Eigen::Vector3d& p = hit.point;
  const auto point = [](const Texture& t, double s, double w, double n_dir, double n_right) {
    return TexturePoint{s * kTexelsPerMetre + t.offset_x, w * kTexelsPerMetre + t.offset_y, t.mean,
                        n_dir, n_right};
  };
  switch (hit.surface) {
    case Surface::kGround:
      return point(textures[0], p.x(), p.y(), dir.z(), right.z());
    case Surface::kWall: {
      const Texture& t = textures[1 + hit.index];
      return hit.index < 2 ? point(t, p.y(), p.z(), dir.x(), right.x())
                           : point(t, p.x(), p.z(), dir.y(), right.y());
    }
    case Surface::kCylinderCap:
      return point(textures[6 + 2 * hit.index], p.x(), p.y(), dir.z(), right.z());
    case Surface::kCylinderSide: {
      // Around the trunk: pseudoAngle scaled to the circumference, 0.79-1.57 times the arc
      // length and much cheaper than atan2. The texture has a seam where it wraps (on the +x
      // side), like a crack in the bark: both cameras see it alike.
      const Texture& t = textures[5 + 2 * hit.index];
      const double dx = p.x() - t.axis_x;
      const double dy = p.y() - t.axis_y;
      const double quarter_turns = (dx == 0 && dy == 0) ? 0 : pseudoAngle(dx, dy);
      return TexturePoint{quarter_turns * t.texels_per_quarter_turn + t.offset_x,
                          p.z() * kTexelsPerMetre + t.offset_y, t.mean,
                          (dx * dir.x() + dy * dir.y()) * t.inverse_radius,
                          (dx * right.x() + dy * right.y()) * t.inverse_radius};
    }
    case Surface::kNone:
      break;
  }
  throw std::invalid_argument("surfaceIntensity: the hit has no surface");
}

}  // namespace

// Surfaces of one kind share a mean gray level; each surface has its own offset in the tile,
// drawn from its kind and index, and each cylinder a mean offset of up to +-20 gray levels, so
// that neighbouring trees differ.
std::vector<StereoRenderer::SurfaceTexture> StereoRenderer::surfaceTextures(
    const std::vector<Cylinder>& cylinders) {
  const auto texture = [](Surface surface, int index, double mean) {
    const uint32_t seed =
        hash32((static_cast<uint32_t>(surface) << 24) ^ static_cast<uint32_t>(index));
    const double mean_offset = (seed >> 24) * (40.0 / 255.0) - 20.0;
    SurfaceTexture t;
    t.offset_x = seed & (kTileTexels - 1);
    t.offset_y = (seed >> kTileBits) & (kTileTexels - 1);
    t.mean = surface == Surface::kGround || surface == Surface::kWall ? mean : mean + mean_offset;
    return t;
  };
  std::vector<SurfaceTexture> textures;
  textures.reserve(5 + 2 * cylinders.size());
  textures.push_back(texture(Surface::kGround, -1, 105));
  for (int wall = 0; wall < 4; ++wall) textures.push_back(texture(Surface::kWall, wall, 150));
  for (size_t i = 0; i < cylinders.size(); ++i) {
    const Cylinder& c = cylinders[i];
    SurfaceTexture side = texture(Surface::kCylinderSide, static_cast<int>(i), 85);
    side.axis_x = c.x;
    side.axis_y = c.y;
    side.inverse_radius = 1 / c.radius;
    side.texels_per_quarter_turn = 0.5 * pi * c.radius * kTexelsPerMetre;
    textures.push_back(side);
    textures.push_back(texture(Surface::kCylinderCap, static_cast<int>(i), 140));
  }
  return textures;
}

double StereoRenderer::surfaceIntensity(const SurfaceHit& hit, double footprint_m) const {
  const TexturePoint point =
      texturePoint(hit, surface_textures_, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const double footprint_texels = footprint_m * kTexelsPerMetre;
  return point.mean +
         TextureTile::instance().sample(point.x, point.y, footprint_texels * footprint_texels);
}

void StereoRenderer::shadeLine(std::span<const Eigen::Vector3d> dirs,
                               std::span<const double> ranges, std::span<const SurfaceHit> hits,
                               const Eigen::Vector3d& image_right, uint8_t* pixels,
                               size_t stride) const {
  const TextureTile& tile = TextureTile::instance();
  const double texels_per_range = kTexelsPerMetre / camera_.fx;
  for (size_t k = 0; k < ranges.size(); ++k) {
    if (ranges[k] == RayCaster::kNoHit) continue;
    const Eigen::Vector3d& dir = dirs[k];
    const TexturePoint point = texturePoint(hits[k], surface_textures_, dir, image_right);
    // The footprint: one pixel to the right turns the ray by about 1 / fx rad, which moves its
    // hit by about range / fx along image_right, projected onto the surface along the ray: by
    // image_right - dir * q with q = (normal . image_right) / cos(incidence), of squared length
    // 1 + q (q - 2 dir . image_right). Only this footprint is filtered: along a column the two
    // cameras sample the same epipolar plane, so whatever aliasing there is along it, they share.
    const double cos_incidence =
        std::copysign(std::max(std::abs(point.normal_dir), kMinCosIncidence), point.normal_dir);
    const double q = point.normal_right / cos_incidence;
    const double texels = ranges[k] * texels_per_range;
    const double footprint_sq = texels * texels * (1 + q * (q - 2 * dir.dot(image_right)));
    const float gray = static_cast<float>(point.mean) + tile.sample(point.x, point.y, footprint_sq);
    pixels[k * stride] = static_cast<uint8_t>(std::clamp(gray, 0.0f, 255.0f) + 0.5f);
  }
}

}  // namespace thicket::sim

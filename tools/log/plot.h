// `thicket-log plot`: a top-down picture of a simulated mission from its log — the ground-truth
// world (the last SIM_WORLD, which includes a dynamic obstacle once one appeared), the map the
// vehicle built (MAP_ESDF or MAP_TSDF), the flown path (SIM_TRUTH), start, goal, the explorer's
// intermediate goals and any collisions (SIM_EVENT).
//
// The map is the layer's last state: every update of the newest map (map_id) applied in revision
// order, a full snapshot replacing what came before. It is drawn as a max-projection of a
// horizontal band around the flight height: a column is occupied when any observed voxel in the
// band is within one voxel of a surface (or behind one), else free when any is observed, else
// unknown (left blank).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::log {

struct PlotOptions {
  std::string out;             ///< the PNG to write
  int size = 1000;             ///< width and height of the image [px], 400 .. 10000
  std::string layer = "auto";  ///< "esdf", "tsdf", or "auto": ESDF if the log has it, else TSDF
  /// The z band of the map projection [m]; default: the median flown height ± 0.5 m (or the
  /// start's height when there is no path).
  std::optional<double> z_min;
  std::optional<double> z_max;
};

/// An 8-bit RGB colour.
struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

/// The colours of the picture: what the legend shows and what tests look for.
namespace colors {
constexpr Rgb kUnknown{255, 255, 255};
constexpr Rgb kFree{200, 228, 250};
constexpr Rgb kOccupied{70, 70, 80};
constexpr Rgb kObstacle{222, 184, 135};
constexpr Rgb kObstacleEdge{139, 90, 43};
constexpr Rgb kBounds{40, 40, 40};
constexpr Rgb kPath{20, 80, 230};
constexpr Rgb kStart{0, 170, 60};
constexpr Rgb kGoal{150, 20, 190};
constexpr Rgb kExplorerGoal{255, 140, 0};
constexpr Rgb kCollision{230, 0, 0};
}  // namespace colors

/// Where world points land in the image (y up in the world is up in the picture).
struct PlotFrame {
  double pixels_per_metre = 0;
  double origin_column = 0;  ///< image column of world x = 0
  double origin_row = 0;     ///< image row of world y = 0

  double column(double x) const { return origin_column + x * pixels_per_metre; }
  double row(double y) const { return origin_row - y * pixels_per_metre; }
};

struct PlotResult {
  PlotFrame frame;
  std::string map_layer;  ///< "MAP_ESDF", "MAP_TSDF" or empty when no map was drawn
  int64_t map_revision = -1;
  double z_min = 0, z_max = 0;  ///< the projected band [m]
  /// What is missing or could not be used ("no SIM_EVENT: no collisions drawn"), for stderr.
  std::vector<std::string> notes;
};

/// Why the options are invalid, or empty.
std::string validatePlotOptions(const PlotOptions& options);

/// Reads the log and writes the picture. Errors: invalid options, the log cannot be opened, it
/// holds nothing to draw (no SIM_WORLD, no map, no path on SIM_TRUTH or STATE_ESTIMATE), or the
/// PNG cannot be written.
Expected<PlotResult> plotLog(const std::string& log_path, const PlotOptions& options);

}  // namespace thicket::log

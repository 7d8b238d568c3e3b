// `thicket-log plot`: a top-down picture of a simulated mission from its log — the ground-truth
// world (the last SIM_WORLD, which includes a dynamic obstacle once one appeared), the map the
// vehicle built (MAP_ESDF or MAP_TSDF), the flown path (SIM_TRUTH), start, goal, the explorer's
// intermediate goals and any collisions (SIM_EVENT).
//
// The map is the layer's last state: every update of the newest map (map_id) applied in revision
// order, a full snapshot replacing what came before. It is drawn as a max-projection of a
// horizontal band around the flight height: a column is occupied when any observed voxel in the
// band is within one voxel of a surface (or behind one), else free when any is observed, else
// unknown (left blank). This side only extracts; tools/log/plot_mission.py draws with matplotlib,
// as the benchmark's figures are drawn.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <thicket/sim_world_t.hpp>

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

/// What a map column shows: the "highest" class of the observed voxels in the band.
enum class Cell : int8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

/// The top-down projection of a map layer's z band, per voxel column (x, y).
struct MapProjection {
  double voxel_size = 0;
  int64_t revision = -1;
  std::map<std::pair<int, int>, Cell> columns;  ///< unknown columns are absent

  /// The class of the column holding world point (x, y).
  Cell at(double x, double y) const;
};

/// A point of the picture [m]; z is kept for the map band.
struct PlotPoint {
  double x = 0, y = 0, z = 0;
};

/// Everything the picture shows, read from the log.
struct PlotScene {
  std::string title;     ///< the log's file name
  std::string subtitle;  ///< the map layer, its revision and the band
  std::optional<sim_world_t> world;
  std::vector<PlotPoint> path;  ///< non-finite positions (a diverged estimate) left out
  bool path_is_estimate = false;
  std::optional<PlotPoint> start, goal;
  std::vector<PlotPoint> explorer_goals, collisions;
  std::optional<MapProjection> map;
  std::string map_layer;        ///< "MAP_ESDF", "MAP_TSDF" or empty when no map is drawn
  double z_min = 0, z_max = 0;  ///< the projected band [m]
  /// What is missing or could not be used ("no SIM_EVENT: no collisions drawn"), for stderr.
  std::vector<std::string> notes;
};

/// Why the options are invalid, or empty.
std::string validatePlotOptions(const PlotOptions& options);

/// Reads what the picture shows from the log. Errors: invalid options, the log cannot be opened,
/// or it holds nothing to draw (no SIM_WORLD, no map, no path on SIM_TRUTH or STATE_ESTIMATE).
Expected<PlotScene> readPlotScene(const std::string& log_path, const PlotOptions& options);

/// The scene as the JSON object plot_mission.py draws (coordinates in metres, map columns as
/// voxel indices).
std::string sceneJson(const PlotScene& scene, int size);

/// Reads the scene and has tools/log/plot_mission.py (matplotlib) draw it into options.out.
/// Errors: those of readPlotScene, or the picture could not be drawn or written.
Expected<PlotScene> plotLog(const std::string& log_path, const PlotOptions& options);

}  // namespace thicket::log

#include "plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <unordered_map>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/sim_event_t.hpp>
#include <thicket/sim_world_t.hpp>

#include "log_events.h"
#include "thicket/common/map_update.h"

namespace thicket::log {
namespace {

// ---- What the picture needs from the log --------------------------------------------------------

struct MissionLog {
  std::string layer;  // PlotOptions::layer
  std::optional<sim_world_t> world;
  std::vector<Eigen::Vector3d> truth;     // SIM_TRUTH positions
  std::vector<Eigen::Vector3d> estimate;  // STATE_ESTIMATE positions: the path without a sim
  std::optional<Eigen::Vector3d> mission_goal;
  std::vector<Eigen::Vector3d> explorer_goals;
  std::vector<Eigen::Vector3d> collisions;
  std::map<std::string, int64_t> messages;  // by channel, of the channels used here
  std::vector<map_update_t> esdf;
  std::vector<map_update_t> tsdf;
  std::map<std::string, int64_t> undecodable;  // by channel
  std::map<std::string, std::string> first_error;
};

Eigen::Vector3d vector3(const double (&v)[3]) {
  return {v[0], v[1], v[2]};
}

template <class Msg>
bool decodeInto(const LogEvent& event, Msg& msg, MissionLog& log) {
  std::string error;
  try {
    error = event.decode(msg);
  } catch (const std::exception& e) {  // a corrupt array length can make the decoder allocate
    error = e.what();
  }
  if (error.empty()) return true;
  if (log.undecodable[event.channel]++ == 0) log.first_error[event.channel] = error;
  return false;
}

// The waypoints of a goal that carries any.
std::vector<Eigen::Vector3d> waypoints(const goal_t& goal) {
  std::vector<Eigen::Vector3d> points;
  if (goal.status != goal_t::STATUS_OK) return points;
  for (const std::vector<double>& w : goal.waypoints) {
    if (w.size() == 3 && Eigen::Vector3d(w[0], w[1], w[2]).allFinite()) {
      points.emplace_back(w[0], w[1], w[2]);
    }
  }
  return points;
}

void collect(const LogEvent& event, MissionLog& log) {
  const std::string& channel = event.channel;
  if (channel == "SIM_WORLD") {
    sim_world_t msg;
    // The last one wins: the simulator publishes the world again when a dynamic obstacle appears.
    if (decodeInto(event, msg, log)) log.world = std::move(msg);
  } else if (channel == "SIM_TRUTH" || channel == "STATE_ESTIMATE") {
    odometry_t msg;
    if (decodeInto(event, msg, log) && vector3(msg.position).allFinite()) {
      (channel == "SIM_TRUTH" ? log.truth : log.estimate).push_back(vector3(msg.position));
    }
  } else if (channel == "MISSION_GOAL" || channel == "EXPLORER_GOAL") {
    goal_t msg;
    if (decodeInto(event, msg, log)) {
      const std::vector<Eigen::Vector3d> points = waypoints(msg);
      if (channel == "EXPLORER_GOAL") {
        log.explorer_goals.insert(log.explorer_goals.end(), points.begin(), points.end());
      } else if (!points.empty()) {
        log.mission_goal = points.back();
      }
    }
  } else if (channel == "SIM_EVENT") {
    sim_event_t msg;
    if (decodeInto(event, msg, log) && msg.type == sim_event_t::TYPE_COLLISION &&
        vector3(msg.position).allFinite()) {
      log.collisions.push_back(vector3(msg.position));
    }
  } else if (channel == "MAP_ESDF" || channel == "MAP_TSDF") {
    // Only the layer to be drawn is kept; with "auto", TSDF updates until the first ESDF one.
    const bool esdf = channel == "MAP_ESDF";
    const bool wanted = esdf ? log.layer != "tsdf"
                             : log.layer == "tsdf" || (log.layer == "auto" && log.esdf.empty());
    map_update_t msg;
    if (wanted && decodeInto(event, msg, log)) {
      if (esdf) log.tsdf.clear();
      (esdf ? log.esdf : log.tsdf).push_back(std::move(msg));
    }
  } else {
    return;
  }
  ++log.messages[channel];
}

// ---- The map ------------------------------------------------------------------------------------

enum class Cell : int8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

Cell classify(const TsdfVoxel& voxel, double voxel_size) {
  if (!(voxel.weight > 0) || std::isnan(voxel.distance)) return Cell::kUnknown;
  return voxel.distance <= voxel_size ? Cell::kOccupied : Cell::kFree;
}

Cell classify(const EsdfVoxel& voxel, double voxel_size) {
  if (!voxel.observed) return Cell::kUnknown;
  return voxel.distance <= voxel_size ? Cell::kOccupied : Cell::kFree;
}

struct ColumnHash {
  size_t operator()(const std::pair<int, int>& c) const {
    return static_cast<size_t>(static_cast<int64_t>(c.first) * 73856093 ^
                               static_cast<int64_t>(c.second) * 19349669);
  }
};

// The top-down projection of a layer's z band: per voxel column, the "highest" class in the band.
struct MapProjection {
  double voxel_size = 0;
  int64_t revision = -1;
  std::unordered_map<std::pair<int, int>, Cell, ColumnHash> columns;
};

// The layer's last state: the updates of its newest map, applied in revision order (a full
// snapshot replaces everything before it), projected over [z_min, z_max].
template <class Voxel>
std::optional<MapProjection> projectMap(std::vector<map_update_t> updates,
                                        const std::string& channel, double z_min, double z_max,
                                        std::vector<std::string>& notes) {
  if (updates.empty()) return std::nullopt;
  const int64_t map_id = updates.back().map_id;
  const auto older =
      std::erase_if(updates, [&](const map_update_t& u) { return u.map_id != map_id; });
  if (older > 0) {
    notes.push_back(channel + ": " + std::to_string(older) +
                    " updates of an earlier map (a mapper restart) left out");
  }
  std::stable_sort(
      updates.begin(), updates.end(),
      [](const map_update_t& a, const map_update_t& b) { return a.revision < b.revision; });
  // The mapper's first frame is revision 1: a log that starts later needs a snapshot.
  if (!updates.front().full_snapshot && updates.front().revision > 1) {
    notes.push_back(channel + ": the log starts at revision " +
                    std::to_string(updates.front().revision) +
                    " without a full snapshot: blocks not updated while recording are missing");
  }

  std::optional<Layer<Voxel>> layer;
  int64_t cleared_revision = -1;
  int64_t refused = 0;
  std::string first_refusal;
  int64_t gaps = 0;
  int64_t first_gap = 0;
  MapProjection projection;
  for (const map_update_t& update : updates) {
    auto part = decodeMapUpdate<Voxel>(update);
    if (part && layer && part->voxel_size != layer->voxelSize()) {
      part = unexpected("voxel size changed within map " + std::to_string(map_id));
    }
    if (!part) {
      if (refused++ == 0) first_refusal = part.error();
      continue;
    }
    if (!layer) layer.emplace(part->voxel_size);
    const int64_t revision = part->revision.revision;
    if (part->revision.full_snapshot && cleared_revision != revision) {
      layer->clear();
      cleared_revision = revision;
    } else if (!part->revision.full_snapshot && projection.revision >= 0 &&
               revision > projection.revision + 1 && gaps++ == 0) {
      first_gap = projection.revision;
    }
    for (auto& block : part->blocks) layer->insertBlock(std::move(block));
    if (!part->revision.full_snapshot) {
      for (const BlockIndex& index : part->removed) layer->removeBlock(index);
    }
    projection.revision = revision;
  }
  if (gaps > 0) {
    notes.push_back(channel + ": " + std::to_string(gaps) + " gaps in the revisions (the first " +
                    "after revision " + std::to_string(first_gap) +
                    "): blocks changed in the missing ones may be stale");
  }
  if (refused > 0) {
    notes.push_back(channel + ": " + std::to_string(refused) + " updates refused (" +
                    first_refusal + ")");
  }
  if (!layer) return std::nullopt;

  projection.voxel_size = layer->voxelSize();
  for (const BlockIndex& index : layer->blockIndices()) {
    const Block<Voxel>& block = *layer->block(index);
    for (int linear = 0; linear < kVoxelsPerBlock; ++linear) {
      const VoxelIndex voxel = voxelOfBlock(index, linear);
      const double z = layer->voxelCenter(voxel).z();
      if (z < z_min || z > z_max) continue;
      const Cell cell = classify(block.voxels[linear], layer->voxelSize());
      if (cell == Cell::kUnknown) continue;
      Cell& column = projection.columns[{voxel.x(), voxel.y()}];
      column = std::max(column, cell);
    }
  }
  return projection;
}

// ---- Drawing ------------------------------------------------------------------------------------

constexpr int kShift = 4;  // sub-pixel bits of OpenCV drawing coordinates
constexpr double kSubPixel = 1 << kShift;

cv::Scalar bgr(const Rgb& c) {
  return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)};
}

// A pixel coordinate safe to round to int: far-off or non-finite values (a diverged estimate)
// land well outside the image instead of overflowing.
double onCanvas(double pixel) {
  constexpr double kFar = 1e6;
  return std::isfinite(pixel) ? std::clamp(pixel, -kFar, kFar) : kFar;
}

// OpenCV puts pixel k's centre at k; the frame puts it at k + 0.5.
cv::Point subPixel(double column, double row) {
  return {static_cast<int>(std::lround((onCanvas(column) - 0.5) * kSubPixel)),
          static_cast<int>(std::lround((onCanvas(row) - 0.5) * kSubPixel))};
}

struct Canvas {
  cv::Mat image;
  PlotFrame frame;
  int line = 3;    // path thickness [px]
  int marker = 8;  // marker radius [px]
  double font = 0.5;
  int text = 1;  // text thickness
  int text_height = 10;
  int row_height = 20;  // of the legend

  cv::Size textSize(const std::string& s) const {
    int baseline = 0;
    return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, font, text, &baseline);
  }
  void put(const std::string& s, int x, int y) {
    cv::putText(image, s, {x, y + text_height / 2}, cv::FONT_HERSHEY_SIMPLEX, font,
                cv::Scalar(0, 0, 0), text, cv::LINE_AA);
  }

  cv::Point at(const Eigen::Vector3d& p) const { return at(p.x(), p.y()); }
  cv::Point at(double x, double y) const { return subPixel(frame.column(x), frame.row(y)); }
  int length(double metres) const {
    return static_cast<int>(
        std::lround(std::max(0.0, onCanvas(metres * frame.pixels_per_metre)) * kSubPixel));
  }
};

void fillRect(cv::Mat& image, double c0, double r0, double c1, double r1, const Rgb& color) {
  c0 = onCanvas(c0), r0 = onCanvas(r0), c1 = onCanvas(c1), r1 = onCanvas(r1);
  const int x0 = static_cast<int>(std::lround(std::min(c0, c1)));
  const int y0 = static_cast<int>(std::lround(std::min(r0, r1)));
  const int x1 = std::max(x0 + 1, static_cast<int>(std::lround(std::max(c0, c1))));
  const int y1 = std::max(y0 + 1, static_cast<int>(std::lround(std::max(r0, r1))));
  const cv::Rect rect = cv::Rect(x0, y0, x1 - x0, y1 - y0) & cv::Rect(0, 0, image.cols, image.rows);
  if (rect.area() > 0) image(rect).setTo(bgr(color));
}

void drawColumns(Canvas& canvas, const MapProjection& map, Cell which, const Rgb& color) {
  for (const auto& [column, cell] : map.columns) {
    if (cell != which) continue;
    const double x = column.first * map.voxel_size;
    const double y = column.second * map.voxel_size;
    fillRect(canvas.image, canvas.frame.column(x), canvas.frame.row(y),
             canvas.frame.column(x + map.voxel_size), canvas.frame.row(y + map.voxel_size), color);
  }
}

void drawDisc(cv::Mat& image, cv::Point centre, int radius, const Rgb& fill, int edge) {
  cv::circle(image, centre, radius * static_cast<int>(kSubPixel), bgr(fill), cv::FILLED,
             cv::LINE_AA, kShift);
  cv::circle(image, centre, radius * static_cast<int>(kSubPixel), cv::Scalar(0, 0, 0), edge,
             cv::LINE_AA, kShift);
}

void drawPolygon(cv::Mat& image, cv::Point centre, int radius, const std::vector<cv::Point2d>& unit,
                 const Rgb& fill) {
  std::vector<cv::Point> points;
  for (const cv::Point2d& u : unit) {
    points.emplace_back(centre.x + static_cast<int>(std::lround(u.x * radius * kSubPixel)),
                        centre.y + static_cast<int>(std::lround(u.y * radius * kSubPixel)));
  }
  cv::fillConvexPoly(image, points, bgr(fill), cv::LINE_AA, kShift);
  cv::polylines(image, points, true, cv::Scalar(0, 0, 0), 1, cv::LINE_AA, kShift);
}

const std::vector<cv::Point2d> kDiamond = {{0, -1.3}, {1.1, 0}, {0, 1.3}, {-1.1, 0}};
const std::vector<cv::Point2d> kTriangle = {{0, -1}, {0.95, 0.8}, {-0.95, 0.8}};

void drawCross(cv::Mat& image, cv::Point centre, int radius, const Rgb& color, int thickness) {
  const int r = radius * static_cast<int>(kSubPixel);
  cv::line(image, centre + cv::Point(-r, -r), centre + cv::Point(r, r), bgr(color), thickness,
           cv::LINE_AA, kShift);
  cv::line(image, centre + cv::Point(-r, r), centre + cv::Point(r, -r), bgr(color), thickness,
           cv::LINE_AA, kShift);
}

// Where the vehicle was last: a ring in the path's colour.
void drawEnd(Canvas& canvas, cv::Point centre) {
  const int radius = canvas.marker * static_cast<int>(kSubPixel) * 2 / 3;
  cv::circle(canvas.image, centre, radius, bgr(colors::kUnknown), cv::FILLED, cv::LINE_AA, kShift);
  cv::circle(canvas.image, centre, radius, bgr(colors::kPath), std::max(2, canvas.line - 1),
             cv::LINE_AA, kShift);
}

enum class Swatch {
  kArea,
  kCylinder,
  kBounds,
  kPath,
  kEnd,
  kStart,
  kGoal,
  kExplorerGoal,
  kCollision
};

struct LegendItem {
  Swatch swatch;
  std::string label;
  Rgb fill{};  // of a kArea swatch
};

void drawSwatch(Canvas& canvas, Swatch swatch, cv::Point centre, int half) {
  cv::Mat& image = canvas.image;
  const int s = static_cast<int>(kSubPixel);
  const cv::Point corner(half * s, half * s);
  switch (swatch) {
    case Swatch::kArea:
      break;  // filled by the caller, who knows the colour
    case Swatch::kCylinder:
      cv::circle(image, centre, half * s, bgr(colors::kObstacle), cv::FILLED, cv::LINE_AA, kShift);
      cv::circle(image, centre, half * s, bgr(colors::kObstacleEdge), 2, cv::LINE_AA, kShift);
      break;
    case Swatch::kBounds:
      cv::rectangle(image, centre - corner, centre + corner, bgr(colors::kBounds), 2, cv::LINE_8,
                    kShift);
      break;
    case Swatch::kPath:
      cv::line(image, centre - cv::Point(half * s * 3 / 2, 0),
               centre + cv::Point(half * s * 3 / 2, 0), bgr(colors::kPath), canvas.line,
               cv::LINE_AA, kShift);
      break;
    case Swatch::kEnd:
      drawEnd(canvas, centre);
      break;
    case Swatch::kStart:
      drawDisc(image, centre, canvas.marker, colors::kStart, 1);
      break;
    case Swatch::kGoal:
      drawPolygon(image, centre, canvas.marker, kDiamond, colors::kGoal);
      break;
    case Swatch::kExplorerGoal:
      drawPolygon(image, centre, canvas.marker, kTriangle, colors::kExplorerGoal);
      break;
    case Swatch::kCollision:
      drawCross(image, centre, canvas.marker, colors::kCollision, canvas.line);
      break;
  }
}

// 1, 2 or 5 times a power of ten, at most `limit`.
double niceLength(double limit) {
  const double power = std::pow(10.0, std::floor(std::log10(limit)));
  for (const double m : {5.0, 2.0, 1.0}) {
    if (m * power <= limit) return m * power;
  }
  return power;
}

// The legend strip from row `top` down: the title (shortened from the front of the file name to
// fit) and the scale bar, then the items on a grid.
void drawLegend(Canvas& canvas, const std::vector<LegendItem>& legend, const std::string& name,
                const std::string& subtitle, int top, int per_row, int margin) {
  cv::Mat& image = canvas.image;
  const int size = image.cols;
  cv::line(image, {0, top}, {size - 1, top}, cv::Scalar(160, 160, 160), 1);
  const int y = top + canvas.row_height / 2 + margin / 2;

  const double plot_width = size - 2.0 * margin;
  const double bar_metres = niceLength(0.2 * plot_width / canvas.frame.pixels_per_metre);
  const int bar_pixels = static_cast<int>(std::lround(bar_metres * canvas.frame.pixels_per_metre));
  char bar_label[32];
  std::snprintf(bar_label, sizeof(bar_label), "%g m", bar_metres);
  const int bar_right = size - margin - canvas.textSize(bar_label).width - margin / 2;
  const int bar_left = bar_right - bar_pixels;
  const cv::Scalar black(0, 0, 0);
  const int tick = canvas.marker / 2;
  cv::line(image, {bar_left, y}, {bar_right, y}, black, canvas.text + 1);
  cv::line(image, {bar_left, y - tick}, {bar_left, y + tick}, black, canvas.text + 1);
  cv::line(image, {bar_right, y - tick}, {bar_right, y + tick}, black, canvas.text + 1);
  canvas.put(bar_label, bar_right + margin / 2, y);

  std::string title = name + subtitle;
  for (size_t cut = 1; cut <= name.size() && canvas.textSize(title).width > bar_left - 2 * margin;
       ++cut) {
    title = "..." + name.substr(cut) + subtitle;
  }
  canvas.put(title, margin, y);

  const int column_width = (size - 2 * margin) / per_row;
  const int half = std::max(4, canvas.row_height / 3);
  for (size_t i = 0; i < legend.size(); ++i) {
    const int x = margin + static_cast<int>(i % per_row) * column_width;
    const int row_y = y + canvas.row_height * (1 + static_cast<int>(i / per_row));
    if (legend[i].swatch == Swatch::kArea) {
      const cv::Rect box(x + half, row_y - half, 2 * half, 2 * half);
      image(box).setTo(bgr(legend[i].fill));
      cv::rectangle(image, box, cv::Scalar(120, 120, 120), 1);
    } else {
      drawSwatch(canvas, legend[i].swatch, subPixel(x + 2 * half + 0.5, row_y + 0.5), half);
    }
    canvas.put(legend[i].label, x + 4 * half, row_y);
  }
}

// Everything the picture shows.
struct Scene {
  std::optional<sim_world_t> world;
  std::vector<Eigen::Vector3d> path;
  bool path_is_estimate = false;
  std::optional<Eigen::Vector3d> start;
  std::optional<Eigen::Vector3d> goal;
  std::vector<Eigen::Vector3d> explorer_goals;
  std::vector<Eigen::Vector3d> collisions;
  std::optional<MapProjection> map;
  std::string map_name;  // "ESDF" or "TSDF"
};

// The scene of a log; fills result's band, map description and notes.
Expected<Scene> readScene(const std::string& log_path, const PlotOptions& options,
                          PlotResult& result) {
  MissionLog log;
  log.layer = options.layer;
  try {
    const LogReadResult read = readLog(log_path, [&](const LogEvent& e) { collect(e, log); });
    if (!read.error.empty()) {
      result.notes.push_back("read " + std::to_string(read.events) +
                             " events, then stopped: " + read.error);
    }
  } catch (const std::exception& e) {
    return unexpected(e.what());
  }
  for (const auto& [channel, count] : log.undecodable) {
    result.notes.push_back(channel + ": " + std::to_string(count) + " messages do not decode (" +
                           log.first_error[channel] + ")");
  }

  Scene scene;
  scene.world = std::move(log.world);
  scene.explorer_goals = std::move(log.explorer_goals);
  scene.collisions = std::move(log.collisions);
  // The path: ground truth, else the state estimate (a real vehicle's log).
  if (log.truth.empty()) {
    result.notes.push_back(log.estimate.empty() ? "no SIM_TRUTH or STATE_ESTIMATE: no path drawn"
                                                : "no SIM_TRUTH: the path is the STATE_ESTIMATE");
  }
  scene.path_is_estimate = log.truth.empty() && !log.estimate.empty();
  scene.path = std::move(scene.path_is_estimate ? log.estimate : log.truth);
  if (!scene.world) {
    result.notes.push_back("no SIM_WORLD: no ground-truth obstacles or bounds drawn");
  }
  if (!log.messages.count("SIM_EVENT")) {
    result.notes.push_back("no SIM_EVENT: collisions unknown, none drawn");
  }
  if (!log.messages.count("EXPLORER_GOAL")) {
    result.notes.push_back("no EXPLORER_GOAL: no intermediate goals drawn");
  }
  if (!scene.path.empty()) {
    scene.start = scene.path.front();
  } else if (scene.world) {
    scene.start = vector3(scene.world->start);
  }
  scene.goal = log.mission_goal;
  if (!scene.goal && scene.world) scene.goal = vector3(scene.world->goal);
  if (!log.mission_goal) {
    result.notes.push_back(scene.world ? "no MISSION_GOAL: the goal is SIM_WORLD's"
                                       : "no MISSION_GOAL or SIM_WORLD: no goal drawn");
  }

  // The map band: around the median flown height, else the start's height.
  if (options.z_min) {
    result.z_min = *options.z_min;
    result.z_max = *options.z_max;
  } else {
    double height = 1.5;
    if (!scene.path.empty()) {
      std::vector<double> heights;
      for (const Eigen::Vector3d& p : scene.path) heights.push_back(p.z());
      std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
      height = heights[heights.size() / 2];
    } else if (scene.start) {
      height = scene.start->z();
    }
    result.z_min = height - 0.5;
    result.z_max = height + 0.5;
  }
  const bool esdf = options.layer == "esdf" || (options.layer == "auto" && !log.esdf.empty());
  scene.map_name = esdf ? "ESDF" : "TSDF";
  const std::string channel = "MAP_" + scene.map_name;
  scene.map = esdf ? projectMap<EsdfVoxel>(std::move(log.esdf), channel, result.z_min, result.z_max,
                                           result.notes)
                   : projectMap<TsdfVoxel>(std::move(log.tsdf), channel, result.z_min, result.z_max,
                                           result.notes);
  if (scene.map) {
    result.map_layer = channel;
    result.map_revision = scene.map->revision;
  } else {
    result.notes.push_back(options.layer == "auto" ? "no MAP_ESDF or MAP_TSDF: no map drawn"
                                                   : "no " + channel + ": no map drawn");
  }

  if (!scene.world && scene.path.empty() && (!scene.map || scene.map->columns.empty())) {
    return unexpected(
        "nothing to draw: no SIM_WORLD, no path (SIM_TRUTH, STATE_ESTIMATE) and no "
        "map in " +
        log_path);
  }
  return scene;
}

// The world area to show [m]: the world's bounds (the map's extent without them) and every
// point flown or proposed, with a margin.
std::pair<Eigen::Vector2d, Eigen::Vector2d> sceneExtent(const Scene& scene) {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(INFINITY);
  Eigen::Vector2d high = Eigen::Vector2d::Constant(-INFINITY);
  const auto extend = [&](double x, double y) {
    if (!std::isfinite(x) || !std::isfinite(y)) return;
    low = low.cwiseMin(Eigen::Vector2d(x, y));
    high = high.cwiseMax(Eigen::Vector2d(x, y));
  };
  if (scene.world) {
    extend(scene.world->bounds_min[0], scene.world->bounds_min[1]);
    extend(scene.world->bounds_max[0], scene.world->bounds_max[1]);
  } else if (scene.map) {
    const double voxel = scene.map->voxel_size;
    for (const auto& [column, cell] : scene.map->columns) {
      extend(column.first * voxel, column.second * voxel);
      extend((column.first + 1) * voxel, (column.second + 1) * voxel);
    }
  }
  for (const auto* points : {&scene.path, &scene.explorer_goals, &scene.collisions}) {
    for (const Eigen::Vector3d& p : *points) extend(p.x(), p.y());
  }
  for (const auto& p : {scene.start, scene.goal}) {
    if (p) extend(p->x(), p->y());
  }
  if (!(low.array() <= high.array()).all()) {  // nothing finite to show
    low.setConstant(-1);
    high.setConstant(1);
  }
  const Eigen::Vector2d pad = ((high - low) * 0.03).cwiseMax(0.5);
  return {low - pad, high + pad};
}

// Back to front: the map's free space, the ground truth, the map's obstacles over it, bounds,
// path, markers.
void drawScene(Canvas& canvas, const Scene& scene) {
  cv::Mat& image = canvas.image;
  if (scene.map) drawColumns(canvas, *scene.map, Cell::kFree, colors::kFree);
  if (scene.world) {
    const sim_world_t& w = *scene.world;
    for (size_t i = 0; i < w.cylinder_x.size(); ++i) {
      cv::circle(image, canvas.at(w.cylinder_x[i], w.cylinder_y[i]),
                 canvas.length(w.cylinder_radius[i]), bgr(colors::kObstacle), cv::FILLED,
                 cv::LINE_AA, kShift);
    }
  }
  if (scene.map) drawColumns(canvas, *scene.map, Cell::kOccupied, colors::kOccupied);
  if (scene.world) {
    const sim_world_t& w = *scene.world;
    const int edge = std::max(1, canvas.line / 2);
    for (size_t i = 0; i < w.cylinder_x.size(); ++i) {
      cv::circle(image, canvas.at(w.cylinder_x[i], w.cylinder_y[i]),
                 canvas.length(w.cylinder_radius[i]), bgr(colors::kObstacleEdge), edge, cv::LINE_AA,
                 kShift);
    }
    cv::rectangle(image, canvas.at(w.bounds_min[0], w.bounds_max[1]),
                  canvas.at(w.bounds_max[0], w.bounds_min[1]), bgr(colors::kBounds), edge,
                  cv::LINE_8, kShift);
  }
  if (scene.path.size() >= 2) {
    std::vector<cv::Point> points;
    for (const Eigen::Vector3d& p : scene.path) points.push_back(canvas.at(p));
    cv::polylines(image, points, false, bgr(colors::kPath), canvas.line, cv::LINE_AA, kShift);
  }
  if (scene.path.size() >= 2) drawEnd(canvas, canvas.at(scene.path.back()));
  for (const Eigen::Vector3d& p : scene.explorer_goals) {
    drawPolygon(image, canvas.at(p), canvas.marker, kTriangle, colors::kExplorerGoal);
  }
  if (scene.start) drawDisc(image, canvas.at(*scene.start), canvas.marker, colors::kStart, 1);
  if (scene.goal)
    drawPolygon(image, canvas.at(*scene.goal), canvas.marker, kDiamond, colors::kGoal);
  for (const Eigen::Vector3d& p : scene.collisions) {
    drawCross(image, canvas.at(p), canvas.marker, colors::kCollision, canvas.line);
  }
}

// What the scene shows, for the legend.
std::vector<LegendItem> legendOf(const Scene& scene) {
  std::vector<LegendItem> legend;
  if (scene.world) {
    legend.push_back({Swatch::kCylinder, "obstacle (SIM_WORLD)"});
    legend.push_back({Swatch::kBounds, "flight volume"});
  }
  if (scene.map) {
    legend.push_back({Swatch::kArea, "free (" + scene.map_name + ")", colors::kFree});
    legend.push_back({Swatch::kArea, "occupied (" + scene.map_name + ")", colors::kOccupied});
    legend.push_back({Swatch::kArea, "unknown", colors::kUnknown});
  }
  if (!scene.path.empty()) {
    legend.push_back({Swatch::kPath, scene.path_is_estimate ? "path (estimate)" : "path"});
    legend.push_back({Swatch::kEnd, "end of path"});
  }
  if (scene.start) legend.push_back({Swatch::kStart, "start"});
  if (scene.goal) legend.push_back({Swatch::kGoal, "goal"});
  if (!scene.explorer_goals.empty()) legend.push_back({Swatch::kExplorerGoal, "explorer goal"});
  if (!scene.collisions.empty()) legend.push_back({Swatch::kCollision, "collision"});
  return legend;
}

}  // namespace

std::string validatePlotOptions(const PlotOptions& options) {
  if (options.out.empty()) return "no output file";
  if (options.size < 400 || options.size > 10000) {
    return "--size must be 400 .. 10000 pixels, not " + std::to_string(options.size);
  }
  if (options.layer != "auto" && options.layer != "esdf" && options.layer != "tsdf") {
    return "--layer must be esdf, tsdf or auto, not '" + options.layer + "'";
  }
  if (options.z_min.has_value() != options.z_max.has_value() ||
      (options.z_min && !(*options.z_min < *options.z_max))) {
    return "--z-band needs its minimum below its maximum";
  }
  return {};
}

Expected<PlotResult> plotLog(const std::string& log_path, const PlotOptions& options) {
  if (const std::string error = validatePlotOptions(options); !error.empty()) {
    return unexpected(error);
  }
  PlotResult result;
  const Expected<Scene> scene = readScene(log_path, options, result);
  if (!scene) return unexpected(scene.error());

  // Sizes scale with the image.
  Canvas canvas;
  const int size = options.size;
  canvas.line = std::max(3, size / 300);
  canvas.marker = std::max(5, size / 110);
  canvas.font = std::clamp(size / 1800.0, 0.35, 2.0);
  canvas.text = std::max(1, size / 1200);
  canvas.text_height = canvas.textSize("Ag").height;
  canvas.row_height = std::max(canvas.text_height * 2, 2 * canvas.marker + 6);

  // Layout: the plot above, the legend (a title row, then the items) below.
  const std::vector<LegendItem> legend = legendOf(*scene);
  const int per_row = size >= 600 ? 4 : 2;
  const int legend_rows = 1 + static_cast<int>((legend.size() + per_row - 1) / per_row);
  const int margin = std::max(8, size / 50);
  const int legend_top = size - legend_rows * canvas.row_height - margin;
  const double plot_width = size - 2.0 * margin;
  const double plot_height = legend_top - 2.0 * margin;

  const auto [low, high] = sceneExtent(*scene);
  const Eigen::Vector2d extent = high - low;
  PlotFrame& frame = canvas.frame;
  frame.pixels_per_metre = std::min(plot_width / extent.x(), plot_height / extent.y());
  frame.origin_column = margin + (plot_width - extent.x() * frame.pixels_per_metre) / 2 -
                        low.x() * frame.pixels_per_metre;
  frame.origin_row = margin + plot_height -
                     (plot_height - extent.y() * frame.pixels_per_metre) / 2 +
                     low.y() * frame.pixels_per_metre;
  canvas.image = cv::Mat(size, size, CV_8UC3, bgr(colors::kUnknown));

  drawScene(canvas, *scene);
  std::string subtitle;
  if (scene->map) {
    char band[96];
    std::snprintf(band, sizeof(band), "  %s rev %lld, max over z %.1f..%.1f m",
                  result.map_layer.c_str(), static_cast<long long>(result.map_revision),
                  result.z_min, result.z_max);
    subtitle = band;
  }
  drawLegend(canvas, legend, std::filesystem::path(log_path).filename().string(), subtitle,
             legend_top, per_row, margin);

  try {
    if (!cv::imwrite(options.out, canvas.image)) {
      return unexpected("cannot write '" + options.out + "'");
    }
  } catch (const cv::Exception& e) {
    return unexpected("cannot write '" + options.out + "': " + e.what());
  }
  result.frame = frame;
  return result;
}

}  // namespace thicket::log

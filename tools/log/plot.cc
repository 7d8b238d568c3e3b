#include "plot.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <thicket/goal_t.hpp>
#include <thicket/map_update_t.hpp>
#include <thicket/odometry_t.hpp>
#include <thicket/sim_event_t.hpp>
#include <thicket/sim_world_t.hpp>

#include "log_events.h"
#include "thicket/common/map_update.h"
#include "thicket/common/subprocess.h"

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

Cell classify(const TsdfVoxel& voxel, double voxel_size) {
  if (!(voxel.weight > 0) || std::isnan(voxel.distance)) return Cell::kUnknown;
  return voxel.distance <= voxel_size ? Cell::kOccupied : Cell::kFree;
}

Cell classify(const EsdfVoxel& voxel, double voxel_size) {
  if (!voxel.observed) return Cell::kUnknown;
  return voxel.distance <= voxel_size ? Cell::kOccupied : Cell::kFree;
}

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

PlotPoint plotPoint(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

// The points with finite coordinates (a diverged estimate leaves the picture).
std::vector<PlotPoint> finitePoints(const std::vector<Eigen::Vector3d>& points) {
  std::vector<PlotPoint> finite;
  for (const Eigen::Vector3d& p : points) {
    if (p.allFinite()) finite.push_back(plotPoint(p));
  }
  return finite;
}

// The scene of a log, with the band, the map description and the notes.
Expected<PlotScene> readScene(const std::string& log_path, const PlotOptions& options) {
  PlotScene scene;
  scene.title = std::filesystem::path(log_path).filename().string();
  MissionLog log;
  log.layer = options.layer;
  try {
    const LogReadResult read = readLog(log_path, [&](const LogEvent& e) { collect(e, log); });
    if (!read.error.empty()) {
      scene.notes.push_back("read " + std::to_string(read.events) +
                            " events, then stopped: " + read.error);
    }
  } catch (const std::exception& e) {
    return unexpected(e.what());
  }
  for (const auto& [channel, count] : log.undecodable) {
    scene.notes.push_back(channel + ": " + std::to_string(count) + " messages do not decode (" +
                          log.first_error[channel] + ")");
  }

  scene.world = std::move(log.world);
  scene.explorer_goals = finitePoints(log.explorer_goals);
  scene.collisions = finitePoints(log.collisions);
  // The path: ground truth, else the state estimate (a real vehicle's log).
  if (log.truth.empty()) {
    scene.notes.push_back(log.estimate.empty() ? "no SIM_TRUTH or STATE_ESTIMATE: no path drawn"
                                               : "no SIM_TRUTH: the path is the STATE_ESTIMATE");
  }
  scene.path_is_estimate = log.truth.empty() && !log.estimate.empty();
  scene.path = finitePoints(scene.path_is_estimate ? log.estimate : log.truth);
  if (!scene.world) {
    scene.notes.push_back("no SIM_WORLD: no ground-truth obstacles or bounds drawn");
  }
  if (!log.messages.count("SIM_EVENT")) {
    scene.notes.push_back("no SIM_EVENT: collisions unknown, none drawn");
  }
  if (!log.messages.count("EXPLORER_GOAL")) {
    scene.notes.push_back("no EXPLORER_GOAL: no intermediate goals drawn");
  }
  if (!scene.path.empty()) {
    scene.start = scene.path.front();
  } else if (scene.world) {
    scene.start = plotPoint(vector3(scene.world->start));
  }
  if (log.mission_goal) {
    scene.goal = plotPoint(*log.mission_goal);
  } else if (scene.world) {
    scene.goal = plotPoint(vector3(scene.world->goal));
  }
  if (!log.mission_goal) {
    scene.notes.push_back(scene.world ? "no MISSION_GOAL: the goal is SIM_WORLD's"
                                      : "no MISSION_GOAL or SIM_WORLD: no goal drawn");
  }

  // The map band: around the median flown height, else the start's height.
  if (options.z_min) {
    scene.z_min = *options.z_min;
    scene.z_max = *options.z_max;
  } else {
    double height = 1.5;
    if (!scene.path.empty()) {
      std::vector<double> heights;
      for (const PlotPoint& p : scene.path) heights.push_back(p.z);
      std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
      height = heights[heights.size() / 2];
    } else if (scene.start) {
      height = scene.start->z;
    }
    scene.z_min = height - 0.5;
    scene.z_max = height + 0.5;
  }
  const bool esdf = options.layer == "esdf" || (options.layer == "auto" && !log.esdf.empty());
  const std::string channel = esdf ? "MAP_ESDF" : "MAP_TSDF";
  scene.map = esdf ? projectMap<EsdfVoxel>(std::move(log.esdf), channel, scene.z_min, scene.z_max,
                                           scene.notes)
                   : projectMap<TsdfVoxel>(std::move(log.tsdf), channel, scene.z_min, scene.z_max,
                                           scene.notes);
  if (scene.map) {
    scene.map_layer = channel;
    char band[96];
    std::snprintf(band, sizeof(band), "%s rev %lld, max over z %.1f..%.1f m", channel.c_str(),
                  static_cast<long long>(scene.map->revision), scene.z_min, scene.z_max);
    scene.subtitle = band;
  } else {
    scene.notes.push_back(options.layer == "auto" ? "no MAP_ESDF or MAP_TSDF: no map drawn"
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

Cell MapProjection::at(double x, double y) const {
  const auto column = columns.find(
      {static_cast<int>(std::floor(x / voxel_size)), static_cast<int>(std::floor(y / voxel_size))});
  return column == columns.end() ? Cell::kUnknown : column->second;
}

Expected<PlotScene> readPlotScene(const std::string& log_path, const PlotOptions& options) {
  if (const std::string error = validatePlotOptions(options); !error.empty()) {
    return unexpected(error);
  }
  return readScene(log_path, options);
}

std::string sceneJson(const PlotScene& scene, int size) {
  using Json = nlohmann::json;
  const auto point = [](const PlotPoint& p) { return Json::array({p.x, p.y}); };
  const auto points = [&](const std::vector<PlotPoint>& list) {
    Json array = Json::array();
    for (const PlotPoint& p : list) array.push_back(point(p));
    return array;
  };
  const auto optional = [&](const std::optional<PlotPoint>& p) {
    return p ? point(*p) : Json(nullptr);
  };
  Json json;
  json["title"] = scene.title;
  json["subtitle"] = scene.subtitle;
  json["size"] = size;
  json["path"] = points(scene.path);
  json["path_is_estimate"] = scene.path_is_estimate;
  json["start"] = optional(scene.start);
  json["goal"] = optional(scene.goal);
  json["explorer_goals"] = points(scene.explorer_goals);
  json["collisions"] = points(scene.collisions);
  json["world"] = nullptr;
  if (scene.world) {
    const sim_world_t& w = *scene.world;
    Json cylinders = Json::array();
    for (size_t i = 0; i < w.cylinder_x.size(); ++i) {
      cylinders.push_back({w.cylinder_x[i], w.cylinder_y[i], w.cylinder_radius[i]});
    }
    json["world"] = {{"bounds_min", {w.bounds_min[0], w.bounds_min[1]}},
                     {"bounds_max", {w.bounds_max[0], w.bounds_max[1]}},
                     {"cylinders", cylinders}};
  }
  json["map"] = nullptr;
  if (scene.map) {
    Json free = Json::array(), occupied = Json::array();
    for (const auto& [column, cell] : scene.map->columns) {
      (cell == Cell::kOccupied ? occupied : free).push_back({column.first, column.second});
    }
    json["map"] = {{"name", scene.map_layer.substr(4)},
                   {"voxel_size", scene.map->voxel_size},
                   {"free", free},
                   {"occupied", occupied}};
  }
  return json.dump();
}

Expected<PlotScene> plotLog(const std::string& log_path, const PlotOptions& options) {
  Expected<PlotScene> scene = readPlotScene(log_path, options);
  if (!scene) return scene;
  // The PNG's folder must take it; the scene and the script's output wait in the temp folder.
  const std::filesystem::path out(options.out);
  const std::string folder = out.has_parent_path() ? out.parent_path().string() : ".";
  if (::access(folder.c_str(), W_OK) != 0) {
    return unexpected("cannot write '" + options.out + "': " + std::strerror(errno));
  }
  const std::string stem =
      (std::filesystem::temp_directory_path() / ("thicket-plot-" + std::to_string(::getpid())))
          .string();
  {
    std::ofstream json(stem + ".json", std::ios::binary);
    json << sceneJson(*scene, options.size);
    json.close();
    if (!json) return unexpected("cannot write '" + stem + ".json'");
  }
  const std::string error = runProgram(
      {"/usr/bin/python3", std::string(THICKET_SOURCE_DIR) + "/tools/log/plot_mission.py",
       stem + ".json", options.out},
      stem + ".log");
  std::error_code ignored;
  std::filesystem::remove(stem + ".json", ignored);
  if (!error.empty()) return unexpected("cannot draw '" + options.out + "': " + error);
  return scene;
}

}  // namespace thicket::log

#include "mapper_node.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include <thicket/map_update_t.hpp>
#include <thicket/module_timing_t.hpp>

#include "thicket/common/depth_image.h"
#include "thicket/common/map_update.h"
#include "thicket/common/statistics.h"
#include "thicket/common/time.h"

namespace thicket::mapper {

void MapperNodeOptions::declare(Params& p) {
  p.group("mapper", mapper, "the map: voxels, integration, ESDF, pose pairing");
  p("map_id", map_id, "identifies the map to mirrors; 0: from the wall clock at start");
  p("depth_channel", depth_channel, "depth frames in (depth_image_t)");
  p("state_channel", state_channel, "body poses in (odometry_t)");
  p("max_message_kib", max_message_kib, "block bytes (as sent) per map message [KiB]",
    Range::between(16, 900));
  p("compress_blocks", compress_blocks,
    "zstd-compress map blocks; off: raw blocks, for a graph inside one process");
  p("load_map", load_map, "a saved map to continue from; empty: start with an empty map");
  p("save_map", save_map, "where to save the map when the node stops; empty: not saved");
  p("checkpoint", checkpoint,
    "crash recovery: the map saved here every checkpoint_period and continued by a restarted "
    "mapper, removed at a clean stop; empty: off");
  p("checkpoint_period", checkpoint_period, "message time between checkpoints [s]",
    Range::positive());
  p("checkpoint_max_age", checkpoint_max_age,
    "a checkpoint older than this at the first message is another flight's [s]", Range::positive());
}

MapperNode::MapperNode(lcm::LCM& lcm, const MapperNodeOptions& options, int64_t map_id,
                       std::function<double()> now_ms)
    : Node("mapper", lcm),
      options_(options),
      map_id_(map_id),
      now_ms_(now_ms),
      mapper_(options.mapper, now_ms) {
  std::string restored;
  if (!options_.checkpoint.empty() && std::filesystem::exists(options_.checkpoint)) {
    auto saved = loadMap(options_.checkpoint);
    if (saved && saved->start && saved->esdf.voxelSize() == options_.mapper.voxel_size) {
      mapper_.restore(*saved, true);
      map_id_ = saved->map_id + 1;
      restored_utime_ = saved->utime;
      restored = "continued the checkpoint " + options_.checkpoint + " (map " +
                 std::to_string(saved->map_id) + " at revision " + std::to_string(saved->revision) +
                 ") as map " + std::to_string(map_id_);
    } else {
      restored = "checkpoint " + options_.checkpoint + " not continued: " +
                 (!saved          ? saved.error()
                  : !saved->start ? std::string("it does not say where the flight started")
                                  : std::string("its voxel size is not the mapper's"));
    }
  }
  if (!restored_utime_) loadConfiguredMap();
  // Depth frames come in bursts when a log replays; poses at 20-200 Hz.
  subscribe<depth_image_t>(
      options_.depth_channel,
      [this](const depth_image_t& msg, const MessageInfo&) { onDepth(msg); }, 100);
  subscribe<odometry_t>(
      options_.state_channel, [this](const odometry_t& msg, const MessageInfo&) { onState(msg); },
      1000);
  subscribe<map_request_t>(
      "MAP_REQUEST", [this](const map_request_t& msg, const MessageInfo&) { onRequest(msg); });
  if (!restored.empty()) {
    std::fprintf(stderr, "[mapper] %s\n", restored.c_str());
    publishStatus(mapper_.utime(), mapper_status_t::RESULT_RESTORED, restored);
  }
}

void MapperNode::loadConfiguredMap() {
  if (options_.load_map.empty()) return;
  auto saved = loadMap(options_.load_map);
  if (!saved) throw std::runtime_error(saved.error());
  mapper_.restore(*saved);
}

bool MapperNode::dropStaleCheckpoint(int64_t utime) {
  if (!restored_utime_ || utime < 0 || utime > kMaxUtime) return false;  // (refused later)
  const int64_t checkpoint = *restored_utime_;
  restored_utime_.reset();
  if (utime >= checkpoint && utime - checkpoint <= secondsToUtime(options_.checkpoint_max_age)) {
    return false;
  }
  // Another flight's map: start as a mapper without the checkpoint would have (load_map, or empty).
  mapper_ = Mapper(options_.mapper, now_ms_);
  loadConfiguredMap();
  const std::string reason = "checkpoint dropped: the first message (" + std::to_string(utime) +
                             " us) is not within checkpoint_max_age after it (" +
                             std::to_string(checkpoint) +
                             " us), so it is another flight's; starting without it";
  std::fprintf(stderr, "[mapper] %s\n", reason.c_str());
  publishStatus(utime, mapper_status_t::RESULT_RESTORED, reason);
  return true;
}

void MapperNode::checkpointIfDue(int64_t utime) {
  // Due a period after the last one, or at once when the clock went back (a new timeline).
  if (options_.checkpoint.empty() ||
      (checkpoint_utime_ && utime >= *checkpoint_utime_ &&
       utime - *checkpoint_utime_ < secondsToUtime(options_.checkpoint_period))) {
    return;
  }
  checkpoint_utime_ = utime;
  try {
    saveMap(options_.checkpoint, mapper_.tsdf(), mapper_.esdf(), mapper_.stamp(map_id_));
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "[mapper] checkpoint not written: %s\n", e.what());
  }
}

void MapperNode::removeCheckpoint() const {
  if (!options_.checkpoint.empty()) std::remove(options_.checkpoint.c_str());
}

void MapperNode::onDepth(const depth_image_t& msg) {
  auto frame = decodeDepthImage(msg);
  if (!frame) {
    ++undecodable_frames_;
    publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED, "bad depth frame: " + frame.error());
    return;
  }
  dropStaleCheckpoint(frame->utime);
  const FrameOutcome outcome = mapper_.addFrame(std::move(*frame));
  if (outcome.status == FrameOutcome::Status::kRefused) {
    publishStatus(outcome.utime, mapper_status_t::RESULT_REFUSED, outcome.reason);
    return;
  }
  const std::vector<int64_t> handled = integrateReady();
  if (std::find(handled.begin(), handled.end(), outcome.utime) == handled.end()) {
    publishStatus(outcome.utime, mapper_status_t::RESULT_PENDING, outcome.reason);
  }
}

void MapperNode::onState(const odometry_t& msg) {
  if (msg.quality == odometry_t::QUALITY_LOST) {
    publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED,
                  "pose refused: the estimator reports it lost (" + msg.reason + ")");
    return;
  }
  auto pose = poseFromArrays(msg.position, msg.orientation);
  if (!pose) {
    publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED, "pose refused: " + pose.error());
    return;
  }
  dropStaleCheckpoint(msg.utime);
  const Timeline::Result added = mapper_.addPose(msg.utime, *pose);
  if (!added.accepted()) {
    publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED, added.reason);
    return;
  }
  if (added.verdict == Timeline::Verdict::kReanchored) {
    publishStatus(msg.utime, mapper_status_t::RESULT_REANCHORED, "poses: " + added.reason);
  }
  integrateReady();
}

std::vector<int64_t> MapperNode::integrateReady() {
  std::vector<MapRevisionUpdate> updates;
  const std::vector<FrameOutcome> outcomes = mapper_.integrateReady(updates);
  std::vector<int64_t> handled;
  auto update = updates.begin();
  for (const FrameOutcome& outcome : outcomes) {
    handled.push_back(outcome.utime);
    if (outcome.status == FrameOutcome::Status::kReanchored) {
      publishStatus(outcome.utime, mapper_status_t::RESULT_REANCHORED, outcome.reason);
      continue;
    }
    if (outcome.status != FrameOutcome::Status::kIntegrated) {
      publishStatus(outcome.utime, mapper_status_t::RESULT_REFUSED, outcome.reason);
      continue;
    }
    // Every revision goes out on both layers, even without changes, so that mirrors see no gap.
    // The ESDF's deltas carry only the voxels that changed (on the mapping benchmark's flight 11 %
    // of the voxels of the blocks a frame changes at 0.1 m, 6 % at 0.2 m); the TSDF's whole blocks,
    // since its integrator reports the voxels the ESDF reads, not weight changes.
    publishLayer("MAP_TSDF", mapper_.tsdf(), update->utime, update->revision, false,
                 update->tsdf_changed, {});
    publishLayer("MAP_ESDF", mapper_.esdf(), update->utime, update->revision, false,
                 update->esdf_changed, update->esdf_removed, update->esdf_changed_voxels);
    tsdf_ms_.push_back(update->tsdf_ms);
    esdf_ms_.push_back(update->esdf_ms);
    module_timing_t timing;
    timing.utime = update->utime;
    timing.module = "mapper";
    timing.sequence = update->revision;
    timing.stages = {"tsdf_insert", "esdf_update"};
    timing.durations_ms = {update->tsdf_ms, update->esdf_ms};
    timing.num_stages = 2;
    publish("MODULE_TIMING", timing);
    publishStatus(outcome.utime, mapper_status_t::RESULT_INTEGRATED, "");
    checkpointIfDue(update->utime);
    ++update;
  }
  return handled;
}

void MapperNode::onRequest(const map_request_t& msg) {
  const std::string who = msg.requester.empty() ? "a mirror" : msg.requester;
  if (msg.layer == map_update_t::LAYER_TSDF || msg.layer == map_update_t::LAYER_ESDF) {
    // Every mirror takes a snapshot when it arrives, so one answers every mirror that asked for
    // this revision; one repeat serves a mirror that lost it, later requests wait for the next
    // revision (whose delta shows the gap, and the next snapshot heals it).
    const int layer = msg.layer;
    if (snapshot_revision_[layer] != mapper_.revision()) {
      snapshot_revision_[layer] = mapper_.revision();
      snapshots_sent_[layer] = 0;
    }
    if (snapshots_sent_[layer] >= kSnapshotsPerRevision) {
      ++requests_refused_;
      // Said once per revision and layer: a flood of requests is not answered by one of statuses.
      if (snapshots_sent_[layer] > kSnapshotsPerRevision) return;
      snapshots_sent_[layer] = kSnapshotsPerRevision + 1;
      publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED,
                    "map request from " + who + " refused: the snapshot of layer " +
                        std::to_string(layer) + " at revision " +
                        std::to_string(mapper_.revision()) + " went out " +
                        std::to_string(kSnapshotsPerRevision) + " times already");
      return;
    }
    ++snapshots_sent_[layer];
  }
  if (msg.layer == map_update_t::LAYER_TSDF) {
    publishLayer("MAP_TSDF", mapper_.tsdf(), mapper_.utime(), mapper_.revision(), true, {}, {});
  } else if (msg.layer == map_update_t::LAYER_ESDF) {
    publishLayer("MAP_ESDF", mapper_.esdf(), mapper_.utime(), mapper_.revision(), true, {}, {});
  } else {
    publishStatus(msg.utime, mapper_status_t::RESULT_REFUSED,
                  "map request from " + who + " for unknown layer " + std::to_string(msg.layer));
    return;
  }
  publishStatus(mapper_.utime(), mapper_status_t::RESULT_SNAPSHOT_SENT,
                "snapshot of layer " + std::to_string(msg.layer) + " at revision " +
                    std::to_string(mapper_.revision()) + " for " + who + " (" + msg.reason + ")");
}

template <class Voxel>
void MapperNode::publishLayer(const std::string& channel, const Layer<Voxel>& layer, int64_t utime,
                              int64_t revision, bool full_snapshot,
                              const std::vector<BlockIndex>& changed,
                              const std::vector<BlockIndex>& removed,
                              const std::vector<BlockVoxels>& changed_voxels) {
  const MapRevision header{utime, map_id_, revision, full_snapshot};
  for (const map_update_t& part : encodeMapUpdate(
           layer, header, changed, removed, static_cast<size_t>(options_.max_message_kib) * 1024,
           options_.compress_blocks, changed_voxels)) {
    publish(channel, part);
  }
}

void MapperNode::publishStatus(int64_t utime, int8_t result, const std::string& reason) {
  mapper_status_t status;
  status.utime = utime;
  status.result = result;
  status.reason = reason;
  status.map_id = map_id_;
  status.revision = mapper_.revision();
  status.num_tsdf_blocks = static_cast<int32_t>(mapper_.tsdf().numBlocks());
  status.num_esdf_blocks = static_cast<int32_t>(mapper_.esdf().numBlocks());
  status.memory_bytes =
      static_cast<int64_t>(mapper_.tsdf().memoryBytes() + mapper_.esdf().memoryBytes());
  status.frames_integrated = mapper_.revision();
  status.frames_refused = framesRefused();
  status.frames_pending = static_cast<int32_t>(mapper_.pendingFrames());
  publish("MAPPER_STATUS", status);
}

std::string MapperNode::saveIfConfigured() const {
  if (options_.save_map.empty()) return "";
  saveMap(options_.save_map, mapper_.tsdf(), mapper_.esdf(), mapper_.stamp(map_id_));
  return options_.save_map;
}

std::string MapperNode::summary() const {
  char line[256];
  std::snprintf(line, sizeof(line),
                "%lld frames integrated, %lld refused; tsdf_insert median %.2f ms, esdf_update "
                "median %.2f ms; %zu TSDF and %zu ESDF blocks",
                static_cast<long long>(mapper_.revision()), static_cast<long long>(framesRefused()),
                median(tsdf_ms_), median(esdf_ms_), mapper_.tsdf().numBlocks(),
                mapper_.esdf().numBlocks());
  return line;
}

}  // namespace thicket::mapper

// thicket-mapper as an LCM node: CAMERA_DEPTH and STATE_ESTIMATE in; MAP_TSDF and MAP_ESDF
// deltas (one revision per integrated frame), MAPPER_STATUS and MODULE_TIMING out; answers
// MAP_REQUEST with a full snapshot of the requested layer.
#pragma once

#include <string>
#include <vector>

#include <thicket/depth_image_t.hpp>
#include <thicket/map_request_t.hpp>
#include <thicket/mapper_status_t.hpp>
#include <thicket/odometry_t.hpp>

#include "thicket/common/node.h"
#include "thicket/common/params.h"
#include "thicket/mapper/mapper.h"

namespace thicket::mapper {

struct MapperNodeOptions {
  MapperOptions mapper;
  /// Identifies this map to the mirrors; 0 picks one from the wall clock at start, so that a
  /// restarted mapper is a new map. Replay and tests set it.
  int64_t map_id = 0;
  std::string depth_channel = "CAMERA_DEPTH";
  std::string state_channel = "STATE_ESTIMATE";
  /// Block bytes (as sent) per map message; a revision is split into parts above this [KiB].
  int max_message_kib = 256;
  /// zstd-compress the blocks of MAP_TSDF/MAP_ESDF. Off sends raw blocks: for a graph inside one
  /// process (the benchmark's memq://), where compressing and decompressing every block costs
  /// more than copying it; over UDP or into a log, keep it on.
  bool compress_blocks = true;
  /// A map saved by thicket-map or a previous run to continue from ("": start empty).
  std::string load_map;
  /// Where the map is saved when the node stops ("": not saved).
  std::string save_map;
  /// Crash recovery ("": off): the map is saved here (atomically) every checkpoint_period of
  /// message time; a mapper that starts and finds the file continues it (the same flight, a new
  /// map id so that every mirror takes a snapshot), unless its first pose or frame is earlier than
  /// the checkpoint or more than checkpoint_max_age after it (another flight). A clean stop
  /// removes it, so only a crash leaves one behind.
  std::string checkpoint;
  double checkpoint_period = 1.0;    // [s] of message time
  double checkpoint_max_age = 30.0;  // [s] of message time

  void declare(Params& p);
};

class MapperNode : public Node {
 public:
  /// now_ms measures stage durations for MODULE_TIMING (never used to decide).
  MapperNode(lcm::LCM& lcm, const MapperNodeOptions& options, int64_t map_id,
             std::function<double()> now_ms = {});

  const Mapper& mapper() const { return mapper_; }
  int64_t mapId() const { return map_id_; }
  /// Snapshot requests refused because the layer's snapshot at the current revision had already
  /// gone out twice (one for the mirrors that asked, one repeat for a mirror that lost it).
  int64_t requestsRefused() const { return requests_refused_; }
  /// Frames refused, whether they did not decode or the mapper refused them.
  int64_t framesRefused() const { return mapper_.framesRefused() + undecodable_frames_; }
  /// "N frames integrated, M refused; tsdf_insert median X ms, esdf_update median Y ms".
  std::string summary() const;
  /// Writes the map to options' save_map, if set; returns the path written or "". Throws
  /// std::runtime_error when the file cannot be written.
  std::string saveIfConfigured() const;
  /// The clean stop: removes the checkpoint, if any (see MapperNodeOptions::checkpoint).
  void removeCheckpoint() const;

 private:
  void onDepth(const depth_image_t& msg);
  void onState(const odometry_t& msg);
  void onRequest(const map_request_t& msg);
  // Integrates what became ready and publishes the results; the utimes of the frames dealt with.
  std::vector<int64_t> integrateReady();
  void publishStatus(int64_t utime, int8_t result, const std::string& reason);
  // With a checkpoint continued: drops it when the first pose or frame (at utime) belongs to
  // another flight. Returns whether it did.
  bool dropStaleCheckpoint(int64_t utime);
  void checkpointIfDue(int64_t utime);
  // Restores options' load_map, if set; throws std::runtime_error when it cannot be read.
  void loadConfiguredMap();
  template <class Voxel>
  void publishLayer(const std::string& channel, const Layer<Voxel>& layer, int64_t utime,
                    int64_t revision, bool full_snapshot, const std::vector<BlockIndex>& changed,
                    const std::vector<BlockIndex>& removed,
                    const std::vector<BlockVoxels>& changed_voxels = {});

  MapperNodeOptions options_;
  int64_t map_id_;
  std::function<double()> now_ms_;
  Mapper mapper_;
  std::optional<int64_t> restored_utime_;    // the checkpoint continued, until the first message
  std::optional<int64_t> checkpoint_utime_;  // the last checkpoint written
  std::vector<double> tsdf_ms_, esdf_ms_;
  int64_t undecodable_frames_ = 0;
  // Snapshots sent per layer at the current revision: at most kSnapshotsPerRevision, so that a
  // flood of requests cannot turn into a flood of snapshots.
  static constexpr int kSnapshotsPerRevision = 2;
  int64_t snapshot_revision_[2] = {-1, -1};
  int snapshots_sent_[2] = {0, 0};
  int64_t requests_refused_ = 0;
};

}  // namespace thicket::mapper

// The mapper core (docs/design.md §2): depth frames and body poses in, a TSDF and an incrementally
// updated ESDF out, one map revision per integrated frame. No LCM: the node adapts messages to
// this.
//
// A frame is integrated with the body pose at its own utime, interpolated from the pose stream;
// a frame newer than the newest pose waits (pending) until the poses catch up, never taking "the
// latest pose". Frames are integrated in utime order; a frame not newer than the last accepted
// one, or one whose pose can never be known (older than the pose history, or inside a gap of the
// pose stream), is refused with the reason, and the map is left as it was.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/depth_image.h"
#include "thicket/common/geometry.h"
#include "thicket/common/params.h"
#include "thicket/common/voxel_layer.h"
#include "thicket/mapper/esdf_integrator.h"
#include "thicket/mapper/map_io.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::mapper {

struct MapperOptions {
  double voxel_size = 0.1;  ///< [m]
  TsdfIntegratorOptions tsdf;
  EsdfIntegratorOptions esdf;
  PoseHistoryOptions poses;
  /// Frames waiting for their pose; when one more arrives the oldest is refused.
  int max_pending_frames = 10;

  void declare(Params& p);
};

/// What became of a frame.
struct FrameOutcome {
  /// kReanchored: the frame clock restarted (or overtook a bad stamp) with this frame, which is
  /// pending or integrated like any other; the frames of the old timeline were dropped.
  enum class Status { kIntegrated, kPending, kRefused, kReanchored };
  Status status = Status::kRefused;
  int64_t utime = 0;
  std::string reason;  ///< why it was refused, what it waits for, or how time re-anchored
};

/// One integrated frame: the map revision it made and what changed.
struct MapRevisionUpdate {
  int64_t utime = 0;
  int64_t revision = 0;
  std::vector<BlockIndex> tsdf_changed;
  std::vector<BlockIndex> esdf_changed;
  std::vector<BlockVoxels> esdf_changed_voxels;  ///< per esdf_changed block, its changed voxels
  std::vector<BlockIndex> esdf_removed;
  double tsdf_ms = 0;  ///< time to integrate the frame (measured, never used to decide)
  double esdf_ms = 0;  ///< time to update the ESDF
};

class Mapper {
 public:
  /// now_ms measures stage durations for the report (e.g. a steady clock); the default reads 0,
  /// so that the core never depends on the wall clock. Throws std::invalid_argument on bad
  /// options.
  explicit Mapper(MapperOptions options, std::function<double()> now_ms = {});

  /// Adds a body pose (world_T_body) to the history (PoseHistory::add: refused when not finite,
  /// not unit, absurdly far or not newer than the previous one; a run of earlier poses
  /// re-anchors the history). The first accepted pose is the initial position (the centre of the
  /// ESDF's clear sphere).
  Timeline::Result addPose(int64_t utime, const Pose& world_T_body);

  /// Takes a decoded frame: pending until its pose is known, or refused. Frame times must
  /// increase; a run of earlier frames re-anchors (Timeline): the pending frames of the old
  /// timeline are dropped and integrateReady() reports them and the re-anchoring. Call
  /// integrateReady() after this and after addPose() to integrate what became ready.
  FrameOutcome addFrame(DepthImage frame);

  /// Integrates, in utime order, every pending frame whose pose is known, and refuses those
  /// whose pose never will be (or that too many newer frames pushed out of the queue). One
  /// outcome per frame dealt with; updates for the integrated ones.
  std::vector<FrameOutcome> integrateReady(std::vector<MapRevisionUpdate>& updates);

  /// Continues a saved map: adopts its layers, revision and time, before any frame was taken.
  /// The ESDF is recomputed from the TSDF with the first integrated frame. For a new flight the
  /// unknown-space policy follows this flight's poses (its first pose is the start); for the same
  /// flight (a checkpoint after a crash) it keeps the map's start, so that no clear sphere opens
  /// unknown space around wherever the vehicle is when the mapper comes back. Throws
  /// std::logic_error once a frame was taken, std::invalid_argument when the map's voxel size is
  /// not options().voxel_size or a same-flight map has no start.
  void restore(const SavedMap& map, bool same_flight = false);

  const TsdfLayer& tsdf() const { return tsdf_; }
  const EsdfLayer& esdf() const { return esdf_; }
  const MapperOptions& options() const { return options_; }
  /// The current revision: the number of frames integrated (counting on from a restored map's).
  int64_t revision() const { return revision_; }
  /// Time of the newest integrated frame [µs], 0 before any.
  int64_t utime() const { return utime_; }
  /// The start of the flight (the first accepted pose, or a restored map's): the centre of the
  /// ESDF's clear sphere.
  const std::optional<Eigen::Vector3d>& start() const { return start_; }
  /// What saveMap writes beside the layers, for a map known as `map_id`.
  MapStamp stamp(int64_t map_id) const { return {map_id, revision_, utime_, start_}; }
  size_t pendingFrames() const { return pending_.size(); }
  int64_t framesRefused() const { return frames_refused_; }

 private:
  FrameOutcome refuse(int64_t utime, std::string reason);

  MapperOptions options_;
  std::function<double()> now_ms_;
  TsdfIntegrator tsdf_integrator_;
  EsdfIntegrator esdf_integrator_;
  TsdfLayer tsdf_;
  EsdfLayer esdf_;
  PoseHistory poses_;
  std::optional<Eigen::Vector3d> start_;
  std::deque<DepthImage> pending_;     // utime order
  std::vector<FrameOutcome> dropped_;  // pending frames pushed out; reported by integrateReady
  Timeline frames_{"frame"};           // stamps of the frames accepted (pending or integrated)
  int64_t revision_ = 0;
  int64_t utime_ = 0;
  int64_t frames_refused_ = 0;
};

}  // namespace thicket::mapper

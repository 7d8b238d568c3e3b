#include "thicket/mapper/mapper.h"

#include <algorithm>
#include <stdexcept>

namespace thicket::mapper {

void MapperOptions::declare(Params& p) {
  p("voxel_size", voxel_size, "edge of a voxel [m]", Range::between(0.01, 2.0));
  p.group("tsdf", tsdf, "TSDF integration");
  p.group("esdf", esdf, "ESDF and the unknown-space policy");
  p("max_pose_gap_us", poses.max_interpolation_gap_us,
    "widest gap in the pose stream that a frame's pose is interpolated across [us]",
    Range::positive());
  p("pose_tolerance_us", poses.tolerance_us,
    "a frame this close to a pose that cannot be interpolated takes that pose; 0 keeps replay "
    "deterministic [us]",
    Range::atLeast(0));
  p("pose_history_us", poses.max_age_us, "how long poses are kept [us]", Range::positive());
  p("max_pending_frames", max_pending_frames, "frames kept waiting for their pose",
    Range::between(1, 1000));
}

namespace {

// `options` when every field keeps the rule its YAML declaration states (also for options built
// in code), else std::invalid_argument, before any part of the mapper is built from them.
const MapperOptions& checked(const MapperOptions& options) {
  if (const std::string error = paramsError(options); !error.empty()) {
    throw std::invalid_argument("Mapper: " + error);
  }
  return options;
}

// The TSDF reports the voxels whose observed-ness changes at the ESDF's threshold.
TsdfIntegratorOptions reportingTo(TsdfIntegratorOptions tsdf, const EsdfIntegratorOptions& esdf) {
  tsdf.observed_weight = esdf.min_weight;
  return tsdf;
}

}  // namespace

Mapper::Mapper(MapperOptions options, std::function<double()> now_ms)
    : options_(checked(options)),
      now_ms_(now_ms ? std::move(now_ms) : [] { return 0.0; }),
      tsdf_integrator_(reportingTo(options.tsdf, options.esdf)),
      esdf_integrator_(options.esdf),
      tsdf_(options.voxel_size),
      esdf_(options.voxel_size),
      poses_(options.poses) {}

Timeline::Result Mapper::addPose(int64_t utime, const Pose& world_T_body) {
  Timeline::Result result = poses_.add(utime, world_T_body);
  if (result.accepted() && !start_) {
    esdf_integrator_.setInitialPosition(world_T_body.position);
    start_ = world_T_body.position;
  }
  return result;
}

FrameOutcome Mapper::refuse(int64_t utime, std::string reason) {
  ++frames_refused_;
  return {FrameOutcome::Status::kRefused, utime, std::move(reason)};
}

FrameOutcome Mapper::addFrame(DepthImage frame) {
  const int64_t utime = frame.utime;
  const Timeline::Result time = frames_.offer(utime);
  if (!time.accepted()) return refuse(utime, "frame refused: " + time.reason);
  if (time.verdict == Timeline::Verdict::kReanchored) {
    for (const DepthImage& old : pending_) {
      dropped_.push_back(refuse(old.utime, "dropped with the frame timeline it belonged to"));
    }
    pending_.clear();
    dropped_.push_back({FrameOutcome::Status::kReanchored, utime, "frames: " + time.reason});
  }
  pending_.push_back(std::move(frame));
  if (static_cast<int>(pending_.size()) > options_.max_pending_frames) {
    const int64_t dropped = pending_.front().utime;
    pending_.pop_front();
    // The oldest frame gives way; the caller learns of it through integrateReady's outcomes,
    // but this frame's own outcome is what the caller asked about.
    dropped_.push_back(refuse(dropped, "waited too long for a pose (" +
                                           std::to_string(options_.max_pending_frames) +
                                           " frames pending)"));
  }
  return {FrameOutcome::Status::kPending, utime, "waiting for the pose at its time"};
}

void Mapper::restore(const SavedMap& map, bool same_flight) {
  if (frames_.last()) {
    throw std::logic_error("Mapper::restore: frames were already taken");
  }
  if (map.tsdf.voxelSize() != options_.voxel_size || map.esdf.voxelSize() != options_.voxel_size) {
    throw std::invalid_argument(
        "Mapper::restore: the map has " + std::to_string(map.tsdf.voxelSize()) +
        " m voxels, the mapper is configured for " + std::to_string(options_.voxel_size) + " m");
  }
  if (same_flight && !map.start) {
    throw std::invalid_argument("Mapper::restore: the map does not say where its flight started");
  }
  if (same_flight) {
    esdf_integrator_.setInitialPosition(*map.start);
    start_ = map.start;
  }
  tsdf_ = map.tsdf;
  esdf_ = map.esdf;  // served until the first frame; its update recomputes from the TSDF
  revision_ = map.revision;
  utime_ = map.utime;
}

std::vector<FrameOutcome> Mapper::integrateReady(std::vector<MapRevisionUpdate>& updates) {
  std::vector<FrameOutcome> outcomes = std::move(dropped_);
  dropped_.clear();
  while (!pending_.empty()) {
    const DepthImage& frame = pending_.front();
    const PoseLookup lookup = poses_.lookup(frame.utime);
    if (lookup.status == PoseLookup::Status::kNotYet ||
        lookup.status == PoseLookup::Status::kEmpty) {
      break;  // later frames need later poses
    }
    if (!lookup.ok()) {
      outcomes.push_back(refuse(frame.utime, "no pose at the frame's time: " + lookup.reason));
      pending_.pop_front();
      continue;
    }
    MapRevisionUpdate update;
    update.utime = frame.utime;
    const Pose world_T_camera = lookup.pose * frame.camera_in_body;
    const double start = now_ms_();
    TsdfIntegrationResult tsdf;
    try {
      tsdf = tsdf_integrator_.integrate(frame, world_T_camera, tsdf_);
    } catch (const std::invalid_argument& e) {
      outcomes.push_back(refuse(frame.utime, e.what()));  // the layer is unchanged
      pending_.pop_front();
      continue;
    }
    const double integrated = now_ms_();
    EsdfUpdateResult esdf;
    try {
      esdf = esdf_integrator_.update(tsdf_, tsdf, lookup.pose.position, esdf_);
    } catch (const std::exception& e) {
      // Never left pending to throw again with every later input. The TSDF took the frame; the
      // ESDF's next update recomputes from the whole TSDF.
      outcomes.push_back(refuse(frame.utime, std::string("ESDF update failed: ") + e.what()));
      pending_.pop_front();
      continue;
    }
    update.esdf_ms = now_ms_() - integrated;
    update.tsdf_ms = integrated - start;
    update.tsdf_changed = std::move(tsdf.changed_blocks);
    update.esdf_changed = std::move(esdf.changed_blocks);
    update.esdf_changed_voxels = std::move(esdf.changed_voxels);
    update.esdf_removed = std::move(esdf.removed_blocks);
    update.revision = ++revision_;
    utime_ = frame.utime;
    outcomes.push_back({FrameOutcome::Status::kIntegrated, frame.utime, ""});
    updates.push_back(std::move(update));
    pending_.pop_front();
  }
  return outcomes;
}

}  // namespace thicket::mapper

// TSDF integration (docs/design.md §1, mapping): one depth image and the camera pose in, updated
// voxels and the blocks and voxels that changed out, so that the ESDF can be updated incrementally
// from them.
//
// Both integrators apply the same per-voxel rule. A return at depth z (optical-frame z [m]) gives
// the voxels along its line of sight sdf = measured - voxel distance, clamped to
// [-truncation, truncation], with weight 1 / z^2 (z clamped below at kMinWeightDepth): full down to
// sdf = -voxel_size, then falling linearly to 0 at sdf = -truncation; voxels deeper than the
// truncation behind the surface are not touched. A voxel moves to the weighted mean
//   d = (w_old d_old + w sdf) / (w_old + w),   weight = min(w_old + w, max_weight),
// so a saturated voxel keeps following new measurements, except that a return within a voxel of a
// voxel stored as clearly free replaces it (new_surfaces_replace), and that behind a new surface
// the free space down to new_surface_shadow past the truncation is reset to unobserved first.
// Pixels that see nothing within range (no return, a return beyond the sensor's max_range or beyond
// max_integration_range) clear the space they looked through up to max_integration_range: sdf =
// truncation, or the distance to the return when it is known and closer than that, with the weight
// of a return at the end of the integration range, 1 / max_integration_range^2, so clearing never
// outweighs a real surface. Returns below the image's min_range are not measurements and are
// ignored.
#pragma once

#include <cstdint>
#include <vector>

#include "thicket/common/depth_image.h"
#include "thicket/common/geometry.h"
#include "thicket/common/params.h"
#include "thicket/common/voxel_layer.h"

namespace thicket::mapper {

struct TsdfIntegratorOptions {
  enum class Method {
    /// Voxel-centric (the default): every voxel of the blocks in the camera frustum is projected
    /// into the image (nearest pixel); its sdf is the projective distance, the measured depth
    /// minus the voxel's optical z. Cost grows with the frustum volume, not with the pixels.
    kProjective,
    /// Ray-centric, for comparison (voxblox's "simple" integrator): each pixel's ray visits the
    /// voxels it passes through (3-D DDA) up to the return plus the truncation; the sdf is the
    /// range of the return minus the voxel centre's distance along the ray.
    kRaycast,
  };
  Method method = Method::kProjective;  ///< "projective" or "raycast"
  /// Truncation distance = this * voxel size.
  double truncation_voxels = 4;
  /// No surface is integrated beyond this, and clearing stops here [m]; measured as optical z by
  /// the projective method and as range along the ray by the ray caster.
  double max_integration_range = 5.0;
  /// Weights saturate here, so that the map can still change.
  double max_weight = 1e4;
  /// Update every voxel the camera sees up to max_integration_range, pixels without a return
  /// within it clearing their line of sight (as above). Off, only the blocks with a voxel within a
  /// voxel of the updated stretch of a return's line of sight are visited (every voxel of such a
  /// block is updated from its pixel, free ones too), and pixels without a return within range say
  /// nothing: the work of Open3D's ScalableTSDFVolume, for surface reconstruction. The planner
  /// needs the observed free space, so the vehicle keeps this on. Projective method only.
  bool carve_free_space = true;
  /// In front of a surface, store the distance along the surface normal (estimated per pixel
  /// from the neighbouring depths; cosine to the line of sight at least 0.3) rather than along
  /// the line of sight, which overstates it by 1 / cosine where the surface is seen at a slant
  /// (`thicket-bench clearance` measures what each choice costs the ESDF's accuracy).
  bool normal_distances = true;
  /// A return within a voxel of a voxel the map had as clearly free (distance beyond half the
  /// truncation) replaces the voxel's history rather than being averaged into it: an obstacle that
  /// appears where the map saw free space many times is in the map at once, not a few frames
  /// later. Only distances toward a surface jump; free space still builds up over frames.
  bool new_surfaces_replace = true;
  /// Behind a new surface, the voxels the map has as free from one voxel behind it down to this
  /// much deeper than the truncation become unobserved again [m]; 0: off. A new surface is a
  /// return within the integration range, seen at a cosine of at least 0.5 to the estimated
  /// normal, whose voxel and the three voxels behind it along the ray the map had as clearly free
  /// before the frame (the probes and the cosine keep trunks seen again at their silhouettes
  /// out). What the map saw there was seen before the surface appeared and is stale: the hidden
  /// part of an obstacle that appeared (a door that swung in, a branch) must not read as free
  /// space. Within the truncation the voxels then take the frame's measurement alone; deeper,
  /// they wait for a view, and the ESDF treats them as it treats unobserved space (occupied near
  /// the vehicle, within its occupied radius). Depths are the method's own: optical z for the
  /// projective integrator, range along the ray for the ray caster. 1 m covers an obstacle up to
  /// 1 m deep behind its visible face, such as the simulator's dynamic obstacle; one thinner than
  /// the probes (three voxels) draws no shadow.
  double new_surface_shadow = 1.0;
  /// Voxels with less weight count as unobserved downstream, as the ESDF's min_weight (the
  /// mapper sets it from there): changed_voxels reports the voxels whose weight crosses it. Not
  /// a parameter of its own.
  double observed_weight = 1e-6;

  void declare(Params& p);
};

struct TsdfIntegrationResult {
  /// Every block with a voxel whose distance or weight changed (newly allocated ones included),
  /// sorted with indexLess, without duplicates.
  std::vector<BlockIndex> changed_blocks;
  /// For each of changed_blocks, the voxels that changed in what the ESDF reads: the distance
  /// (bit for bit), or whether the weight reaches observed_weight.
  std::vector<BlockVoxels> changed_voxels;
  /// The options' observed_weight, as the float the voxels' weights are compared with.
  float observed_weight = 0;
  /// Voxel updates applied; the ray caster counts a voxel once per ray that updates it.
  int64_t voxels_updated = 0;
};

class TsdfIntegrator {
 public:
  /// Weights come from depths no smaller than this [m], so that a return right in front of the
  /// lens cannot dominate a voxel.
  static constexpr double kMinWeightDepth = 0.1;

  /// Throws std::invalid_argument unless the truncation, range and maximum weight are positive
  /// and finite, new_surface_shadow is finite and not negative, and the method is known.
  explicit TsdfIntegrator(TsdfIntegratorOptions options);

  const TsdfIntegratorOptions& options() const { return options_; }

  /// Integrates one depth image seen from world_T_camera (optical frame: z forward, x right,
  /// y down) into layer. Allocates only blocks in which some voxel is updated. Deterministic: the
  /// same inputs give the same layer bit for bit. Throws std::invalid_argument, before changing
  /// the layer, when the image is inconsistent (depth size other than width * height, an invalid
  /// camera or range limits, negative or non-finite depths) or the pose is not finite with a unit
  /// quaternion (within 1e-3).
  TsdfIntegrationResult integrate(const DepthImage& image, const Pose& world_T_camera,
                                  TsdfLayer& layer) const;

 private:
  TsdfIntegratorOptions options_;
};

}  // namespace thicket::mapper

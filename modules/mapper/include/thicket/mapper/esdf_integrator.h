// The incremental Euclidean signed distance field (docs/design.md §1, mapping): the TSDF blocks
// (or voxels) that a depth frame changed, and the vehicle's position, in; the ESDF updated in
// place, and the ESDF blocks that changed, out.
//
// Every voxel gets a class from its TSDF voxel and two spheres ("unknown space is occupied"):
//   - observed (TSDF weight >= min_weight, distance not NaN; compared as floats) with
//     |distance| <= the surface band: a fixed site carrying its TSDF distance, capped at
//     +-max_distance (observed, fixed);
//   - observed beyond the band: free (distance > 0) or inside an obstacle (distance < 0), with
//     the magnitude from propagation (observed, not fixed);
//   - unobserved within clear_radius of the initial position: free (observed, not fixed), so that
//     the vehicle can take off;
//   - otherwise unobserved: an occupied site at distance 0 (occupied_everywhere, the default), or,
//     with the paper's sphere (occupied_everywhere off), one only within occupied_radius of the
//     current position and unknown, outside the propagation, beyond it.
// The layer shows observed voxels with their distance (fixed: a site), and unobserved ones, the
// occupied sites among them, as unknown (distance 0, neither observed nor fixed): its readers
// treat unobserved space as an obstacle, and the sites act through the distances near them.
// Distances propagate from the sites over the 26-neighbourhood (edges of 1, sqrt 2, sqrt 3 voxel
// sizes): a free voxel gets max(0, min over free or site neighbours n of d_n + edge), an inside
// voxel minus the same through inside voxels with the sites' distances negated. Magnitudes
// saturate at max_distance, which is also what voxels that no site reaches within it get.
//
// update() is a raise/lower wavefront over the changes only (a dynamic shortest-path tree with a
// parent direction per voxel); its result equals recompute() on the same TSDF and positions (the
// same flags and blocks, and the same distances bit for bit on the tested flights: each is the one
// fixed point of the propagation, whatever order the wavefront visits voxels in; only the parents
// may differ where paths tie). An ESDF block is allocated exactly when one of its voxels is
// observed, so unobserved space (or the occupied sphere moving through it) changes no block.
// Deterministic: the same calls give the same bytes.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/params.h"
#include "thicket/common/voxel_layer.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::mapper {

struct EsdfIntegratorOptions {
  /// Distances saturate at +-this [m].
  double max_distance = 2.0;
  /// r_c: unobserved voxels this close to the initial position count as observed free [m]. Wins
  /// over occupied_radius where both apply.
  double clear_radius = 1.5;
  /// r_o, the paper's occupied sphere (used only with occupied_everywhere off): unobserved voxels
  /// this close to the current position count as occupied [m]. Smaller than clear_radius is
  /// allowed (then only the clear sphere's outside is occupied near the start).
  double occupied_radius = 5.0;
  /// Unobserved voxels outside the clear sphere are occupied sites wherever they are; false: only
  /// within occupied_radius of the current position (the paper's sphere). Within occupied_radius -
  /// max_distance - one voxel of the current position the distances are the sphere's bit for bit
  /// (a path to a site beyond the sphere is longer than max_distance); farther out they can only
  /// be shorter, and the flags are the same everywhere. Nothing moves with the vehicle, so an
  /// update does only the work its TSDF changes make, and unobserved space takes no state.
  bool occupied_everywhere = true;
  /// Observed voxels with |TSDF distance| <= this * voxel size are fixed sites. Wider than one
  /// voxel, so that surfaces seen at grazing angles (the ground), whose projective distances
  /// stretch by 1 / cos(incidence), still have a site in every voxel column through them.
  double surface_band_voxels = 1.5;
  /// TSDF voxels with less weight than this are unobserved.
  double min_weight = 1e-6;
  /// Observed voxels next to a sign change of the TSDF (a face neighbour observed on the other
  /// side of the surface) are sites too, at no more than the distance to the zero crossing
  /// interpolated between the two: the surface is there, whatever the distances claim.
  bool crossing_sites = true;

  void declare(Params& p);
};

struct EsdfUpdateResult {
  /// ESDF blocks with a voxel whose distance or flags changed, new blocks included; sorted
  /// (indexLess), unique.
  std::vector<BlockIndex> changed_blocks;
  /// For each of changed_blocks, its voxels whose distance or flags changed (after a recompute,
  /// every voxel: the layer was rebuilt from empty).
  std::vector<BlockVoxels> changed_voxels;
  /// ESDF blocks deleted because none of their voxels is observed any more; sorted.
  std::vector<BlockIndex> removed_blocks;
  /// Voxels whose distance or flags changed.
  int64_t voxels_updated = 0;
};

class EsdfIntegrator {
 public:
  /// Throws std::invalid_argument unless every option is positive and finite.
  explicit EsdfIntegrator(EsdfIntegratorOptions options);
  ~EsdfIntegrator();
  EsdfIntegrator(EsdfIntegrator&&) noexcept;
  EsdfIntegrator& operator=(EsdfIntegrator&&) noexcept;

  const EsdfIntegratorOptions& options() const;

  /// The first position of the vehicle, the centre of the clear sphere. Must be called before
  /// update() or recompute(); calling it again with another position makes the next update()
  /// recompute from scratch. Throws std::invalid_argument if p is not finite.
  void setInitialPosition(const Eigen::Vector3d& p);

  /// Incremental: the TSDF blocks in changed_tsdf_blocks (any order, duplicates allowed, blocks
  /// no longer allocated allowed) changed since the last call, and the vehicle is now at
  /// current_position (the occupied sphere moves with it). esdf must be the layer of the previous
  /// call, its blocks neither added nor removed since (a mismatch in the number of blocks throws
  /// std::logic_error). The first call, and the first after the initial position or the voxel
  /// size changed, recomputes from scratch. Throws std::logic_error before setInitialPosition(),
  /// std::invalid_argument if the layers' voxel sizes differ or the position is not finite or
  /// farther than 1e6 m from the origin; the layer is unchanged when it throws so. Throws
  /// std::length_error beyond 2^20 ESDF blocks. After any throw the next call recomputes, so
  /// that no TSDF change is lost.
  EsdfUpdateResult update(const TsdfLayer& tsdf, const std::vector<BlockIndex>& changed_tsdf_blocks,
                          const Eigen::Vector3d& current_position, EsdfLayer& esdf);

  /// The same, from the integration of the one frame since the last call: only the voxels it
  /// reports (changed_voxels) and their face neighbours are classified again, not the whole
  /// changed blocks; the result is the same. The whole blocks are classified again where the
  /// report was made for another weight than min_weight, and where a block is no longer in the
  /// TSDF. Throws std::invalid_argument, the layer unchanged, when an incremental update gets a
  /// report without a voxel set per changed block (a recompute reads no report); otherwise as
  /// above.
  EsdfUpdateResult update(const TsdfLayer& tsdf, const TsdfIntegrationResult& integration,
                          const Eigen::Vector3d& current_position, EsdfLayer& esdf);

  /// The integrator's own memory [bytes]: its per-block wavefront state (each voxel's class,
  /// value and parent, and the block's neighbours) and the capacity of its per-call work lists.
  size_t memoryBytes() const;

  /// From scratch on the whole TSDF: clears esdf and all internal state first. removed_blocks
  /// lists the blocks esdf had before that it no longer has. Throws as update() does.
  EsdfUpdateResult recompute(const TsdfLayer& tsdf, const Eigen::Vector3d& current_position,
                             EsdfLayer& esdf);

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace thicket::mapper

// Distance queries on an ESDF layer, as the planner and the explorer ask them.
#pragma once

#include <Eigen/Core>

#include "thicket/common/voxel_layer.h"

namespace thicket {

/// The ESDF at a point: trilinear between the centres of the 8 voxels around it.
struct EsdfSample {
  /// False when any of the 8 voxels is not observed (or not allocated): the map does not know the
  /// distance there, and a planner must read it as an obstacle. distance and gradient are then 0.
  bool known = false;
  double distance = 0;                                 ///< [m]
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();  ///< of the interpolant [m/m]
};

/// The interpolated distance and its exact gradient (the derivative of the trilinear
/// interpolant, continuous inside a cell). A non-finite p is unknown.
EsdfSample sampleEsdf(const EsdfLayer& esdf, const Eigen::Vector3d& p);

/// Whether the TSDF observed (weight > 0) all 8 voxels sampleEsdf interpolates between at p: a
/// measured distance there, not the take-off sphere's assumed free space. For checking maps
/// against ground truth. A non-finite p is not observed.
bool tsdfObservedAround(const TsdfLayer& tsdf, const Eigen::Vector3d& p);

}  // namespace thicket

// SPDX-License-Identifier: Apache-2.0
// Branch clustering (thesis 4.3.1, Eq. 4.9): Euclidean clustering of the
// HSI-filtered points with a 6 cm tolerance (two points share a cluster when
// a chain of points with gaps <= tolerance joins them), then the choice of
// the closest feasible branch, the one the robot works on.
//
// Exact and fast: points fall into cubic cells of side tolerance / sqrt(3),
// so any two points of one cell are within the tolerance and a cell is
// joined whole; only cells up to two apart are compared, pairwise with an
// early exit and bounding-box shortcuts. Result identical to PCL's
// EuclideanClusterExtraction with the same tolerance (a test checks).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/cloud.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct BranchClusteringParams {
  /// Eq. 4.9 d_threshold [m]. The thesis used 6 cm; 8 cm keeps a truss whole when a hidden
  /// fruit leaves a gap between the red surfaces of its neighbours
  /// (docs/tomato_reasoning.md, held-out trusses).
  double tolerance_m = 0.08;
  /// A branch needs this many points (a 2.5 cm tomato at 0.6 m shows about
  /// 2000 pixels at VGA; fewer is noise, a leaf edge or a far-off fruit).
  int min_points = 150;
  double min_range_m = 0.2;   ///< feasible: the branch centroid is this far from the camera at least [m]
  double max_range_m = 1.2;   ///< ... and at most (the arm's reach) [m]
  double max_extent_m = 0.6;  ///< a cluster wider than this (bounding-box diagonal) is not one branch [m]
};

common::Status validate(const BranchClusteringParams& p);

struct Cluster {
  Indices indices;  ///< into the cloud
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double extent_m = 0.0;  ///< bounding-box diagonal [m]
  double range_m = 0.0;   ///< centroid distance from the nearest viewpoint [m]
  bool feasible = false;
  std::string why_not;  ///< when not feasible
};

struct BranchResult {
  std::vector<Cluster> clusters;  ///< all clusters, largest first
  int chosen = -1;                ///< index into clusters of the closest feasible branch, -1 if none
  /// Not ok when nothing was chosen: InvalidArgument for bad parameters, a
  /// malformed cloud or a candidate outside it, NotFound for no candidates
  /// or no feasible cluster.
  common::Status status;

  [[nodiscard]] const Cluster* branch() const {
    return chosen >= 0 ? &clusters[static_cast<std::size_t>(chosen)] : nullptr;
  }
};

/// Euclidean clusters of `indices` (all finite points of the cloud when empty).
[[nodiscard]] std::vector<Indices> euclidean_clusters(const std::vector<Eigen::Vector3f>& points,
                                                      const Indices& indices, double tolerance_m);

/// Clusters the points and picks the closest feasible branch: the one whose
/// centroid is nearest to a viewpoint (the camera; the origin of the cloud's
/// frame when none is given).
[[nodiscard]] BranchResult cluster_branches(const ColorCloud& cloud, const Indices& candidates,
                                            const BranchClusteringParams& params = {},
                                            const std::vector<Eigen::Vector3f>& viewpoints = {});

}  // namespace tinyline::tomato_reasoning

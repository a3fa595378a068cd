// SPDX-License-Identifier: Apache-2.0
// Smoothing (thesis 4.3.2): moving least squares, as PCL's
// MovingLeastSquares does it (a weighted plane through each point's
// neighbours, then a weighted polynomial height field over that plane; the
// point moves onto the polynomial and takes its normal), after an optional
// voxel-grid thinning that keeps the cloud's shape at a fraction of the
// points. Normals face the viewpoint (the camera), as the sphere hypotheses
// with normals (Eq. 4.12) and the visible-cap test need.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/cloud.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct SmoothingParams {
  /// Voxel-grid thinning before smoothing [m]: each occupied cube keeps the
  /// centroid of its points. 0 keeps every point.
  double voxel_m = 0.003;
  double search_radius_m = 0.012;  ///< MLS neighbourhood [m] (PCL: setSearchRadius)
  int polynomial_order = 2;        ///< 1: plane only; 2: quadratic height field (PCL's default)
  int min_neighbours = 5;          ///< fewer neighbours (itself included): the point is dropped as isolated
  bool project_points = true;      ///< false: keep positions, only estimate normals
};

common::Status validate(const SmoothingParams& p);

struct SmoothedCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;  ///< unit, facing the viewpoint
  std::vector<float> curvature;          ///< surface variation lambda_0 / sum(lambda) of the neighbourhood
  std::vector<std::uint8_t> view;        ///< the view each point's normal faces (index into the viewpoints)
  int dropped_isolated = 0;
  /// Not ok when `points` is empty: InvalidArgument for bad parameters or
  /// views, NotFound for no (finite, non-isolated) points.
  common::Status status;

  [[nodiscard]] std::size_t size() const { return points.size(); }
};

/// Voxel-grid thinning of cloud points `indices`: the centroid per occupied cube.
[[nodiscard]] std::vector<Eigen::Vector3f> voxel_thin(const std::vector<Eigen::Vector3f>& points,
                                                      const Indices& indices, double voxel_m);

/// Thins (voxel_m > 0) and smooths the cloud points `indices`; normals face
/// `viewpoint` (the camera).
[[nodiscard]] SmoothedCloud smooth_mls(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                                       const SmoothingParams& params = {},
                                       const Eigen::Vector3f& viewpoint = Eigen::Vector3f::Zero());

/// The same for points merged from several views: point k was seen from
/// viewpoints[view_of[k]], and each normal faces the viewpoint of the view
/// that saw most of its voxel.
[[nodiscard]] SmoothedCloud smooth_mls(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                                       const SmoothingParams& params, const std::vector<Eigen::Vector3f>& viewpoints,
                                       const std::vector<std::uint8_t>& view_of);

}  // namespace tinyline::tomato_reasoning

// SPDX-License-Identifier: Apache-2.0
// Reflectance clustering (thesis 5.3, Figure 5.8): DBSCAN on position and
// reflectance together, so a metal stick a few millimetres in front of a
// background, indistinguishable by distance (5.8 B), separates by its far
// higher reflectance (5.8 C; Table 3.2: metal 25-37 against 5-7 for paper,
// cardboard or cloth).
//
// Each valid pixel becomes (x, z, s log(reflectance)) with
// s = eps / log(reflectance_ratio_at_eps): two pixels at the same place whose
// reflectances differ by that factor are exactly eps apart. Log, because
// reflectance varies by factors (incidence, material), not by offsets.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/dbscan.hpp"
#include "laser_clustering/line_scan.hpp"

namespace tinyline::laser_clustering {

/// Defaults tuned on simulated Figure 5.8 B scenes (docs/laser_clustering.md):
/// eps about three times the spread of adjacent pixels' distances at 30 cm,
/// so a surface chains whatever its range noise.
struct ReflectanceClusteringParams {
  /// eps in metres of position (and metre-equivalents of scaled log reflectance).
  DbscanParams dbscan{0.015, 5};
  /// Reflectance factor that weighs as much as eps of distance; > 1.
  double reflectance_ratio_at_eps = 1.6;
  /// false: cluster on distance alone (the baseline that fails on Figure 5.8 B).
  bool use_reflectance = true;
  /// Range smoothing before clustering, as in the edge filter: each range
  /// becomes the mean of the ranges within this many pixels that lie within
  /// smooth_step_m of it [pixels]; 0 turns it off.
  int smooth_half_width_px = 2;
  double smooth_step_m = 0.01;
};

/// InvalidArgument naming the field when one is outside its table's range.
[[nodiscard]] common::Status validate(const ReflectanceClusteringParams& params);

struct ReflectanceCluster {
  int id = -1;
  int first_pixel = -1, last_pixel = -1;
  int num_points = 0;
  Eigen::Vector2d centroid_xz_m = Eigen::Vector2d::Zero();
  double mean_range_m = 0.0;
  double median_reflectance = 0.0;
  double width_m = 0.0;  ///< bearing span plus one pixel, times the mean range [m]
};

struct ReflectanceClusteringResult {
  /// InvalidArgument: bad parameters or a malformed scan (the message says which).
  common::Status status;
  std::string note;         ///< on success, what is worth knowing ("no valid pixels", "12 pixels without reflectance")
  std::vector<int> labels;  ///< per pixel: cluster id, kNoise or kInvalid (no range or no positive reflectance)
  std::vector<ReflectanceCluster> clusters;
  int brightest = -1;  ///< index of the cluster with the highest median reflectance, -1 if none
};

/// Needs scan.reflectance unless params.use_reflectance is false.
[[nodiscard]] ReflectanceClusteringResult cluster_by_reflectance(const LineScan& scan,
                                                                 const ReflectanceClusteringParams& params = {});

}  // namespace tinyline::laser_clustering

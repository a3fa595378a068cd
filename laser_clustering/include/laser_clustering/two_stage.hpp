// SPDX-License-Identifier: Apache-2.0
// Two-stage line-scan clustering (thesis 4.4.2, Figure 4.6):
//   1. DBSCAN with a large eps and a large minimum count groups the scan into
//      objects that may touch each other; the trails of mixed pixels at an
//      object's emitter-side edge ("distance drag", up to tens of cm) are too
//      sparse to hold core points, so they cannot bridge groups;
//   2. the edge filter drops the mixed pixels inside every run of a group
//      (a range half-way down a depth step) and peels, from both ends of each
//      piece, the points that step away from its inner points (the dragged,
//      high-variance edge pixels), then smooths the kept ranges without
//      crossing depth steps;
//   3. DBSCAN with a small eps inside each group separates the objects
//      ("each ladder means one cluster").
// Metres everywhere; pixels only where a count of pixels is meant.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/dbscan.hpp"
#include "laser_clustering/line_scan.hpp"

namespace tinyline::laser_clustering {

struct EdgeFilterParams {
  /// How many pixels at each end of a run may be peeled off as dragged.
  int edge_width_px = 4;
  /// Inner points the candidate is compared with (their median); 1 to 16.
  int reference_px = 3;
  /// A candidate is dragged when it differs from that median by more than
  /// step_m + step_per_m * range: about three times the sensor's range noise
  /// (4-7 mm at 10-50 cm, Table 3.1), which grows with range. Tuned on the
  /// simulator (docs/laser_clustering.md).
  double step_m = 0.018;
  double step_per_m = 0.03;
  /// Points a run keeps at least, however dragged its ends look.
  int min_keep_px = 2;
  /// Inside a run, a pixel whose two neighbours differ by more than
  /// mixed_step_m + step_per_m * range, and whose own range lies in the
  /// middle half of that step, is a mixed pixel: dropped, and the run is
  /// cut there (so objects touching in depth do not chain in stage 3).
  double mixed_step_m = 0.015;
  /// Half width of the range smoothing [pixels]; 0 turns it off. Each kept
  /// range becomes the mean of the kept ranges within this many pixels of the
  /// same run that lie within smooth_step_m + step_per_m * range of it, so a
  /// depth step (a pedicel 2 cm before a tomato) is not averaged across.
  int smooth_half_width_px = 2;
  double smooth_step_m = 0.012;
};

/// Defaults tuned on simulated truss scans (held-out seeds, docs/laser_clustering.md).
struct TwoStageParams {
  /// Stage 1: object groups [m]; large eps, large count.
  DbscanParams groups{0.03, 4};
  EdgeFilterParams edge;
  /// Stage 3: objects inside each group [m]; small eps.
  DbscanParams objects{0.008, 2};
};

[[nodiscard]] common::Status validate(const TwoStageParams& params);

/// What happened to a pixel.
enum class PixelFate : std::uint8_t {
  kInvalid = 0,      ///< no usable range
  kNotGrouped = 1,   ///< stage-1 noise (isolated, or a sparse drag trail)
  kEdgeDropped = 2,  ///< peeled off by the edge filter
  kKept = 3,         ///< smoothed and given to stage 3
};

/// One final object (a stage-3 cluster).
struct ScanCluster {
  int id = -1;           ///< its label in TwoStageResult::labels
  int group = -1;        ///< the stage-1 group it lies in
  int first_pixel = -1;  ///< lowest pixel index of its points
  int last_pixel = -1;   ///< highest pixel index of its points
  int num_points = 0;
  Eigen::Vector2d centroid_xz_m = Eigen::Vector2d::Zero();  ///< mean of its (smoothed) points
  double mean_range_m = 0.0;
  double range_sd_m = 0.0;
  /// Lateral extent: the bearing span of its points plus one pixel's
  /// footprint, times its mean range [m] (a thin rod of diameter D measures ~D).
  double width_m = 0.0;
  double mean_reflectance = 0.0;  ///< NaN when the scan has no reflectance
  /// It reaches the first or last pixel of the scan (within one pixel): the
  /// field of view may cut it, so its width is a lower bound.
  bool touches_fov_edge = false;
  /// One of the two valid pixels just beyond that end is nearer than it by
  /// more than the mixed-pixel step (EdgeFilterParams::mixed_step_m + step_per_m
  /// * range): something in front hides part of it.
  bool occluded_low = false;
  bool occluded_high = false;
};

struct TwoStageResult {
  /// InvalidArgument: bad parameters or a malformed scan (the message says which).
  common::Status status;
  std::string note;                      ///< on success, what is worth knowing ("empty scan", "no valid pixels")
  std::vector<int> group_labels;         ///< per pixel: stage-1 group, kNoise or kInvalid
  std::vector<PixelFate> fate;           ///< per pixel
  std::vector<double> smoothed_range_m;  ///< per pixel: the range stage 3 saw (NaN unless kept)
  std::vector<int> labels;               ///< per pixel: final object id, kNoise or kInvalid
  std::vector<ScanCluster> clusters;     ///< one per final object, ordered by id
  int num_groups = 0;
  int num_edge_dropped = 0;
};

/// Runs the three stages; reuses its buffers (one instance per thread).
class LineScanClusterer {
 public:
  explicit LineScanClusterer(TwoStageParams params = {});
  [[nodiscard]] const TwoStageParams& params() const { return params_; }
  [[nodiscard]] TwoStageResult run(const LineScan& scan);
  /// The same into `out`, reusing its storage: a loop that keeps one result
  /// allocates nothing per scan once the sizes settle.
  void run(const LineScan& scan, TwoStageResult& out);

 private:
  // The steps of a run, in order (two_stage.cpp).
  static void reset(TwoStageResult& out);
  common::Status check_once(const LineScan& scan);
  void edge_filter(const LineScan& scan, TwoStageResult& out);
  void filter_run(const LineScan& scan, int group, TwoStageResult& out);
  void filter_piece(int first, int last, int group, TwoStageResult& out);
  bool sum_clusters(const LineScan& scan, TwoStageResult& out);
  void finish_cluster(const LineScan& scan, std::size_t l, TwoStageResult& out) const;

  TwoStageParams params_;
  common::Status valid_;
  OrderedScanDbscan dbscan_;
  DbscanResult groups_, objects_;  // the two DBSCAN passes' results, reused
  std::vector<double> range_, checked_angle_, sum_r2_, sum_refl_;
  std::vector<int> run_, group_, n_refl_;
};

/// One-shot convenience.
[[nodiscard]] TwoStageResult cluster_line_scan(const LineScan& scan, const TwoStageParams& params = {});

}  // namespace tinyline::laser_clustering

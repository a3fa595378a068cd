// SPDX-License-Identifier: Apache-2.0
// Alignment search (thesis 5.3.2): the robot pitches the gripper in small
// steps and records the target surface's reflectance at each; the pitch of
// maximum reflectance is where the sensor faces the wrench squarely. The
// maximum sample is refined between the steps by a least-squares parabola
// through it and its neighbours, on log reflectance by default (a Gaussian
// specular lobe is exactly a parabola in log).
#pragma once

#include <span>
#include <string>

#include "laser_clustering/line_scan.hpp"
#include "laser_clustering/reflectance_clustering.hpp"

namespace tinyline::laser_clustering {

struct AlignmentSample {
  double pitch_rad = 0.0;    ///< gripper pitch when the scan was taken
  double reflectance = 0.0;  ///< the target surface's reflectance in that scan (> 0)
};

struct AlignmentParams {
  /// Samples on each side of the maximum that the parabola fits (>= 1).
  int fit_half_width = 1;
  /// Fit log reflectance (true) or reflectance itself.
  bool fit_log = true;
  /// The maximum must exceed the sweep's median by this factor to be a peak (>= 1).
  double min_peak_ratio = 1.3;
};

/// InvalidArgument naming the field when one is outside its table's range.
[[nodiscard]] common::Status validate(const AlignmentParams& params);

/// The detail beside AlignmentResult::status: a caller extends the sweep on
/// kAtSweepEdge and gives up on kNoPeak, both NotFound; the wire carries it
/// (tinyline_msgs/AlignmentResult's outcome).
enum class AlignmentOutcome {
  kFound,         ///< an interior peak; best_pitch_rad is refined between the steps (status ok)
  kAtSweepEdge,   ///< the maximum is the first or last pitch: extend the sweep that way (NotFound)
  kNoPeak,        ///< the sweep is flat (no target, or no specular surface in view) (NotFound)
  kInvalidInput,  ///< bad parameters or too few usable samples (InvalidArgument)
};
[[nodiscard]] const char* to_string(AlignmentOutcome o);

struct AlignmentResult {
  AlignmentOutcome outcome = AlignmentOutcome::kInvalidInput;
  /// Why no peak: InvalidArgument (kInvalidInput), NotFound (kAtSweepEdge, kNoPeak).
  common::Status status;
  std::string note;  ///< on kFound, where the peak is and whether it was refined
  double best_pitch_rad = 0.0;
  double peak_reflectance = 0.0;  ///< at best_pitch_rad (from the fit when refined)
  int peak_sample = -1;           ///< index of the maximum among the usable samples, sorted by pitch
  bool refined = false;           ///< false: the parabola was not concave, best_pitch_rad is the sample's
  int num_samples = 0;            ///< usable samples
};

/// Samples may come in any order; non-finite or non-positive ones are skipped.
/// Samples at the same pitch are averaged.
[[nodiscard]] AlignmentResult find_alignment(std::span<const AlignmentSample> samples,
                                             const AlignmentParams& params = {});

/// How one scan's target reflectance is measured.
struct SurfaceReflectanceParams {
  enum class Method {
    /// The `quantile` of the valid pixels' reflectance in the region: the
    /// brightest surface in view (a metal's specular return) without
    /// segmenting it. Robust when the metal is no brighter than its
    /// background away from the peak (a polished wrench on a grey panel).
    kTopQuantile,
    /// The median reflectance of the brightest reflectance cluster: needs
    /// the metal to separate from its background at every pitch.
    kBrightestCluster,
  };
  Method method = Method::kTopQuantile;
  double quantile = 0.95;  ///< kTopQuantile, in (0, 1]
  /// kTopQuantile: also count invalid pixels with a finite reflectance, the
  /// lower bounds of saturated pixels (saturated_reflectance_bound): else a
  /// specular peak that saturates even the fewest-pulse read-out vanishes
  /// from the sweep exactly at its maximum.
  bool use_saturated = true;
  /// Region of interest, pixel indices inclusive (last_pixel < 0: to the end).
  int first_pixel = 0;
  int last_pixel = -1;
  ReflectanceClusteringParams clustering;  ///< kBrightestCluster
};

/// InvalidArgument naming the field or the rule: a field outside its table's
/// range, or a region that ends before it starts.
[[nodiscard]] common::Status validate(const SurfaceReflectanceParams& params);

struct SurfaceReflectance {
  /// InvalidArgument: bad parameters or a malformed scan; NotFound: no pixel
  /// or cluster with a reflectance in the region.
  common::Status status;
  double reflectance = 0.0;
  int cluster = -1;  ///< kBrightestCluster: index into the clustering's clusters
};
/// One alignment sample's reflectance from a scan.
[[nodiscard]] SurfaceReflectance surface_reflectance(const LineScan& scan, const SurfaceReflectanceParams& params = {});

}  // namespace tinyline::laser_clustering

// SPDX-License-Identifier: Apache-2.0
// Tomato registration: where the vision's truss really is, from one line
// scan taken through its tomatoes.
//
// The pedicel finder's hardest trials (Table 4.3's "mistaken the nearby
// pedicels as target") are those where the vision's whole recognition result
// is off by a few centimetres and a neighbouring pedicel then sits nearer the
// expected point than the target. Pedicels are thin and alike; tomatoes are
// big, each a different size and height, and the vision knows them to a few
// millimetres (thesis 4.4.1 detects the tomatoes first). Lowering the laser
// plane through them and fitting the vision's tomato cross-sections to the
// scan measures the vision's common offset directly: every tomato votes, and
// a shift by one pedicel spacing fits only where the truss happens to repeat.
//
// Frames: the laser frame of the scan (z forward along the optical axis, x
// along the line, y = z x x, across the plane). A sphere of radius R whose
// centre is y off the plane shows as a circle of radius sqrt(R^2 - y^2);
// the scan sees its near arc.
#pragma once

#include <span>
#include <string>

#include <Eigen/Core>

#include "laser_clustering/dbscan.hpp"
#include "laser_clustering/line_scan.hpp"

namespace tinyline::laser_clustering {

/// A tomato as the vision sees it, in the scan's laser frame.
struct ExpectedTomato {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
  double radius_m = 0.03;
};

struct TomatoRegistrationParams {
  /// The vision's common offset is searched within this of zero, in the
  /// plane [m] (Table 4.3's offsets are under 5 cm; a pedicel hangs up to
  /// 2 cm off its tomato's vertical). It bounds the grid search; the
  /// refinement follows the returns and may end a little beyond it.
  double max_shift_m = 0.07;
  double grid_step_m = 0.0025;  ///< coarse search step [m]; then a 4x finer grid around the best, then Gauss-Newton
  /// A return within this of a shifted cross-section's near arc supports the
  /// shift (range noise, calibration bias, the vision's per-tomato error) [m].
  double inlier_m = 0.01;
  /// A cross-section narrower than this is too small to show (the plane
  /// grazes the tomato's top or bottom) and is left out [m].
  double min_section_radius_m = 0.01;
  double min_range_m = 0.05;  ///< returns outside the working range are ignored [m]
  double max_range_m = 0.40;
  /// Free space: a pixel whose ray would pass through the middle of a
  /// shifted cross-section (within core_fraction of its radius from the
  /// centre) but returns from more than free_space_margin_m behind its near
  /// arc, or not at all, shows that no tomato is there; each such pixel
  /// costs violation_cost of an inlier's support. It is what tells a shift
  /// by one tomato apart from the true one when the arcs alone fit both.
  double core_fraction = 0.7;
  double free_space_margin_m = 0.02;
  double violation_cost = 1.0;
  double no_return_cost = 0.5;  ///< the same for a pixel with no valid return
  /// Tomatoes whose arcs the best shift must meet, each with at least
  /// min_points_per_tomato returns, for a registration.
  int min_tomatoes = 2;
  int min_points_per_tomato = 6;
  /// A second-best shift farther than this from the best (a different
  /// pairing of arcs and tomatoes) with at least ambiguity_ratio of its
  /// support makes the registration ambiguous [m].
  double distinct_shift_m = 0.02;
  double ambiguity_ratio = 0.8;
};

/// InvalidArgument naming the field or the rule: a field outside its table's
/// range, a grid step over max_shift_m, or min_range_m not below max_range_m.
[[nodiscard]] common::Status validate(const TomatoRegistrationParams& params);

struct TomatoRegistration {
  /// Ok: a clear shift was found. InvalidArgument: bad parameters, scan or
  /// tomatoes; NotFound: no tomato in the plane, no return in range, too few
  /// tomatoes met, or an ambiguous shift (the message says which).
  common::Status status;
  std::string note;  ///< when ok, how well the shift fits (tomatoes matched, returns, RMS)
  /// Add this to every position the vision expected (in the plane) to get
  /// where the truss is [m].
  Eigen::Vector2d shift_xz_m = Eigen::Vector2d::Zero();
  int tomatoes_in_plane = 0;  ///< expected cross-sections wide enough to show
  int tomatoes_matched = 0;   ///< of those, met by the scan at the shift
  int inliers = 0;            ///< returns on a shifted near arc
  double rms_m = 0.0;         ///< their RMS distance to it [m]
  double support =
      0.0;  ///< the best shift's score (sum over inliers of 1 - (d / inlier_m)^2, less free-space violations)
  int violations = 0;              ///< pixels that see through a shifted tomato
  double runner_up_support = 0.0;  ///< the best distinct shift's
  Eigen::Vector2d runner_up_shift_xz_m = Eigen::Vector2d::Zero();
};

/// Fits the vision's tomatoes to `scan`, shifted together in the plane: a
/// grid search over the shift (robust support: truncated quadratic on the
/// distance to the nearest shifted near arc), then Gauss-Newton on the
/// inliers. Bad parameters, a non-finite or non-positive tomato, or an empty
/// list give a status that is not ok, never an exception.
[[nodiscard]] TomatoRegistration register_tomatoes(const LineScan& scan, std::span<const ExpectedTomato> tomatoes,
                                                   const TomatoRegistrationParams& params = {});

}  // namespace tinyline::laser_clustering

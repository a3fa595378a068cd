// SPDX-License-Identifier: Apache-2.0
// A box seen from the side (thesis Figure 6.7 A): in the sensing plane the
// scan points of a rectangular object lie on one or two perpendicular sides
// of a rectangle. Robust fit: MSAC for the first side (2-point line
// hypotheses), MSAC for a perpendicular second side among the rest (1-point
// hypotheses, its corner at an end of the first side), then a joint
// least-squares fit of the two sides sharing one orientation, re-selecting
// the inliers. With the box's size known, its centre follows from the
// visible sides (and, for one visible side, from the side of the viewpoints).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrus_fitting/circle_fit.hpp"

namespace tinyline::hydrus_fitting {

struct RectangleFitParams {
  double inlier_threshold_m = 0.015;  ///< orthogonal distance to a side counted as support
  int min_points_per_side = 8;        ///< a side with fewer inliers does not count
  int max_iterations = 500;
  double confidence = 0.999;
  double max_corner_gap_m = 0.05;  ///< second side's corner within this of the first side's end
  int refine_rounds = 3;
  std::uint64_t seed = 1;
  /// Side lengths of the box [m] (any order), if known: gives the centre.
  std::optional<Eigen::Vector2d> known_size_m;
};

struct RectangleFit {
  common::Status status{common::StatusCode::NotFound, ""};  ///< the message says why when not ok
  FitStatus detail = FitStatus::kTooFewPoints;              ///< the finer case, kOk when ok
  int sides_visible = 0;                                    ///< 1 or 2
  double yaw_rad = 0.0;                                     ///< direction u1 of the first side, in (-pi/2, pi/2]
  Eigen::Vector2d u1 = Eigen::Vector2d::UnitX(),
                  u2 = Eigen::Vector2d::UnitY();       ///< side directions (u2 = u1 turned +90 deg)
  Eigen::Vector2d corner_m = Eigen::Vector2d::Zero();  ///< where the sides meet (2 sides) or the first side's start (1)
  Eigen::Vector2d extent_m = Eigen::Vector2d::Zero();  ///< visible length along u1 and u2 from the corner (signed)
  /// Box centre: from known_size_m when given; with two sides and no size,
  /// the centre of the visible extents (a box at least that big).
  std::optional<Eigen::Vector2d> centre_m;
  Eigen::Vector2d size_m = Eigen::Vector2d::Zero();  ///< along u1, u2 (known or visible)
  double rms_residual_m = 0.0;
  int points_used = 0;
  int points_side1 = 0, points_side2 = 0;
  int non_finite = 0;
  std::vector<std::uint8_t> side_of_point;  ///< per input point: 0 none, 1 or 2

  [[nodiscard]] bool ok() const { return status.ok(); }
  /// Sets status and detail together.
  void set_outcome(FitStatus d, std::string message = {}) {
    detail = d;
    status = fit_status(d, std::move(message));
  }
};

/// The parameter check fit_rectangle makes first.
common::Status validate(const RectangleFitParams& params);

[[nodiscard]] RectangleFit fit_rectangle(const Eigen::Ref<const Eigen::Matrix2Xd>& points,
                                         const RectangleFitParams& params = {}, const Viewpoints& viewpoints = {});

}  // namespace tinyline::hydrus_fitting

// SPDX-License-Identifier: Apache-2.0
// The two calibrations of thesis 4.2.3, as tools:
//
//   Depth correction of a structured-light camera: z_c = z + Z(u, v) + theta(z),
//   a per-region offset Z over the image (a grid of cells) plus a polynomial
//   in the measured depth, fitted by linear least squares to frames of
//   targets at known depth.
//   Hand-to-head camera calibration: the hand camera's pose in the head
//   camera's frame, refined by ICP from the kinematic guess on one scene both
//   cameras see (Eq. 4.5: x_r = R_r x + t_r).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "tomato_reasoning/cloud.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct DepthSample {
  int u = 0, v = 0;         ///< pixel
  double measured_m = 0.0;  ///< the camera's depth z
  double true_m = 0.0;      ///< the target's depth there
};

struct DepthCorrectionParams {
  int cells_u = 16;  ///< Z(u, v) is constant on a cells_u x cells_v grid over the image
  int cells_v = 12;
  int degree = 2;  ///< theta(z) = sum_{k=1..degree} c_k z^k (its constant is Z's)
};

common::Status validate(const DepthCorrectionParams& p);

struct DepthCorrection {
  /// InvalidArgument: bad parameters or image size, too few usable samples, a
  /// depth range too narrow to fit; NotFound when never fitted.
  common::Status status{common::StatusCode::NotFound, "not fitted"};
  std::string note;  ///< on a fitted model: what it could not fit (cells without samples)
  int width = 0, height = 0;
  DepthCorrectionParams params;
  std::vector<double> cell_offset_m;  ///< Z per cell, row-major (cells_v rows)
  std::vector<double> theta;          ///< c_1 .. c_degree [m / m^k]
  std::size_t samples_used = 0;
  int empty_cells = 0;                           ///< cells without samples (their Z is 0)
  double rms_before_m = 0.0, rms_after_m = 0.0;  ///< on the fitting samples

  /// z_c for pixel (u, v); z unchanged when not fitted or the pixel is outside the image.
  [[nodiscard]] double correct(int u, int v, double z_m) const;
};

/// Fits Z and theta to samples of an image of width x height pixels. Samples
/// with non-finite depths or pixels outside the image are skipped.
[[nodiscard]] DepthCorrection fit_depth_correction(const std::vector<DepthSample>& samples, int width, int height,
                                                   const DepthCorrectionParams& params = {});

struct HandToHeadParams {
  double voxel_m = 0.003;  ///< both clouds are thinned to this before ICP [m]
  /// Only points nearer than this to their camera take part [m]: the
  /// calibration object (a truss, a box), not the walls and floor behind it,
  /// along which ICP slides.
  double max_range_m = 0.8;
  double max_correspondence_m = 0.03;  ///< ICP pairs farther apart are ignored [m]
  int max_iterations = 60;
  double min_overlap = 0.3;  ///< share of hand points that must find a partner
};

struct HandToHeadResult {
  /// InvalidArgument for unusable clouds, guess or parameters; NotFound when
  /// ICP did not converge or too few points paired; ok when the pose holds.
  common::Status status{common::StatusCode::NotFound, ""};
  Eigen::Isometry3d T_head_hand = Eigen::Isometry3d::Identity();
  double rms_m = 0.0;    ///< RMS distance of the final pairs [m]
  double overlap = 0.0;  ///< share of the hand's (thinned) points paired
  [[nodiscard]] bool ok() const { return status.ok(); }
};

/// The hand camera's pose in the head camera's frame from a guess (the
/// robot's kinematics) and one scene both see; clouds in their camera's frame.
[[nodiscard]] HandToHeadResult calibrate_hand_to_head(const ColorCloud& head, const ColorCloud& hand,
                                                      const Eigen::Isometry3d& T_head_hand_guess,
                                                      const HandToHeadParams& params = {});

}  // namespace tinyline::tomato_reasoning

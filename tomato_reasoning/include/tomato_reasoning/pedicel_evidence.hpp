// SPDX-License-Identifier: Apache-2.0
// Pedicel evidence from what the camera sees (beyond thesis 4.3.3): where the
// fused cloud holds green points of a fruit's calyx or pedicel (thin, green,
// on the top of the fruit), they say where the pedicel leaves it. The force
// model's distribution (reasoning.hpp) is the prior, the seen direction the
// likelihood (a von Mises-Fisher density whose concentration grows with the
// points that support it), and the pick uses the posterior. Where nothing is
// seen the prior stands unchanged.
//
//   Sighting: green points in a shell around the fruit (from just inside its
//   surface to `shell_outer_m` beyond it), within `max_prior_angle_deg` of
//   the prior's expected direction and nearer this fruit than any other; a
//   mean shift on their directions from the centre finds the strongest
//   bundle, whose mean direction is the seen one (a line fitted to the
//   pedicel's first centimetres or the calyx disc's normal did worse on the
//   tuning trusses: `direction_source`). The camera sees a thin rod's near
//   side: each point is pushed back along its ray by the pedicel's radius.
//   Posterior: prior = mixture of vMF(mu_i, kp) over the force model's draws,
//   likelihood vMF(m, ko); each component's product is vMF(kp mu_i + ko m)
//   with a weight from the normalising constants; the draws are resampled by
//   those weights.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/cloud.hpp"
#include "tomato_reasoning/reasoning.hpp"
#include "tomato_reasoning/sphere_ransac.hpp"

#include <tinyline/common/validation.hpp>

namespace tinyline::tomato_reasoning {

struct PedicelEvidenceParams {
  bool enabled = true;  ///< false: the force model's distribution alone (the thesis)
  /// A point is green when its green channel exceeds red and blue by this
  /// many 8-bit counts (ripe fruit, the wall and highlights do not).
  int green_margin = 12;
  int min_intensity = 15;             ///< (r + g + b) / 3 at least [0, 255]
  double shell_inner_m = 0.006;       ///< points from this far inside the fruit's surface ...
  double shell_outer_m = 0.025;       ///< ... to this far beyond it [m]
  double max_prior_angle_deg = 60.0;  ///< look only within this of the prior's expected direction
  double cone_deg = 20.0;             ///< the mean shift's window [deg]
  double calyx_depth_m = 0.004;       ///< points beyond surface + this are pedicel, not calyx [m]
  double calyx_cone_deg = 35.0;       ///< calyx points within this of the bundle (the disc spans ~24 deg) [deg]
  double line_reach_m = 0.015;        ///< the pedicel's line is fitted up to this beyond the surface [m]
  /// 0: the bundle's mean direction from the centre (seen error median 8.5
  /// deg on tuning trusses 21-32, elastic rods); 1: the pedicel's line, else
  /// the calyx disc's normal, else the mean direction (worse there).
  int direction_source = 0;
  int min_points = 6;             ///< fewer supporting points: not seen
  int min_pedicel_points = 4;     ///< pedicel points needed to take the direction from them
  double rod_radius_m = 0.003;    ///< pushed back along the ray by this (a thin rod's near side) [m]
  double kappa_per_point = 15.0;  ///< likelihood concentration per supporting point
  /// ... at most (the points' errors are not independent): 120 trades the
  /// direction error (9.6 deg at 120, 10.2 at 60) against HPD50 coverage
  /// (26 % at 120, 36 % at 60) on tuning trusses 21-30, elastic rods.
  double kappa_max = 120.0;
  double cut_band_m = 0.004;  ///< seen cut point: pedicel points this close to the cut distance [m]
};

common::Validation validate(const PedicelEvidenceParams& p);

/// The cheap colour test of a calyx, pedicel, stem or leaf point.
[[nodiscard]] bool is_green(const Rgb& c, const PedicelEvidenceParams& p);

/// What the camera saw of one fruit's pedicel.
struct PedicelSighting {
  bool seen = false;
  int points = 0;                                        ///< supporting points (calyx and pedicel)
  int pedicel_points = 0;                                ///< ... of which beyond the calyx
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit, from the centre along the seen pedicel
  double kappa = 0.0;                                    ///< the likelihood's concentration
  bool cut_point_seen = false;
  Eigen::Vector3d cut_point = Eigen::Vector3d::Zero();  ///< on the seen pedicel at the cut distance [m]
};

/// Green points of the fused cloud with the camera each was seen from.
struct GreenPoints {
  std::vector<Eigen::Vector3f> xyz;
  std::vector<std::uint8_t> view;  ///< index into `viewpoints`
  std::vector<Eigen::Vector3f> viewpoints;
};

/// The sighting of sphere `index`'s pedicel; `cut_distance_m` from the
/// centre is where a seen cut point is looked for.
[[nodiscard]] PedicelSighting sight_pedicel(const GreenPoints& green, const std::vector<Sphere>& spheres, int index,
                                            const Eigen::Vector3d& prior_dir, double cut_distance_m,
                                            const PedicelEvidenceParams& params = {});

/// The prior with the sighting's likelihood: the expected direction, the
/// distribution, the spreads and the gravity angle of the posterior; the
/// prior unchanged when nothing was seen.
[[nodiscard]] PedicelEstimate pedicel_posterior(const PedicelEstimate& prior, const PedicelSighting& sighting,
                                                const Eigen::Vector3d& gravity);

}  // namespace tinyline::tomato_reasoning

// SPDX-License-Identifier: Apache-2.0
// The parameter tables of tomato_reasoning's settings: each field's name in
// launch files, unit, range and meaning, described once
// (<tinyline/common/param_table.hpp>). The nodes declare their parameters
// from these, `tinyline describe` and docs/parameters.md show them.
#pragma once

#include <tinyline/common/param_table.hpp>

#include "tomato_reasoning/branch_clustering.hpp"
#include "tomato_reasoning/harvest.hpp"
#include "tomato_reasoning/pedicel_evidence.hpp"
#include "tomato_reasoning/hsi_filter.hpp"
#include "tomato_reasoning/pick_pose.hpp"
#include "tomato_reasoning/pipeline.hpp"
#include "tomato_reasoning/reasoning.hpp"
#include "tomato_reasoning/smoothing.hpp"
#include "tomato_reasoning/sphere_ransac.hpp"

namespace tinyline::tomato_reasoning {

template <class S, class V>
requires common::SettingsOf<S, HsiFilterParams>
void for_each_param(S& p, V&& v) {
  v(p.h_min_deg, {"h_min_deg", "deg", -180.0, 180.0, "HSI filter hue range, low end"});
  v(p.h_max_deg, {"h_max_deg", "deg", -180.0, 180.0, "HSI filter hue range, high end"});
  v(p.s_min, {"s_min", "", 0, 255, "saturation range, low end"});
  v(p.s_max, {"s_max", "", 0, 255, "saturation range, high end"});
  v(p.i_min, {"i_min", "", 0, 255, "intensity range, low end"});
  v(p.i_max, {"i_max", "", 0, 255, "intensity range, high end"});
}

template <class S, class V>
requires common::SettingsOf<S, BranchClusteringParams>
void for_each_param(S& p, V&& v) {
  v(p.tolerance_m, {"tolerance_m", "m", 1e-3, 1.0, "Euclidean branch clustering distance (Eq. 4.9)"});
  v(p.min_points, {"min_points", "", 1, 10'000'000, "points a branch has at least"});
  v(p.min_range_m, {"min_range_m", "m", 0.0, 10.0, "nearest feasible branch (its centroid from the camera)"});
  v(p.max_range_m, {"max_range_m", "m", 0.05, 10.0, "farthest feasible branch"});
  v(p.max_extent_m,
    {"max_extent_m", "m", 1e-3, 10.0, "a cluster wider than this (bounding-box diagonal) is not one branch"});
}

template <class S, class V>
requires common::SettingsOf<S, SmoothingParams>
void for_each_param(S& p, V&& v) {
  v(p.voxel_m, {"voxel_m", "m", 0.0, 0.1, "voxel-grid thinning before smoothing (0: every point)"});
  v(p.search_radius_m, {"search_radius_m", "m", 1e-4, 0.5, "MLS neighbourhood"});
  v(p.polynomial_order, {"polynomial_order", "", 1, 2, "1: plane only; 2: quadratic height field"});
  v(p.min_neighbours, {"min_neighbours", "", 3, 10000, "fewer neighbours (itself included): the point is dropped"});
  v(p.project_points, {"project_points", "", {}, {}, "move points onto the fitted surface (false: normals only)"});
}

/// The words of SphereHypothesis.
inline constexpr common::Choice<SphereHypothesis> kSphereHypotheses[] = {
    {"four_points", SphereHypothesis::kFourPoints},
    {"two_points_with_normals", SphereHypothesis::kTwoPointsWithNormals},
};

template <class S, class V>
requires common::SettingsOf<S, SphereRansacParams>
void for_each_param(S& p, V&& v) {
  v(p.radius_min_m, {"radius_min_m", "m", 0.005, 0.2, "smallest tomato radius"});
  v(p.radius_max_m, {"radius_max_m", "m", 0.005, 0.2, "largest tomato radius"});
  v(p.inlier_distance_m, {"inlier_distance_m", "m", 1e-5, 0.1, "|distance to the surface| of an inlier"});
  v(p.normal_tolerance_deg, {"normal_tolerance_deg", "deg", -1.0, 89.9,
                             "an inlier's normal lies within this of the radial direction (<= 0: off)"});
  v(p.hypothesis, {"hypothesis", "", {}, {}, "minimal sample of a hypothesis"}, kSphereHypotheses);
  v(p.max_iterations, {"max_iterations", "", 1, 1'000'000, "hypotheses per round at most"});
  v(p.confidence, {"confidence", "", 0.5, 0.999999, "early stop: P(at least one all-inlier sample) (Eq. 4.15)"});
  v(p.local_sampling, {"local_sampling", "", {}, {}, "draw a hypothesis's other points near its first"});
  v(p.min_inliers, {"min_inliers", "", 4, 1'000'000, "inliers a sphere needs"});
  v(p.min_remaining, {"min_remaining", "", 4, 1'000'000, "stop when fewer points remain"});
  v(p.max_spheres, {"max_spheres", "", 1, 1000, "spheres at most"});
  v(p.max_failed_rounds, {"max_failed_rounds", "", 1, 1000, "stop after this many rounds in a row without a sphere"});
  v(p.max_overlap_m, {"max_overlap_m", "m", 0.0, 0.2, "a new sphere may reach this far into an accepted one"});
  v(p.removal_factor, {"removal_factor", "", 1.0, 100.0,
                       "points within this many inlier distances of an accepted sphere are removed with it"});
  v(p.refine, {"refine", "", {}, {}, "geometric least squares within the radius range"});
  v(p.seed, {"seed", "", 0, 2e9, "sampling seed (reproducible)"});
}

template <class S, class V>
requires common::SettingsOf<S, NoiseBiasParams>
void for_each_param(S& p, V&& v) {
  v(p.enabled, {"enabled", "", {}, {}, "remove the spheres' bias under depth noise (false: as segmented)"});
  v(p.band_m, {"band_m", "m", 1e-4, 0.1, "raw points within this of the sphere's front along their ray"});
  v(p.min_cos, {"min_cos", "", 0.0, 0.999, "rays meeting the surface at least this squarely"});
  v(p.min_points, {"min_points", "", 3, 1'000'000, "front points needed to measure the noise"});
  v(p.radius_bias_m, {"radius_bias_m", "m", -0.02, 0.02, "radius added at zero noise"});
  v(p.radius_per_var, {"radius_per_var", "1/m", -1e4, 1e4, "radius added per depth noise variance"});
  v(p.centre_bias_m, {"centre_bias_m", "m", -0.02, 0.02, "centre moved away from the cameras at zero noise"});
  v(p.centre_per_var, {"centre_per_var", "1/m", -1e4, 1e4, "centre moved away per depth noise variance"});
}

template <class S, class V>
requires common::SettingsOf<S, ForceModelParams>
void for_each_param(S& p, V&& v) {
  v(p.contact_tolerance_m, {"contact_tolerance_m", "m", 0.0, 0.1, "contact graph tolerance d_e (Eq. 4.17)"});
  v(p.eps_mean, {"eps_mean", "", 0.0, 1.0, "interaction weight mean (Eq. 4.19)"});
  v(p.eps_variance, {"eps_variance", "", 1e-6, 10.0, "interaction weight variance (Eq. 4.19)"});
  v(p.eps_max, {"eps_max", "", 1e-6, 100.0, "interaction weights are truncated to [0, eps_max)"});
  v(p.weight_exponent, {"weight_exponent", "", 0.0, 10.0, "a tomato's weight grows as radius^exponent"});
  v(p.kernel_kappa, {"kernel_kappa", "", 0.0, 1e6,
                     "vMF kernel concentration of the pedicel distribution (default: fitted for calibrated HPD "
                     "regions; 0: the thesis's model)"});
  v(p.samples, {"samples", "", 10, 100000, "Monte Carlo draws per tomato"});
  v(p.seed, {"seed", "", 0, 2e9, "Monte Carlo seed (reproducible)"});
}

template <class S, class V>
requires common::SettingsOf<S, PickOrderParams>
void for_each_param(S& p, V&& v) {
  v(p.w_energy_per_m, {"w_energy_per_m", "1/m", 0.0, 1e6, "Eq. 4.23 sigma_1: per metre of height"});
  v(p.w_edges, {"w_edges", "", 0.0, 1e6, "Eq. 4.23 sigma_2: per contact edge"});
  v(p.w_angle_per_rad, {"w_angle_per_rad", "1/rad", 0.0, 1e6, "Eq. 4.23 sigma_3: per radian off straight up"});
  v(p.edge_softness_m, {"edge_softness_m", "m", 0.0, 0.05,
                        "a contact counts fully below d_e - this, not above d_e + this (0: Eq. 4.23's count)"});
}

template <class S, class V>
requires common::SettingsOf<S, CutParams>
void for_each_param(S& p, V&& v) {
  v(p.scissor_opening_m, {"scissor_opening_m", "m", 1e-3, 0.2, "blade opening"});
  v(p.cut_offset_m, {"cut_offset_m", "m", 0.0, 0.1, "cut beyond the fruit's surface along the pedicel"});
  v(p.candidates, {"candidates", "", 1, 100000, "cut directions tried (draws of the distribution)"});
}

template <class S, class V>
requires common::SettingsOf<S, PedicelEvidenceParams>
void for_each_param(S& p, V&& v) {
  v(p.enabled, {"enabled", "", {}, {}, "use the seen calyx and pedicel (false: the force model alone)"});
  v(p.green_margin, {"green_margin", "", 0, 255, "green channel above red and blue by this: a calyx/pedicel point"});
  v(p.min_intensity, {"min_intensity", "", 0, 255, "(r + g + b) / 3 of a green point at least"});
  v(p.shell_inner_m, {"shell_inner_m", "m", 0.0, 0.05, "green points from this far inside the fruit's surface"});
  v(p.shell_outer_m, {"shell_outer_m", "m", 1e-3, 0.1, "... to this far beyond it"});
  v(p.max_prior_angle_deg,
    {"max_prior_angle_deg", "deg", 1.0, 180.0, "look only within this of the force model's expected direction"});
  v(p.cone_deg, {"cone_deg", "deg", 1.0, 89.0, "mean-shift window on the points' directions"});
  v(p.calyx_depth_m, {"calyx_depth_m", "m", 0.0, 0.05, "points beyond the surface + this are pedicel"});
  v(p.calyx_cone_deg, {"calyx_cone_deg", "deg", 1.0, 89.0, "calyx points within this of the bundle"});
  v(p.line_reach_m, {"line_reach_m", "m", 1e-3, 0.1, "the pedicel's line is fitted up to this beyond the surface"});
  v(p.direction_source, {"direction_source", "", 0, 1, "0: mean direction of the bundle; 1: line, disc, mean"});
  v(p.min_points, {"min_points", "", 1, 100000, "supporting points of a sighting at least"});
  v(p.min_pedicel_points, {"min_pedicel_points", "", 1, 100000, "pedicel points to take the direction from them"});
  v(p.rod_radius_m, {"rod_radius_m", "m", 0.0, 0.02, "points pushed back along their ray by this"});
  v(p.kappa_per_point, {"kappa_per_point", "", 1e-3, 1e6, "likelihood concentration per supporting point"});
  v(p.kappa_max, {"kappa_max", "", 1e-3, 1e6, "likelihood concentration at most"});
  v(p.cut_band_m, {"cut_band_m", "m", 1e-4, 0.05, "seen cut point: pedicel points this close to the cut distance"});
}

template <class S, class V>
requires common::SettingsOf<S, PipelineParams>
void for_each_param(S& p, V&& v) {
  common::nest(p.hsi, "hsi.", v);
  common::nest(p.branch, "branch.", v);
  common::nest(p.smoothing, "smoothing.", v);
  common::nest(p.spheres, "spheres.", v);
  common::nest(p.noise_bias, "noise_bias.", v);
  common::nest(p.force, "force.", v);
  common::nest(p.pick, "pick.", v);
  common::nest(p.cut, "cut.", v);
  common::nest(p.pedicel, "pedicel.", v);
  v(p.gravity, {"gravity", "", -1e6, 1e6, "gravity direction in the cloud's frame (3 numbers, normalised)"});
}

template <class S, class V>
requires common::SettingsOf<S, BladeBox>
void for_each_param(S& p, V&& v) {
  v(p.opening_m, {"opening_m", "m", 0.001, 0.2, "the blades' opening across the throat"});
  v(p.reach_m, {"reach_m", "m", 0.001, 0.2, "how far along the blades, either side of the throat, they close"});
  v(p.thickness_m, {"thickness_m", "m", 0.0, 0.05, "through the two blade layers"});
  v(p.margin_m, {"margin_m", "m", 0.0, 0.05, "every reconstructed fruit stays this far outside the blades' box"});
}

template <class S, class V>
requires common::SettingsOf<S, PickPoseParams>
void for_each_param(S& p, V&& v) {
  v(p.throat_z_m, {"throat_z_m", "m", 0.01, 1.0, "blade throat along the hand laser's axis"});
  v(p.approach_from, {"approach_from", "m", -1e6, 1e6,
                      "where the robot comes from, reference frame (3 numbers): the laser looks from this side"});
  v(p.max_move_m, {"max_move_m", "m", 0.0, 1.0, "a longer move is not trusted: nothing found"});
  v(p.view_clearance_m,
    {"view_clearance_m", "m", 0.0, 0.1, "the laser's view of the throat clears other fruit by this"});
  v(p.max_turn_deg,
    {"max_turn_deg", "deg", 0.0, 180.0,
     "turn the picking pose about the pedicel by up to this to see past a fruit (0: straight approach)"});
  common::nest(p.blades, "blades.", v);
  v(p.cut_offsets_m, {"cut_offsets_m", "m", 0.0, 0.05,
                      "cut points tried beyond the fruit's surface along the pedicel, the first preferred"});
  v(p.roll_step_deg, {"roll_step_deg", "deg", 1.0, 90.0, "the blades' roll about the pedicel is tried in these steps"});
}

template <class S, class V>
requires common::SettingsOf<S, HarvestParams>
void for_each_param(S& p, V&& v) {
  v(p.max_attempts, {"max_attempts", "", 1, 5,
                     "laser scans per pick: the picking pose, then re-scans after a move or an empty closing"});
  v(p.retry_roll_deg, {"retry_roll_deg", "deg", 0.0, 90.0,
                       "a retry after nothing found or an empty closing turns the pose about the pedicel by this"});
}

}  // namespace tinyline::tomato_reasoning

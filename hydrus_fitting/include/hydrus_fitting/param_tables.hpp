// SPDX-License-Identifier: Apache-2.0
// The parameter tables of hydrus_fitting's settings: each field's name in
// launch files, unit, range and meaning, described once
// (<tinyline/common/param_table.hpp>). The nodes declare their parameters
// from these, `tinyline describe` and docs/parameters.md show them.
#pragma once

#include <tinyline/common/param_table.hpp>

#include "hydrus_fitting/base_motion.hpp"
#include "hydrus_fitting/circle_fit.hpp"
#include "hydrus_fitting/estimator.hpp"
#include "hydrus_fitting/fusion.hpp"
#include "hydrus_fitting/robot_model.hpp"
#include "hydrus_fitting/sequencer.hpp"
#include "hydrus_fitting/trajectory.hpp"

namespace tinyline::hydrus_fitting {

template <class S, class V>
requires common::SettingsOf<S, SecondOrderCorrection>
void for_each_param(S& p, V&& v) {
  v(p.end_weight, {"end_weight", "", 0.0, 10.0, "end weighting k at sigma/r = reference_sigma_over_r (0: no refit)"});
  v(p.reference_sigma_over_r, {"reference_sigma_over_r", "", 1e-6, 10.0, "sigma/r at which k = end_weight"});
  v(p.max_end_weight, {"max_end_weight", "", 0.0, 1.0, "k at most (weights stay >= 5 %)"});
  v(p.full_weighting_arc_deg, {"full_weighting_arc_deg", "deg", 0.0, 360.0, "end weighting in full up to this arc"});
  v(p.no_weighting_arc_deg, {"no_weighting_arc_deg", "deg", 0.0, 360.0, "... and none from this arc on"});
  v(p.full_weighting_rel_sd_r,
    {"full_weighting_rel_sd_r", "", 0.0, 10.0, "end weighting in full up to this SD(r) / r of the fit"});
  v(p.no_weighting_rel_sd_r, {"no_weighting_rel_sd_r", "", 0.0, 10.0, "... and none from this SD(r) / r on"});
  v(p.mode_shift, {"mode_shift", "", 0.0, 100.0, "gamma of the mode shift (0: no shift)"});
  v(p.max_shift_sds, {"max_shift_sds", "", 0.0, 100.0, "|radius shift| at most this many SDs of the fitted radius"});
  v(p.max_sigma_over_r, {"max_sigma_over_r", "", 0.0, 10.0,
                         "correct only while the noise over the radius seen in the residuals is at most this"});
  v(p.max_points, {"max_points", "", 1, 2147483647, "correct only fits of at most this many points"});
}

template <class S, class V>
requires common::SettingsOf<S, RefineParams>
void for_each_param(S& p, V&& v) {
  v(p.max_iterations, {"max_iterations", "", 1, 100000, "Levenberg-Marquardt iterations at most"});
  v(p.step_tolerance_m, {"step_tolerance_m", "m", 0.0, 1.0, "stop when the update is shorter than this"});
  v(p.initial_lambda, {"initial_lambda", "", 0.0, 1e6, "initial LM damping (Marquardt, scaled by diag(J^T W J))"});
  common::not_a_parameter(p.known_radius_m, "the robust fit's known_radius_m");
  v(p.covariance_from_residuals, {"covariance_from_residuals",
                                  "",
                                  {},
                                  {},
                                  "covariance scaled by the residuals (false: the per-point sigmas as given)"});
  v(p.remove_radius_bias,
    {"remove_radius_bias", "", {}, {}, "remove the isotropic-noise radius bias sigma^2 / (2 r) in the refit"});
  common::not_a_parameter(p.correction, "the estimator's second_order_correction, on its final refit");
  common::nest(p.second_order, "second_order.", v);
}

template <class S, class V>
requires common::SettingsOf<S, RobustCircleParams>
void for_each_param(S& p, V&& v) {
  v(p.inlier_threshold_m,
    {"inlier_threshold_m", "m", 1e-4, 1.0, "largest distance of a supporting point from the circle"});
  v(p.inlier_threshold_sigmas,
    {"inlier_threshold_sigmas", "", 0.0, 100.0, "and at most this many of its range SDs (Table 3.1 model); 0: off"});
  v(p.min_radius_m, {"min_radius_m", "m", 0.0, 10.0, "smallest accepted radius"});
  v(p.max_radius_m, {"max_radius_m", "m", 1e-3, 100.0, "largest accepted radius"});
  v(p.known_radius_m, {"known_radius_m", "m", 0.0, 10.0, "radius of the object if known; 0: fit it"});
  v(p.max_iterations, {"max_iterations", "", 1, 1e6, "MSAC hypotheses at most"});
  v(p.confidence, {"confidence", "", 0.5, 0.999999, "MSAC stop: P(an all-inlier sample was drawn)"});
  v(p.min_inliers, {"min_inliers", "", 3, 1e6, "a circle needs this many supporting points"});
  v(p.local_optimisation_rounds,
    {"local_optimisation_rounds", "", 0, 100, "Hyper fit of the consensus set and re-selection, at most this often"});
  v(p.final_threshold_sigmas, {"final_threshold_sigmas", "", 0.0, 100.0,
                               "re-selection within this many robust SDs of the set's own residuals (0: off)"});
  v(p.seed, {"seed", "", 0, 2e9, "MSAC sampling seed (deterministic)"});
  v(p.final_geometric_fit,
    {"final_geometric_fit", "", {}, {}, "end with the geometric (LM) fit of the set, which gives the covariance"});
  common::nest(p.refine, "refine.", v);
}

template <class S, class V>
requires common::SettingsOf<S, FusionParams>
void for_each_param(S& p, V&& v) {
  v(p.self_filter, {"self_filter", "", {}, {}, "remove points on the robot's own links (thesis 6.2.3)"});
  v(p.self_filter_margin_m, {"self_filter_margin_m", "m", 0.0, 1.0, "clearance around each link's footprint"});
  v(p.noise.range_sd_m, {"range_noise_sd_m", "m", 0.0, 100.0,
                         "range noise model (Table 3.1): range, SD, range, SD, ... by increasing range"});
}

template <class S, class V>
requires common::SettingsOf<S, CircleEstimatorParams>
void for_each_param(S& p, V&& v) {
  common::nest(p.fusion, "", v);
  common::nest(p.robust, "", v);
  v(p.use_viewpoints, {"use_viewpoints", "", {}, {}, "reject circles through points their sensor could not have seen"});
  v(p.weight_by_range, {"weight_by_range", "", {}, {}, "weight points by the range noise at their distance"});
  v(p.incidence_weighting,
    {"incidence_weighting", "", {}, {}, "refit with the noise across the surface (range SD x cos incidence)"});
  v(p.min_cos_incidence, {"min_cos_incidence", "", 0.01, 1.0, "floor of cos(incidence) in the weights"});
  v(p.remove_radius_bias, {"remove_radius_bias", "", {}, {}, "remove the geometric fit's essential radius bias"});
  v(p.arc_correction,
    {"second_order_correction",
     "",
     {},
     {},
     "end weighting and mode shift of the final refit at large noise on short arcs (docs/hydrus_fitting.md); "
     "false: the plain maximum-likelihood refit"},
    common::Flag{ArcCorrection::kNone, ArcCorrection::kSecondOrder});
  v(p.max_scan_skew_s,
    {"max_scan_skew_s", "s", 0.0, 60.0, "scans older than the newest by more than this are left out"});
}

template <class S, class V>
requires common::SettingsOf<S, JointBufferParams>
void for_each_param(S& p, V&& v) {
  v(p.tolerance_s, {"tolerance_s", "s", 0.0, 60.0, "a scan may be this much newer than the newest joint state"});
  v(p.history_s, {"history_s", "s", 0.01, 600.0, "joint states kept"});
}

template <class S, class V>
requires common::SettingsOf<S, BasePoseBufferParams>
void for_each_param(S& p, V&& v) {
  v(p.tolerance_s, {"tolerance_s", "s", 0.0, 10.0, "a scan may be this much newer than the newest base_pose"});
  v(p.history_s, {"history_s", "s", 0.01, 600.0, "base poses kept"});
}

template <class S, class V>
requires common::SettingsOf<S, InterferenceParams>
void for_each_param(S& p, V&& v) {
  v(p.rays_per_fan, {"rays_per_fan", "", 2, 100000, "rays cast across each emitter's fan"});
  v(p.step_m, {"ray_step_m", "m", 1e-3, 1.0, "sampling along rays that hit nothing known"});
  v(p.angle_margin_rad, {"angle_margin_rad", "rad", 0.0, 1.0, "widens every field of view and fan"});
  v(p.occluder_shrink_m,
    {"occluder_shrink_m", "m", 0.0, 1.0, "the object estimate is shrunk by this before occluding"});
}

template <class S, class V>
requires common::SettingsOf<S, SlotTiming>
void for_each_param(S& p, V&& v) {
  v(p.set_period_s, {"set_period_s", "s", 1e-4, 10.0, "one measurement set at the sensor's free-running rate"});
  v(p.guard_s, {"guard_s", "s", 0.0, 10.0, "margin per slot for the on/off commands to take effect"});
}

template <class S, class V>
requires common::SettingsOf<S, SequencerParams>
void for_each_param(S& p, V&& v) {
  common::nest(p.timing, "", v);
  v(p.fill, {"fill", "", {}, {}, "add each sensor to every other slot it conflicts with nobody in"});
  v(p.links_occlude, {"links_occlude", "", {}, {}, "the robot's links block light"});
  common::nest(p.interference, "", v);
  v(p.recompute_translation_m, {"recompute_translation_m", "m", 0.0, 10.0, "rebuild when a sensor moved this far"});
  v(p.recompute_rotation_rad, {"recompute_rotation_rad", "rad", 0.0, 3.2, "or turned this much"});
  v(p.recompute_object_m, {"recompute_object_m", "m", 0.0, 10.0, "or the object estimate moved this far"});
}

template <class S, class V>
requires common::SettingsOf<S, ApproachParams>
void for_each_param(S& p, V&& v) {
  common::not_a_parameter(p.joints, "the robot description's joints");
  v(p.grasp_base_xy_m, {"grasp_base_xy_m", "m", -100.0, 100.0, "where the base stops, world x and y"});
  v(p.base_yaw_rad, {"base_yaw_deg", "deg", -360.0, 360.0, "the base's yaw, world", common::kRadPerDeg});
  v(p.approach_direction,
    {"approach_direction", "", -1e6, 1e6, "direction of flight, world x and y (normalised on use)"});
  v(p.start_distance_m, {"start_distance_m", "m", 0.0, 100.0, "the base starts this far before the grasp point"});
  v(p.open_joint_rad, {"open_joint_deg", "deg", -180.0, 180.0, "every joint while flying in", common::kRadPerDeg});
  v(p.closed_joint_rad,
    {"closed_joint_deg", "deg", -180.0, 180.0, "every joint around the object", common::kRadPerDeg});
  v(p.approach_s, {"approach_s", "s", 0.0, 3600.0, "flight in"});
  v(p.close_s, {"close_s", "s", 0.0, 3600.0, "closing the links"});
  v(p.hold_s, {"hold_s", "s", 0.0, 3600.0, "holding"});
}

}  // namespace tinyline::hydrus_fitting

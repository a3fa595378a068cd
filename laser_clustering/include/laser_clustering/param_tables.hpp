// SPDX-License-Identifier: Apache-2.0
// The parameter tables of laser_clustering's settings: each field's name in
// launch files, unit, range and meaning, described once
// (<tinyline/common/param_table.hpp>). The nodes declare their parameters
// from these, `tinyline describe` shows them, docs/parameters.md is made
// from them, and a test fails when a settings field is missing here.
#pragma once

#include <tinyline/common/param_table.hpp>

#include "laser_clustering/alignment_search.hpp"
#include "laser_clustering/dbscan.hpp"
#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/reflectance_clustering.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "laser_clustering/two_stage.hpp"

namespace tinyline::laser_clustering {

template <class S, class V>
requires common::SettingsOf<S, DbscanParams>
void for_each_param(S& p, V&& v) {
  v(p.eps, {"eps_m", "m", 1e-4, 2.0, "DBSCAN radius"});
  v(p.min_points, {"min_points", "", 1, 256, "neighbours (self included) of a core pixel"});
}

template <class S, class V>
requires common::SettingsOf<S, EdgeFilterParams>
void for_each_param(S& p, V&& v) {
  v(p.edge_width_px, {"edge_width_px", "px", 0, 64, "pixels at each end of a run the edge filter may drop"});
  v(p.reference_px, {"edge_reference_px", "px", 1, 16, "inner pixels whose median an edge pixel is compared with"});
  v(p.step_m, {"edge_step_m", "m", 0.0, 1.0, "edge/depth step threshold at range 0"});
  v(p.step_per_m, {"edge_step_per_m", "m/m", 0.0, 1.0, "growth of the step threshold per metre of range"});
  v(p.min_keep_px, {"edge_min_keep_px", "px", 1, 256, "pixels a run keeps at least"});
  v(p.smooth_half_width_px, {"smooth_half_width_px", "px", 0, 32, "half width of the range smoothing (0: off)"});
  v(p.mixed_step_m, {"mixed_step_m", "m", 0.0, 1.0,
                     "a pixel half-way down a depth step larger than this (+ edge_step_per_m * range) is mixed"});
  v(p.smooth_step_m, {"smooth_step_m", "m", 0.0, 1.0,
                      "smoothing never averages ranges further apart than this (+ edge_step_per_m * range)"});
}

template <class S, class V>
requires common::SettingsOf<S, TwoStageParams>
void for_each_param(S& p, V&& v) {
  common::nest(p.groups, "groups_", v, "stage 1 (object groups): ");
  common::nest(p.edge, "", v);
  common::nest(p.objects, "objects_", v, "stage 3 (objects): ");
}

template <class S, class V>
requires common::SettingsOf<S, ScissorGeometry>
void for_each_param(S& p, V&& v) {
  v(p.centre_x_m, {"centre_x_m", "m", -1.0, 1.0, "blade throat along the line, laser frame"});
  v(p.centre_z_m, {"centre_z_m", "m", 0.0, 2.0, "blade throat along the optical axis, laser frame"});
  v(p.opening_m, {"opening_m", "m", 1e-3, 0.2, "gap between the open blades"});
}

template <class S, class V>
requires common::SettingsOf<S, PedicelFinderParams>
void for_each_param(S& p, V&& v) {
  v(p.diameter_m, {"pedicel_diameter_m", "m", 1e-4, 0.1, "pedicel width prior"});
  v(p.diameter_sd_m, {"pedicel_diameter_sd_m", "m", 1e-5, 0.1, "spread of measured widths around the prior"});
  v(p.min_width_m, {"min_width_m", "m", 0.0, 0.1, "narrower objects are never pedicels"});
  v(p.max_width_m, {"max_width_m", "m", 1e-4, 0.5, "wider objects are never pedicels"});
  v(p.min_points, {"min_points", "", 1, 256, "pixels a pedicel shows at least"});
  v(p.min_range_m, {"min_range_m", "m", 0.0, 3.0, "working range, near end"});
  v(p.max_range_m, {"max_range_m", "m", 0.0, 3.0, "working range, far end"});
  v(p.search_sd_m, {"search_sd_m", "m", 1e-4, 1.0, "spread of the pedicel around the expected point"});
  v(p.blade_margin_m, {"blade_margin_m", "m", 0.0, 0.1, "margin inside the blades for 'cut here'"});
  v(p.depth_tolerance_m, {"depth_tolerance_m", "m", 0.0, 0.5, "depth off the throat still 'cut here'"});
  v(p.layout_miss_factor, {"layout_miss_factor", "", 1e-6, 1.0,
                           "truss layout: weight factor for an expected neighbour in view with no pedicel near it"});
  v(p.layout_extra_factor, {"layout_extra_factor", "", 1e-6, 1.0,
                            "truss layout: weight factor for a pedicel-like object no expected pedicel explains"});
  v(p.occlusion_margin_m,
    {"occlusion_margin_m", "m", 0.0, 1.0,
     "an expected pedicel behind a return this much nearer on its bearing is hidden, not missing"});
  v(p.recentre_sd_m,
    {"recentre_sd_m", "m", 1e-5, 1.0, "after centring a pedicel: how far it may still be from the throat"});
  v(p.range_bias_m, {"range_bias_m", "m", -0.05, 0.05,
                     "thin dark objects read this much farther than their axis; moved back along the bearing"});
  common::nest(p.scissors, "scissor_", v);
}

template <class S, class V>
requires common::SettingsOf<S, ReflectanceClusteringParams>
void for_each_param(S& p, V&& v) {
  common::nest(p.dbscan, "", v);
  v(p.reflectance_ratio_at_eps,
    {"reflectance_ratio_at_eps", "", 1.0001, 1000.0, "reflectance factor that weighs as much as eps_m"});
  v(p.use_reflectance, {"use_reflectance", "", {}, {}, "cluster on reflectance too (false: distance only)"});
  v(p.smooth_half_width_px, {"smooth_half_width_px", "px", 0, 32, "half width of the range smoothing (0: off)"});
  v(p.smooth_step_m, {"smooth_step_m", "m", 0.0, 1.0, "smoothing never crosses this step"});
}

template <class S, class V>
requires common::SettingsOf<S, AlignmentParams>
void for_each_param(S& p, V&& v) {
  v(p.fit_half_width, {"fit_half_width", "", 1, 50, "samples each side of the maximum in the parabola fit"});
  v(p.fit_log, {"fit_log", "", {}, {}, "fit log reflectance (Gaussian lobe) instead of reflectance"});
  v(p.min_peak_ratio, {"min_peak_ratio", "", 1.0, 1000.0, "peak over the sweep's median needed to count as a peak"});
}

/// The words of SurfaceReflectanceParams::Method.
inline constexpr common::Choice<SurfaceReflectanceParams::Method> kSurfaceMethods[] = {
    {"top_quantile", SurfaceReflectanceParams::Method::kTopQuantile},
    {"brightest_cluster", SurfaceReflectanceParams::Method::kBrightestCluster},
};

template <class S, class V>
requires common::SettingsOf<S, SurfaceReflectanceParams>
void for_each_param(S& p, V&& v) {
  v(p.method,
    {"surface_method",
     "",
     {},
     {},
     "how a scan's target reflectance is measured: top_quantile of the pixels, or the brightest_cluster's median"},
    kSurfaceMethods);
  v(p.quantile, {"surface_quantile", "", 0.01, 1.0, "top_quantile: the quantile taken"});
  v(p.use_saturated,
    {"surface_use_saturated", "", {}, {}, "top_quantile: count saturated pixels at their reflectance lower bound"});
  v(p.first_pixel, {"roi_first_pixel", "px", 0, 4096, "region of interest, first pixel"});
  v(p.last_pixel, {"roi_last_pixel", "px", -1, 4096, "region of interest, last pixel (-1: to the end)"});
  common::nest(p.clustering, "", v);
}

template <class S, class V>
requires common::SettingsOf<S, TomatoRegistrationParams>
void for_each_param(S& p, V&& v) {
  v(p.max_shift_m,
    {"max_shift_m", "m", 1e-4, 1.0, "the vision's common offset is searched within this of zero, in the plane"});
  v(p.grid_step_m, {"grid_step_m", "m", 1e-4, 1.0, "coarse search step, then refined"});
  v(p.inlier_m, {"inlier_m", "m", 1e-4, 0.2, "a return within this of a shifted tomato's near arc supports the shift"});
  v(p.min_section_radius_m,
    {"min_section_radius_m", "m", 0.0, 0.5, "tomato cross-sections narrower than this are left out"});
  v(p.min_range_m, {"min_range_m", "m", 0.0, 3.0, "returns nearer than this are ignored"});
  v(p.max_range_m, {"max_range_m", "m", 0.0, 3.0, "returns farther than this are ignored"});
  v(p.core_fraction,
    {"core_fraction", "", 0.0, 1.0,
     "free space: a ray within this fraction of a shifted section's radius of its centre must hit it"});
  v(p.free_space_margin_m,
    {"free_space_margin_m", "m", 0.0, 1.0, "free space: a return this far behind the near arc sees through it"});
  v(p.violation_cost,
    {"violation_cost", "", 0.0, 100.0, "support an inlier's worth lost per pixel that sees through a tomato"});
  v(p.no_return_cost, {"no_return_cost", "", 0.0, 100.0, "the same for a pixel with no valid return there"});
  v(p.min_tomatoes, {"min_tomatoes", "", 1, 256, "tomatoes the best shift must meet for a registration"});
  v(p.min_points_per_tomato, {"min_points_per_tomato", "", 1, 256, "returns a met tomato shows at least"});
  v(p.distinct_shift_m,
    {"distinct_shift_m", "m", 0.0, 1.0, "a second-best shift farther than this from the best is a rival"});
  v(p.ambiguity_ratio,
    {"ambiguity_ratio", "", 1e-3, 1.0, "a rival with this share of the best's support makes it ambiguous"});
}

}  // namespace tinyline::laser_clustering

#include "common.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace tinyline::laser_clustering::nodes {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// to_core's scratch (nodes call it from their own callbacks, never concurrently per thread).
thread_local std::vector<std::uint8_t> saturated_;
thread_local std::vector<double> intensity_;

}  // namespace

std::string to_core(const tinyline_msgs::msg::LineScan& m, LineScan& out, double min_reflectance) {
  const std::size_t n = m.distance_m.size();
  if (m.angles.size() != n || m.status.size() != n || (!m.reflectance.empty() && m.reflectance.size() != n)) {
    return fmt::format("LineScan arrays disagree: {} angles, {} distances, {} statuses, {} reflectances",
                       m.angles.size(), n, m.status.size(), m.reflectance.size());
  }
  out.angle_rad.resize(n);
  out.range_m.resize(n);
  out.reflectance.resize(m.reflectance.size());
  for (std::size_t i = 0; i < n; ++i) {
    out.angle_rad[i] = m.angles[i];
    const bool valid = m.status[i] == tinyline_msgs::msg::LineScan::STATUS_VALID && std::isfinite(m.distance_m[i]) &&
                       m.distance_m[i] > 0.0f;
    out.range_m[i] = valid ? static_cast<double>(m.distance_m[i]) : kNaN;
  }
  for (std::size_t i = 0; i < m.reflectance.size(); ++i) {
    out.reflectance[i] = m.reflectance[i];
    // NaN reflectance fails the comparison too: no light figure, no return.
    if (min_reflectance > 0.0 && !(out.reflectance[i] >= min_reflectance)) out.range_m[i] = kNaN;
    if (!out.valid(i)) out.reflectance[i] = kNaN;  // a finite figure on an invalid pixel means a bound
  }
  // Saturated pixels: their fewest-pulse light as a reflectance lower bound.
  if (!m.reflectance.empty() && m.intensity.size() == n) {
    saturated_.assign(n, 0);
    intensity_.resize(n);
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
      saturated_[i] = m.status[i] == tinyline_msgs::msg::LineScan::STATUS_SATURATED;
      any = any || saturated_[i];
      intensity_[i] = m.intensity[i];
    }
    if (any) (void)saturated_reflectance_bound(out, saturated_, intensity_);
  }
  return {};
}

double declare_min_reflectance(bus::Node& n) {
  return n.declare_parameter("min_reflectance", 0.0,
                             "pixels whose reflectance figure (distance_cm^2 (a + b) / (pulses / 10)) is below this "
                             "are no return (0: off)",
                             bus::ParamConstraints::range(0.0, 1e9));
}

namespace {

tinyline_msgs::msg::LineCluster cluster_msg(int id, int group, int first, int last, int n, const Eigen::Vector2d& c,
                                            double mean_range, double range_sd, double width, double refl) {
  tinyline_msgs::msg::LineCluster m;
  m.id = id;
  m.group = group;
  m.first_pixel = first;
  m.last_pixel = last;
  m.num_points = n;
  m.centroid_x_m = c.x();
  m.centroid_z_m = c.y();
  m.mean_range_m = mean_range;
  m.range_sd_m = range_sd;
  m.width_m = width;
  m.reflectance = refl;
  return m;
}

}  // namespace

void to_msg(const TwoStageResult& r, tinyline_msgs::msg::LineClusters& out) {
  out.labels.assign(r.labels.begin(), r.labels.end());
  out.fate.resize(r.fate.size());
  for (std::size_t i = 0; i < r.fate.size(); ++i) out.fate[i] = static_cast<std::uint8_t>(r.fate[i]);
  out.filtered_range_m.assign(r.smoothed_range_m.begin(), r.smoothed_range_m.end());
  out.clusters.clear();
  for (const auto& c : r.clusters) {
    auto m = cluster_msg(c.id, c.group, c.first_pixel, c.last_pixel, c.num_points, c.centroid_xz_m, c.mean_range_m,
                         c.range_sd_m, c.width_m, c.mean_reflectance);
    m.touches_fov_edge = c.touches_fov_edge;
    m.occluded_low = c.occluded_low;
    m.occluded_high = c.occluded_high;
    out.clusters.push_back(m);
  }
  out.brightest = -1;
  out.note = r.ok ? r.reason : "clustering failed: " + r.reason;
}

void to_msg(const ReflectanceClusteringResult& r, tinyline_msgs::msg::LineClusters& out) {
  out.labels.assign(r.labels.begin(), r.labels.end());
  out.fate.clear();
  out.filtered_range_m.clear();
  out.clusters.clear();
  for (const auto& c : r.clusters) {
    out.clusters.push_back(cluster_msg(c.id, -1, c.first_pixel, c.last_pixel, c.num_points, c.centroid_xz_m,
                                       c.mean_range_m, 0.0, c.width_m, c.median_reflectance));
  }
  out.brightest = r.brightest;
  out.note = r.ok ? r.reason : "clustering failed: " + r.reason;
}

TwoStageParams declare_two_stage(bus::Node& n) {
  using bus::ParamConstraints;
  const TwoStageParams d;
  TwoStageParams p;
  p.groups.eps = n.declare_parameter("groups_eps_m", d.groups.eps, "stage-1 (object groups) DBSCAN radius [m]",
                                     ParamConstraints::range(1e-4, 2.0));
  p.groups.min_points = n.declare_parameter("groups_min_points", d.groups.min_points,
                                            "stage-1 neighbours (self included) of a core pixel",
                                            ParamConstraints::range(1, 256));
  p.edge.edge_width_px = n.declare_parameter("edge_width_px", d.edge.edge_width_px,
                                             "pixels at each end of a run the edge filter may drop",
                                             ParamConstraints::range(0, 64));
  p.edge.reference_px = n.declare_parameter("edge_reference_px", d.edge.reference_px,
                                            "inner pixels whose median an edge pixel is compared with",
                                            ParamConstraints::range(1, 16));
  p.edge.step_m = n.declare_parameter("edge_step_m", d.edge.step_m, "edge/depth step threshold at range 0 [m]",
                                      ParamConstraints::range(0.0, 1.0));
  p.edge.step_per_m = n.declare_parameter("edge_step_per_m", d.edge.step_per_m,
                                          "growth of the step threshold per metre of range [m/m]",
                                          ParamConstraints::range(0.0, 1.0));
  p.edge.min_keep_px = n.declare_parameter("edge_min_keep_px", d.edge.min_keep_px,
                                           "pixels a run keeps at least", ParamConstraints::range(1, 256));
  p.edge.smooth_half_width_px = n.declare_parameter("smooth_half_width_px", d.edge.smooth_half_width_px,
                                                    "half width of the range smoothing [px] (0: off)",
                                                    ParamConstraints::range(0, 32));
  p.edge.mixed_step_m = n.declare_parameter("mixed_step_m", d.edge.mixed_step_m,
                                            "a pixel half-way down a depth step larger than this (+ edge_step_per_m * range) is mixed [m]",
                                            ParamConstraints::range(0.0, 1.0));
  p.edge.smooth_step_m = n.declare_parameter("smooth_step_m", d.edge.smooth_step_m,
                                             "smoothing never averages ranges further apart than this (+ edge_step_per_m * range) [m]",
                                             ParamConstraints::range(0.0, 1.0));
  p.objects.eps = n.declare_parameter("objects_eps_m", d.objects.eps, "stage-3 (objects) DBSCAN radius [m]",
                                      ParamConstraints::range(1e-4, 2.0));
  p.objects.min_points = n.declare_parameter("objects_min_points", d.objects.min_points,
                                             "stage-3 neighbours (self included) of a core pixel",
                                             ParamConstraints::range(1, 256));
  n.require_valid(validate(p));
  return p;
}

PedicelFinderParams declare_pedicel_finder(bus::Node& n) {
  using bus::ParamConstraints;
  const PedicelFinderParams d;
  PedicelFinderParams p;
  p.diameter_m = n.declare_parameter("pedicel_diameter_m", d.diameter_m, "pedicel width prior [m]",
                                     ParamConstraints::range(1e-4, 0.1));
  p.diameter_sd_m = n.declare_parameter("pedicel_diameter_sd_m", d.diameter_sd_m,
                                        "spread of measured widths around the prior [m]",
                                        ParamConstraints::range(1e-5, 0.1));
  p.min_width_m = n.declare_parameter("min_width_m", d.min_width_m, "narrower objects are never pedicels [m]",
                                      ParamConstraints::range(0.0, 0.1));
  p.max_width_m = n.declare_parameter("max_width_m", d.max_width_m, "wider objects are never pedicels [m]",
                                      ParamConstraints::range(1e-4, 0.5));
  p.min_points = n.declare_parameter("min_points", d.min_points, "pixels a pedicel shows at least",
                                     ParamConstraints::range(1, 256));
  p.min_range_m = n.declare_parameter("min_range_m", d.min_range_m, "working range, near end [m]",
                                      ParamConstraints::range(0.0, 3.0));
  p.max_range_m = n.declare_parameter("max_range_m", d.max_range_m, "working range, far end [m]",
                                      ParamConstraints::range(0.0, 3.0));
  p.search_sd_m = n.declare_parameter("search_sd_m", d.search_sd_m,
                                      "spread of the pedicel around the expected point [m]",
                                      ParamConstraints::range(1e-4, 1.0));
  p.blade_margin_m = n.declare_parameter("blade_margin_m", d.blade_margin_m,
                                         "margin inside the blades for 'cut here' [m]", ParamConstraints::range(0.0, 0.1));
  p.depth_tolerance_m = n.declare_parameter("depth_tolerance_m", d.depth_tolerance_m,
                                            "depth off the throat still 'cut here' [m]", ParamConstraints::range(0.0, 0.5));
  p.scissors.centre_x_m = n.declare_parameter("scissor_centre_x_m", d.scissors.centre_x_m,
                                              "blade throat along the line, laser frame [m]",
                                              ParamConstraints::range(-1.0, 1.0));
  p.scissors.centre_z_m = n.declare_parameter("scissor_centre_z_m", d.scissors.centre_z_m,
                                              "blade throat along the optical axis, laser frame [m]",
                                              ParamConstraints::range(0.0, 2.0));
  p.scissors.opening_m = n.declare_parameter("scissor_opening_m", d.scissors.opening_m,
                                             "gap between the open blades [m]", ParamConstraints::range(1e-3, 0.2));
  n.require_valid(validate(p));
  return p;
}

ReflectanceClusteringParams declare_reflectance(bus::Node& n) {
  using bus::ParamConstraints;
  const ReflectanceClusteringParams d;
  ReflectanceClusteringParams p;
  p.dbscan.eps = n.declare_parameter("eps_m", d.dbscan.eps, "DBSCAN radius in position [m]",
                                     ParamConstraints::range(1e-4, 2.0));
  p.dbscan.min_points = n.declare_parameter("min_points", d.dbscan.min_points,
                                            "neighbours (self included) of a core pixel", ParamConstraints::range(1, 256));
  p.reflectance_ratio_at_eps = n.declare_parameter("reflectance_ratio_at_eps", d.reflectance_ratio_at_eps,
                                                   "reflectance factor that weighs as much as eps_m",
                                                   ParamConstraints::range(1.0001, 1000.0));
  p.use_reflectance = n.declare_parameter("use_reflectance", d.use_reflectance,
                                          "cluster on reflectance too (false: distance only)");
  p.smooth_half_width_px = n.declare_parameter("smooth_half_width_px", d.smooth_half_width_px,
                                               "half width of the range smoothing [px] (0: off)",
                                               ParamConstraints::range(0, 32));
  p.smooth_step_m = n.declare_parameter("smooth_step_m", d.smooth_step_m, "smoothing never crosses this step [m]",
                                        ParamConstraints::range(0.0, 1.0));
  n.require_valid(validate(p));
  return p;
}

AlignmentParams declare_alignment(bus::Node& n) {
  using bus::ParamConstraints;
  const AlignmentParams d;
  AlignmentParams p;
  p.fit_half_width = n.declare_parameter("fit_half_width", d.fit_half_width,
                                         "samples each side of the maximum in the parabola fit",
                                         ParamConstraints::range(1, 50));
  p.fit_log = n.declare_parameter("fit_log", d.fit_log, "fit log reflectance (Gaussian lobe) instead of reflectance");
  p.min_peak_ratio = n.declare_parameter("min_peak_ratio", d.min_peak_ratio,
                                         "peak over the sweep's median needed to count as a peak",
                                         ParamConstraints::range(1.0, 1000.0));
  n.require_valid(validate(p));
  return p;
}

SurfaceReflectanceParams declare_surface_reflectance(bus::Node& n) {
  using bus::ParamConstraints;
  const SurfaceReflectanceParams d;
  SurfaceReflectanceParams p;
  const std::string method = n.declare_parameter<std::string>(
      "surface_method", "top_quantile",
      "how a scan's target reflectance is measured: top_quantile of the pixels, or the brightest_cluster's median",
      ParamConstraints::one_of({"top_quantile", "brightest_cluster"}));
  p.method = method == "top_quantile" ? SurfaceReflectanceParams::Method::kTopQuantile
                                      : SurfaceReflectanceParams::Method::kBrightestCluster;
  p.quantile = n.declare_parameter("surface_quantile", d.quantile, "top_quantile: the quantile taken",
                                   ParamConstraints::range(0.01, 1.0));
  p.use_saturated = n.declare_parameter("surface_use_saturated", d.use_saturated,
                                       "top_quantile: count saturated pixels at their reflectance lower bound");
  p.first_pixel = n.declare_parameter("roi_first_pixel", d.first_pixel, "region of interest, first pixel",
                                      ParamConstraints::range(0, 4096));
  p.last_pixel = n.declare_parameter("roi_last_pixel", d.last_pixel, "region of interest, last pixel (-1: to the end)",
                                     ParamConstraints::range(-1, 4096));
  p.clustering = declare_reflectance(n);
  n.require_valid(validate(p));
  return p;
}

TomatoRegistrationParams declare_tomato_registration(bus::Node& n) {
  using bus::ParamConstraints;
  const TomatoRegistrationParams d;
  TomatoRegistrationParams p;
  p.max_shift_m = n.declare_parameter("max_shift_m", d.max_shift_m,
                                      "the vision's common offset is searched within this of zero, in the plane [m]",
                                      ParamConstraints::range(1e-4, 1.0));
  p.grid_step_m = n.declare_parameter("grid_step_m", d.grid_step_m, "coarse search step, then refined [m]",
                                      ParamConstraints::range(1e-4, 1.0));
  p.inlier_m = n.declare_parameter("inlier_m", d.inlier_m,
                                   "a return within this of a shifted tomato's near arc supports the shift [m]",
                                   ParamConstraints::range(1e-4, 0.2));
  p.min_section_radius_m = n.declare_parameter("min_section_radius_m", d.min_section_radius_m,
                                               "tomato cross-sections narrower than this are left out [m]",
                                               ParamConstraints::range(0.0, 0.5));
  p.min_range_m = n.declare_parameter("min_range_m", d.min_range_m, "returns nearer than this are ignored [m]",
                                      ParamConstraints::range(0.0, 3.0));
  p.max_range_m = n.declare_parameter("max_range_m", d.max_range_m, "returns farther than this are ignored [m]",
                                      ParamConstraints::range(0.0, 3.0));
  p.core_fraction = n.declare_parameter("core_fraction", d.core_fraction,
                                        "free space: a ray within this fraction of a shifted section's radius of its "
                                        "centre must hit it",
                                        ParamConstraints::range(0.0, 1.0));
  p.free_space_margin_m = n.declare_parameter("free_space_margin_m", d.free_space_margin_m,
                                              "free space: a return this far behind the near arc sees through it [m]",
                                              ParamConstraints::range(0.0, 1.0));
  p.violation_cost = n.declare_parameter("violation_cost", d.violation_cost,
                                         "support an inlier's worth lost per pixel that sees through a tomato",
                                         ParamConstraints::range(0.0, 100.0));
  p.no_return_cost = n.declare_parameter("no_return_cost", d.no_return_cost,
                                         "the same for a pixel with no valid return there",
                                         ParamConstraints::range(0.0, 100.0));
  p.min_tomatoes = n.declare_parameter("min_tomatoes", d.min_tomatoes,
                                       "tomatoes the best shift must meet for a registration",
                                       ParamConstraints::range(1, 256));
  p.min_points_per_tomato = n.declare_parameter("min_points_per_tomato", d.min_points_per_tomato,
                                                "returns a met tomato shows at least", ParamConstraints::range(1, 256));
  p.distinct_shift_m = n.declare_parameter("distinct_shift_m", d.distinct_shift_m,
                                           "a second-best shift farther than this from the best is a rival [m]",
                                           ParamConstraints::range(0.0, 1.0));
  p.ambiguity_ratio = n.declare_parameter("ambiguity_ratio", d.ambiguity_ratio,
                                          "a rival with this share of the best's support makes it ambiguous",
                                          ParamConstraints::range(1e-3, 1.0));
  n.require_valid(validate(p));
  return p;
}

}  // namespace tinyline::laser_clustering::nodes

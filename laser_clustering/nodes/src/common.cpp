// SPDX-License-Identifier: Apache-2.0
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
  out.note = r.status.ok() ? r.note : "clustering failed: " + r.status.message;
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
  out.note = r.status.ok() ? r.note : "clustering failed: " + r.status.message;
}

}  // namespace tinyline::laser_clustering::nodes

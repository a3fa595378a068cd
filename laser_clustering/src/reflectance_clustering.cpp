// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/reflectance_clustering.hpp"

#include "laser_clustering/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

common::Status validate(const ReflectanceClusteringParams& p) {
  // Every rule is a single field's range: the table holds them.
  return common::within_table(p);
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Range smoothing that never averages across a depth step: each valid
// range becomes the mean of the valid ranges within smooth_half_width_px
// pixels that lie within smooth_step_m of it; NaN elsewhere.
std::vector<double> smooth_ranges(const LineScan& scan, const ReflectanceClusteringParams& p) {
  const std::size_t n = scan.size();
  std::vector<double> range(n, kNaN);
  const int h = p.smooth_half_width_px;
  for (std::size_t i = 0; i < n; ++i) {
    if (!scan.valid(i)) continue;
    double sum = 0.0;
    int cnt = 0;
    const auto lo = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, static_cast<std::ptrdiff_t>(i) - h));
    const std::size_t hi = std::min(n - 1, i + static_cast<std::size_t>(h));
    for (std::size_t j = lo; j <= hi; ++j) {
      if (scan.valid(j) && std::abs(scan.range_m[j] - scan.range_m[i]) <= p.smooth_step_m) {
        sum += scan.range_m[j];
        ++cnt;
      }
    }
    range[i] = sum / cnt;
  }
  return range;
}

// The DBSCAN feature: log reflectance scaled so that a ratio of
// reflectance_ratio_at_eps is eps apart (NaN without a positive
// reflectance). Returns the valid pixels left out for want of one.
std::size_t reflectance_feature(const LineScan& scan, const ReflectanceClusteringParams& p,
                                std::vector<double>& feature) {
  std::size_t no_reflectance = 0;
  const double scale = p.dbscan.eps / std::log(p.reflectance_ratio_at_eps);
  feature.assign(scan.size(), kNaN);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double r = scan.reflectance[i];
    if (std::isfinite(r) && r > 0.0) {
      feature[i] = scale * std::log(r);
    } else if (scan.valid(i)) {
      ++no_reflectance;  // a range without a usable reflectance: left out
    }
  }
  return no_reflectance;
}

// Per cluster: pixel span, point count, mean range and centroid (sums
// here), and its pixels' finite reflectances into refl.
void sum_clusters(const LineScan& scan, const std::vector<double>& range, const DbscanResult& r,
                  std::vector<ReflectanceCluster>& clusters, std::vector<std::vector<double>>& refl) {
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const int l = r.labels[i];
    if (l < 0) continue;
    auto& c = clusters[static_cast<std::size_t>(l)];
    if (c.num_points == 0) {
      c.id = l;
      c.first_pixel = static_cast<int>(i);
    }
    c.last_pixel = static_cast<int>(i);
    ++c.num_points;
    c.mean_range_m += range[i];
    c.centroid_xz_m += Eigen::Vector2d(range[i] * std::sin(scan.angle_rad[i]), range[i] * std::cos(scan.angle_rad[i]));
    if (!scan.reflectance.empty() && std::isfinite(scan.reflectance[i]))
      refl[static_cast<std::size_t>(l)].push_back(scan.reflectance[i]);
  }
}

// From sums to means, the median reflectance (v is reordered) and the width.
void finish_cluster(const LineScan& scan, std::vector<double>& v, ReflectanceCluster& c) {
  const std::size_t n = scan.size();
  c.mean_range_m /= c.num_points;
  c.centroid_xz_m /= c.num_points;
  if (v.empty()) {
    c.median_reflectance = kNaN;
  } else {
    auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    c.median_reflectance = *mid;
  }
  const auto f = static_cast<std::size_t>(c.first_pixel), b = static_cast<std::size_t>(c.last_pixel);
  const std::size_t lo = f > 0 ? f - 1 : f, hi = b + 1 < n ? b + 1 : b;
  const double pitch = hi > lo ? std::abs(scan.angle_rad[hi] - scan.angle_rad[lo]) / static_cast<double>(hi - lo) : 0.0;
  c.width_m = c.mean_range_m * (std::abs(scan.angle_rad[b] - scan.angle_rad[f]) + pitch);
}

}  // namespace

ReflectanceClusteringResult cluster_by_reflectance(const LineScan& scan, const ReflectanceClusteringParams& p) {
  ReflectanceClusteringResult out;
  if (out.status = validate(p); !out.status.ok()) return out;
  if (out.status = check_scan(scan); !out.status.ok()) return out;
  if (p.use_reflectance && scan.reflectance.size() != scan.size()) {
    out.status = common::Status::invalid(
        fmt::format("reflectance clustering needs a reflectance per pixel; the scan has {} for {} pixels",
                    scan.reflectance.size(), scan.size()));
    return out;
  }
  const std::vector<double> range = smooth_ranges(scan, p);
  std::vector<double> feature;
  const std::size_t no_reflectance = p.use_reflectance ? reflectance_feature(scan, p, feature) : 0;
  OrderedScanDbscan dbscan;
  const DbscanResult r = dbscan.run({scan.angle_rad, range, feature, {}}, p.dbscan);
  if (out.status = r.status; !out.status.ok()) return out;
  out.labels = r.labels;
  if (scan.size() == 0) {
    out.note = "empty scan";
  } else if (scan.num_valid() == 0) {
    out.note = "no valid pixels";
  } else if (no_reflectance > 0) {
    out.note = fmt::format("{} pixels without a positive reflectance left out", no_reflectance);
  }
  out.clusters.resize(static_cast<std::size_t>(r.num_clusters));
  std::vector<std::vector<double>> refl(out.clusters.size());
  sum_clusters(scan, range, r, out.clusters, refl);
  double brightest = -std::numeric_limits<double>::infinity();
  for (std::size_t l = 0; l < out.clusters.size(); ++l) {
    finish_cluster(scan, refl[l], out.clusters[l]);
    if (!refl[l].empty() && out.clusters[l].median_reflectance > brightest) {
      brightest = out.clusters[l].median_reflectance;
      out.brightest = static_cast<int>(l);
    }
  }
  return out;
}

}  // namespace tinyline::laser_clustering

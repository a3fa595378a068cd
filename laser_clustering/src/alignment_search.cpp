// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/alignment_search.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <fmt/format.h>

namespace tinyline::laser_clustering {

const char* to_string(AlignmentOutcome o) {
  switch (o) {
    case AlignmentOutcome::kFound: return "found";
    case AlignmentOutcome::kAtSweepEdge: return "at_sweep_edge";
    case AlignmentOutcome::kNoPeak: return "no_peak";
    case AlignmentOutcome::kInvalidInput: return "invalid_input";
  }
  return "unknown";
}

common::Validation validate(const AlignmentParams& p) {
  if (p.fit_half_width < 1) return {false, fmt::format("fit_half_width must be >= 1 (got {})", p.fit_half_width)};
  if (!std::isfinite(p.min_peak_ratio) || p.min_peak_ratio < 1.0) {
    return {false, fmt::format("min_peak_ratio must be finite and >= 1 (got {})", p.min_peak_ratio)};
  }
  return {};
}

AlignmentResult find_alignment(std::span<const AlignmentSample> samples, const AlignmentParams& p) {
  AlignmentResult out;
  if (auto v = validate(p); !v.valid) {
    out.reason = v.reason;
    return out;
  }
  std::vector<AlignmentSample> s;
  for (const auto& x : samples) {
    if (std::isfinite(x.pitch_rad) && std::isfinite(x.reflectance) && x.reflectance > 0.0) s.push_back(x);
  }
  const std::size_t skipped = samples.size() - s.size();
  std::sort(s.begin(), s.end(), [](const auto& a, const auto& b) { return a.pitch_rad < b.pitch_rad; });
  // Average repeated pitches.
  std::vector<AlignmentSample> u;
  for (std::size_t i = 0; i < s.size();) {
    std::size_t j = i;
    double sum = 0.0;
    while (j < s.size() && s[j].pitch_rad == s[i].pitch_rad) sum += s[j++].reflectance;
    u.push_back({s[i].pitch_rad, sum / static_cast<double>(j - i)});
    i = j;
  }
  const int n = static_cast<int>(u.size());
  out.num_samples = n;
  if (n < 3) {
    out.reason =
        fmt::format("need at least 3 usable pitches, got {} ({} samples skipped as non-finite or <= 0)", n, skipped);
    return out;
  }
  const auto k = static_cast<int>(
      std::max_element(u.begin(), u.end(), [](const auto& a, const auto& b) { return a.reflectance < b.reflectance; }) -
      u.begin());
  out.peak_sample = k;
  out.best_pitch_rad = u[static_cast<std::size_t>(k)].pitch_rad;
  out.peak_reflectance = u[static_cast<std::size_t>(k)].reflectance;
  std::vector<double> r(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) r[i] = u[i].reflectance;
  std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
  const double median = r[r.size() / 2];
  if (out.peak_reflectance < p.min_peak_ratio * median) {
    out.outcome = AlignmentOutcome::kNoPeak;
    out.reason = fmt::format("maximum {:.3g} is only {:.2f} x the sweep's median {:.3g} (need {:.2f})",
                             out.peak_reflectance, out.peak_reflectance / median, median, p.min_peak_ratio);
    return out;
  }
  if (k == 0 || k == n - 1) {
    out.outcome = AlignmentOutcome::kAtSweepEdge;
    out.reason = fmt::format("maximum at the {} pitch of the sweep ({:.4f} rad): extend the sweep",
                             k == 0 ? "lowest" : "highest", out.best_pitch_rad);
    return out;
  }
  // Least-squares parabola y = a + b t + c t^2 in t = pitch - pitch_k.
  const int lo = std::max(0, k - p.fit_half_width), hi = std::min(n - 1, k + p.fit_half_width);
  Eigen::MatrixXd A(hi - lo + 1, 3);
  Eigen::VectorXd y(hi - lo + 1);
  const double pk = u[static_cast<std::size_t>(k)].pitch_rad;
  for (int i = lo; i <= hi; ++i) {
    const double t = u[static_cast<std::size_t>(i)].pitch_rad - pk;
    A.row(i - lo) << 1.0, t, t * t;
    const double v = u[static_cast<std::size_t>(i)].reflectance;
    y(i - lo) = p.fit_log ? std::log(v) : v;
  }
  const Eigen::Vector3d c = A.colPivHouseholderQr().solve(y);
  out.outcome = AlignmentOutcome::kFound;
  if (c(2) < 0.0) {
    // The vertex, kept between the neighbouring samples (the true maximum lies there).
    const double t = std::clamp(-c(1) / (2.0 * c(2)), u[static_cast<std::size_t>(k - 1)].pitch_rad - pk,
                                u[static_cast<std::size_t>(k + 1)].pitch_rad - pk);
    const double v = c(0) + c(1) * t + c(2) * t * t;
    out.best_pitch_rad = pk + t;
    out.peak_reflectance = p.fit_log ? std::exp(v) : v;
    out.refined = true;
  }
  out.reason = fmt::format("peak at {:.4f} rad ({} usable pitches{})", out.best_pitch_rad, n,
                           out.refined ? "" : ", not refined: the neighbourhood is not concave");
  return out;
}

common::Validation validate(const SurfaceReflectanceParams& p) {
  if (!(p.quantile > 0.0 && p.quantile <= 1.0))
    return {false, fmt::format("quantile must be in (0, 1] (got {})", p.quantile)};
  if (p.first_pixel < 0) return {false, fmt::format("first_pixel must be >= 0 (got {})", p.first_pixel)};
  if (p.last_pixel >= 0 && p.last_pixel < p.first_pixel) {
    return {false, fmt::format("last_pixel ({}) is before first_pixel ({})", p.last_pixel, p.first_pixel)};
  }
  if (p.method == SurfaceReflectanceParams::Method::kBrightestCluster) {
    if (auto v = validate(p.clustering); !v.valid) return {false, "clustering: " + v.reason};
  }
  return {};
}

SurfaceReflectance surface_reflectance(const LineScan& scan, const SurfaceReflectanceParams& p) {
  SurfaceReflectance out;
  if (auto v = validate(p); !v.valid) {
    out.reason = v.reason;
    return out;
  }
  if (out.reason = check_scan(scan); !out.reason.empty()) return out;
  if (scan.reflectance.size() != scan.size()) {
    out.reason = fmt::format("the scan has {} reflectance values for {} pixels", scan.reflectance.size(), scan.size());
    return out;
  }
  const auto n = static_cast<int>(scan.size());
  const int first = std::min(p.first_pixel, n), last = p.last_pixel < 0 ? n - 1 : std::min(p.last_pixel, n - 1);
  if (p.method == SurfaceReflectanceParams::Method::kTopQuantile) {
    std::vector<double> v;
    for (int i = first; i <= last; ++i) {
      const auto u = static_cast<std::size_t>(i);
      // Invalid pixels with a finite figure are saturated ones' lower bounds:
      // the peak itself when the metal faces the sensor (line_scan.hpp).
      if ((scan.valid(u) || p.use_saturated) && std::isfinite(scan.reflectance[u]) && scan.reflectance[u] > 0.0) {
        v.push_back(scan.reflectance[u]);
      }
    }
    if (v.empty()) {
      out.reason = fmt::format("no valid pixel with a reflectance in pixels {}..{}", first, last);
      return out;
    }
    const auto k = static_cast<std::size_t>(std::ceil(p.quantile * static_cast<double>(v.size()))) - 1;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    out.found = true;
    out.reflectance = v[k];
    return out;
  }
  LineScan roi;
  for (int i = first; i <= last; ++i) {
    const auto u = static_cast<std::size_t>(i);
    roi.angle_rad.push_back(scan.angle_rad[u]);
    roi.range_m.push_back(scan.range_m[u]);
    roi.reflectance.push_back(scan.reflectance[u]);
  }
  const auto c = cluster_by_reflectance(roi, p.clustering);
  if (!c.ok) {
    out.reason = c.reason;
    return out;
  }
  if (c.brightest < 0) {
    out.reason = c.reason.empty() ? "no reflectance cluster in the scan" : "no reflectance cluster: " + c.reason;
    return out;
  }
  out.found = true;
  out.cluster = c.brightest;
  out.reflectance = c.clusters[static_cast<std::size_t>(c.brightest)].median_reflectance;
  return out;
}

}  // namespace tinyline::laser_clustering

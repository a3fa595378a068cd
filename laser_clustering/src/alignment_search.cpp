// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/alignment_search.hpp"

#include "laser_clustering/param_tables.hpp"

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

common::Status validate(const AlignmentParams& p) {
  // Every rule is a single field's range: the table holds them.
  return common::within_table(p);
}

AlignmentResult find_alignment(std::span<const AlignmentSample> samples, const AlignmentParams& p) {
  AlignmentResult out;
  if (out.status = validate(p); !out.status.ok()) return out;
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
    out.status = common::Status::invalid(
        fmt::format("need at least 3 usable pitches, got {} ({} samples skipped as non-finite or <= 0)", n, skipped));
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
    out.status = common::Status::not_found(
        fmt::format("maximum {:.3g} is only {:.2f} x the sweep's median {:.3g} (need {:.2f})", out.peak_reflectance,
                    out.peak_reflectance / median, median, p.min_peak_ratio));
    return out;
  }
  if (k == 0 || k == n - 1) {
    out.outcome = AlignmentOutcome::kAtSweepEdge;
    out.status =
        common::Status::not_found(fmt::format("maximum at the {} pitch of the sweep ({:.4f} rad): extend the sweep",
                                              k == 0 ? "lowest" : "highest", out.best_pitch_rad));
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
  out.note = fmt::format("peak at {:.4f} rad ({} usable pitches{})", out.best_pitch_rad, n,
                         out.refined ? "" : ", not refined: the neighbourhood is not concave");
  return out;
}

common::Status validate(const SurfaceReflectanceParams& p) {
  // The single fields' ranges are the table's; the region spans two.
  if (common::Status v = common::within_table(p); !v.ok()) return v;
  if (p.last_pixel >= 0 && p.last_pixel < p.first_pixel) {
    return common::Status::invalid(
        fmt::format("last_pixel ({}) is before first_pixel ({})", p.last_pixel, p.first_pixel));
  }
  return {};
}

SurfaceReflectance surface_reflectance(const LineScan& scan, const SurfaceReflectanceParams& p) {
  SurfaceReflectance out;
  if (out.status = validate(p); !out.status.ok()) return out;
  if (out.status = check_scan(scan); !out.status.ok()) return out;
  if (scan.reflectance.size() != scan.size()) {
    out.status = common::Status::invalid(
        fmt::format("the scan has {} reflectance values for {} pixels", scan.reflectance.size(), scan.size()));
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
      out.status =
          common::Status::not_found(fmt::format("no valid pixel with a reflectance in pixels {}..{}", first, last));
      return out;
    }
    const auto k = static_cast<std::size_t>(std::ceil(p.quantile * static_cast<double>(v.size()))) - 1;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
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
  if (out.status = c.status; !out.status.ok()) return out;
  if (c.brightest < 0) {
    out.status = common::Status::not_found(c.note.empty() ? "no reflectance cluster in the scan"
                                                          : "no reflectance cluster: " + c.note);
    return out;
  }
  out.cluster = c.brightest;
  out.reflectance = c.clusters[static_cast<std::size_t>(c.brightest)].median_reflectance;
  return out;
}

}  // namespace tinyline::laser_clustering

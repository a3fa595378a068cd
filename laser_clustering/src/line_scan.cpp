// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/line_scan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

std::size_t LineScan::num_valid() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < range_m.size(); ++i) n += valid(i);
  return n;
}

std::size_t saturated_reflectance_bound(LineScan& scan, const std::vector<std::uint8_t>& saturated,
                                        const std::vector<double>& intensity, int max_gap_px) {
  const std::size_t n = scan.size();
  if (saturated.size() != n || intensity.size() != n || scan.reflectance.size() != n || max_gap_px < 1) return 0;
  std::size_t bounded = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!saturated[i] || scan.valid(i) || !(intensity[i] > 0.0) || !std::isfinite(intensity[i])) continue;
    // The nearest valid pixel on either side, the nearer one first.
    double range = std::numeric_limits<double>::quiet_NaN();
    for (int g = 1; g <= max_gap_px && !std::isfinite(range); ++g) {
      const auto gap = static_cast<std::size_t>(g);
      if (i >= gap && scan.valid(i - gap))
        range = scan.range_m[i - gap];
      else if (i + gap < n && scan.valid(i + gap))
        range = scan.range_m[i + gap];
    }
    if (!std::isfinite(range)) continue;
    const double d_cm = 100.0 * range;
    scan.reflectance[i] =
        d_cm * d_cm * intensity[i] * 10.0;  // the sensor's reflectance figure with pulses/10 folded in
    ++bounded;
  }
  return bounded;
}

double LineScan::pixel_pitch_rad() const {
  if (angle_rad.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> d(angle_rad.size() - 1);
  for (std::size_t i = 1; i < angle_rad.size(); ++i) d[i - 1] = std::abs(angle_rad[i] - angle_rad[i - 1]);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

common::Status check_scan(const LineScan& s) {
  if (s.angle_rad.size() != s.range_m.size()) {
    return common::Status::invalid(
        fmt::format("scan has {} angles but {} ranges", s.angle_rad.size(), s.range_m.size()));
  }
  if (!s.reflectance.empty() && s.reflectance.size() != s.range_m.size()) {
    return common::Status::invalid(
        fmt::format("scan has {} ranges but {} reflectance values", s.range_m.size(), s.reflectance.size()));
  }
  // One pass; the error path re-reads to name the culprit.
  const std::size_t n = s.angle_rad.size();
  const double* a = s.angle_rad.data();
  const double dir = n >= 2 && a[1] < a[0] ? -1.0 : 1.0;
  bool ok = true;
  for (std::size_t i = 0; i < n; ++i) {
    ok &= std::isfinite(a[i]);
    if (i > 0) ok &= dir * (a[i] - a[i - 1]) > 0.0;
  }
  if (ok) return {};
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(a[i]))
      return common::Status::invalid(fmt::format("pixel {} has a non-finite angle ({})", i, a[i]));
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (!(dir * (a[i] - a[i - 1]) > 0.0)) {
      return common::Status::invalid(
          fmt::format("pixel angles must be strictly monotone: pixel {} at {} rad after pixel {} at {} rad", i, a[i],
                      i - 1, a[i - 1]));
    }
  }
  return {};
}

}  // namespace tinyline::laser_clustering

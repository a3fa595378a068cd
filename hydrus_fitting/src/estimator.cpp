#include "hydrus_fitting/estimator.hpp"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

CircleEstimator::CircleEstimator(const RobotModel& model, CircleEstimatorParams params)
    : params_(std::move(params)), fuser_(model, params_.fusion) {}

CircleEstimate CircleEstimator::estimate(std::span<const ScanView> scans, const JointStateBuffer& joints) {
  CircleEstimate e;
  fuser_.clear();
  std::int64_t newest = std::numeric_limits<std::int64_t>::min();
  for (const auto& s : scans) newest = std::max(newest, s.stamp_ns);
  e.stamp_ns = scans.empty() ? 0 : newest;
  const auto skew_ns = static_cast<std::int64_t>(params_.max_scan_skew_s * 1e9);
  for (const auto& s : scans) {
    if (newest - s.stamp_ns > skew_ns) {
      ScanOutcome o;
      o.status = ScanStatus::kJointState;
      o.sensor = fuser_.model().sensor_index(s.sensor).value_or(-1);
      o.reason = fmt::format("scan of '{}' is {:.3f} s older than the newest (max_scan_skew_s {:.3f}): left out",
                             s.sensor, 1e-9 * static_cast<double>(newest - s.stamp_ns), params_.max_scan_skew_s);
      e.scans.push_back(std::move(o));
      continue;
    }
    e.scans.push_back(fuser_.add(s, joints));
    if (e.scans.back().ok()) ++e.scans_fused;
  }
  const FusedCloud& c = fuser_.cloud();
  e.points = c.size();
  e.self_filtered = c.self_filtered;
  const std::span<const double> sigma = params_.weight_by_range ? std::span<const double>(c.sigma_m)
                                                                : std::span<const double>();
  Viewpoints views;
  if (params_.use_viewpoints) views = {c.views, c.view_of_point};
  e.fit = fit_circle_robust(c.points_m(), params_.robust, sigma, views);
  if (!e.fit.ok() && e.scans_fused == 0 && !scans.empty()) {
    e.fit.reason = fmt::format("no scan could be fused ({}); {}", e.scans.front().reason, e.fit.reason);
  }
  return e;
}

}  // namespace tinyline::hydrus_fitting

// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/estimator.hpp"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

CircleEstimator::CircleEstimator(const RobotModel& model, CircleEstimatorParams params)
    : params_(std::move(params)), fuser_(model, params_.fusion) {
  // The incidence refit replaces the robust fit's own final LM.
  if (params_.incidence_weighting) params_.robust.final_geometric_fit = false;
}

CircleEstimate CircleEstimator::estimate(std::span<const ScanView> scans, const JointStateBuffer& joints,
                                         const BasePoseBuffer* base_poses) {
  CircleEstimate e;
  fuser_.clear();
  std::int64_t newest = std::numeric_limits<std::int64_t>::min();
  for (const auto& s : scans) newest = std::max(newest, s.stamp_ns);
  e.stamp_ns = scans.empty() ? 0 : newest;
  const auto skew_ns = static_cast<std::int64_t>(params_.max_scan_skew_s * 1e9);
  // The base's motion from each scan's time to the newest: all or none.
  motion_.assign(scans.size(), Eigen::Isometry2d::Identity());
  if (base_poses && !scans.empty()) {
    e.base_motion_compensated = true;
    for (std::size_t i = 0; i < scans.size() && e.base_motion_compensated; ++i) {
      if (newest - scans[i].stamp_ns > skew_ns) continue;  // left out below
      const BasePoseLookup m = base_poses->motion(scans[i].stamp_ns, newest);
      if (!m.status.ok()) {
        e.base_motion_compensated = false;
        e.base_motion_reason =
            fmt::format("scan of '{}': {}; no scan moved by the base's motion", scans[i].sensor, m.status.message);
        motion_.assign(scans.size(), Eigen::Isometry2d::Identity());
      } else {
        motion_[i] = m.T_fixed_base;
      }
    }
  }
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const ScanView& s = scans[i];
    if (newest - s.stamp_ns > skew_ns) {
      ScanOutcome o;
      o.sensor = fuser_.model().sensor_index(s.sensor).value_or(-1);
      o.status = {common::StatusCode::OutOfRange,
                  fmt::format("scan of '{}' is {:.3f} s older than the newest (max_scan_skew_s {:.3f}): left out",
                              s.sensor, 1e-9 * static_cast<double>(newest - s.stamp_ns), params_.max_scan_skew_s)};
      e.scans.push_back(std::move(o));
      continue;
    }
    e.scans.push_back(fuser_.add(s, joints, motion_[i]));
    if (e.scans.back().ok()) ++e.scans_fused;
  }
  const FusedCloud& c = fuser_.cloud();
  e.points = c.size();
  e.self_filtered = c.self_filtered;
  const std::span<const double> sigma =
      params_.weight_by_range ? std::span<const double>(c.sigma_m) : std::span<const double>();
  Viewpoints views;
  if (params_.use_viewpoints) views = {c.views, c.view_of_point};
  e.fit = fit_circle_robust(c.points_m(), params_.robust, sigma, views);
  if (e.fit.ok() && (params_.incidence_weighting || params_.remove_radius_bias)) gather_inliers(e.fit);
  if (e.fit.ok() && params_.incidence_weighting) {
    // Twice: the second pass takes the incidences from the better circle.
    refine_with_incidence(e.fit, false, false);
    refine_with_incidence(e.fit, params_.remove_radius_bias, true);
  } else if (e.fit.ok() && params_.remove_radius_bias) {
    refine_with_incidence(e.fit, true, true);
  }
  if (!e.fit.ok() && e.scans_fused == 0 && !scans.empty()) {
    e.fit.status.message =
        fmt::format("no scan could be fused ({}); {}", e.scans.front().status.message, e.fit.status.message);
  }
  return e;
}

void CircleEstimator::gather_inliers(const CircleFit& fit) {
  const FusedCloud& c = fuser_.cloud();
  const auto pts = c.points_m();
  // What does not depend on the circle, once for both refits: each inlier,
  // its sensor's origin, the unit ray to it and its distance from the sensor.
  in_xy_.clear();
  in_o_.clear();
  in_ray_.clear();
  in_dist_.clear();
  for (int i = 0; i < c.size(); ++i) {
    if (!fit.inlier_mask[static_cast<std::size_t>(i)]) continue;
    const Eigen::Vector2d p = pts.col(i);
    const Eigen::Vector2d o = c.views[static_cast<std::size_t>(c.view_of_point[static_cast<std::size_t>(i)])];
    in_xy_.push_back(p.x());
    in_xy_.push_back(p.y());
    in_o_.push_back(o);
    in_ray_.push_back((p - o).normalized());
    in_dist_.push_back((p - o).norm());
  }
}

void CircleEstimator::refine_with_incidence(CircleFit& fit, bool remove_bias, bool last) {
  // The inliers' range, normal and tangential noise for the fitted circle.
  const std::size_t m = in_o_.size();
  sr_.resize(m);
  sn_.resize(m);
  st_.resize(m);
  const double R2 = fit.circle.radius_m * fit.circle.radius_m;
  const RangeNoiseModel& noise = fuser_.params().noise;
  for (std::size_t j = 0; j < m; ++j) {
    const Eigen::Vector2d& o = in_o_[j];
    const Eigen::Vector2d& ray = in_ray_[j];
    // Incidence and range where the ray meets the fitted circle, not at the
    // noisy point: weights that depend on a point's own noise bias the fit
    // (points pushed inside along a grazing ray would look more grazing,
    // get more weight, and pull the radius in).
    const Eigen::Vector2d oc = fit.circle.centre_m - o;
    const double along = oc.dot(ray);
    const double perp2 = std::max(0.0, oc.squaredNorm() - along * along);
    const double cosa = perp2 < R2 ? std::sqrt(1.0 - perp2 / R2) : 0.0;
    const double range = perp2 < R2 ? along - std::sqrt(R2 - perp2) : in_dist_[j];
    const double sr = noise.sd_at(range > 0.0 ? range : in_dist_[j]);
    sr_[j] = sr;
    sn_[j] = sr * std::max(cosa, params_.min_cos_incidence);
    st_[j] = sr * std::sqrt(std::max(0.0, 1.0 - cosa * cosa));
  }
  const Eigen::Map<const Eigen::Matrix2Xd> in(in_xy_.data(), 2, static_cast<Eigen::Index>(sr_.size()));
  std::span<const double> w;
  if (params_.incidence_weighting) {
    w = sn_;
  } else if (params_.weight_by_range) {
    w = sr_;
  }
  if (params_.incidence_weighting) {
    RefineParams rp = params_.robust.refine;
    rp.known_radius_m = params_.robust.known_radius_m;
    // The second-order correction once, on the final refit: the first one
    // only sets the incidences.
    rp.correction = last ? params_.arc_correction : ArcCorrection::kNone;
    // A local refinement of the consensus set: on a short, noisy arc it can
    // run off (huge radius, far centre). Such a result is refused: the
    // refit must keep the radius limits and stay within one radius of the
    // robust circle; else the range-weighted fit is tried, else the robust
    // circle stays as it is.
    const auto acceptable = [&](const CircleFit& f) {
      return f.ok() && f.circle.radius_m >= params_.robust.min_radius_m &&
             f.circle.radius_m <= params_.robust.max_radius_m &&
             (f.circle.centre_m - fit.circle.centre_m).norm() <= fit.circle.radius_m;
    };
    CircleFit refined = refine_circle(in, fit.circle, rp, w);
    if (!acceptable(refined)) refined = refine_circle(in, fit.circle, rp, std::span<const double>(sr_));
    if (!acceptable(refined)) return;
    fit.circle = refined.circle;
    fit.covariance = refined.covariance;
    fit.end_weight_applied = refined.end_weight_applied;
    fit.mode_shift_m = refined.mode_shift_m;
    fit.rms_residual_m = refined.rms_residual_m;
    fit.converged = refined.converged;
  }
  if (remove_bias && !params_.robust.known_radius_m) {
    (void)remove_essential_bias(in, fit, w, st_);
  }
}

}  // namespace tinyline::hydrus_fitting

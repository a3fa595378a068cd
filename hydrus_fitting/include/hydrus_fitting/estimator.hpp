// SPDX-License-Identifier: Apache-2.0
// One update of the whole-body object estimate (thesis 6.2.2-6.2.3): the
// latest scan of every sensor fused at its own joint angles, the robot's own
// links filtered out, and a robust circle fitted with each point weighted by
// the sensor's range noise at its distance and checked against the side its
// sensor saw it from. What the circle_fitter node runs per scan, and what the
// benchmark times.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "hydrus_fitting/base_motion.hpp"
#include "hydrus_fitting/circle_fit.hpp"
#include "hydrus_fitting/fusion.hpp"
#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting {

struct CircleEstimatorParams {
  FusionParams fusion;
  RobustCircleParams robust;
  bool use_viewpoints = true;   ///< reject circles through points their sensor could not see
  bool weight_by_range = true;  ///< per-point sigma from fusion.noise (else equal weights)
  /// Range noise moves a point along its ray; across the surface that is
  /// sigma_r cos(incidence) (what the fit feels) and sigma_r sin(incidence)
  /// (what biases the radius). After the robust fit, refit the inliers with
  /// sigma_r max(cos, min_cos_incidence) -- the maximum-likelihood weights --
  /// and remove the essential bias of the tangential part.
  bool incidence_weighting = true;
  double min_cos_incidence = 0.1;
  bool remove_radius_bias = true;
  /// The final refit's second-order correction (RefineParams::correction,
  /// with robust.refine.second_order): at sigma/r ~ 0.1 on arcs of 90-180
  /// deg it takes the fit from 1.2 to within 1.1 of the KCR bound; at small
  /// noise or on closed rings it leaves the fit as it is. kNone: the plain
  /// maximum-likelihood refit. Only with incidence_weighting (the refit).
  ArcCorrection arc_correction = ArcCorrection::kSecondOrder;
  /// Scans older than the newest one by more than this are left out [s]: a
  /// sensor that stopped sending must not hold the estimate.
  double max_scan_skew_s = 0.25;
};

struct CircleEstimate {
  CircleFit fit;
  std::vector<ScanOutcome> scans;  ///< per scan offered, in order (skipped stale scans: OutOfRange with the times)
  int scans_fused = 0;
  int points = 0;  ///< fused points offered to the fit
  int self_filtered = 0;
  std::int64_t stamp_ns = 0;  ///< newest scan offered
  /// With base poses: every fused scan was moved into the base frame at
  /// stamp_ns. False when none were given, or (with the reason) when a pose
  /// was missing for a scan or the reference: then no scan is moved, since
  /// mixing moved and unmoved scans is worse than moving none.
  bool base_motion_compensated = false;
  std::string base_motion_reason;
};

class CircleEstimator {
 public:
  explicit CircleEstimator(const RobotModel& model, CircleEstimatorParams params = {});

  /// Fuses `scans` (typically the latest of each sensor) with the joint
  /// states at their stamps, then fits. With `base_poses`, each scan is
  /// first moved by the base's own motion from its stamp to the newest
  /// scan's (the circle is then in the base frame at stamp_ns). Never throws
  /// on bad data: every problem is in the outcome.
  [[nodiscard]] CircleEstimate estimate(std::span<const ScanView> scans, const JointStateBuffer& joints,
                                        const BasePoseBuffer* base_poses = nullptr);
  /// The points of the last estimate (base frame).
  [[nodiscard]] const FusedCloud& cloud() const { return fuser_.cloud(); }
  [[nodiscard]] const CircleEstimatorParams& params() const { return params_; }

 private:
  void gather_inliers(const CircleFit& fit);
  void refine_with_incidence(CircleFit& fit, bool remove_bias, bool last);
  CircleEstimatorParams params_;
  ScanFuser fuser_;
  // Reused per update: the robust fit's inliers (x0, y0, x1, ...), their
  // sensor's origin, unit ray and distance from it; per refit their range,
  // normal and tangential noise SDs.
  std::vector<double> in_xy_, in_dist_, sr_, sn_, st_;
  std::vector<Eigen::Vector2d> in_o_, in_ray_;
  std::vector<Eigen::Isometry2d> motion_;  // per scan offered: base frame at its stamp -> at the newest
};

}  // namespace tinyline::hydrus_fitting

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

#include "hydrus_fitting/circle_fit.hpp"
#include "hydrus_fitting/fusion.hpp"
#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting {

struct CircleEstimatorParams {
  FusionParams fusion;
  RobustCircleParams robust;
  bool use_viewpoints = true;     ///< reject circles through points their sensor could not see
  bool weight_by_range = true;    ///< per-point sigma from fusion.noise (else equal weights)
  /// Scans older than the newest one by more than this are left out [s]: a
  /// sensor that stopped sending must not hold the estimate.
  double max_scan_skew_s = 0.25;
};

struct CircleEstimate {
  CircleFit fit;
  std::vector<ScanOutcome> scans;  ///< per scan offered, in order (skipped stale scans: kJointState with a reason)
  int scans_fused = 0;
  int points = 0;                  ///< fused points offered to the fit
  int self_filtered = 0;
  std::int64_t stamp_ns = 0;       ///< newest scan offered
};

class CircleEstimator {
 public:
  CircleEstimator(const RobotModel& model, CircleEstimatorParams params = {});

  /// Fuses `scans` (typically the latest of each sensor) with the joint
  /// states at their stamps, then fits. Never throws on bad data: every
  /// problem is in the outcome.
  [[nodiscard]] CircleEstimate estimate(std::span<const ScanView> scans, const JointStateBuffer& joints);
  /// The points of the last estimate (base frame).
  [[nodiscard]] const FusedCloud& cloud() const { return fuser_.cloud(); }
  [[nodiscard]] const CircleEstimatorParams& params() const { return params_; }

 private:
  CircleEstimatorParams params_;
  ScanFuser fuser_;
};

}  // namespace tinyline::hydrus_fitting

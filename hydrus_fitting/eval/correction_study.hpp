// SPDX-License-Identifier: Apache-2.0
// Where the second-order correction helps: the fit CircleEstimator runs
// (geometric, radius bias removed) with and without
// RefineParams::correction = kSecondOrder, outside the design the
// correction's constants were chosen in (100 points, isotropic noise up to
// sigma/r = 0.13): 30-400 points, sigma/r up to 0.25, a share of outliers
// (then the robust fit, whose final refit takes the correction), and noise
// along the rays of one sensor facing the arc. Per cell, on the same draws:
// the median-based error (1.4826 median |error|, the kcr_study metric) and
// the root mean squared error, each over the KCR bound's SD (worst of centre
// x, centre y and radius), for the plain fit, the correction applied always,
// and the correction as shipped (SecondOrderCorrection's applicability
// rule, second_order_applies()).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace tinyline::hydrus_fitting::eval {

enum class NoiseKind { kIsotropic, kRays };

struct CorrectionStudyParams {
  std::vector<double> arcs_deg{60, 90, 120, 180, 270, 360};
  std::vector<int> points{30, 100, 400};
  std::vector<double> sigma_over_r{0.024, 0.07, 0.13, 0.17, 0.20, 0.25};
  std::vector<double> outlier_fractions{0.0, 0.1};
  std::vector<NoiseKind> noise{NoiseKind::kIsotropic, NoiseKind::kRays};
  double radius_m = 0.15;
  double sensor_distance_m = 0.28;  ///< ray noise: the sensor this far from the arc's middle, facing it
  int trials = 2000;
  std::uint64_t seed = 1;
};

struct CorrectionRow {
  double arc_deg = 0, sigma_over_r = 0, outlier_fraction = 0;
  int points = 0;
  NoiseKind noise = NoiseKind::kIsotropic;
  int trials = 0, failed = 0;
  /// [plain, always, shipped]: worst over (cx, cy, r) of the metric / KCR SD.
  double robust[3] = {0, 0, 0};
  double rms[3] = {0, 0, 0};
  double applied_share = 0;  ///< draws the shipped rule corrected
};

std::vector<CorrectionRow> correction_study(const CorrectionStudyParams& p);
std::string correction_csv(const std::vector<CorrectionRow>& rows);

}  // namespace tinyline::hydrus_fitting::eval

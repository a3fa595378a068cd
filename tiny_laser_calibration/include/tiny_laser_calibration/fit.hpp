// SPDX-License-Identifier: Apache-2.0
// Fitting the declared calibration model (thesis 3.3.3-3.3.4) to a data set
// with ground truth, and measuring a model's error on one.
//
//   X = (b - Vle(p)) / ((a Rsen - Vle(p)) + (b - Vle(p)))            Eq. 3.16
//   L = P(X) + c_T (T_ref - T) + sum of terms                        Eq. 3.18, 3.3.4
//   argmin sum_i K_i / N_i sum_j (L_i - L(read-out j at distance i))^2   Eq. 3.20
//
// The polynomial, c_T and the term coefficients are linear and solved exactly;
// Rsen (global or per pixel) and the leakage Vle(p) = offset + per_pulse * p
// are found around that solve (variable projection with Levenberg-Marquardt,
// then Gauss-Newton per pixel). The thesis measured Rsen and Vle separately
// (ambient-only and dark frames); here they can be fitted from the ranging data
// or fixed to measured values.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_driver/calibration_impl.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::tiny_laser_calibration {

/// A common Rsen of all pixels only re-maps X monotonically, which the
/// polynomial absorbs: ranging data cannot tell it (the thesis measured it
/// under ambient light). Differences between pixels it can tell, because the
/// polynomial is shared.
enum class SensitivityRatioMode {
  kFixed,     ///< DeclaredFitParams::sensitivity_ratio for every pixel
  kPerPixel,  ///< per pixel with enough data, relative: their median is held at sensitivity_ratio
};

/// K_i of Eq. 3.20 (the thesis set it to all ones).
enum class DistanceWeighting {
  kOnes,
  kInverseVariance,  ///< K_i = 1 / residual variance at distance i, from a first fit (one reweighting)
};

/// Which read-outs the fit uses. The driver applies the model only to the read-out
/// it selects per pixel (the most pulses without saturation), so by default the fit
/// uses and judges exactly those: the low-signal read-outs it never applies the model
/// to carry a ratio biased by noise and by the validity rule's cut-off.
enum class ReadoutSelection {
  kDriver,  ///< per pixel and frame (same t_s), only the valid read-out with the most pulses, as the driver does
  kAll,     ///< every valid read-out (the multi-discharge data set of Eq. 3.20)
};

struct DeclaredFitParams {
  int degree = 6;  ///< polynomial degree of Eq. 3.18 (1 reproduces the linear Eq. 3.16)
  SensitivityRatioMode sensitivity_ratio_mode = SensitivityRatioMode::kPerPixel;
  double sensitivity_ratio = 1.0;  ///< common Rsen (measured separately; 1 when unknown)
  bool fit_leakage = true;         ///< false: keep the two values below
  double leakage_offset = 0.0;     ///< [charge_unit] start / fixed value
  double leakage_per_pulse = 0.0;  ///< [charge_unit per pulse] start / fixed value
  bool fit_temperature = true;
  double temperature_reference_c = 48.0;  ///< T_ref: the warm temperature (the thesis's warm-sensor temperature)
  double min_temperature_span_c = 1.0;    ///< less spread than this: no temperature term (not identifiable)
  bool equalize_distances = true;         ///< the 1 / N_i of Eq. 3.20: every target distance weighs the same
  DistanceWeighting weighting = DistanceWeighting::kOnes;
  ReadoutSelection selection = ReadoutSelection::kDriver;
  ValidityRule validity;
  /// true: the saturation ceiling comes from the data where it shows one below
  /// validity.high (validity_from_data()); the rule written is the one applied.
  bool ceiling_from_data = true;
  int min_rows_per_pixel = 20;      ///< per-pixel Rsen only for pixels with this many valid read-outs
  int min_distances_per_pixel = 4;  ///< ... spread over at least this many target distances
  double term_ridge = 1.0;          ///< pseudo-observations pulling each term coefficient to 0
  /// false: a per-pulse charge term over a continuous covariate is fitted centred (its
  /// mean over the fitted read-outs held at 0, the level left to the declared leakage).
  /// On one surface the light per pulse falls with the distance, so such a term's level
  /// mixes that light into the ratio and acts as a distance cue; only its variation with
  /// the covariate is an effect of the sensor. The residual loop sets it from the data.
  bool per_pulse_charge_levels = true;
  int passes = 3;  ///< outer passes (global parameters <-> per-pixel Rsen)
};

struct DeclaredFitResult {
  /// InvalidArgument: no rows, parameters or data the fit cannot work with
  /// (the message says which: a degree out of range, too few distances, no
  /// valid read-out, an unknown term covariate); NotFound: the fit diverged.
  common::Status status;
  CalibrationModel model;
  std::size_t rows = 0;                                      ///< rows offered
  std::size_t used = 0;                                      ///< valid read-outs the fit used
  std::size_t saturated = 0;                                 ///< rows the validity rule calls saturated
  std::size_t too_dark = 0;                                  ///< rows the validity rule calls too dark
  std::size_t not_selected = 0;                              ///< valid rows left out by ReadoutSelection::kDriver
  std::size_t distances = 0;                                 ///< distinct true distances (mm) among the used rows
  double rmse_m = std::numeric_limits<double>::quiet_NaN();  ///< in-sample, unweighted
  std::vector<std::string> notes;                            ///< decisions the fit took (e.g. no temperature term)
};

/// Fits the declared model (no discovered terms) to every row of `data`.
[[nodiscard]] DeclaredFitResult fit_declared_model(const CalibrationDataset& data,
                                                   const DeclaredFitParams& params = {});

/// Fits the declared model plus `terms` (their structure: covariate, form,
/// knots or keys, amplitude reference; coefficients are fitted) on the rows
/// `rows` of `data` (all rows when empty).
[[nodiscard]] DeclaredFitResult fit_calibration_model(const CalibrationDataset& data,
                                                      const std::vector<std::size_t>& rows,
                                                      const DeclaredFitParams& params,
                                                      const std::vector<CalibrationTerm>& terms);

/// The share of the saturation plateau the ceiling sits at: the published rule's
/// 230 of the 250 charge_unit a capacitor holds.
inline constexpr double kCeilingShareOfPlateau = 230.0 / 250.0;

/// A saturated capacitor reads a plateau: the same top value again and again.
/// When the read-outs of `data` pile up at one top level below `rule.high` (at
/// least 1 % of all charges within 0.5 charge_unit of the largest; e.g. a
/// read-out compressed by its transfer curve tops out at 175), the rule's
/// constant never sees saturation: the ceiling becomes kCeilingShareOfPlateau
/// of that level. Otherwise `rule` as given. `plateau` (when given) receives
/// the level found, NaN when none.
[[nodiscard]] ValidityRule validity_from_data(const CalibrationDataset& data, ValidityRule rule,
                                              double* plateau = nullptr);

/// Of rows `rows` of `data` (all when empty), the read-outs valid under `rule`; with
/// kDriver, per pixel and frame (same t_s) only the one with the most pulses. Sorted.
/// Counts what it left out when given the pointers.
[[nodiscard]] std::vector<std::size_t> select_readouts(const CalibrationDataset& data,
                                                       const std::vector<std::size_t>& rows, const ValidityRule& rule,
                                                       ReadoutSelection selection, std::size_t* saturated = nullptr,
                                                       std::size_t* too_dark = nullptr,
                                                       std::size_t* not_selected = nullptr);

/// Error of a model on data, over the read-outs it gives a distance for.
struct ErrorStats {
  std::size_t n = 0;  ///< read-outs with a distance
  double rmse_m = std::numeric_limits<double>::quiet_NaN();
  double bias_m = std::numeric_limits<double>::quiet_NaN();  ///< mean(model - truth)
  double sd_m = std::numeric_limits<double>::quiet_NaN();
  double p95_abs_m = std::numeric_limits<double>::quiet_NaN();  ///< 95th percentile of |model - truth|
  std::size_t saturated = 0, too_dark = 0, out_of_range = 0, missing_covariate = 0;
};

/// Evaluates `model` through its own distance path (CalibrationModel::evaluate)
/// on the read-outs of rows `rows` of `data` (all when empty) that `selection`
/// keeps under the model's validity rule. Read-outs with a missing extra
/// covariate count in missing_covariate and are left out.
[[nodiscard]] ErrorStats evaluate_model(const CalibrationModel& model, const CalibrationDataset& data,
                                        const std::vector<std::size_t>& rows = {},
                                        ReadoutSelection selection = ReadoutSelection::kDriver);

/// Residuals model - truth per row of `rows` (NaN where the model gives no distance).
[[nodiscard]] std::vector<double> model_residuals(const CalibrationModel& model, const CalibrationDataset& data,
                                                  const std::vector<std::size_t>& rows);

/// The read-out noise law of section 3.5 from a model's errors on data with repeated
/// sets: per target distance and pixel the spread of the driver's read-outs in units
/// of X, var(X) (a + b)^2 fitted as shot (a + b) + per_pulse pulses + read (weighted
/// least squares, no term negative). Empty when the data has too few repeated
/// read-outs (200). The driver publishes the range's SD from it.
[[nodiscard]] tiny_laser_driver::NoiseLaw fit_noise_law(const CalibrationModel& model, const CalibrationDataset& data);

/// Summary statistics of residuals (NaNs skipped).
[[nodiscard]] ErrorStats error_stats(const std::vector<double>& residuals_m);

}  // namespace tinyline::tiny_laser_calibration

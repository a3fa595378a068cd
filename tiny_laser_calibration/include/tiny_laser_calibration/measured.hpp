// SPDX-License-Identifier: Apache-2.0
// The calibration loop on the real sensor's measurements: the only measured
// figures there are (tiny_laser_calibration/data/measured.yaml: the thesis's
// Tables 3.1 and 3.2 and section 3.5 fits, and the factory calibration curves
// of five real sensors from the sensor's public driver). None of them holds
// per-read-out charges, so the loop cannot refit the model on them; it holds
// each candidate effect, in the form the physics gives it on that kind of
// data, against the figures, with leave-one-out errors before and after.
//
//   Table 3.2  bias per material at 30 cm against the reflectance the sensor
//              reports: which effect of the amplitude explains it
//   Table 3.1  bias and spread against distance on white paper
//   3.5        what the variances of the published fits say about the noise
//   curves     the declared physical model (Eq. 3.16: linear in X, with Rsen)
//              held against each real curve on its usable range
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <tiny_laser_driver/calibration_impl.hpp>

namespace tinyline::tiny_laser_calibration {

struct MeasuredMaterial {
  std::string name;
  double mean_cm = 0.0, sd_cm = 0.0;
  double reflectance = 0.0;  ///< the sensor's relative figure [mV per pulse]
};

struct MeasuredNoise {
  double truth_cm = 0.0, mean_cm = 0.0, var_cm2 = 0.0, sd_cm = 0.0;
};

struct MeasuredFit {
  std::string name;  ///< e.g. poly6_discharge_40pct
  double var_cm2 = std::numeric_limits<double>::quiet_NaN();
  double sd_cm = std::numeric_limits<double>::quiet_NaN();  ///< NaN when only a bound is given
};

struct RealSensorCurve {
  std::string name;
  std::vector<double> poly;     ///< highest power first [cm]
  std::vector<double> offsets;  ///< added by the public driver, highest power first [cm]
  double stable_temperature_decic = 0.0;
  double temperature_sensi_cm_per_decic = 0.0;
};

struct MeasuredData {
  std::string source;
  double pulse_width_ns = 40.0;
  double warm_temperature_c = 48.0;
  std::vector<MeasuredNoise> table31;
  std::vector<MeasuredMaterial> table32;
  std::vector<MeasuredFit> fits;
  std::vector<RealSensorCurve> sensors;
};

/// The largest measured-figures file read [bytes] (the shipped one is ~5 KB).
inline constexpr std::uint64_t kMaxMeasuredFileBytes = 1u << 20;

/// Reads the measured figures (a regular file of at most kMaxMeasuredFileBytes);
/// throws CalibrationDataError naming the file, the line and the field on a
/// missing section or a bad value.
[[nodiscard]] MeasuredData load_measured_data(const std::string& path);
[[nodiscard]] MeasuredData parse_measured_data(const std::string& text, const std::string& source);

/// One candidate effect held against a small table: fitted on every point,
/// and leave-one-out (each point predicted from the others).
struct EffectHypothesis {
  std::string effect;  ///< the physical effect ("additive charge per pulse")
  std::string form;    ///< how it shows on this data ("bias = c (1/q - 1)")
  std::vector<double> params;
  std::vector<std::string> param_names;
  double in_sample_rmse_cm = std::numeric_limits<double>::quiet_NaN();
  double loo_rmse_cm = std::numeric_limits<double>::quiet_NaN();  ///< leave-one-out
  std::vector<double> loo_residual_cm;  ///< per point (measured - predicted), NaN for the anchor
  std::string reading;                  ///< the fitted effect in physical units
  std::size_t n_params = 0;             ///< free parameters (linear coefficients and grid parameters)
  /// Leave-one-out RMSE with the size penalty: loo_rmse_cm * sqrt(n / (n - n_params)), n the points
  /// predicted; what the choice ranks (NaN when n <= n_params).
  double score_cm = std::numeric_limits<double>::quiet_NaN();
  std::string bound;  ///< empty, or which parameter the fit left on its bound
};

/// The size penalty of a hypothesis predicting n points (see EffectHypothesis::score_cm).
[[nodiscard]] double penalised_loo(double loo_rmse_cm, std::size_t n, std::size_t n_params);

/// The local charge-ratio slope of the real sensors at a distance, from their
/// factory curves: what turns a charge effect into a distance effect.
struct RatioSlope {
  double distance_cm = 0.0;
  double ratio = 0.0;              ///< k = b / (a + b) where the curve reads distance_cm (median of the sensors)
  double cm_per_unit_ratio = 0.0;  ///< dL/dk there (median)
  double cm_per_unit_ratio_lo = 0.0, cm_per_unit_ratio_hi = 0.0;  ///< spread over the sensors
};
[[nodiscard]] RatioSlope real_ratio_slope(const MeasuredData& data, double distance_cm);

struct MaterialAnalysis {
  double white_bias_cm = 0.0;   ///< the calibration target's own bias (the anchor)
  double before_rmse_cm = 0.0;  ///< declared model: every surface reads like white paper
  std::vector<EffectHypothesis> hypotheses;
  int best = -1;                         ///< lowest penalised leave-one-out error (score_cm)
  RatioSlope slope;                      ///< at 30 cm
  std::vector<std::string> unexplained;  ///< what the best hypothesis leaves, in words
  /// What drives the choice: per surface other than the anchor, the form chosen when that surface
  /// is left out of the whole choice (the same ranking on the other surfaces).
  std::vector<std::string> choice_without;
  std::vector<std::string> drivers;  ///< the surfaces without which another form would be chosen
  double q_min = 0.0, q_max = 0.0;   ///< the light levels (relative to white paper's) the forms were fitted on
};
/// Table 3.2: leave-one-material-out over the surfaces other than the
/// calibration target (white paper, the anchor every hypothesis passes through).
[[nodiscard]] MaterialAnalysis analyse_materials(const MeasuredData& data);

/// The chosen Table 3.2 form as a term of the calibration the driver applies:
/// a light_walk on the albedo (the light per pulse relative to the calibration
/// target's at that distance and pixel, q of Table 3.2), zero at q = 1, held
/// on the q the table spans. Throws std::runtime_error naming the form when
/// the chosen form is not a walk in the log of the light.
[[nodiscard]] tiny_laser_driver::CalibrationTerm material_walk_term(const MaterialAnalysis& a);

struct DistanceAnalysis {
  double before_rmse_cm = 0.0;  ///< the calibration as published: bias as measured
  std::vector<EffectHypothesis> hypotheses;
  int best = -1;
  double sd_log_slope = 0.0;  ///< d ln SD / d ln distance
  std::string sd_reading;     ///< what that slope says about the noise
};
/// Table 3.1: leave-one-distance-out.
[[nodiscard]] DistanceAnalysis analyse_distances(const MeasuredData& data);

struct FitsAnalysis {
  double discharge_variance_ratio = 0.0;   ///< var(20 %) / var(40 %)
  double noise_exponent = 0.0;             ///< gamma in SD(X) ~ S^-gamma (0.5 shot, 1 read noise)
  double multi_shot_prediction_cm2 = 0.0;  ///< multi-discharge variance if shot noise alone (stated read-outs)
  double multi_read_prediction_cm2 = 0.0;  ///< ... if read noise alone
  std::vector<std::string> readings;
};
/// Section 3.5.
[[nodiscard]] FitsAnalysis analyse_fits(const MeasuredData& data);

struct CurveAnalysis {
  std::string sensor;
  double k_min = 0.0, k_max = 0.0;        ///< usable stretch of k
  double l_min_cm = 0.0, l_max_cm = 0.0;  ///< distances it spans
  /// Declared Eq. 3.16, + gain on A, + pulse shape; loo_* are held out by blocks of distance (five
  /// contiguous stretches of k, each predicted from a fit on the other four).
  std::vector<EffectHypothesis> models;
  int best = -1;                                  ///< lowest held-out error
  double delay_drift_ps_per_c = 0.0;              ///< from its temperature coefficient
  double effective_pulse_ns = 0.0;                ///< 2 K / c of the best model (held out)
  std::vector<double> k, l_cm, best_residual_cm;  ///< the curve and the best model's residual (plots)
};
/// The declared physical model against each real sensor's factory curve on its usable range.
[[nodiscard]] std::vector<CurveAnalysis> analyse_curves(const MeasuredData& data);

}  // namespace tinyline::tiny_laser_calibration

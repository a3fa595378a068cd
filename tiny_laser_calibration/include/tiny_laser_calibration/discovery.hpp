// SPDX-License-Identifier: Apache-2.0
// The residual loop: after the declared model, look for structure
// left in the residuals against every covariate, name the strongest, add a
// term for it, repeat; report the error before and after on held-out data.
//
// Candidates: every numeric column the declared model does not use, plus
// always pixel, t_s, pulses, amplitude (a + b), amplitude per pulse, the ratio
// X, temperature and reflectance (declared distance^2 * amplitude per pulse,
// the sensor's own reflectance figure). Forms: a smooth 1-D function
// (piecewise linear on quantile knots), a per-value offset table for integer
// covariates with few values, and the covariate's smooth function times the
// amplitude. Albedo and reflectance need data from surfaces of different
// albedo (see DiscoveryParams::min_albedo_spread).
//
// Scoring: grouped K-fold cross-validation on the training groups (groups are
// target distances on a rail, else frames; never rows, because the rows of one
// frame share its target, temperature and noise). The extreme target
// distances stay in training so no fold asks the polynomial to extrapolate.
// A quarter of the groups is held out from everything and gives the reported
// before/after errors.
//
// Acceptance margin: the best candidate must (1) lower the cross-validated
// squared error in a paired comparison over groups with z above the one-sided
// Bonferroni threshold for the number of tests made in the round (family-wise
// false-acceptance rate `alpha` per round; two statistics per candidate, the
// larger counts: the per-group log ratio of squared errors, which weighs every
// group the same, and the per-group squared error removed, which sees an
// effect that lives in a few groups only, e.g. one dark surface), and (2) remove at
// least `min_relative_gain` of the squared error: smaller gains are within what
// a term's extrapolation at run time could cost. Finally every accepted term
// must also lower the held-out error, else it is dropped: on data without an
// undeclared effect the loop reports none and the error is unchanged.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <tiny_laser_calibration/fit.hpp>

namespace tinyline::tiny_laser_calibration {

enum class GroupBy {
  kAuto,            ///< target distance when there are enough distinct ones, else frame
  kTargetDistance,  ///< target_distance_groups()
  kFrame,           ///< frame_ids()
};
std::string_view to_string(GroupBy g);

struct DiscoveryParams {
  DeclaredFitParams declared;
  GroupBy group_by = GroupBy::kAuto;
  int folds = 5;
  double holdout_fraction = 0.25;  ///< share of groups held out of fitting and selection
  std::uint64_t seed = 1;          ///< shuffles groups into hold-out and folds
  int max_terms = 4;
  /// Chance of naming anything on effect-free data: Bonferroni over every candidate
  /// of the round (the loop stops at the first round where nothing passes).
  double alpha = 0.01;
  double min_relative_gain = 0.05;  ///< share of the cross-validated squared error a term must remove
  int smooth_knots = 8;             ///< knots of a smooth term (at quantiles of the covariate)
  int interaction_knots = 4;        ///< knots of g(z) in an amplitude interaction
  int charge_knots = 4;             ///< knots of g(z) of a term on the charges over a continuous covariate
  int table_max_values = 300;       ///< integer covariates with at most this many values get a table form
  /// albedo and reflectance are tried only when the albedo's 90th/10th percentile
  /// ratio reaches this: on one surface they only echo the distance error.
  double min_albedo_spread = 1.5;
  std::vector<std::string> exclude;  ///< covariates never tried ("charge": no hypothesis on the charges)
  /// Time constants of the low-pass filtered temperatures tried as covariates
  /// (lagged_temperature_name()): a delay that follows a part warming more slowly
  /// than the MCU. Only when the temperature moves and the session lasts.
  std::vector<double> temperature_lags_s{30.0, 60.0, 120.0, 240.0, 480.0};
};

/// One (covariate, form) tried in one round.
struct CandidateScore {
  std::string covariate;
  TermForm form = TermForm::kSmooth;
  double cv_rmse_m = std::numeric_limits<double>::quiet_NaN();  ///< with the term
  double gain = 0.0;                                            ///< relative cross-validated squared error removed
  double z = 0.0;                                               ///< paired statistic over groups
  bool passes = false;
};

struct DiscoveredEffect {
  std::string covariate;
  TermForm form = TermForm::kSmooth;
  double rmse_before_m = std::numeric_limits<double>::quiet_NaN();  ///< held out, without this term
  double rmse_after_m = std::numeric_limits<double>::quiet_NaN();   ///< held out, with it
  double cv_rmse_before_m = std::numeric_limits<double>::quiet_NaN();
  double cv_rmse_after_m = std::numeric_limits<double>::quiet_NaN();
  double gain = 0.0;
  double z = 0.0;
  std::string reading;  ///< the fitted term in physical units (term_reading())
  bool written = true;  ///< false: reported only (a time-since-power-on term one session cannot confirm)
};

struct DiscoveryResult {
  /// InvalidArgument: no rows, too few folds or groups, no read-out the fit
  /// or the model can use (the message says which); a failed fit's status.
  common::Status status;
  /// Declared + accepted terms, fitted on every row (what `calib fit --discover` writes).
  CalibrationModel model;
  /// The same two fitted on the training groups only (their held-out residuals are the report's).
  CalibrationModel train_before, train_after;
  double rmse_before_m = std::numeric_limits<double>::quiet_NaN();  ///< held out
  double rmse_after_m = std::numeric_limits<double>::quiet_NaN();   ///< held out
  std::vector<DiscoveredEffect> effects;
  std::vector<std::vector<CandidateScore>> rounds;
  std::vector<CalibrationTerm> rejected_on_holdout;  ///< accepted by CV, dropped on held-out data
  /// Terms on time since power-on (t_s) that held on the held-out groups but not on
  /// a second session (or there was none): reported, not written to `model`.
  std::vector<CalibrationTerm> unconfirmed_session;
  GroupBy grouping = GroupBy::kAuto;
  std::size_t groups = 0, holdout_groups = 0;
  double z_threshold = 0.0;  ///< of the first round
  std::vector<std::size_t> train_rows, holdout_rows;
  /// The held-out read-outs the errors are measured on (selection applied), with
  /// their residuals (model - truth) before and after the accepted terms; NaN
  /// where a model gives no distance.
  std::vector<std::size_t> heldout_eval_rows;
  std::vector<double> heldout_residual_before_m, heldout_residual_after_m;
  std::vector<std::string> candidates;  ///< covariates tried
  std::vector<std::string> notes;
};

/// Fits the declared model and runs the residual loop (`calib fit --discover`).
[[nodiscard]] DiscoveryResult discover_effects(const CalibrationDataset& data, const DiscoveryParams& params = {});

/// The residual analysis of a given model on data (`calib diagnose`): terms are
/// fitted to its residuals (the model itself is not refitted); `model` in the
/// result is the given one, train_before/train_after are unset, and
/// rmse_after_m is the held-out error of the model plus the accepted terms.
[[nodiscard]] DiscoveryResult diagnose_model(const CalibrationModel& model, const CalibrationDataset& data,
                                             const DiscoveryParams& params = {});

/// One-sided normal quantile: z with P(Z > z) = p.
double normal_upper_quantile(double p);

/// A term in physical units: what it adds to which capacitor, or the delay it
/// stands for (a distance offset d is a delay of 2 d / c).
std::string term_reading(const CalibrationTerm& t);

}  // namespace tinyline::tiny_laser_calibration

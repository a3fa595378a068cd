// SPDX-License-Identifier: Apache-2.0
// The fitter's working state, shared by the declared fit and the residual loop.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include <tiny_laser_calibration/fit.hpp>

#include "normal_equations.hpp"

namespace tinyline::tiny_laser_calibration::detail {

/// Covariate value of a term for dataset row `row` (dataset_extra: the term's
/// column in the data set for kExtra), given the row's X and declared distance.
double term_covariate(const CalibrationDataset& data, std::size_t row, const CalibrationTerm& term, int dataset_extra,
                      double x, double declared_m, const AmplitudeReference& reference);

/// Fits the amplitude reference (ln amplitude per pulse by declared distance, plus a
/// per-pixel offset) to rows with their declared distances.
AmplitudeReference fit_amplitude_reference(const CalibrationDataset& data, const std::vector<std::size_t>& rows,
                                           const std::vector<double>& declared_m);

/// How the declared prediction of one read-out moves with its charges (at the
/// current fit): the columns of a linearised charge term in the residual loop.
struct ChargeSensitivity {
  double add_a = 0.0, add_b = 0.0;    ///< d distance / d (charge added to A, to B) [m per charge_unit]
  double gain_a = 0.0, gain_b = 0.0;  ///< d distance / d (relative gain of A, of B) [m]
  double a = 0.0, b = 0.0;            ///< the raw read-out (the readout form's covariate)
  int pulses = 0;
};

/// The pixel-group covariates' first group is the reference (its value held
/// at 0): the others are told apart from it, the level itself is the declared
/// leakage's or Rsen's. Not for a centred term (centred_charge_term).
bool first_value_fixed(const CalibrationTerm& t, bool per_pulse_charge_levels);

/// A charge term fitted with its mean over the fitted read-outs held at 0 (when
/// DeclaredFitParams::per_pulse_charge_levels is false): a per-pulse charge on one
/// capacitor over a covariate other than `one`, on both over a built-in covariate,
/// and every added charge over pixel groups (the contrast between them).
bool centred_charge_term(const CalibrationTerm& t, bool per_pulse_charge_levels);

/// Mean hat-basis weight of each knot of `t` over the covariate values `z` (NaNs skipped).
std::vector<double> mean_knot_weights(const CalibrationTerm& t, const std::vector<double>& z);

class FitEngine {
 public:
  /// Keeps the valid rows of `rows` (all of data when empty), selected per params.selection.
  FitEngine(const CalibrationDataset& data, const std::vector<std::size_t>& rows, const DeclaredFitParams& params,
            const std::vector<CalibrationTerm>& terms);

  /// Empty when the data can be fitted; else why not.
  [[nodiscard]] const std::string& problem() const { return problem_; }

  /// Runs the whole declared fit (nonlinear parameters, linear solve, weighting).
  void fit();
  /// Fills a model from the current state.
  [[nodiscard]] CalibrationModel model() const;

  // --- pieces for the residual loop (nonlinear parameters held fixed) ---
  [[nodiscard]] std::size_t size() const { return rows_.size(); }
  [[nodiscard]] const std::vector<std::size_t>& rows() const { return rows_; }
  [[nodiscard]] std::size_t declared_columns() const { return declared_cols_; }
  /// Entries of the declared columns (polynomial, temperature) for kept row i.
  void declared_entries(std::size_t i, Entries& out) const;
  [[nodiscard]] double x(std::size_t i) const { return x_[i]; }
  [[nodiscard]] double y(std::size_t i) const { return y_[i]; }
  [[nodiscard]] double weight(std::size_t i) const { return w_[i]; }
  /// Declared distance of kept row i under the current coefficients.
  [[nodiscard]] double declared_m(std::size_t i) const;
  [[nodiscard]] double ratio_min() const { return ratio_min_; }
  [[nodiscard]] double ratio_max() const { return ratio_max_; }
  [[nodiscard]] const AmplitudeReference& amplitude_reference() const { return reference_; }
  [[nodiscard]] ChargeSensitivity charge_sensitivity(std::size_t i) const;
  /// Ridge per column (tiny on the declared columns, term_ridge on the term columns).
  [[nodiscard]] Eigen::VectorXd ridge(std::size_t total_columns) const;

  std::size_t saturated = 0, too_dark = 0, not_selected = 0, offered = 0, distances = 0;
  std::vector<std::string> notes;

 private:
  // Steps of the constructor (each false with problem_ set when the data cannot be fitted).
  void take_ceiling_from_data();
  bool group_rows();
  bool enough_data();
  void decide_leakage_offset();
  void decide_temperature();
  bool resolve_terms();
  bool scale_ratio();
  // Steps of the per-pixel Rsen refinement.
  std::vector<bool> rsen_eligible_pixels(std::size_t& n_eligible) const;
  double rsen_jacobian(std::size_t i, double rsen) const;
  void corrected(std::size_t i, double& a, double& b) const;  // kept row i's charges after the charge terms
  double polynomial_slope(std::size_t i) const;               // dP/dX at kept row i [m]
  void rsen_step(const std::vector<bool>& eligible);

  void compute_x();
  void compute_covariates();
  void entries(std::size_t i, Entries& out) const;
  double solve_linear();
  double residual_cost(std::vector<double>* residuals);
  // A parameter the Levenberg-Marquardt loop moves, in scaled units so one
  // finite-difference step fits all.
  struct GlobalParam {
    double* value;
    double typical;
    double lo, hi;
  };
  std::vector<GlobalParam> global_parameters();  // leakage and the charge terms' values
  void centre_charge_terms();                    // the knot weights of the centred terms (after resolve_terms)
  void apply_centring();                         // each centred term's dependent value from the others
  void optimise_global();
  void refine_per_pixel();
  void reweight_inverse_variance();
  void set_weights(const std::vector<double>& k_per_group);

  const CalibrationDataset& data_;
  DeclaredFitParams p_;
  std::string problem_;

  std::vector<std::size_t> rows_;  // dataset rows kept
  std::vector<double> y_, w_, x_;
  std::vector<int> group_;  // target-distance group of each kept row
  std::size_t groups_ = 0;

  double rsen_ = 1.0;
  std::vector<double> rsen_pixel_;  // empty or kPixels
  double leak_offset_ = 0.0, leak_per_pulse_ = 0.0;
  double center_ = 0.5, scale_ = 0.5;
  double ratio_min_ = 0.0, ratio_max_ = 1.0;
  bool use_temp_ = false;
  bool fit_leak_offset_ = false;
  bool notes_rsen_once_ = true;

  AmplitudeReference reference_;
  void update_reference();
  void set_ratio_range();
  /// Share of the data left out of the ratio range at each end (set_ratio_range).
  static constexpr double kRatioRangeTail = 0.001;
  std::vector<CalibrationTerm> terms_;               // the distance terms (linear columns)
  std::vector<CalibrationTerm> charge_;              // the terms on the charges (nonlinear, fitted around the solve)
  std::vector<std::vector<double>> centre_;          // per charge term: mean knot weights when centred, else empty
  std::vector<std::size_t> centre_dep_;              // per charge term: the value set from the others when centred
  std::vector<std::pair<bool, std::size_t>> order_;  // given order: (charge?, index)
  std::vector<int> term_extra_;                      // dataset extra column per term
  std::vector<std::vector<double>> z_;               // per term, per kept row
  std::vector<std::size_t> term_col_;                // first column per term
  std::size_t declared_cols_ = 0, cols_ = 0;
  Eigen::VectorXd coef_;
  SparseRows design_;             // of the last solve
  std::vector<double> residual_;  // y - prediction of the last solve (unweighted)
  mutable Entries tmp_;
  std::string weighting_note_ = "K_i = 1";
};

}  // namespace tinyline::tiny_laser_calibration::detail

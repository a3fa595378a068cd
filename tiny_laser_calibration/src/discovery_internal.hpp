// SPDX-License-Identifier: Apache-2.0
// The residual loop's working data, shared by the loop (discovery.cpp) and
// the hypotheses that act on the charges (charge_hypotheses.cpp).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <tiny_laser_calibration/discovery.hpp>

#include "fit_engine.hpp"
#include "normal_equations.hpp"

namespace tinyline::tiny_laser_calibration::detail {

/// The rows one round scores candidates on, with their fixed columns.
struct CvData {
  std::vector<std::size_t> row;  // dataset row
  std::vector<Entries> base;     // fixed columns (declared model, or a constant)
  std::size_t base_cols = 0;
  std::vector<double> y, w, x, declared, amplitude;
  std::vector<ChargeSensitivity> sens;  // per row; empty in residual mode (no model to move)
  std::vector<int> fold;                // -1: always training; -2: held out (never fitted on)
  std::vector<int> group;               // dense among rows with fold >= 0
  std::size_t groups = 0;
  int folds = 0;
  const AmplitudeReference* reference = nullptr;
  bool rsen_per_pixel = false;          // the fit refits each pixel's Rsen (charge terms are scored beyond it)
  double rsen_min_rows = 0.0;           // ... for pixels with this many fitted rows
  bool per_pulse_charge_levels = true;  // DeclaredFitParams::per_pulse_charge_levels of the fit
};

/// A candidate term on the CV rows: its columns, computed once.
struct CvTerm {
  CalibrationTerm term;
  int data_extra = -1;
  std::vector<double> z;  // per CvData row
  SparseRows cols;        // per CvData row, columns relative to the term's first
  std::size_t ncols = 0;
  double looks = 1.0;  // hypotheses this one stands for (a pixel chosen from the data stands for every pixel)
};

/// Fills t.cols: the term's basis (distance forms) or, for a form that acts on
/// the charges, its linearisation at the current fit (d distance / d value).
void materialise(CvTerm& t, const CvData& d, const CalibrationDataset& data);

std::vector<double> quantile_knots(std::vector<double> v, int n);

/// Every hypothesis that acts on the charges, on the covariates that can carry
/// one: a constant, temperature, time, the extra columns and pixel groups
/// (parity, banks, the single pixel the residuals single out).
/// `residual` is y minus the current model's prediction on each CV row.
void build_charge_forms(const CalibrationDataset& data, const CvData& d, const DiscoveryParams& p,
                        const std::vector<double>& residual, const std::vector<std::string>& used,
                        std::vector<CvTerm>& out, std::vector<std::string>& notes);

}  // namespace tinyline::tiny_laser_calibration::detail

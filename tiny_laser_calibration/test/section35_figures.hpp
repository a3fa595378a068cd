// SPDX-License-Identifier: Apache-2.0
// Section 3.5's figures for one fit of the declared model: the in-sample
// residual the thesis reports, and the held-out one (5 folds over the
// interior target distances). Shared by the synthetic-sensor and the
// simulator versions of the reproduction.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include <tiny_laser_calibration/fit.hpp>

namespace tinyline::tiny_laser_calibration::testing {

struct Section35Figures {
  const char* name = "";
  double var_cm2 = 0.0, sd_cm = 0.0;  // in-sample residual, as the thesis reports
  double heldout_sd_cm = 0.0;         // 5 folds over the interior target distances
  std::size_t n = 0;
  double thesis_var = 0.0, thesis_sd = 0.0;
};

inline Section35Figures section35_figures(const char* name, const CalibrationDataset& data, const DeclaredFitParams& p,
                                          double thesis_var, double thesis_sd) {
  Section35Figures f;
  f.name = name;
  f.thesis_var = thesis_var;
  f.thesis_sd = thesis_sd;
  const auto r = fit_declared_model(data, p);
  EXPECT_TRUE(r.status.ok()) << name << ": " << r.status.message;
  if (!r.status.ok()) return f;
  const auto s_in = evaluate_model(r.model, data, {}, ReadoutSelection::kAll);
  f.n = s_in.n;
  f.sd_cm = s_in.sd_m * 100.0;
  f.var_cm2 = f.sd_cm * f.sd_cm;
  // Held out: each fifth of the interior target distances predicted by a fit on the rest.
  const auto groups = target_distance_groups(data);
  const int n_groups = *std::max_element(groups.begin(), groups.end()) + 1;
  std::vector<double> residuals;
  for (int fold = 0; fold < 5; ++fold) {
    std::vector<std::size_t> train, test;
    for (std::size_t i = 0; i < data.size(); ++i) {
      const int g = groups[i];
      const bool interior = g > 0 && g < n_groups - 1;
      (interior && g % 5 == fold ? test : train).push_back(i);
    }
    const auto rf = fit_calibration_model(data, train, p, {});
    EXPECT_TRUE(rf.status.ok()) << rf.status.message;
    const auto res = model_residuals(rf.model, data, select_readouts(data, test, p.validity, p.selection));
    for (double v : res) {
      if (std::isfinite(v)) residuals.push_back(v);
    }
  }
  f.heldout_sd_cm = error_stats(residuals).sd_m * 100.0;
  return f;
}

/// The five fits of section 3.5 beside the thesis's figures (thesis_measured.yaml
/// calibration_fits_cm; the thesis gives "sd over 5" for the linear fit), each
/// fitted with `params(degree)`, and printed as the table in docs/calibration.md.
struct Section35Table {
  Section35Figures lin, p3, p6, p6_20, p6_multi;
};

template <class ParamsForDegree>
Section35Table section35_table(const CalibrationDataset& d40, const CalibrationDataset& d20,
                               const CalibrationDataset& multi, ParamsForDegree params) {
  const Section35Table t{
      section35_figures("linear (Eq. 3.16), 40 %", d40, params(1), 29.3814, std::sqrt(29.3814)),
      section35_figures("degree 3, 40 %", d40, params(3), 1.6863, 1.2986),
      section35_figures("degree 6, 40 %", d40, params(6), 0.7424, 0.8616),
      section35_figures("degree 6, 20 %", d20, params(6), 1.442, 1.20),
      section35_figures("degree 6, multi-discharge", multi, params(6), 3.4618, 1.8606),
  };
  std::printf("\n| fit | var [cm^2] | SD [cm] | held-out SD [cm] | read-outs | thesis var | thesis SD |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (const auto* f : {&t.lin, &t.p3, &t.p6, &t.p6_20, &t.p6_multi}) {
    std::printf("| %s | %.3f | %.3f | %.3f | %zu | %.4f | %.4f |\n", f->name, f->var_cm2, f->sd_cm, f->heldout_sd_cm,
                f->n, f->thesis_var, f->thesis_sd);
  }
  return t;
}

}  // namespace tinyline::tiny_laser_calibration::testing

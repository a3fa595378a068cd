// SPDX-License-Identifier: Apache-2.0
// Hypotheses where the physics is: effects that act on the two capacitors'
// charges before the ratio of Eq. 3.16 (an added charge on A, on B or on
// both, constant or per pulse; a gain on A or on B; a read-out
// nonlinearity), each a function of a covariate that can carry it. Scored by
// the residual loop through their linearisation at the current fit (the
// Gauss-Newton step of refitting the whole model with the term), and refitted
// exactly once accepted (FitEngine fits their values with Rsen and Vle).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <tiny_laser_driver/protocol.hpp>

#include "discovery_internal.hpp"

namespace tinyline::tiny_laser_calibration::detail {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool per_pulse(TermForm f) {
  return f == TermForm::kChargeAPerPulse || f == TermForm::kChargeBPerPulse || f == TermForm::kChargeBothPerPulse;
}

// d distance / d g for one read-out, g the form's value at its covariate.
double sensitivity(TermForm f, const ChargeSensitivity& s) {
  const double p = per_pulse(f) ? s.pulses : 1.0;
  switch (f) {
    case TermForm::kChargeA:
    case TermForm::kChargeAPerPulse: return p * s.add_a;
    case TermForm::kChargeB:
    case TermForm::kChargeBPerPulse: return p * s.add_b;
    case TermForm::kChargeBoth:
    case TermForm::kChargeBothPerPulse: return p * (s.add_a + s.add_b);
    case TermForm::kGainA: return s.gain_a;
    case TermForm::kGainB: return s.gain_b;
    default: return 0.0;
  }
}

// Per-pixel Rsen is refitted with a new term (the whole model is refitted), so a
// charge term is scored on what it adds beyond a change of each pixel's Rsen: its
// columns are made orthogonal, pixel by pixel over the fitted rows, to the
// read-outs' sensitivity to that pixel's Rsen (Frisch-Waugh: the Gauss-Newton
// step with both free). Without it a charge on B of a bank of pixels, which each
// pixel's Rsen half absorbs, is scored on the whole of its column and fits little.
void project_off_pixel_sensitivity(std::vector<Entries>& rows, std::size_t ncols, const CvData& d,
                                   const CalibrationDataset& data) {
  using tiny_laser_driver::kPixels;
  std::vector<double> rr(kPixels, 0.0), n(kPixels, 0.0);
  std::vector<std::vector<double>> rc(kPixels, std::vector<double>(ncols, 0.0));
  const auto pixel = [&](std::size_t i) { return static_cast<std::size_t>(data.readouts[d.row[i]].pixel); };
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (d.fold[i] == -2) continue;
    const double r = d.sens[i].gain_a;
    rr[pixel(i)] += d.w[i] * r * r;
    n[pixel(i)] += 1.0;
    for (const auto& [c, v] : rows[i]) rc[pixel(i)][c] += d.w[i] * r * v;
  }
  // The fit holds the pixels' median Rsen (only differences are identifiable): the
  // per-pixel steps delta_px are projected with sum delta_px = 0 (a Lagrange
  // multiplier per column), delta_px = beta_px - lambda / rr_px.
  std::vector<bool> free(kPixels, false);
  std::vector<double> lambda(ncols, 0.0);
  double inv = 0.0;
  for (std::size_t px = 0; px < kPixels; ++px) {
    free[px] = n[px] >= d.rsen_min_rows && rr[px] > 0.0;
    if (!free[px]) continue;  // no per-pixel Rsen for this pixel
    inv += 1.0 / rr[px];
    for (std::size_t c = 0; c < ncols; ++c) lambda[c] += rc[px][c] / rr[px];
  }
  if (!(inv > 0.0)) return;
  for (double& l : lambda) l /= inv;
  std::vector<double> dense(ncols);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::size_t px = pixel(i);
    if (!free[px]) continue;
    std::fill(dense.begin(), dense.end(), 0.0);
    for (const auto& [c, v] : rows[i]) dense[c] += v;
    rows[i].clear();
    for (std::size_t c = 0; c < ncols; ++c) {
      const double delta = (rc[px][c] - lambda[c]) / rr[px];
      const double v = dense[c] - delta * d.sens[i].gain_a;
      if (v != 0.0) rows[i].emplace_back(c, v);
    }
  }
}

// A centred term (centred_charge_term) is g(z) - mean g over the fitted read-outs:
// column j is (h_j(z) - m_j) times the read-out's sensitivity, m_j the mean weight
// of knot j, so no combination of the columns is a level.
void centre_columns(std::vector<Entries>& rows, const CvTerm& t, const CvData& d) {
  std::vector<double> fitted;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (d.fold[i] != -2) fitted.push_back(t.z[i]);
  }
  const std::vector<double> m = mean_knot_weights(t.term, fitted);
  std::vector<double> dense(t.ncols);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const double k = sensitivity(t.term.form, d.sens[i]);
    for (std::size_t c = 0; c < t.ncols; ++c) dense[c] = -m[c] * k;
    for (const auto& [c, v] : rows[i]) dense[c] += v;
    rows[i].clear();
    for (std::size_t c = 0; c < t.ncols; ++c) {
      if (dense[c] != 0.0) rows[i].emplace_back(c, dense[c]);
    }
  }
}

// A charge term's column is in metres per charge_unit (a constant charge moves a
// far read-out by millimetres per unit), so the ridge every term gets (term_ridge
// pseudo-observations on its coefficients) would hold a charge of several units
// near 0: each column is scaled to RMS 1 over the fitted rows, as a distance
// term's basis is, so the ridge weighs the same on every form.
void unit_columns(std::vector<Entries>& rows, std::size_t ncols, const CvData& d) {
  std::vector<double> ss(ncols, 0.0);
  double n = 0.0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (d.fold[i] == -2) continue;
    n += 1.0;
    for (const auto& [c, v] : rows[i]) ss[c] += v * v;
  }
  std::vector<double> scale(ncols, 1.0);
  for (std::size_t c = 0; c < ncols; ++c) {
    if (ss[c] > 0.0 && n > 0.0) scale[c] = 1.0 / std::sqrt(ss[c] / n);
  }
  for (auto& e : rows) {
    for (auto& [c, v] : e) v *= scale[c];
  }
}

}  // namespace

void materialise(CvTerm& t, const CvData& d, const CalibrationDataset& data) {
  t.cols.clear();
  const bool charge = acts_on_charges(t.term.form);
  const std::size_t skip = first_value_fixed(t.term, d.per_pulse_charge_levels) ? 1 : 0;
  t.ncols = t.term.basis_size() - (charge ? skip : 0);
  Entries tmp;
  std::vector<Entries> rows(d.y.size());
  CalibrationTerm hat = t.term;
  hat.form = TermForm::kSmooth;  // a charge form's g(z) is a smooth's hat basis
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    Entries& e = rows[i];
    if (!charge) {
      t.term.basis(t.z[i], d.amplitude[i], e);
    } else if (!d.sens.empty()) {
      const ChargeSensitivity& s = d.sens[i];
      tmp.clear();
      if (t.term.form == TermForm::kReadout) {
        // v + g(v) on both: A moves the distance like a charge removed from A, B like one removed from B.
        hat.basis(s.a, 0.0, tmp);
        for (const auto& [c, v] : tmp) e.emplace_back(c, -v * s.add_a);
        tmp.clear();
        hat.basis(s.b, 0.0, tmp);
        for (const auto& [c, v] : tmp) e.emplace_back(c, -v * s.add_b);
      } else {
        hat.basis(t.z[i], 0.0, tmp);
        const double k = sensitivity(t.term.form, s);
        for (const auto& [c, v] : tmp) e.emplace_back(c, v * k);
      }
      std::erase_if(e, [&](const auto& ce) { return ce.first < skip; });
      for (auto& ce : e) ce.first -= skip;
    }
  }
  if (charge && !d.sens.empty() && centred_charge_term(t.term, d.per_pulse_charge_levels)) centre_columns(rows, t, d);
  if (charge && d.rsen_per_pixel && !d.sens.empty()) project_off_pixel_sensitivity(rows, t.ncols, d, data);
  if (charge) unit_columns(rows, t.ncols, d);
  for (const auto& e : rows) t.cols.push(e);
}

namespace {

struct ChargeCovariate {
  std::string name;
  std::vector<double> knots;
  double looks = 1.0;
  bool group = false;  // a pixel group: its first value is held at 0
};

// Values of a covariate on the CV rows, NaN where missing.
std::vector<double> values_on_rows(const CalibrationDataset& data, const CvData& d, const std::string& name) {
  CalibrationTerm t;
  t.covariate = name;
  t.kind = covariate_from_name(name);
  const int extra = t.kind == Covariate::kExtra ? data.extra_index(name) : covariate_parameter(name);
  t.extra_index = extra;
  std::vector<double> z(d.y.size(), kNaN);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    const Readout& r = data.readouts[d.row[i]];
    z[i] = t.kind == Covariate::kExtra
               ? (extra >= 0 ? r.extra[static_cast<std::size_t>(extra)] : kNaN)
               : CalibrationModel::Impl::covariate_value(t.kind, extra, r, kNaN, kNaN, AmplitudeReference{});
  }
  return z;
}

// The pixel whose training residuals stand out most (|mean| / standard error);
// -1 when no pixel has enough read-outs.
int odd_pixel(const CalibrationDataset& data, const CvData& d, const std::vector<double>& residual,
              std::size_t& pixels) {
  using tiny_laser_driver::kPixels;
  std::vector<double> sum(kPixels, 0.0), sum2(kPixels, 0.0), n(kPixels, 0.0);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] == -2 || !std::isfinite(residual[i])) continue;
    const auto px = static_cast<std::size_t>(data.readouts[d.row[i]].pixel);
    sum[px] += residual[i];
    sum2[px] += residual[i] * residual[i];
    n[px] += 1.0;
  }
  int best = -1;
  double best_t = 0.0;
  pixels = 0;
  for (std::size_t px = 0; px < kPixels; ++px) {
    if (n[px] < 10) continue;
    ++pixels;
    const double mean = sum[px] / n[px];
    const double var = std::max(sum2[px] / n[px] - mean * mean, 1e-18);
    const double t = std::abs(mean) / std::sqrt(var / n[px]);
    if (t > best_t) {
      best_t = t;
      best = static_cast<int>(px);
    }
  }
  return best;
}

bool excluded(const DiscoveryParams& p, const std::string& n) {
  return std::find(p.exclude.begin(), p.exclude.end(), n) != p.exclude.end();
}

// Knots of a continuous covariate (at quantiles of its fitted values); empty
// when it is missing somewhere or does not vary.
std::vector<double> continuous_knots(const std::vector<double>& z, const CvData& d, int n) {
  std::vector<double> fitted;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (!std::isfinite(z[i])) return {};
    if (d.fold[i] != -2) fitted.push_back(z[i]);
  }
  if (fitted.size() < 10) return {};
  const auto k = quantile_knots(fitted, n);
  return k.size() >= 2 ? k : std::vector<double>{};
}

std::vector<ChargeCovariate> charge_covariates(const CalibrationDataset& data, const CvData& d,
                                               const DiscoveryParams& p, const std::vector<double>& residual,
                                               std::vector<std::string>& notes) {
  std::vector<ChargeCovariate> out;
  out.push_back({"one", {1.0}, 1.0, false});
  // Continuous: what the sensor measures beside the charges, and time.
  std::vector<std::string> continuous = {"temperature_c", "t_s"};
  for (const auto& n : data.extra_names) {
    if (n != "session" && n.rfind("temperature_c_lp", 0) != 0 && covariate_from_name(n) == Covariate::kExtra) {
      continuous.push_back(n);
    }
  }
  for (const auto& n : continuous) {
    if (excluded(p, n)) continue;
    auto k = continuous_knots(values_on_rows(data, d, n), d, p.charge_knots);
    if (!k.empty()) out.push_back({n, std::move(k), 1.0, false});
  }
  // Pixel structure: parity, banks of 16-128 effective pixels, the odd pixel out.
  if (excluded(p, "pixel")) return out;
  std::vector<std::pair<std::string, double>> groups = {{"pixel_parity", 1.0}};
  for (int bank : {16, 32, 64, 128}) groups.emplace_back(fmt::format("pixel_bank{}", bank), 1.0);
  std::size_t pixels = 0;
  const int odd = odd_pixel(data, d, residual, pixels);
  if (odd >= 0) groups.emplace_back(fmt::format("pixel_is{}", odd), static_cast<double>(pixels));
  for (const auto& [name, looks] : groups) {
    const auto z = values_on_rows(data, d, name);
    std::vector<double> ids;
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (d.fold[i] != -2 && std::isfinite(z[i])) ids.push_back(z[i]);
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    if (ids.size() >= 2) out.push_back({name, ids, looks, true});
  }
  if (odd >= 0) {
    notes.push_back(
        fmt::format("pixel {} stands out most in the residuals: tried alone, counted as {} looks", odd, pixels));
  }
  return out;
}

CvTerm charge_term(const CalibrationDataset& data, const CvData& d, const ChargeCovariate& c, TermForm form,
                   const std::vector<double>& z) {
  CvTerm t;
  t.term.covariate = c.name;
  t.term.kind = covariate_from_name(c.name);
  t.term.form = form;
  t.term.knots = c.knots;
  t.term.values.assign(c.knots.size(), 0.0);
  t.z = z;
  t.looks = c.looks;
  materialise(t, d, data);
  return t;
}

// The forms tried over one covariate.
std::vector<TermForm> charge_forms(const ChargeCovariate& c, const DiscoveryParams& p) {
  std::vector<TermForm> forms = {TermForm::kChargeA, TermForm::kChargeB, TermForm::kChargeAPerPulse,
                                 TermForm::kChargeBPerPulse};
  // On both capacitors a constant is the declared leakage (Vle, Eq. 3.16) unless it was measured apart.
  // On one surface (per_pulse_charge_levels false) a level per pulse acts as a distance cue (the twin of
  // the group-leakage case, seed 6, named one on both); and between pixel groups, which the lens lights
  // unevenly, so does any charge but one per pulse on one capacitor (the effect-free synthetic rail,
  // seed 5, named a constant charge over banks of 16 at 0.95-0.96 of its floor, on A or on both).
  const bool one_surface = !p.declared.per_pulse_charge_levels;
  if (c.group && one_surface) forms = {TermForm::kChargeAPerPulse, TermForm::kChargeBPerPulse};
  if ((c.name != "one" || !p.declared.fit_leakage) && !(c.group && one_surface)) {
    forms.push_back(TermForm::kChargeBoth);
    forms.push_back(TermForm::kChargeBothPerPulse);
  }
  if (c.name == "one" && one_surface) {  // a level per pulse: the declared leakage's
    std::erase_if(forms, [](TermForm f) {
      return f == TermForm::kChargeAPerPulse || f == TermForm::kChargeBPerPulse || f == TermForm::kChargeBothPerPulse;
    });
  }
  // Gains over pixel groups only: a constant gain is the common Rsen (absorbed by the polynomial), a
  // per-pixel one the per-pixel Rsen; and over a measured covariate a gain of A mimics a delay on one
  // surface (a small delay moves charge from A to B in proportion to the signal), which the distance
  // terms of that covariate already hold.
  if (c.group && p.declared.sensitivity_ratio_mode != SensitivityRatioMode::kPerPixel) {
    forms.push_back(TermForm::kGainA);
    forms.push_back(TermForm::kGainB);
  }
  return forms;
}

}  // namespace

void build_charge_forms(const CalibrationDataset& data, const CvData& d, const DiscoveryParams& p,
                        const std::vector<double>& residual, const std::vector<std::string>& used,
                        std::vector<CvTerm>& out, std::vector<std::string>& notes) {
  if (d.sens.empty() || excluded(p, "charge")) return;
  for (const auto& c : charge_covariates(data, d, p, residual, notes)) {
    if (std::find(used.begin(), used.end(), c.name) != used.end()) continue;  // one term per covariate
    const auto z = values_on_rows(data, d, c.name);
    for (TermForm f : charge_forms(c, p)) out.push_back(charge_term(data, d, c, f, z));
  }
  // Read-out nonlinearity: g(v) on both capacitors' own read-outs.
  if (std::find(used.begin(), used.end(), "charge") == used.end()) {
    std::vector<double> v;
    for (const auto& s : d.sens) {
      v.push_back(s.a);
      v.push_back(s.b);
    }
    ChargeCovariate c{"charge", quantile_knots(v, p.charge_knots), 1.0, false};
    if (c.knots.size() >= 2)
      out.push_back(charge_term(data, d, c, TermForm::kReadout, std::vector<double>(d.y.size(), 0.0)));
  }
}

}  // namespace tinyline::tiny_laser_calibration::detail

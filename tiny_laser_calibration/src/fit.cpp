// SPDX-License-Identifier: Apache-2.0
// The declared-model fitter (thesis 3.3.3-3.3.4): variable projection over
// Rsen and the leakage, an exact weighted least-squares solve for everything
// linear (polynomial, temperature coefficient, term coefficients).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>
#include <utility>

#include <fmt/format.h>

#include <tiny_laser_driver/protocol.hpp>
#include <tinyline/common/least_squares.hpp>

#include "fit_engine.hpp"

namespace tinyline::tiny_laser_calibration {

using tiny_laser_driver::kDarkPixels;
using tiny_laser_driver::kPixels;

namespace detail {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kMissPenaltyM = 1.0;  // residual charged to a row whose X is undefined under trial parameters

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}
}  // namespace

double term_covariate(const CalibrationDataset& data, std::size_t row, const CalibrationTerm& term, int dataset_extra,
                      double x, double declared_m, const AmplitudeReference& reference) {
  const Readout& r = data.readouts[row];
  if (term.kind == Covariate::kExtra) {
    return dataset_extra >= 0 ? r.extra[static_cast<std::size_t>(dataset_extra)] : kNaN;
  }
  return CalibrationModel::Impl::covariate_value(term.kind, covariate_parameter(term.covariate), r, x, declared_m,
                                                 reference);
}

AmplitudeReference fit_amplitude_reference(const CalibrationDataset& data, const std::vector<std::size_t>& rows,
                                           const std::vector<double>& declared_m) {
  constexpr int kKnots = 16;
  AmplitudeReference ref;
  std::vector<std::size_t> use;
  std::vector<double> d;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const Readout& r = data.readouts[rows[k]];
    if (r.pulses > 0 && r.a + r.b > 0.0 && std::isfinite(declared_m[k]) && declared_m[k] > 0.0) {
      use.push_back(k);
      d.push_back(declared_m[k]);
    }
  }
  if (use.size() < 50) return ref;
  std::vector<double> sorted = d;
  std::sort(sorted.begin(), sorted.end());
  for (int i = 0; i < kKnots; ++i) {
    const double v = sorted[static_cast<std::size_t>(std::lround(i * (sorted.size() - 1.0) / (kKnots - 1)))];
    if (ref.knots_m.empty() || v > ref.knots_m.back() + 1e-6) ref.knots_m.push_back(v);
  }
  if (ref.knots_m.size() < 2) return {};
  // ln amplitude = hat basis in distance + per-pixel offset (a ridge keeps the offsets
  // centred) + per-material offset when the data names materials: then the curve is
  // that of one material (the most common), not of whichever mix is valid at each distance.
  const std::size_t nk = ref.knots_m.size();
  std::size_t n_mat = 0, ref_mat = 0;
  if (data.has_material && data.materials.size() > 1) {
    n_mat = data.materials.size();
    std::vector<std::size_t> count(n_mat, 0);
    for (std::size_t j : use) {
      const int m = data.material[rows[j]];
      if (m >= 0) ++count[static_cast<std::size_t>(m)];
    }
    ref_mat = static_cast<std::size_t>(std::max_element(count.begin(), count.end()) - count.begin());
  }
  const std::size_t cols = nk + kPixels + n_mat;
  NormalEquations ne(cols);
  CalibrationTerm hat;
  hat.knots = ref.knots_m;
  Entries e;
  for (std::size_t j = 0; j < use.size(); ++j) {
    const Readout& r = data.readouts[rows[use[j]]];
    e.clear();
    hat.basis(d[j], 0.0, e);
    e.emplace_back(nk + static_cast<std::size_t>(r.pixel), 1.0);
    const int m = n_mat ? data.material[rows[use[j]]] : -1;
    if (m >= 0 && static_cast<std::size_t>(m) != ref_mat)
      e.emplace_back(nk + kPixels + static_cast<std::size_t>(m), 1.0);
    ne.add(e, std::log((r.a + r.b) / r.pulses), 1.0);
  }
  Eigen::VectorXd ridge = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(cols), 1e-9);
  for (std::size_t c = nk; c < nk + kPixels; ++c) ridge[static_cast<Eigen::Index>(c)] = 1.0;
  const Eigen::VectorXd c = ne.solve(ridge);
  ref.log_amplitude.assign(c.data(), c.data() + nk);
  ref.pixel_log_offset.assign(c.data() + nk, c.data() + nk + kPixels);
  return ref;
}

namespace {
bool pixel_group_charge(const CalibrationTerm& t) {
  const Covariate k = covariate_from_name(t.covariate);
  return acts_on_charges(t.form) &&
         (k == Covariate::kPixelParity || k == Covariate::kPixelBank || k == Covariate::kPixelIs);
}
}  // namespace

bool first_value_fixed(const CalibrationTerm& t, bool per_pulse_charge_levels) {
  return pixel_group_charge(t) && !centred_charge_term(t, per_pulse_charge_levels);
}

bool centred_charge_term(const CalibrationTerm& t, bool per_pulse_charge_levels) {
  if (per_pulse_charge_levels) return false;
  const bool one_capacitor = t.form == TermForm::kChargeAPerPulse || t.form == TermForm::kChargeBPerPulse;
  const Covariate k = covariate_from_name(t.covariate);
  // Over pixel groups a charge term holds the contrast between them; the level is `one`'s.
  const bool gain = t.form == TermForm::kGainA || t.form == TermForm::kGainB;
  if (pixel_group_charge(t)) return !gain && t.form != TermForm::kReadout;
  // On both capacitors the level is the declared leakage's, except over a measured
  // column (such as ambient light), whose level the declared leakage was measured without.
  return k != Covariate::kOne && (one_capacitor || (t.form == TermForm::kChargeBothPerPulse && k != Covariate::kExtra));
}

std::vector<double> mean_knot_weights(const CalibrationTerm& t, const std::vector<double>& z) {
  CalibrationTerm hat = t;
  hat.form = TermForm::kSmooth;
  std::vector<double> m(t.knots.size(), 0.0);
  Entries e;
  double n = 0.0;
  for (double v : z) {
    if (!std::isfinite(v)) continue;
    e.clear();
    hat.basis(v, 0.0, e);
    for (const auto& [c, w] : e) m[c] += w;
    n += 1.0;
  }
  if (n > 0.0) {
    for (double& w : m) w /= n;
  }
  return m;
}

FitEngine::FitEngine(const CalibrationDataset& data, const std::vector<std::size_t>& rows,
                     const DeclaredFitParams& params, const std::vector<CalibrationTerm>& terms)
    : data_(data), p_(params) {
  for (const auto& t : terms) {
    auto& to = acts_on_charges(t.form) ? charge_ : terms_;
    order_.emplace_back(acts_on_charges(t.form), to.size());
    to.push_back(t);
  }
  if (p_.degree < 1 || p_.degree > 12) {
    problem_ = fmt::format("polynomial degree {} is outside 1-12", p_.degree);
    return;
  }
  offered = rows.empty() ? data.size() : rows.size();
  if (p_.ceiling_from_data) take_ceiling_from_data();
  rows_ = select_readouts(data, rows, p_.validity, p_.selection, &saturated, &too_dark, &not_selected);
  if (rows_.empty()) {
    problem_ = fmt::format(
        "no valid read-outs among {} rows of {}: {} saturated (a or b >= {}), {} too dark (a or b <= {}, or "
        "a + b <= {} + {} * pulses / 10)",
        offered, data.source, saturated, p_.validity.high, too_dark, p_.validity.low, p_.validity.min_sum,
        p_.validity.per_pulse);
    return;
  }
  if (!group_rows() || !enough_data()) return;
  decide_leakage_offset();
  decide_temperature();
  if (!resolve_terms()) return;
  centre_charge_terms();
  declared_cols_ = static_cast<std::size_t>(p_.degree + 1) + (use_temp_ ? 1 : 0);
  cols_ = declared_cols_;
  for (const auto& t : terms_) {
    term_col_.push_back(cols_);
    cols_ += t.basis_size();
  }
  coef_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(cols_));
  rsen_ = p_.sensitivity_ratio;
  leak_offset_ = p_.leakage_offset;
  leak_per_pulse_ = p_.leakage_per_pulse;
  if (!scale_ratio()) return;
  set_weights(std::vector<double>(groups_, 1.0));
}

void FitEngine::take_ceiling_from_data() {
  double plateau = 0.0;
  const ValidityRule rule = validity_from_data(data_, p_.validity, &plateau);
  if (rule.high == p_.validity.high) return;
  notes.push_back(
      fmt::format("the read-outs saturate at {:.1f} charge_unit, below the validity rule's {:.0f}: "
                  "ceiling {:.1f} ({:.0f} % of the plateau)",
                  plateau, p_.validity.high, rule.high, 100.0 * kCeilingShareOfPlateau));
  p_.validity = rule;
}

bool FitEngine::group_rows() {
  const auto target_group = target_distance_groups(data_);
  std::vector<long long> mm;
  group_.reserve(rows_.size());
  y_.reserve(rows_.size());
  for (std::size_t i : rows_) {
    const double d = data_.distance_m[i];
    y_.push_back(d);
    mm.push_back(std::llround(d * 1000.0));
    group_.push_back(target_group[i]);
  }
  // Dense group ids over the kept rows (weights of Eq. 3.20 are per target distance).
  std::vector<int> group_ids = group_;
  std::sort(group_ids.begin(), group_ids.end());
  group_ids.erase(std::unique(group_ids.begin(), group_ids.end()), group_ids.end());
  for (int& g : group_)
    g = static_cast<int>(std::lower_bound(group_ids.begin(), group_ids.end(), g) - group_ids.begin());
  groups_ = group_ids.size();
  std::sort(mm.begin(), mm.end());
  mm.erase(std::unique(mm.begin(), mm.end()), mm.end());
  distances = mm.size();
  return true;
}

bool FitEngine::enough_data() {
  const std::size_t min_rows = 2 * static_cast<std::size_t>(p_.degree + 2);
  if (rows_.size() < min_rows) {
    problem_ =
        fmt::format("only {} valid read-outs: a degree-{} fit needs at least {}", rows_.size(), p_.degree, min_rows);
    return false;
  }
  if (distances < static_cast<std::size_t>(p_.degree + 1)) {
    problem_ = fmt::format("only {} distinct true distances (mm): a degree-{} polynomial needs at least {}", distances,
                           p_.degree, p_.degree + 1);
    return false;
  }
  return true;
}

void FitEngine::decide_leakage_offset() {
  // The leakage offset shows only as X changing with the pulse count at one
  // target: it needs frames with several valid pulse levels per pixel.
  fit_leak_offset_ = p_.fit_leakage;
  if (!fit_leak_offset_) return;
  std::vector<std::tuple<double, int, int>> keys;
  keys.reserve(rows_.size());
  for (std::size_t i : rows_)
    keys.emplace_back(data_.readouts[i].t_s, data_.readouts[i].pixel, data_.readouts[i].pulses);
  std::sort(keys.begin(), keys.end());
  std::size_t multi = 0;
  for (std::size_t k = 1; k < keys.size(); ++k) {
    const auto& [t0, px0, p0] = keys[k - 1];
    const auto& [t1, px1, p1] = keys[k];
    multi += (t0 == t1 && px0 == px1 && p0 != p1) ? 1 : 0;
  }
  if (multi >= rows_.size() / 10) return;
  fit_leak_offset_ = false;
  notes.push_back(p_.selection == ReadoutSelection::kDriver
                      ? fmt::format("one read-out per pixel and frame (the driver's choice) cannot tell a leakage "
                                    "offset from a per-pulse leakage: offset kept at {} charge_unit",
                                    p_.leakage_offset)
                      : fmt::format("few frames hold several valid pulse levels of a pixel: leakage offset kept "
                                    "at {} charge_unit",
                                    p_.leakage_offset));
}

void FitEngine::decide_temperature() {
  double tmin = 1e300, tmax = -1e300;
  for (std::size_t i : rows_) {
    tmin = std::min(tmin, data_.readouts[i].temperature_c);
    tmax = std::max(tmax, data_.readouts[i].temperature_c);
  }
  use_temp_ = p_.fit_temperature && (tmax - tmin) >= p_.min_temperature_span_c;
  if (p_.fit_temperature && !use_temp_) {
    notes.push_back(fmt::format("temperature spans {:.2f} degC (< {:.2f}): no temperature term fitted", tmax - tmin,
                                p_.min_temperature_span_c));
  }
}

bool FitEngine::resolve_terms() {
  for (auto& t : charge_) {
    // Indices into the data set's rows (Readout::extra in column order), not the model's.
    t.kind = covariate_from_name(t.covariate);
    t.extra_index = t.kind == Covariate::kExtra ? data_.extra_index(t.covariate) : covariate_parameter(t.covariate);
    if (t.kind == Covariate::kExtra && t.extra_index < 0) {
      problem_ = fmt::format("term covariate '{}' is neither a built-in covariate nor a column of {}", t.covariate,
                             data_.source);
      return false;
    }
    if (t.values.size() != t.knots.size()) t.values.assign(t.knots.size(), 0.0);
  }
  term_extra_.assign(terms_.size(), -1);
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    auto& t = terms_[k];
    t.kind = covariate_from_name(t.covariate);
    if (t.kind != Covariate::kExtra) continue;
    term_extra_[k] = data_.extra_index(t.covariate);
    if (term_extra_[k] < 0) {
      problem_ = fmt::format("term covariate '{}' is neither a built-in covariate nor a column of {}", t.covariate,
                             data_.source);
      return false;
    }
  }
  return true;
}

bool FitEngine::scale_ratio() {
  compute_x();
  double lo = 1e300, hi = -1e300;
  for (double x : x_) {
    if (std::isfinite(x)) {
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
  }
  if (!(hi - lo > 1e-6)) {
    problem_ = fmt::format("the charge ratio X does not vary over the valid read-outs (span {:.3g}): nothing to fit",
                           hi > lo ? hi - lo : 0.0);
    return false;
  }
  center_ = 0.5 * (lo + hi);
  scale_ = 0.5 * (hi - lo);
  return true;
}

void FitEngine::set_weights(const std::vector<double>& k_per_group) {
  std::vector<double> count(groups_, 0.0);
  for (int g : group_) count[static_cast<std::size_t>(g)] += 1.0;
  w_.resize(rows_.size());
  double sum = 0.0;
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const auto g = static_cast<std::size_t>(group_[i]);
    w_[i] = k_per_group[g] / (p_.equalize_distances ? count[g] : 1.0);  // K_i / N_i, Eq. 3.20
    sum += w_[i];
  }
  const double norm = static_cast<double>(rows_.size()) / sum;  // mean weight 1: ridge reads as pseudo-rows
  for (double& w : w_) w *= norm;
}

void FitEngine::corrected(std::size_t i, double& a, double& b) const {
  const Readout& r = data_.readouts[rows_[i]];
  a = r.a;
  b = r.b;
  if (!charge_.empty()) (void)CalibrationModel::Impl::correct_charges(charge_, r, a, b);
}

void FitEngine::compute_x() {
  x_.resize(rows_.size());
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const Readout& r = data_.readouts[rows_[i]];
    const double rsen = rsen_pixel_.empty() ? rsen_ : rsen_pixel_[static_cast<std::size_t>(r.pixel)];
    double a = 0.0, b = 0.0;
    corrected(i, a, b);
    x_[i] = CalibrationModel::Impl::charge_ratio(a, b, r.pulses, rsen, leak_offset_, leak_per_pulse_);  // Eq. 3.16
  }
}

double FitEngine::polynomial_slope(std::size_t i) const {
  const double u = (x_[i] - center_) / scale_;
  double dp = 0.0, pw = 1.0;
  for (int k = 1; k <= p_.degree; ++k) {
    dp += k * coef_[k] * pw;
    pw *= u;
  }
  return dp / scale_;
}

ChargeSensitivity FitEngine::charge_sensitivity(std::size_t i) const {
  const Readout& r = data_.readouts[rows_[i]];
  ChargeSensitivity s;
  s.a = r.a;
  s.b = r.b;
  s.pulses = r.pulses;
  if (!std::isfinite(x_[i])) return s;
  const double rsen = rsen_pixel_.empty() ? rsen_ : rsen_pixel_[static_cast<std::size_t>(r.pixel)];
  double a = 0.0, b = 0.0;
  corrected(i, a, b);
  const double vle = leak_offset_ + leak_per_pulse_ * r.pulses;
  const double ap = a * rsen - vle, bp = b - vle, sum = ap + bp;
  // X = B' / (A' + B'), A' = a Rsen - Vle, B' = b - Vle (Eq. 3.16); pred = P(X).
  const double k = polynomial_slope(i) / (sum * sum);
  s.add_a = k * rsen * bp;       // a - delta
  s.add_b = -k * ap;             // b - delta
  s.gain_a = k * bp * a * rsen;  // a / (1 + gamma)
  s.gain_b = -k * ap * b;
  return s;
}

double FitEngine::declared_m(std::size_t i) const {
  const double u = (x_[i] - center_) / scale_;
  double acc = 0.0;
  for (int k = p_.degree; k >= 0; --k) acc = acc * u + coef_[k];
  if (use_temp_) acc += coef_[p_.degree + 1] * (p_.temperature_reference_c - data_.readouts[rows_[i]].temperature_c);
  return acc;
}

void FitEngine::update_reference() {
  const bool solved = coef_.size() > 0 && coef_.cwiseAbs().maxCoeff() > 0.0;
  std::vector<double> declared(rows_.size());
  for (std::size_t i = 0; i < rows_.size(); ++i) declared[i] = solved ? declared_m(i) : y_[i];
  reference_ = fit_amplitude_reference(data_, rows_, declared);
}

void FitEngine::compute_covariates() {
  z_.assign(terms_.size(), std::vector<double>(rows_.size(), kNaN));
  const bool solved = coef_.size() > 0 && coef_.cwiseAbs().maxCoeff() > 0.0;
  const bool needs_reference =
      std::any_of(terms_.begin(), terms_.end(), [](const auto& t) { return t.kind == Covariate::kAlbedo; });
  if (needs_reference) update_reference();
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    for (std::size_t i = 0; i < rows_.size(); ++i) {
      // Before the first solve the truth stands in for the declared distance (reflectance only).
      const double declared = solved ? declared_m(i) : y_[i];
      z_[k][i] = term_covariate(data_, rows_[i], terms_[k], term_extra_[k], x_[i], declared, reference_);
    }
  }
}

void FitEngine::declared_entries(std::size_t i, Entries& out) const {
  out.clear();
  if (!std::isfinite(x_[i])) return;
  const double u = (x_[i] - center_) / scale_;
  double pw = 1.0;
  for (int k = 0; k <= p_.degree; ++k) {
    out.emplace_back(static_cast<std::size_t>(k), pw);
    pw *= u;
  }
  if (use_temp_) {
    out.emplace_back(static_cast<std::size_t>(p_.degree + 1),
                     p_.temperature_reference_c - data_.readouts[rows_[i]].temperature_c);  // 3.3.4
  }
}

void FitEngine::entries(std::size_t i, Entries& out) const {
  declared_entries(i, out);
  if (out.empty()) return;
  const Readout& r = data_.readouts[rows_[i]];
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    tmp_.clear();
    terms_[k].basis(z_[k][i], r.a + r.b, tmp_);
    for (const auto& [c, v] : tmp_) out.emplace_back(term_col_[k] + c, v);
  }
}

Eigen::VectorXd FitEngine::ridge(std::size_t total_columns) const {
  Eigen::VectorXd r = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(total_columns), p_.term_ridge);
  for (std::size_t c = 0; c < declared_cols_; ++c) r[static_cast<Eigen::Index>(c)] = 1e-9;
  return r;
}

double FitEngine::solve_linear() {
  if (z_.size() != terms_.size()) compute_covariates();
  // The design once per solve, for the normal equations and the residuals.
  design_.clear();
  Entries e;
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    entries(i, e);
    design_.push(e);
  }
  NormalEquations ne(cols_);
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    if (design_.size(i)) ne.add(design_.row(i), design_.size(i), y_[i], w_[i]);
  }
  coef_ = ne.solve(ridge(cols_));
  residual_.resize(rows_.size());
  double sse = 0.0;
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const std::size_t n = design_.size(i);
    const double r = n ? y_[i] - dot(design_.row(i), n, coef_.data()) : kMissPenaltyM;
    residual_[i] = r;
    sse += w_[i] * r * r;
  }
  return sse;
}

double FitEngine::residual_cost(std::vector<double>* residuals) {
  compute_x();
  const double sse = solve_linear();
  if (residuals) {
    residuals->resize(rows_.size());
    for (std::size_t i = 0; i < rows_.size(); ++i) (*residuals)[i] = std::sqrt(w_[i]) * residual_[i];
  }
  return sse;
}

void FitEngine::centre_charge_terms() {
  centre_.assign(charge_.size(), {});
  centre_dep_.assign(charge_.size(), 0);
  for (std::size_t k = 0; k < charge_.size(); ++k) {
    const auto& t = charge_[k];
    if (!centred_charge_term(t, p_.per_pulse_charge_levels)) continue;
    std::vector<double> z;
    z.reserve(rows_.size());
    for (std::size_t i : rows_) {
      z.push_back(CalibrationModel::Impl::covariate_value(t.kind, t.extra_index, data_.readouts[i], kNaN, kNaN,
                                                          AmplitudeReference{}));
    }
    centre_[k] = mean_knot_weights(t, z);
    centre_dep_[k] =
        static_cast<std::size_t>(std::max_element(centre_[k].begin(), centre_[k].end()) - centre_[k].begin());
    if (!(centre_[k][centre_dep_[k]] > 0.0)) centre_[k].clear();
  }
  apply_centring();
}

void FitEngine::apply_centring() {
  for (std::size_t k = 0; k < charge_.size(); ++k) {
    if (centre_[k].empty()) continue;
    auto& v = charge_[k].values;
    const std::size_t dep = centre_dep_[k];
    double sum = 0.0;
    for (std::size_t j = 0; j < v.size(); ++j) {
      if (j != dep) sum += centre_[k][j] * v[j];
    }
    v[dep] = -sum / centre_[k][dep];
  }
}

std::vector<FitEngine::GlobalParam> FitEngine::global_parameters() {
  std::vector<GlobalParam> ps;
  if (fit_leak_offset_) ps.push_back({&leak_offset_, 1.0, -50.0, 50.0});
  if (p_.fit_leakage) ps.push_back({&leak_per_pulse_, 0.01, -1.0, 1.0});
  for (auto& t : charge_) {
    // Typical size and range of each form's values: charge_unit, charge_unit per pulse, relative gain.
    const bool per_pulse = t.form == TermForm::kChargeAPerPulse || t.form == TermForm::kChargeBPerPulse ||
                           t.form == TermForm::kChargeBothPerPulse;
    const bool gain = t.form == TermForm::kGainA || t.form == TermForm::kGainB;
    const double typical = per_pulse ? 0.01 : gain ? 0.01 : 1.0, bound = per_pulse ? 1.0 : gain ? 0.5 : 100.0;
    const std::size_t k = static_cast<std::size_t>(&t - charge_.data());
    for (std::size_t j = first_value_fixed(t, p_.per_pulse_charge_levels) ? 1 : 0; j < t.values.size(); ++j) {
      if (!centre_[k].empty() && j == centre_dep_[k]) continue;  // set from the others (apply_centring)
      ps.push_back({&t.values[j], typical, -bound, bound});
    }
  }
  return ps;
}

namespace {

common::LevenbergMarquardtSettings global_lm_settings() {
  common::LevenbergMarquardtSettings lm;
  lm.max_iterations = 40;
  lm.max_tries = std::numeric_limits<int>::max();
  lm.max_lambda = 1e10;
  lm.initial_lambda = 1e-3;
  lm.increase = 4.0;
  lm.decrease = 1.0;
  lm.decrease_divisor = 3.0;
  lm.min_lambda = 1e-9;
  return lm;
}

}  // namespace

void FitEngine::optimise_global() {
  const std::vector<GlobalParam> ps = global_parameters();
  if (ps.empty()) {
    residual_cost(nullptr);
    return;
  }
  const std::size_t k = ps.size();
  auto get = [&] {
    Eigen::VectorXd t(static_cast<Eigen::Index>(k));
    for (std::size_t j = 0; j < k; ++j) t[static_cast<Eigen::Index>(j)] = *ps[j].value / ps[j].typical;
    return t;
  };
  auto set = [&](const Eigen::VectorXd& t) {
    for (std::size_t j = 0; j < k; ++j) {
      *ps[j].value = std::clamp(t[static_cast<Eigen::Index>(j)] * ps[j].typical, ps[j].lo, ps[j].hi);
    }
    apply_centring();
  };
  // r = sqrt(w)(y - pred): minimise |r|^2 with a forward-difference Jacobian.
  struct Problem {
    FitEngine& engine;
    decltype(get)& read;         // the parameters, scaled
    decltype(set)& write;        // ... clamped into their ranges
    std::vector<double> r0, r1;  // residuals at x, and at the last candidate

    std::pair<Eigen::MatrixXd, Eigen::VectorXd> linearise(const Eigen::VectorXd& theta) {
      constexpr double kStep = 1e-5;
      const auto n = static_cast<Eigen::Index>(engine.rows_.size());
      Eigen::MatrixXd jac(n, theta.size());
      for (Eigen::Index j = 0; j < theta.size(); ++j) {
        Eigen::VectorXd t = theta;
        t[j] += kStep;
        write(t);
        engine.residual_cost(&r1);
        double* col = jac.data() + static_cast<std::size_t>(n) * static_cast<std::size_t>(j);
        for (std::size_t i = 0; i < r1.size(); ++i) col[i] = (r1[i] - r0[i]) / kStep;
      }
      const Eigen::Map<const Eigen::VectorXd> f(r0.data(), n);
      return {jac.transpose() * jac, jac.transpose() * f};
    }
    // The parameters are clamped to their ranges: the accepted value is the clamped one.
    double cost(Eigen::VectorXd& candidate) {
      write(candidate);
      const double c = engine.residual_cost(&r1);
      candidate = read();
      return c;
    }
    void accept() { r0.swap(r1); }
    bool converged(double old_cost, double new_cost, const Eigen::VectorXd&) const {
      return !((old_cost - new_cost) / std::max(old_cost, 1e-300) > 1e-10);
    }
  };
  Problem problem{*this, get, set, {}, {}};
  Eigen::VectorXd theta = get();
  const double cost = residual_cost(&problem.r0);
  (void)common::levenberg_marquardt(problem, theta, cost, global_lm_settings());
  set(theta);
  residual_cost(nullptr);
}

std::vector<bool> FitEngine::rsen_eligible_pixels(std::size_t& n_eligible) const {
  std::vector<int> count(kPixels, 0);
  std::vector<std::vector<int>> seen(kPixels);
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const auto px = static_cast<std::size_t>(data_.readouts[rows_[i]].pixel);
    ++count[px];
    auto& s = seen[px];
    if (std::find(s.begin(), s.end(), group_[i]) == s.end() && s.size() < 64) s.push_back(group_[i]);
  }
  std::vector<bool> eligible(kPixels, false);
  n_eligible = 0;
  for (std::size_t px = 0; px < kPixels; ++px) {
    eligible[px] =
        count[px] >= p_.min_rows_per_pixel && static_cast<int>(seen[px].size()) >= p_.min_distances_per_pixel;
    n_eligible += eligible[px] ? 1 : 0;
  }
  return eligible;
}

// d pred / d Rsen of kept row i = P'(X) dX/dRsen, dX/dRsen = -(b - Vle) a / den^2 (terms' share ignored).
double FitEngine::rsen_jacobian(std::size_t i, double rsen) const {
  const Readout& r = data_.readouts[rows_[i]];
  double a = 0.0, b = 0.0;
  corrected(i, a, b);
  const double vle = leak_offset_ + leak_per_pulse_ * r.pulses;
  const double num = b - vle;
  const double den = (a * rsen - vle) + num;
  const double dx = -num * a / (den * den);
  return polynomial_slope(i) * dx;
}

// One Gauss-Newton step of every eligible pixel's Rsen (each pixel alone), then the linear solve.
void FitEngine::rsen_step(const std::vector<bool>& eligible) {
  std::vector<double> jr(kPixels, 0.0), jj(kPixels, 0.0);
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const auto px = static_cast<std::size_t>(data_.readouts[rows_[i]].pixel);
    if (!eligible[px] || !std::isfinite(x_[i])) continue;
    const double jac = rsen_jacobian(i, rsen_pixel_[px]);
    jr[px] += w_[i] * jac * residual_[i];
    jj[px] += w_[i] * jac * jac;
  }
  for (std::size_t px = 0; px < kPixels; ++px) {
    if (!eligible[px] || !(jj[px] > 0.0)) continue;
    const double step = std::clamp(jr[px] / jj[px], -0.05 * rsen_pixel_[px], 0.05 * rsen_pixel_[px]);
    rsen_pixel_[px] = std::clamp(rsen_pixel_[px] + step, 0.3, 3.0);
  }
  compute_x();
  solve_linear();
}

void FitEngine::refine_per_pixel() {
  std::size_t n_eligible = 0;
  const std::vector<bool> eligible = rsen_eligible_pixels(n_eligible);
  if (n_eligible == 0) {
    rsen_pixel_.clear();
    if (notes_rsen_once_)
      notes.push_back(fmt::format("no pixel has {} valid read-outs over {} distances: one global Rsen",
                                  p_.min_rows_per_pixel, p_.min_distances_per_pixel));
    notes_rsen_once_ = false;
    return;
  }
  if (rsen_pixel_.empty()) rsen_pixel_.assign(kPixels, rsen_);
  for (int iter = 0; iter < 4; ++iter) rsen_step(eligible);
  std::vector<double> fitted;
  for (std::size_t px = 0; px < kPixels; ++px) {
    if (eligible[px]) fitted.push_back(rsen_pixel_[px]);
  }
  // Only differences between pixels are identifiable: hold their median at the common value.
  const double shift = p_.sensitivity_ratio / median(fitted);
  for (std::size_t px = 0; px < kPixels; ++px) {
    rsen_pixel_[px] = eligible[px] ? rsen_pixel_[px] * shift : p_.sensitivity_ratio;
  }
  rsen_ = p_.sensitivity_ratio;
  if (n_eligible < kPixels - 2 * kDarkPixels && notes_rsen_once_) {
    notes_rsen_once_ = false;
    notes.push_back(
        fmt::format("per-pixel Rsen fitted for {} pixels; the others use the median {:.4f}", n_eligible, rsen_));
  }
  compute_x();
  solve_linear();
}

void FitEngine::reweight_inverse_variance() {
  std::vector<double> sse(groups_, 0.0), n(groups_, 0.0);
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    if (design_.size(i) == 0) continue;
    const double r = residual_[i];
    sse[static_cast<std::size_t>(group_[i])] += r * r;
    n[static_cast<std::size_t>(group_[i])] += 1.0;
  }
  std::vector<double> mse;
  for (std::size_t g = 0; g < groups_; ++g) {
    if (n[g] > 0) mse.push_back(sse[g] / n[g]);
  }
  const double floor = std::max(1e-3 * median(mse), 1e-12);
  std::vector<double> k(groups_, 1.0);
  for (std::size_t g = 0; g < groups_; ++g) k[g] = n[g] > 0 ? 1.0 / std::max(sse[g] / n[g], floor) : 1.0;
  set_weights(k);
  weighting_note_ = "K_i = 1 / residual variance at distance i (one reweighting)";
}

void FitEngine::fit() {
  const bool per_pixel = p_.sensitivity_ratio_mode == SensitivityRatioMode::kPerPixel;
  auto run_passes = [&](int passes) {
    for (int pass = 0; pass < passes; ++pass) {
      compute_x();
      compute_covariates();
      optimise_global();
      if (per_pixel) refine_per_pixel();
      if (!per_pixel && !p_.fit_leakage && terms_.empty() && charge_.empty() && pass > 0)
        break;  // nothing left to iterate
    }
  };
  run_passes(std::max(p_.passes, 1));
  if (p_.weighting == DistanceWeighting::kInverseVariance) {
    reweight_inverse_variance();
    run_passes(1);
  }
  compute_x();
  compute_covariates();
  solve_linear();
  update_reference();
  set_ratio_range();
}

// The ratio range the polynomial is valid on is where its data is: the
// 0.1 % and 99.9 % quantiles of X, so that a few dim read-outs far out (a
// ratio of noisy charges) do not stretch it over a stretch the polynomial
// only extrapolates into. The driver flags pixels beyond it (and its margin).
void FitEngine::set_ratio_range() {
  std::vector<double> xs;
  xs.reserve(x_.size());
  for (double x : x_)
    if (std::isfinite(x)) xs.push_back(x);
  if (xs.empty()) return;
  const auto at = [&xs](double q) {
    const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(xs.size() - 1) + 0.5);
    std::nth_element(xs.begin(), xs.begin() + k, xs.end());
    return xs[static_cast<std::size_t>(k)];
  };
  ratio_min_ = at(kRatioRangeTail);
  ratio_max_ = at(1.0 - kRatioRangeTail);
}

CalibrationModel FitEngine::model() const {
  CalibrationModel model;
  auto& m = model.impl();
  m.validity = p_.validity;
  m.sensitivity_ratio = rsen_;
  m.sensitivity_ratio_per_pixel = rsen_pixel_;
  m.leakage_offset = leak_offset_;
  m.leakage_per_pulse = leak_per_pulse_;
  m.ratio_min = ratio_min_;
  m.ratio_max = ratio_max_;
  m.poly_center = center_;
  m.poly_scale = scale_;
  m.poly_m.assign(coef_.data(), coef_.data() + p_.degree + 1);
  m.temperature_reference_c = p_.temperature_reference_c;
  m.temperature_coef_m_per_c = use_temp_ ? coef_[p_.degree + 1] : 0.0;
  m.amplitude_reference = reference_;
  m.terms.clear();
  for (const auto& [charge, k] : order_) {
    if (charge) {
      m.terms.push_back(charge_[k]);
    } else {
      m.terms.push_back(terms_[k]);
      m.terms.back().set_coefficients(coef_.data() + term_col_[k]);
    }
  }
  m.info.data = data_.source;
  m.info.rows = rows_.size();
  m.info.weighting = weighting_note_ + (p_.equalize_distances ? ", N_i = read-outs at distance i" : ", N_i = 1");
  m.resolve();
  return model;
}

}  // namespace detail

// ------------------------------------------------------------------ public API

ValidityRule validity_from_data(const CalibrationDataset& data, ValidityRule rule, double* plateau) {
  constexpr double kBand = 0.5;       // [charge_unit] read-outs this close to the top are on the plateau
  constexpr double kMinShare = 0.01;  // of all charges on it
  constexpr std::size_t kMinCount = 20;
  if (plateau) *plateau = std::numeric_limits<double>::quiet_NaN();
  double top = -std::numeric_limits<double>::infinity();
  for (const auto& r : data.readouts) top = std::max({top, r.a, r.b});
  if (!(top < rule.high)) return rule;  // the constant sees the top: nothing to learn
  std::size_t on = 0;
  for (const auto& r : data.readouts) on += (r.a >= top - kBand ? 1 : 0) + (r.b >= top - kBand ? 1 : 0);
  const double share = static_cast<double>(on) / static_cast<double>(2 * data.size());
  if (on < kMinCount || share < kMinShare) return rule;  // no pile-up: the light never filled a capacitor
  if (plateau) *plateau = top;
  rule.high = std::max(kCeilingShareOfPlateau * top, rule.low + 1.0);
  return rule;
}

std::vector<std::size_t> select_readouts(const CalibrationDataset& data, const std::vector<std::size_t>& rows,
                                         const ValidityRule& rule, ReadoutSelection selection, std::size_t* saturated,
                                         std::size_t* too_dark, std::size_t* not_selected) {
  std::size_t sat = 0, dark = 0, dropped = 0;
  std::vector<std::size_t> valid;
  valid.reserve(rows.empty() ? data.size() : rows.size());
  auto consider = [&](std::size_t i) {
    switch (rule.check(data.readouts[i])) {
      case ValidityRule::Verdict::kValid: valid.push_back(i); break;
      case ValidityRule::Verdict::kSaturated: ++sat; break;
      case ValidityRule::Verdict::kTooDark: ++dark; break;
    }
  };
  if (rows.empty()) {
    for (std::size_t i = 0; i < data.size(); ++i) consider(i);
  } else {
    for (std::size_t i : rows) consider(i);
  }
  if (selection == ReadoutSelection::kDriver) {
    // Per pixel and frame keep the valid read-out with the most pulses (the driver's choice).
    const int session = data.extra_index("session");
    auto frame = [&](const Readout& r) {
      return std::pair<double, double>(session >= 0 ? r.extra[static_cast<std::size_t>(session)] : 0.0, r.t_s);
    };
    std::sort(valid.begin(), valid.end(), [&](std::size_t i, std::size_t j) {
      const Readout& a = data.readouts[i];
      const Readout& b = data.readouts[j];
      if (frame(a) != frame(b)) return frame(a) < frame(b);
      if (a.pixel != b.pixel) return a.pixel < b.pixel;
      return a.pulses > b.pulses;
    });
    std::vector<std::size_t> kept;
    kept.reserve(valid.size());
    for (std::size_t k = 0; k < valid.size(); ++k) {
      if (k > 0) {
        const Readout& prev = data.readouts[valid[k - 1]];
        const Readout& r = data.readouts[valid[k]];
        if (frame(prev) == frame(r) && prev.pixel == r.pixel) {
          ++dropped;
          continue;
        }
      }
      kept.push_back(valid[k]);
    }
    valid = std::move(kept);
  }
  std::sort(valid.begin(), valid.end());
  if (saturated) *saturated = sat;
  if (too_dark) *too_dark = dark;
  if (not_selected) *not_selected = dropped;
  return valid;
}

DeclaredFitResult fit_calibration_model(const CalibrationDataset& data, const std::vector<std::size_t>& rows,
                                        const DeclaredFitParams& params, const std::vector<CalibrationTerm>& terms) {
  DeclaredFitResult res;
  if (data.empty()) {
    res.status = common::Status::invalid(fmt::format("{}: no rows", data.source));
    return res;
  }
  detail::FitEngine engine(data, rows, params, terms);
  res.rows = engine.offered;
  res.saturated = engine.saturated;
  res.too_dark = engine.too_dark;
  res.not_selected = engine.not_selected;
  res.distances = engine.distances;
  if (!engine.problem().empty()) {
    res.status = common::Status::invalid(engine.problem());
    return res;
  }
  engine.fit();
  res.model = engine.model();
  res.used = engine.size();
  res.notes = engine.notes;
  const auto residuals = model_residuals(res.model, data, engine.rows());
  const auto stats = error_stats(residuals);
  res.rmse_m = stats.rmse_m;
  res.model.impl().info.rmse_m = stats.rmse_m;
  if (stats.n == 0) {
    res.status = common::Status::not_found("the fitted model gives no distance on its own data (fit diverged)");
    return res;
  }
  return res;
}

DeclaredFitResult fit_declared_model(const CalibrationDataset& data, const DeclaredFitParams& params) {
  return fit_calibration_model(data, {}, params, {});
}

std::vector<double> model_residuals(const CalibrationModel& model, const CalibrationDataset& data,
                                    const std::vector<std::size_t>& rows) {
  const auto& names = model.extra_covariates();
  std::vector<int> idx;
  for (const auto& n : names) idx.push_back(data.extra_index(n));
  std::vector<double> out;
  out.reserve(rows.size());
  Readout r;
  for (std::size_t i : rows) {
    r = data.readouts[i];
    r.extra.assign(names.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t k = 0; k < idx.size(); ++k) {
      if (idx[k] >= 0) r.extra[k] = data.readouts[i].extra[static_cast<std::size_t>(idx[k])];
    }
    const auto ev = model.evaluate(r);
    out.push_back(ev.status == CalibrationEvaluation::Status::kValid ? ev.distance_m - data.distance_m[i]
                                                                     : std::numeric_limits<double>::quiet_NaN());
  }
  return out;
}

ErrorStats error_stats(const std::vector<double>& residuals) {
  ErrorStats s;
  std::vector<double> abs;
  double sum = 0.0, sum2 = 0.0;
  for (double r : residuals) {
    if (!std::isfinite(r)) continue;
    sum += r;
    sum2 += r * r;
    abs.push_back(std::abs(r));
  }
  s.n = abs.size();
  if (s.n == 0) return s;
  const double n = static_cast<double>(s.n);
  s.bias_m = sum / n;
  s.rmse_m = std::sqrt(sum2 / n);
  s.sd_m = std::sqrt(std::max(0.0, sum2 / n - s.bias_m * s.bias_m));
  const std::size_t k = static_cast<std::size_t>(std::ceil(0.95 * n)) - 1;
  std::nth_element(abs.begin(), abs.begin() + static_cast<std::ptrdiff_t>(k), abs.end());
  s.p95_abs_m = abs[k];
  return s;
}

ErrorStats evaluate_model(const CalibrationModel& model, const CalibrationDataset& data,
                          const std::vector<std::size_t>& rows_in, ReadoutSelection selection) {
  std::size_t sat0 = 0, dark0 = 0;
  const std::vector<std::size_t> rows =
      select_readouts(data, rows_in, model.validity(), selection, &sat0, &dark0, nullptr);
  const auto readouts = readouts_for_model(data.subset(rows), model);
  std::vector<double> residuals;
  residuals.reserve(rows.size());
  std::size_t sat = 0, dark = 0, oor = 0, missing = 0;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto ev = model.evaluate(readouts[k]);
    using S = CalibrationEvaluation::Status;
    switch (ev.status) {
      case S::kValid: residuals.push_back(ev.distance_m - data.distance_m[rows[k]]); break;
      case S::kSaturated: ++sat; break;
      case S::kTooDark: ++dark; break;
      case S::kOutOfRange: ++oor; break;
      case S::kMissingCovariate: ++missing; break;
    }
  }
  ErrorStats s = error_stats(residuals);
  s.saturated = sat + sat0;
  s.too_dark = dark + dark0;
  s.out_of_range = oor;
  s.missing_covariate = missing;
  return s;
}

}  // namespace tinyline::tiny_laser_calibration

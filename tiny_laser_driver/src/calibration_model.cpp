// SPDX-License-Identifier: Apache-2.0
// Run-time evaluation of the calibration model: the part the driver calls per
// pixel. No allocation on the distance path.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include <tiny_laser_driver/calibration_impl.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_driver {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct CovariateEntry {
  Covariate kind;
  std::string_view name;
};
constexpr CovariateEntry kCovariates[] = {
    {Covariate::kPixel, "pixel"},
    {Covariate::kTime, "t_s"},
    {Covariate::kPulses, "pulses"},
    {Covariate::kAmplitude, "amplitude"},
    {Covariate::kAmplitudePerPulse, "amplitude_per_pulse"},
    {Covariate::kRatio, "ratio"},
    {Covariate::kTemperature, "temperature_c"},
    {Covariate::kReflectance, "reflectance"},
    {Covariate::kAlbedo, "albedo"},
};
constexpr std::size_t kReportedCovariates = 9;  // the ones above; the rest are for charge terms
constexpr CovariateEntry kChargeCovariates[] = {
    {Covariate::kOne, "one"}, {Covariate::kPixelParity, "pixel_parity"}, {Covariate::kCharge, "charge"}};

// "pixel_bankN" / "pixel_isN": the kind and N (0 when the name is not one of them).
std::pair<Covariate, int> pixel_group(std::string_view name) {
  for (const auto& [prefix, kind] : {std::pair{std::string_view("pixel_bank"), Covariate::kPixelBank},
                                     std::pair{std::string_view("pixel_is"), Covariate::kPixelIs}}) {
    if (name.size() <= prefix.size() || name.substr(0, prefix.size()) != prefix) continue;
    int n = 0;
    for (char c : name.substr(prefix.size())) {
      if (c < '0' || c > '9' || n > 100000) return {Covariate::kExtra, 0};
      n = 10 * n + (c - '0');
    }
    return {kind, n};
  }
  return {Covariate::kExtra, 0};
}

// Index i of the knot interval holding z (z clamped) and the weight of knot i+1.
std::pair<std::size_t, double> locate(const std::vector<double>& knots, double z) {
  if (knots.size() < 2 || z <= knots.front()) return {0, 0.0};
  if (z >= knots.back()) return {knots.size() - 2, 1.0};
  const auto it = std::upper_bound(knots.begin(), knots.end(), z);
  const std::size_t i = static_cast<std::size_t>(it - knots.begin()) - 1;
  const double span = knots[i + 1] - knots[i];
  return {i, span > 0.0 ? (z - knots[i]) / span : 0.0};
}
}  // namespace

std::string_view covariate_name(Covariate c) {
  for (const auto& e : kCovariates) {
    if (e.kind == c) return e.name;
  }
  for (const auto& e : kChargeCovariates) {
    if (e.kind == c) return e.name;
  }
  return "";
}

Covariate covariate_from_name(std::string_view name) {
  for (const auto& e : kCovariates) {
    if (e.name == name) return e.kind;
  }
  for (const auto& e : kChargeCovariates) {
    if (e.name == name) return e.kind;
  }
  return pixel_group(name).first;
}

int covariate_parameter(std::string_view name) { return pixel_group(name).second; }

const std::vector<Covariate>& builtin_covariates() {
  static const std::vector<Covariate> all = [] {
    std::vector<Covariate> v;
    for (std::size_t i = 0; i < kReportedCovariates; ++i) v.push_back(kCovariates[i].kind);
    return v;
  }();
  return all;
}

namespace {
constexpr std::pair<TermForm, std::string_view> kForms[] = {
    {TermForm::kSmooth, "smooth"},
    {TermForm::kTable, "table"},
    {TermForm::kAmplitudeInteraction, "amplitude_interaction"},
    {TermForm::kChargeA, "charge_a"},
    {TermForm::kChargeB, "charge_b"},
    {TermForm::kChargeBoth, "charge_both"},
    {TermForm::kChargeAPerPulse, "charge_a_per_pulse"},
    {TermForm::kChargeBPerPulse, "charge_b_per_pulse"},
    {TermForm::kChargeBothPerPulse, "charge_both_per_pulse"},
    {TermForm::kGainA, "gain_a"},
    {TermForm::kGainB, "gain_b"},
    {TermForm::kReadout, "readout"},
    {TermForm::kLightWalk, "light_walk"},
};
}  // namespace

std::string_view to_string(TermForm f) {
  for (const auto& [form, name] : kForms) {
    if (form == f) return name;
  }
  return "?";
}

std::optional<TermForm> term_form_from_string(std::string_view s) {
  for (const auto& [form, name] : kForms) {
    if (name == s) return form;
  }
  return std::nullopt;
}

bool acts_on_charges(TermForm f) {
  return f != TermForm::kSmooth && f != TermForm::kTable && f != TermForm::kAmplitudeInteraction &&
         f != TermForm::kLightWalk;
}

std::string_view to_string(ValidityRule::Verdict v) {
  switch (v) {
    case ValidityRule::Verdict::kValid: return "valid";
    case ValidityRule::Verdict::kSaturated: return "saturated";
    case ValidityRule::Verdict::kTooDark: return "too_dark";
  }
  return "?";
}

std::string_view to_string(CalibrationEvaluation::Status s) {
  using S = CalibrationEvaluation::Status;
  switch (s) {
    case S::kValid: return "valid";
    case S::kSaturated: return "saturated";
    case S::kTooDark: return "too_dark";
    case S::kOutOfRange: return "out_of_range";
    case S::kMissingCovariate: return "missing_covariate";
  }
  return "?";
}

// ------------------------------------------------------------------ validity

ValidityRule::Verdict ValidityRule::check(const Readout& r) const {
  // NaN charges fail every comparison below and land in kTooDark.
  if (r.a >= high || r.b >= high) return Verdict::kSaturated;
  if (!(r.a > low && r.b > low)) return Verdict::kTooDark;
  if (!(r.a + r.b > min_sum + per_pulse * r.pulses / 10.0)) return Verdict::kTooDark;
  return Verdict::kValid;
}

// ------------------------------------------------------------------ terms

std::size_t CalibrationTerm::basis_size() const {
  if (form == TermForm::kLightWalk) return values.size();
  return form == TermForm::kTable ? keys.size() : knots.size();
}

namespace {
// ln(z / reference) with z held inside [knots.front(), knots.back()]; NaN when it has no log.
double walk_log(const CalibrationTerm& t, double z) {
  if (t.knots.size() != 2 || !(z > 0.0) || !(t.reference > 0.0)) return kNaN;
  return std::log(std::clamp(z, t.knots.front(), t.knots.back()) / t.reference);
}
}  // namespace

void CalibrationTerm::basis(double z, double amplitude, std::vector<std::pair<std::size_t, double>>& out) const {
  if (!std::isfinite(z)) return;
  if (form == TermForm::kTable) {
    const long k = std::lround(z);
    const auto it = std::lower_bound(keys.begin(), keys.end(), k);
    if (it != keys.end() && *it == k) out.emplace_back(static_cast<std::size_t>(it - keys.begin()), 1.0);
    return;
  }
  if (form == TermForm::kLightWalk) {
    const double l = walk_log(*this, z);
    for (std::size_t k = 0; std::isfinite(l) && k < values.size(); ++k)
      out.emplace_back(k, std::pow(l, static_cast<double>(k + 1)));
    return;
  }
  if (knots.empty()) return;
  double scale = 1.0;
  if (form == TermForm::kAmplitudeInteraction) scale = (amplitude - amplitude_reference) / amplitude_scale;
  if (knots.size() == 1) {
    out.emplace_back(0, scale);
    return;
  }
  const auto [i, t] = locate(knots, z);
  if (t < 1.0) out.emplace_back(i, (1.0 - t) * scale);
  if (t > 0.0) out.emplace_back(i + 1, t * scale);
}

void CalibrationTerm::set_coefficients(const double* c) {
  auto& dst = form == TermForm::kTable ? offsets_m : values;
  dst.assign(c, c + basis_size());
}

double CalibrationTerm::value(double z, double amplitude) const {
  if (!std::isfinite(z)) return 0.0;
  if (form == TermForm::kTable) {
    const long k = std::lround(z);
    if (dense_keys) {
      const long i = k - first_key;
      return (i >= 0 && i < static_cast<long>(offsets_m.size())) ? offsets_m[static_cast<std::size_t>(i)] : 0.0;
    }
    const auto it = std::lower_bound(keys.begin(), keys.end(), k);
    return (it != keys.end() && *it == k) ? offsets_m[static_cast<std::size_t>(it - keys.begin())] : 0.0;
  }
  if (values.empty()) return 0.0;
  if (form == TermForm::kLightWalk) {
    const double l = walk_log(*this, z);
    if (!std::isfinite(l)) return 0.0;
    double g = 0.0;
    for (std::size_t k = 0; k < values.size(); ++k) g += values[k] * std::pow(l, static_cast<double>(k + 1));
    return g;
  }
  double g = values[0];
  if (knots.size() >= 2) {
    const auto [i, t] = locate(knots, z);
    g = (1.0 - t) * values[i] + t * values[i + 1];
  }
  if (form == TermForm::kAmplitudeInteraction) g *= (amplitude - amplitude_reference) / amplitude_scale;
  return g;
}

// ------------------------------------------------------------------ declared model

double CalibrationModel::Impl::sensitivity_ratio_of(int pixel) const {
  if (!sensitivity_ratio_per_pixel.empty() && pixel >= 0 &&
      static_cast<std::size_t>(pixel) < sensitivity_ratio_per_pixel.size()) {
    return sensitivity_ratio_per_pixel[static_cast<std::size_t>(pixel)];
  }
  return sensitivity_ratio;
}

double CalibrationModel::Impl::charge_ratio(double a, double b, int pulses, double rsen, double leakage_offset,
                                            double leakage_per_pulse) {
  const double vle = leakage_offset + leakage_per_pulse * pulses;  // Eq. 3.16: Vle grows with the pulses
  const double num = b - vle;
  const double den = (a * rsen - vle) + num;
  if (!(den > 0.0)) return kNaN;
  return num / den;
}

bool CalibrationModel::Impl::correct_charges(const std::vector<CalibrationTerm>& terms, const Readout& r, double& a,
                                             double& b) {
  bool complete = true;
  for (int stage = 0; stage < 3; ++stage) {  // read-out, gain, added charge
    for (const auto& t : terms) {
      const TermForm f = t.form;
      if (!acts_on_charges(f)) continue;
      const bool readout = f == TermForm::kReadout, gain = f == TermForm::kGainA || f == TermForm::kGainB;
      if ((stage == 0) != readout || (stage == 1) != gain) continue;
      if (readout) {
        a += t.value(a, 0.0);
        b += t.value(b, 0.0);
        continue;
      }
      const double z = covariate_value(t.kind, t.extra_index, r, kNaN, kNaN, AmplitudeReference{});
      if (!std::isfinite(z)) {
        complete = false;
        continue;
      }
      const double g = t.value(z, 0.0);
      if (f == TermForm::kGainA) a /= 1.0 + g;
      if (f == TermForm::kGainB) b /= 1.0 + g;
      if (gain) continue;
      const bool per_pulse =
          f == TermForm::kChargeAPerPulse || f == TermForm::kChargeBPerPulse || f == TermForm::kChargeBothPerPulse;
      const double q = per_pulse ? g * r.pulses : g;
      if (f != TermForm::kChargeB && f != TermForm::kChargeBPerPulse) a -= q;
      if (f != TermForm::kChargeA && f != TermForm::kChargeAPerPulse) b -= q;
    }
  }
  return complete;
}

double CalibrationModel::Impl::ratio(const Readout& r) const {
  double a = r.a, b = r.b;
  (void)correct_charges(terms, r, a, b);
  return charge_ratio(a, b, r.pulses, sensitivity_ratio_of(r.pixel), leakage_offset, leakage_per_pulse);
}

double CalibrationModel::Impl::polynomial_m(double x) const {
  const double u = (x - poly_center) / poly_scale;
  double acc = 0.0;
  for (auto it = poly_m.rbegin(); it != poly_m.rend(); ++it) acc = acc * u + *it;  // Horner, Eq. 3.18
  return acc;
}

double CalibrationModel::Impl::polynomial_slope_m(double x) const {
  const double u = (x - poly_center) / poly_scale;
  double acc = 0.0;
  for (std::size_t k = poly_m.size(); k-- > 1;) acc = acc * u + static_cast<double>(k) * poly_m[k];
  return acc / poly_scale;
}

double NoiseLaw::ratio_sd_at(double sum, int pulses) const {
  if (empty() || !(sum > 0.0)) return kNaN;
  return std::sqrt(shot * sum + per_pulse * pulses + read) / sum;
}

double CalibrationModel::Impl::declared_m(double x, double temperature_c) const {
  return polynomial_m(x) + temperature_coef_m_per_c * (temperature_reference_c - temperature_c);  // 3.3.4
}

double AmplitudeReference::albedo(const Readout& r, double declared_m) const {
  if (empty() || r.pulses <= 0 || !std::isfinite(declared_m)) return kNaN;
  const double amp = (r.a + r.b) / r.pulses;
  if (!(amp > 0.0)) return kNaN;
  double ref = log_amplitude.front();
  if (knots_m.size() >= 2) {
    const auto [i, t] = locate(knots_m, declared_m);
    ref = (1.0 - t) * log_amplitude[i] + t * log_amplitude[i + 1];
  }
  if (!pixel_log_offset.empty() && r.pixel >= 0 && static_cast<std::size_t>(r.pixel) < pixel_log_offset.size()) {
    ref += pixel_log_offset[static_cast<std::size_t>(r.pixel)];
  }
  return amp / std::exp(ref);
}

double CalibrationModel::Impl::covariate_value(Covariate kind, int extra_index, const Readout& r, double x,
                                               double declared, const AmplitudeReference& reference) {
  switch (kind) {
    case Covariate::kPixel: return r.pixel;
    case Covariate::kTime: return r.t_s;
    case Covariate::kPulses: return r.pulses;
    case Covariate::kAmplitude: return r.a + r.b;
    case Covariate::kAmplitudePerPulse: return r.pulses > 0 ? (r.a + r.b) / r.pulses : kNaN;
    case Covariate::kRatio: return x;
    case Covariate::kTemperature: return r.temperature_c;
    case Covariate::kReflectance: return r.pulses > 0 ? declared * declared * (r.a + r.b) / r.pulses : kNaN;
    case Covariate::kAlbedo: return reference.albedo(r, declared);
    case Covariate::kOne: return 1.0;
    case Covariate::kPixelParity: return r.pixel % 2;
    case Covariate::kPixelBank:
      return extra_index > 0 ? std::max(0, r.pixel - static_cast<int>(kDarkPixels)) / extra_index : kNaN;
    case Covariate::kPixelIs: return r.pixel == extra_index ? 1.0 : 0.0;
    case Covariate::kCharge: return kNaN;  // the readout form takes each capacitor's own value
    case Covariate::kExtra:
      if (extra_index >= 0 && static_cast<std::size_t>(extra_index) < r.extra.size()) {
        return r.extra[static_cast<std::size_t>(extra_index)];
      }
      return kNaN;
  }
  return kNaN;
}

void CalibrationModel::Impl::resolve() {
  extra_covariates.clear();
  has_charge_terms = std::any_of(terms.begin(), terms.end(), [](const auto& t) { return acts_on_charges(t.form); });
  for (auto& t : terms) {
    t.kind = covariate_from_name(t.covariate);
    t.dense_keys = t.form == TermForm::kTable && !t.keys.empty() && t.offsets_m.size() == t.keys.size() &&
                   t.keys.back() - t.keys.front() + 1 == static_cast<long>(t.keys.size());
    t.first_key = t.keys.empty() ? 0 : t.keys.front();
    t.extra_index = -1;
    if (t.kind == Covariate::kPixelBank || t.kind == Covariate::kPixelIs)
      t.extra_index = covariate_parameter(t.covariate);
    if (t.kind != Covariate::kExtra) continue;
    const auto it = std::find(extra_covariates.begin(), extra_covariates.end(), t.covariate);
    t.extra_index = static_cast<int>(it - extra_covariates.begin());
    if (it == extra_covariates.end()) extra_covariates.push_back(t.covariate);
  }
}

// ------------------------------------------------------------------ CalibrationModel

CalibrationModel::CalibrationModel() : impl_(new Impl) {}
CalibrationModel::~CalibrationModel() { delete impl_; }
CalibrationModel::CalibrationModel(const CalibrationModel& o) : impl_(new Impl(*o.impl_)) {}
CalibrationModel& CalibrationModel::operator=(const CalibrationModel& o) {
  if (this != &o) *impl_ = *o.impl_;
  return *this;
}
CalibrationModel::CalibrationModel(CalibrationModel&& o) noexcept : impl_(o.impl_) {
  o.impl_ = new (std::nothrow) Impl;
}
CalibrationModel& CalibrationModel::operator=(CalibrationModel&& o) noexcept {
  std::swap(impl_, o.impl_);
  return *this;
}

const ValidityRule& CalibrationModel::validity() const { return impl_->validity; }
const std::vector<std::string>& CalibrationModel::extra_covariates() const { return impl_->extra_covariates; }

namespace {

// The per-pixel path. `Full` also fills reflectance and albedo; the distance-only
// path (the driver's, once per pixel) computes only what its terms need.
template <bool Full>
CalibrationEvaluation compute(const CalibrationModel::Impl& m, const Readout& r) {
  using S = CalibrationEvaluation::Status;
  CalibrationEvaluation ev;
  switch (m.validity.check(r)) {
    case ValidityRule::Verdict::kSaturated: ev.status = S::kSaturated; return ev;
    case ValidityRule::Verdict::kTooDark: ev.status = S::kTooDark; return ev;
    case ValidityRule::Verdict::kValid: break;
  }
  ev.ratio = m.ratio(r);
  if (!std::isfinite(ev.ratio)) {
    ev.status = S::kTooDark;
    return ev;
  }
  const double margin = m.ratio_margin * (m.ratio_max - m.ratio_min);
  if (ev.ratio < m.ratio_min - margin || ev.ratio > m.ratio_max + margin) {
    ev.status = S::kOutOfRange;
    return ev;
  }
  // Without a temperature reading the offset of 3.3.4 cannot be applied: distance
  // at the reference temperature, flagged like any other missing covariate.
  const bool has_temperature = std::isfinite(r.temperature_c);
  ev.declared_distance_m = m.declared_m(ev.ratio, has_temperature ? r.temperature_c : m.temperature_reference_c);
  if constexpr (Full) {
    ev.reflectance = CalibrationModel::Impl::covariate_value(Covariate::kReflectance, -1, r, ev.ratio,
                                                             ev.declared_distance_m, m.amplitude_reference);
    ev.albedo = m.amplitude_reference.albedo(r, ev.declared_distance_m);
    ev.range_sd_m = std::abs(m.polynomial_slope_m(ev.ratio)) * m.noise.ratio_sd_at(r.a + r.b, r.pulses);
  }
  double d = ev.declared_distance_m;
  bool missing = !has_temperature && m.temperature_coef_m_per_c != 0.0;
  if (m.has_charge_terms) {
    double a = r.a, b = r.b;
    missing = !CalibrationModel::Impl::correct_charges(m.terms, r, a, b) || missing;
  }
  const double amplitude = r.a + r.b;
  for (const auto& t : m.terms) {
    if (acts_on_charges(t.form)) continue;
    const double z = CalibrationModel::Impl::covariate_value(t.kind, t.extra_index, r, ev.ratio, ev.declared_distance_m,
                                                             m.amplitude_reference);
    if (!std::isfinite(z)) {
      missing = true;
      continue;
    }
    d += t.value(z, amplitude);
  }
  ev.distance_m = d;
  ev.status = missing ? S::kMissingCovariate : S::kValid;
  return ev;
}

}  // namespace

CalibrationEvaluation CalibrationModel::evaluate(const Readout& r) const { return compute<true>(*impl_, r); }

double CalibrationModel::distance_m(const Readout& r) const { return compute<false>(*impl_, r).distance_m; }

std::string CalibrationModel::describe() const {
  const Impl& m = *impl_;
  std::string s;
  const bool per_pixel = !m.sensitivity_ratio_per_pixel.empty();
  s += fmt::format("charge ratio (Eq. 3.16): Rsen {}{:.4f}, leakage {:.4g} + {:.4g} * pulses charge_unit\n",
                   per_pixel ? "per pixel, median " : "", m.sensitivity_ratio, m.leakage_offset, m.leakage_per_pulse);
  s += fmt::format("polynomial (Eq. 3.18): degree {} in X on [{:.3f}, {:.3f}]\n",
                   m.poly_m.empty() ? 0 : m.poly_m.size() - 1, m.ratio_min, m.ratio_max);
  s += fmt::format("temperature (3.3.4): {:.4g} mm/degC below {:.1f} degC\n", m.temperature_coef_m_per_c * 1e3,
                   m.temperature_reference_c);
  if (!m.noise.empty()) {
    s += fmt::format("noise (3.5): var(X) (a + b)^2 = {:.4g} (a + b) + {:.4g} pulses + {:.4g}\n", m.noise.shot,
                     m.noise.per_pulse, m.noise.read);
  }
  for (const auto& t : m.terms) {
    s += fmt::format("term: {} of {} ({} coefficients)\n", to_string(t.form), t.covariate, t.basis_size());
  }
  return s;
}

CalibrationModel CalibrationModel::from_public_driver(const std::vector<double>& poly,
                                                      const std::vector<double>& offsets_added,
                                                      double stable_temperature_decic,
                                                      double temperature_sensi_cm_per_decic) {
  if (poly.empty()) throw std::invalid_argument("from_public_driver: empty polynomial");
  if (!offsets_added.empty() && offsets_added.size() != poly.size()) {
    throw std::invalid_argument(
        fmt::format("from_public_driver: {} offsets for {} coefficients", offsets_added.size(), poly.size()));
  }
  CalibrationModel model;
  Impl& m = model.impl();
  // k = b / (a + b): no sensitivity ratio, no leakage.
  m.sensitivity_ratio = 1.0;
  m.poly_center = 0.0;
  m.poly_scale = 1.0;
  const std::size_t n = poly.size();
  m.poly_m.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double c = poly[i] + (offsets_added.empty() ? 0.0 : offsets_added[i]);
    m.poly_m[n - 1 - i] = c / 100.0;  // highest power first, cm -> ascending, m
  }
  m.temperature_reference_c = stable_temperature_decic / 10.0;
  m.temperature_coef_m_per_c = temperature_sensi_cm_per_decic * 10.0 / 100.0;  // cm per 0.1 degC -> m per degC
  // Such a polynomial is usable only where it is monotone and reads inside the
  // sensor's range (0-3 m): take that stretch of k around 1 m.
  constexpr int kSteps = 2000;
  constexpr double kMaxRangeM = 3.0;
  auto p = [&](int i) { return m.polynomial_m(static_cast<double>(i) / kSteps); };
  auto usable = [&](int i) { return i < kSteps && p(i + 1) > p(i) && p(i) >= 0.0 && p(i) <= kMaxRangeM; };
  int best = -1;
  double best_gap = 1e300;
  for (int i = 0; i <= kSteps; ++i) {
    const double gap = std::abs(p(i) - 1.0);
    if (usable(i) && gap < best_gap) {
      best_gap = gap;
      best = i;
    }
  }
  if (best < 0)
    throw std::invalid_argument("from_public_driver: the polynomial rises nowhere inside 0-3 m on k in [0, 1]");
  int lo = best, hi = best;
  while (lo > 0 && usable(lo - 1)) --lo;
  while (usable(hi + 1)) ++hi;
  m.ratio_min = static_cast<double>(lo) / kSteps;
  m.ratio_max = static_cast<double>(hi + 1) / kSteps;
  m.ratio_margin = 0.0;  // beyond the monotone stretch the polynomial folds back
  m.info.data = "public driver polynomial";
  return model;
}

}  // namespace tinyline::tiny_laser_driver

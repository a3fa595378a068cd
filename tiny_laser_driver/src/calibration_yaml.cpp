// SPDX-License-Identifier: Apache-2.0
// The calibration YAML: what `tinyline calib fit` writes and the driver loads.
// Strict on load: an unknown key, a missing field or a bad value stops with
// the file, line and field, because a silently ignored typo in a calibration
// shows up much later as a wrong distance.
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <tinyline/common/files.hpp>
#include <tinyline/common/yaml_documents.hpp>
#include <tinyline/common/yaml_fields.hpp>

#include <tiny_laser_driver/calibration_impl.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_driver {

namespace {

constexpr std::string_view kFormat = "tinyline_calibration/1";

// Bounds on what a file may ask the loader to hold: a fitted model has a few
// terms of at most one entry per pixel; more is a broken or hostile file.
constexpr std::size_t kMaxListLength = 4096;
constexpr std::size_t kMaxTerms = 64;

// A fitted polynomial follows noisy data near the ends of its range; reading
// more than this beyond the physical range there is a broken file.
constexpr double kLoadToleranceM = 0.5;
constexpr int kRangeSamples = 1000;

// What `tinyline calib fit` always writes: a file without one of these is
// not one it wrote (the loader's defaults would then apply silently).
struct RequiredSection {
  const char* name;
  std::vector<const char*> keys;
};
const RequiredSection kRequired[] = {
    {"polynomial", {"center", "scale", "coefficients_m"}},
    {"validity", {"low", "high", "min_sum", "per_pulse"}},
    {"ratio", {"sensitivity_ratio", "leakage_offset", "leakage_per_pulse", "range", "range_margin"}},
    {"temperature", {"reference_c", "coefficient_m_per_c"}},
};

using Reader = common::YamlFields<std::runtime_error>;

template <typename T>
bool strictly_increasing(const std::vector<T>& v) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    if (!(v[i] > v[i - 1])) return false;
  }
  return true;
}

using Impl = CalibrationModel::Impl;

void parse_format(const YAML::Node& root, const Reader& rd) {
  const auto fmt_node = rd.required(root, "", "format");
  if (rd.text(fmt_node, "format") != kFormat) {
    rd.fail(fmt_node, "format", fmt::format("'{}' is not '{}'", fmt_node.Scalar(), kFormat));
  }
}

void parse_validity(const YAML::Node& v, const Reader& rd, ValidityRule& rule) {
  rd.only_keys(v, "validity", {"low", "high", "min_sum", "per_pulse"});
  rule.low = rd.number_or(v, "validity", "low", rule.low);
  rule.high = rd.number_or(v, "validity", "high", rule.high);
  rule.min_sum = rd.number_or(v, "validity", "min_sum", rule.min_sum);
  rule.per_pulse = rd.number_or(v, "validity", "per_pulse", rule.per_pulse);
  if (!(rule.low < rule.high)) rd.fail(v, "validity", "low must be below high");
}

// One positive value per pixel (sensitivity ratio), or one value per pixel (offsets).
std::vector<double> per_pixel(const YAML::Node& n, const Reader& rd, const std::string& field, bool positive) {
  auto v = rd.numbers(n, field);
  if (v.size() != kPixels)
    rd.fail(n, field, fmt::format("has {} values, expected one per pixel ({})", v.size(), kPixels));
  for (std::size_t i = 0; positive && i < kPixels; ++i) {
    if (!(v[i] > 0.0)) rd.fail(n, fmt::format("{}[{}]", field, i), "must be positive");
  }
  return v;
}

void parse_ratio(const YAML::Node& r, const Reader& rd, Impl& m) {
  rd.only_keys(r, "ratio",
               {"sensitivity_ratio", "sensitivity_ratio_per_pixel", "leakage_offset", "leakage_per_pulse", "range",
                "range_margin"});
  m.sensitivity_ratio = rd.number_or(r, "ratio", "sensitivity_ratio", 1.0);
  if (!(m.sensitivity_ratio > 0.0)) rd.fail(r["sensitivity_ratio"], "ratio.sensitivity_ratio", "must be positive");
  if (const auto pp = r["sensitivity_ratio_per_pixel"]) {
    m.sensitivity_ratio_per_pixel = per_pixel(pp, rd, "ratio.sensitivity_ratio_per_pixel", true);
  }
  m.leakage_offset = rd.number_or(r, "ratio", "leakage_offset", 0.0);
  m.leakage_per_pulse = rd.number_or(r, "ratio", "leakage_per_pulse", 0.0);
  if (const auto range = r["range"]) {
    const auto v = rd.numbers(range, "ratio.range");
    if (v.size() != 2 || !(v[0] < v[1])) rd.fail(range, "ratio.range", "expected [low, high] with low < high");
    m.ratio_min = v[0];
    m.ratio_max = v[1];
  }
  m.ratio_margin = rd.number_or(r, "ratio", "range_margin", m.ratio_margin);
  // A share of the fitted X range: beyond 1 the out-of-range check is as good as off (1e300 was).
  if (m.ratio_margin < 0.0 || m.ratio_margin > 1.0)
    rd.fail(r["range_margin"], "ratio.range_margin", "must be 0-1 (a share of the fitted range)");
}

void parse_polynomial(const YAML::Node& p, const Reader& rd, Impl& m) {
  rd.only_keys(p, "polynomial", {"center", "scale", "coefficients_m"});
  m.poly_center = rd.number_or(p, "polynomial", "center", 0.0);
  m.poly_scale = rd.number_or(p, "polynomial", "scale", 1.0);
  if (m.poly_scale == 0.0) rd.fail(p["scale"], "polynomial.scale", "must not be zero");
  const auto coef = rd.required(p, "polynomial", "coefficients_m");
  m.poly_m = rd.numbers(coef, "polynomial.coefficients_m");
  if (m.poly_m.empty()) rd.fail(coef, "polynomial.coefficients_m", "must hold at least one coefficient");
  if (m.poly_m.size() > kMaxPolynomialCoefficients) {
    rd.fail(coef, "polynomial.coefficients_m",
            fmt::format("has {} coefficients, at most {} (degree {})", m.poly_m.size(), kMaxPolynomialCoefficients,
                        kMaxPolynomialCoefficients - 1));
  }
}

void parse_temperature(const YAML::Node& t, const Reader& rd, Impl& m) {
  rd.only_keys(t, "temperature", {"reference_c", "coefficient_m_per_c"});
  m.temperature_reference_c = rd.number_or(t, "temperature", "reference_c", m.temperature_reference_c);
  m.temperature_coef_m_per_c = rd.number_or(t, "temperature", "coefficient_m_per_c", 0.0);
}

void parse_amplitude_reference(const YAML::Node& a, const Reader& rd, AmplitudeReference& ref) {
  rd.only_keys(a, "amplitude_reference", {"knots_m", "log_amplitude", "pixel_log_offset"});
  const auto kn = rd.required(a, "amplitude_reference", "knots_m");
  ref.knots_m = rd.numbers(kn, "amplitude_reference.knots_m");
  if (ref.knots_m.empty() || !strictly_increasing(ref.knots_m)) {
    rd.fail(kn, "amplitude_reference.knots_m", "must be a non-empty, strictly increasing list");
  }
  const auto ln = rd.required(a, "amplitude_reference", "log_amplitude");
  ref.log_amplitude = rd.numbers(ln, "amplitude_reference.log_amplitude");
  if (ref.log_amplitude.size() != ref.knots_m.size()) {
    rd.fail(ln, "amplitude_reference.log_amplitude",
            fmt::format("has {} values for {} knots", ref.log_amplitude.size(), ref.knots_m.size()));
  }
  if (const auto pp = a["pixel_log_offset"]) {
    ref.pixel_log_offset = per_pixel(pp, rd, "amplitude_reference.pixel_log_offset", false);
  }
}

void parse_table_term(const YAML::Node& n, const Reader& rd, const std::string& f, CalibrationTerm& t) {
  const auto kn = rd.required(n, f, "keys");
  t.keys = rd.integers(kn, f + ".keys");
  if (!strictly_increasing(t.keys)) rd.fail(kn, f + ".keys", "must be strictly increasing");
  const auto on = rd.required(n, f, "offsets_m");
  t.offsets_m = rd.numbers(on, f + ".offsets_m");
  if (t.offsets_m.size() != t.keys.size()) {
    rd.fail(on, f + ".offsets_m", fmt::format("has {} values for {} keys", t.offsets_m.size(), t.keys.size()));
  }
}

// At most a cubic in the log of the light: more is not a walk the data can carry.
constexpr std::size_t kMaxWalkCoefficients = 3;

void parse_walk_term(const YAML::Node& n, const Reader& rd, const std::string& f, CalibrationTerm& t) {
  const auto kn = rd.required(n, f, "knots");
  t.knots = rd.numbers(kn, f + ".knots");
  if (t.knots.size() != 2 || !(t.knots[0] > 0.0) || !(t.knots[1] > t.knots[0]))
    rd.fail(kn, f + ".knots", "must be [lo, hi], the light levels it was fitted on, 0 < lo < hi");
  const auto vn = rd.required(n, f, "values_m");
  t.values = rd.numbers(vn, f + ".values_m");
  if (t.values.empty() || t.values.size() > kMaxWalkCoefficients)
    rd.fail(vn, f + ".values_m",
            fmt::format("has {} coefficients, expected 1 to {} (of ln, ln^2, ln^3 of the light)", t.values.size(),
                        kMaxWalkCoefficients));
  const auto rn = rd.required(n, f, "reference");
  t.reference = rd.number(rn, f + ".reference");
  if (!(t.reference > 0.0)) rd.fail(rn, f + ".reference", "must be positive (the light level of zero walk)");
}

void parse_knot_term(const YAML::Node& n, const Reader& rd, const std::string& f, CalibrationTerm& t) {
  const auto kn = rd.required(n, f, "knots");
  t.knots = rd.numbers(kn, f + ".knots");
  if (t.knots.empty() || !strictly_increasing(t.knots))
    rd.fail(kn, f + ".knots", "must be a non-empty, strictly increasing list");
  const auto vn = rd.required(n, f, "values_m");
  t.values = rd.numbers(vn, f + ".values_m");
  if (t.values.size() != t.knots.size()) {
    rd.fail(vn, f + ".values_m", fmt::format("has {} values for {} knots", t.values.size(), t.knots.size()));
  }
  if (t.form == TermForm::kAmplitudeInteraction) {
    t.amplitude_reference = rd.number(rd.required(n, f, "amplitude_reference"), f + ".amplitude_reference");
    const auto sn = rd.required(n, f, "amplitude_scale");
    t.amplitude_scale = rd.number(sn, f + ".amplitude_scale");
    if (!(t.amplitude_scale > 0.0)) rd.fail(sn, f + ".amplitude_scale", "must be positive");
  }
}

CalibrationTerm parse_term(const YAML::Node& n, const Reader& rd, const std::string& f) {
  rd.only_keys(n, f,
               {"covariate", "form", "knots", "values_m", "keys", "offsets_m", "amplitude_reference", "amplitude_scale",
                "reference", "heldout_rmse_before_m", "heldout_rmse_after_m"});
  CalibrationTerm t;
  t.covariate = rd.text(rd.required(n, f, "covariate"), f + ".covariate");
  if (t.covariate.empty()) rd.fail(n, f + ".covariate", "must not be empty");
  const auto form_node = rd.required(n, f, "form");
  const auto form = term_form_from_string(rd.text(form_node, f + ".form"));
  if (!form)
    rd.fail(form_node, f + ".form",
            fmt::format("'{}' is not a term form (smooth, table, amplitude_interaction, light_walk, charge_*, "
                        "gain_*, readout)",
                        form_node.Scalar()));
  t.form = *form;
  if (t.form == TermForm::kTable) {
    parse_table_term(n, rd, f, t);
  } else if (t.form == TermForm::kLightWalk) {
    parse_walk_term(n, rd, f, t);
  } else {
    parse_knot_term(n, rd, f, t);
  }
  t.rmse_before_m = rd.number_or(n, f, "heldout_rmse_before_m", t.rmse_before_m);
  t.rmse_after_m = rd.number_or(n, f, "heldout_rmse_after_m", t.rmse_after_m);
  return t;
}

void parse_terms(const YAML::Node& terms, const Reader& rd, Impl& m) {
  if (!terms.IsSequence()) rd.fail(terms, "terms", "expected a list");
  if (terms.size() > kMaxTerms)
    rd.fail(terms, "terms", fmt::format("has {} terms, more than {}", terms.size(), kMaxTerms));
  for (std::size_t i = 0; i < terms.size(); ++i)
    m.terms.push_back(parse_term(terms[i], rd, fmt::format("terms[{}]", i)));
}

void parse_fit(const YAML::Node& fit, const Reader& rd, CalibrationFitInfo& info) {
  rd.only_keys(fit, "fit", {"data", "rows", "rmse_m", "heldout_rmse_before_m", "heldout_rmse_after_m", "weighting"});
  if (fit["data"]) info.data = rd.text(fit["data"], "fit.data");
  if (fit["weighting"]) info.weighting = rd.text(fit["weighting"], "fit.weighting");
  const double rows = rd.number_or(fit, "fit", "rows", 0.0);
  if (!(rows >= 0.0 && rows <= 1e15)) rd.fail(fit["rows"], "fit.rows", "must be a count");
  info.rows = static_cast<std::size_t>(rows);
  info.rmse_m = rd.number_or(fit, "fit", "rmse_m", info.rmse_m);
  info.heldout_rmse_before_m = rd.number_or(fit, "fit", "heldout_rmse_before_m", info.heldout_rmse_before_m);
  info.heldout_rmse_after_m = rd.number_or(fit, "fit", "heldout_rmse_after_m", info.heldout_rmse_after_m);
}

// Checked after the values, so a bad value is named before a missing neighbour.
void require_complete(const YAML::Node& root, const Reader& rd) {
  for (const auto& section : kRequired) {
    const YAML::Node s = rd.required(root, "", section.name);
    for (const char* key : section.keys) (void)rd.required(s, section.name, key);
  }
}

// The declared part (Eq. 3.18 at the reference temperature) over the ratio
// range it was fitted on must read near the physical range: -1e19 m or -5 m
// there is a broken file, not a calibration. (Beyond the fitted range, in its
// margin, a polynomial may wander: the driver flags such pixels one by one.)
void require_plausible(const YAML::Node& root, const Reader& rd, const Impl& m) {
  for (int i = 0; i <= kRangeSamples; ++i) {
    const double x = m.ratio_min + (m.ratio_max - m.ratio_min) * i / kRangeSamples;
    const double d = m.polynomial_m(x);
    if (std::isfinite(d) && d >= kPhysicalMinDistanceM - kLoadToleranceM &&
        d <= kPhysicalMaxDistanceM + kLoadToleranceM) {
      continue;
    }
    rd.fail(root["polynomial"]["coefficients_m"], "polynomial.coefficients_m",
            fmt::format("reads {:.4g} m at ratio X = {:.4g}, inside the fitted ratio range [{:.4g}, {:.4g}]: the "
                        "sensor measures {} to {} m (Eq. 3.4)",
                        d, x, m.ratio_min, m.ratio_max, kPhysicalMinDistanceM, kPhysicalMaxDistanceM));
  }
}

void parse_noise(const YAML::Node& n, const Reader& rd, NoiseLaw& law) {
  rd.only_keys(n, "noise", {"shot", "per_pulse", "read"});
  double* fields[] = {&law.shot, &law.per_pulse, &law.read};
  const char* names[] = {"shot", "per_pulse", "read"};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto v = rd.required(n, "noise", names[k]);
    const std::string field = std::string("noise.") + names[k];
    *fields[k] = rd.number(v, field);
    if (!(*fields[k] >= 0.0)) rd.fail(v, field, "must not be negative: a variance");
  }
  if (law.empty()) rd.fail(n, "noise", "every term is 0: leave the section out");
}

void parse(const YAML::Node& root, const Reader& rd, Impl& m) {
  rd.only_keys(
      root, "",
      {"format", "validity", "ratio", "polynomial", "temperature", "amplitude_reference", "noise", "terms", "fit"});
  parse_format(root, rd);
  if (const auto v = root["validity"]) parse_validity(v, rd, m.validity);
  if (const auto r = root["ratio"]) parse_ratio(r, rd, m);
  if (const auto p = root["polynomial"]) parse_polynomial(p, rd, m);
  if (const auto t = root["temperature"]) parse_temperature(t, rd, m);
  if (const auto a = root["amplitude_reference"]) parse_amplitude_reference(a, rd, m.amplitude_reference);
  if (const auto n = root["noise"]) parse_noise(n, rd, m.noise);
  if (const auto terms = root["terms"]) parse_terms(terms, rd, m);
  if (const auto fit = root["fit"]) parse_fit(fit, rd, m.info);
  require_complete(root, rd);
  require_plausible(root, rd, m);
  m.resolve();
}

// Shortest text that reads back to the same double.
std::string num(double v) { return fmt::format("{}", v); }

template <typename T>
std::string list(const std::vector<T>& v, const std::string& indent) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i) s += (i % 8 == 0) ? ",\n" + indent : ", ";
    if constexpr (std::is_floating_point_v<T>) {
      s += num(v[i]);
    } else {
      s += std::to_string(v[i]);
    }
  }
  return s + "]";
}

// A YAML double-quoted string that reads back as `s` (control characters escaped:
// a raw line break inside quotes would read back as a space).
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      out += fmt::format("\\x{:02x}", u);
      continue;
    }
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

CalibrationModel CalibrationModel::from_yaml(const std::string& text, const std::string& source_name) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
    if (const auto second = common::second_document(text)) {
      throw std::runtime_error(fmt::format("{}:{}: a second YAML document ('---'): a calibration file holds one",
                                           source_name, second->line + 1));
    }
  } catch (const YAML::ParserException& e) {
    throw std::runtime_error(fmt::format("{}:{}: not valid YAML: {}", source_name, e.mark.line + 1, e.msg));
  }
  if (!root || root.IsNull()) throw std::runtime_error(fmt::format("{}: empty calibration file", source_name));
  CalibrationModel model;
  const Reader rd(source_name, kMaxListLength);
  try {
    parse(root, rd, model.impl());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(fmt::format("{}:{}: {}", source_name, e.mark.line + 1, e.msg));
  }
  return model;
}

CalibrationModel CalibrationModel::load(const std::string& path) {
  // A FIFO would block the open, a device would never end: only a regular
  // file, and no more of it than a calibration can be (FileError names it).
  return from_yaml(files::read_text(path, "calibration file", kMaxCalibrationFileBytes), path);
}

std::string CalibrationModel::to_yaml() const {
  const Impl& m = *impl_;
  std::string y;
  y += "# tinyline calibration model (thesis 3.3): written by `tinyline calib fit`, applied by the driver.\n";
  y += "# Distance [m] = P(u) + temperature offset + terms, u = (X - center) / scale,\n";
  y += "# X = (b - Vle) / ((a Rsen - Vle) + (b - Vle)), Vle = leakage_offset + leakage_per_pulse * pulses.\n";
  y += fmt::format("format: {}\n", kFormat);
  y += "validity:                 # a read-out is used when low < a, b < high and a + b > min_sum + per_pulse * pulses "
       "/ 10\n";
  y += fmt::format("  low: {}\n  high: {}\n  min_sum: {}\n  per_pulse: {}\n", num(m.validity.low), num(m.validity.high),
                   num(m.validity.min_sum), num(m.validity.per_pulse));
  y += "ratio:                    # Eq. 3.16; charges in charge_unit\n";
  y += fmt::format("  sensitivity_ratio: {}\n", num(m.sensitivity_ratio));
  if (!m.sensitivity_ratio_per_pixel.empty()) {
    y += fmt::format("  sensitivity_ratio_per_pixel: {}\n", list(m.sensitivity_ratio_per_pixel, "    "));
  }
  y += fmt::format("  leakage_offset: {}\n  leakage_per_pulse: {}\n", num(m.leakage_offset), num(m.leakage_per_pulse));
  y += fmt::format("  range: [{}, {}]          # X the polynomial was fitted on\n  range_margin: {}\n",
                   num(m.ratio_min), num(m.ratio_max), num(m.ratio_margin));
  y += "polynomial:               # Eq. 3.18, ascending powers of u, metres\n";
  y += fmt::format("  center: {}\n  scale: {}\n  coefficients_m: {}\n", num(m.poly_center), num(m.poly_scale),
                   list(m.poly_m, "    "));
  y += "temperature:              # 3.3.4: + coefficient_m_per_c * (reference_c - T)\n";
  y += fmt::format("  reference_c: {}\n  coefficient_m_per_c: {}\n", num(m.temperature_reference_c),
                   num(m.temperature_coef_m_per_c));
  if (!m.amplitude_reference.empty()) {
    const auto& ref = m.amplitude_reference;
    y += "amplitude_reference:      # ln((a + b) / pulses) of the calibration target: the albedo covariate's "
         "reference\n";
    y +=
        fmt::format("  knots_m: {}\n  log_amplitude: {}\n", list(ref.knots_m, "    "), list(ref.log_amplitude, "    "));
    if (!ref.pixel_log_offset.empty()) y += fmt::format("  pixel_log_offset: {}\n", list(ref.pixel_log_offset, "    "));
  }
  if (!m.noise.empty()) {
    y += "noise:                    # section 3.5: var(X) = (shot (a + b) + per_pulse pulses + read) / (a + b)^2\n";
    y += fmt::format("  shot: {}\n  per_pulse: {}\n  read: {}\n", num(m.noise.shot), num(m.noise.per_pulse),
                     num(m.noise.read));
  }
  if (m.terms.empty()) {
    y += "terms: []                # effects found by the residual analysis (none)\n";
  } else {
    y +=
        "terms:                   # effects found by the residual analysis: "
        "smooth/table/amplitude_interaction/light_walk add\n"
        "                         # to the distance [m]; charge_*, gain_*, readout act on the charges before Eq. 3.16\n"
        "                         # (values_m then in charge_unit, charge_unit per pulse or a relative gain)\n";
    for (const auto& t : m.terms) {
      y += fmt::format("  - covariate: {}\n    form: {}\n", quoted(t.covariate), to_string(t.form));
      if (t.form == TermForm::kTable) {
        y += fmt::format("    keys: {}\n    offsets_m: {}\n", list(t.keys, "      "), list(t.offsets_m, "      "));
      } else {
        y += fmt::format("    knots: {}\n    values_m: {}\n", list(t.knots, "      "), list(t.values, "      "));
        if (t.form == TermForm::kAmplitudeInteraction) {
          y += fmt::format("    amplitude_reference: {}\n    amplitude_scale: {}\n", num(t.amplitude_reference),
                           num(t.amplitude_scale));
        }
        if (t.form == TermForm::kLightWalk) y += fmt::format("    reference: {}\n", num(t.reference));
      }
      if (std::isfinite(t.rmse_before_m)) y += fmt::format("    heldout_rmse_before_m: {}\n", num(t.rmse_before_m));
      if (std::isfinite(t.rmse_after_m)) y += fmt::format("    heldout_rmse_after_m: {}\n", num(t.rmse_after_m));
    }
  }
  y += "fit:                      # provenance (informational)\n";
  y += fmt::format("  data: {}\n  rows: {}\n", quoted(m.info.data), m.info.rows);
  if (std::isfinite(m.info.rmse_m)) y += fmt::format("  rmse_m: {}\n", num(m.info.rmse_m));
  if (std::isfinite(m.info.heldout_rmse_before_m)) {
    y += fmt::format("  heldout_rmse_before_m: {}\n", num(m.info.heldout_rmse_before_m));
  }
  if (std::isfinite(m.info.heldout_rmse_after_m)) {
    y += fmt::format("  heldout_rmse_after_m: {}\n", num(m.info.heldout_rmse_after_m));
  }
  if (!m.info.weighting.empty()) y += fmt::format("  weighting: {}\n", quoted(m.info.weighting));
  return y;
}

void CalibrationModel::save(const std::string& path) const {
  // Written beside the target and renamed: a reader never sees half a file.
  files::write_atomically(path, to_yaml(), files::named("calibration"));
}

}  // namespace tinyline::tiny_laser_driver

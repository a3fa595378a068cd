// The calibration YAML: what `tinyline calib fit` writes and the driver loads.
// Strict on load: an unknown key, a missing field or a bad value stops with
// the file, line and field, because a silently ignored typo in a calibration
// shows up much later as a wrong distance.
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <tiny_laser_driver/calibration_impl.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_driver {

namespace {

constexpr std::string_view kFormat = "tinyline_calibration/1";

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const YAML::Node& at, const std::string& field, const std::string& what) const {
    const auto mark = at.Mark();
    const std::string where = mark.line >= 0 ? fmt::format("{}:{}", source_, mark.line + 1) : source_;
    throw std::runtime_error(fmt::format("{}: field '{}': {}", where, field, what));
  }

  void only_keys(const YAML::Node& map, const std::string& field, std::initializer_list<std::string_view> known) const {
    if (!map.IsMap()) fail(map, field, "expected a mapping");
    for (const auto& kv : map) {
      const auto key = kv.first.as<std::string>();
      bool ok = false;
      for (auto k : known) ok = ok || k == key;
      if (!ok) {
        std::string list;
        for (auto k : known) list += (list.empty() ? "" : ", ") + std::string(k);
        fail(kv.first, field.empty() ? key : field + "." + key, fmt::format("unknown key (known here: {})", list));
      }
    }
  }

  YAML::Node required(const YAML::Node& map, const std::string& parent, const char* key) const {
    const YAML::Node n = map[key];
    if (!n) fail(map, join(parent, key), "missing");
    return n;
  }

  double number(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) fail(n, field, "expected a number");
    double v = 0.0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(n, field, fmt::format("'{}' is not a number", n.Scalar()));
    }
    if (!std::isfinite(v)) fail(n, field, "must be finite");
    return v;
  }

  double number_or(const YAML::Node& map, const std::string& parent, const char* key, double fallback) const {
    const YAML::Node n = map[key];
    return n ? number(n, join(parent, key)) : fallback;
  }

  std::vector<double> numbers(const YAML::Node& n, const std::string& field) const {
    if (!n.IsSequence()) fail(n, field, "expected a list of numbers");
    std::vector<double> v;
    v.reserve(n.size());
    for (std::size_t i = 0; i < n.size(); ++i) v.push_back(number(n[i], fmt::format("{}[{}]", field, i)));
    return v;
  }

  std::vector<long> integers(const YAML::Node& n, const std::string& field) const {
    if (!n.IsSequence()) fail(n, field, "expected a list of integers");
    std::vector<long> v;
    for (std::size_t i = 0; i < n.size(); ++i) {
      long x = 0;
      try {
        x = n[i].as<long>();
      } catch (const YAML::Exception&) {
        fail(n[i], fmt::format("{}[{}]", field, i), fmt::format("'{}' is not an integer", n[i].Scalar()));
      }
      v.push_back(x);
    }
    return v;
  }

  std::string text(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) fail(n, field, "expected text");
    return n.Scalar();
  }

  static std::string join(const std::string& parent, const char* key) {
    return parent.empty() ? std::string(key) : parent + "." + key;
  }

 private:
  std::string source_;
};

template <typename T>
bool strictly_increasing(const std::vector<T>& v) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    if (!(v[i] > v[i - 1])) return false;
  }
  return true;
}

void parse(const YAML::Node& root, const Reader& rd, CalibrationModel::Impl& m) {
  rd.only_keys(root, "", {"format", "validity", "ratio", "polynomial", "temperature", "amplitude_reference", "terms", "fit"});
  const auto fmt_node = rd.required(root, "", "format");
  if (rd.text(fmt_node, "format") != kFormat) {
    rd.fail(fmt_node, "format", fmt::format("'{}' is not '{}'", fmt_node.Scalar(), kFormat));
  }

  if (const auto v = root["validity"]) {
    rd.only_keys(v, "validity", {"low", "high", "min_sum", "per_pulse"});
    m.validity.low = rd.number_or(v, "validity", "low", m.validity.low);
    m.validity.high = rd.number_or(v, "validity", "high", m.validity.high);
    m.validity.min_sum = rd.number_or(v, "validity", "min_sum", m.validity.min_sum);
    m.validity.per_pulse = rd.number_or(v, "validity", "per_pulse", m.validity.per_pulse);
    if (!(m.validity.low < m.validity.high)) rd.fail(v, "validity", "low must be below high");
  }

  if (const auto r = root["ratio"]) {
    rd.only_keys(r, "ratio", {"sensitivity_ratio", "sensitivity_ratio_per_pixel", "leakage_offset",
                              "leakage_per_pulse", "range", "range_margin"});
    m.sensitivity_ratio = rd.number_or(r, "ratio", "sensitivity_ratio", 1.0);
    if (!(m.sensitivity_ratio > 0.0)) rd.fail(r["sensitivity_ratio"], "ratio.sensitivity_ratio", "must be positive");
    if (const auto pp = r["sensitivity_ratio_per_pixel"]) {
      m.sensitivity_ratio_per_pixel = rd.numbers(pp, "ratio.sensitivity_ratio_per_pixel");
      if (m.sensitivity_ratio_per_pixel.size() != kPixels) {
        rd.fail(pp, "ratio.sensitivity_ratio_per_pixel",
                fmt::format("has {} values, expected one per pixel ({})", m.sensitivity_ratio_per_pixel.size(), kPixels));
      }
      for (std::size_t i = 0; i < kPixels; ++i) {
        if (!(m.sensitivity_ratio_per_pixel[i] > 0.0)) {
          rd.fail(pp, fmt::format("ratio.sensitivity_ratio_per_pixel[{}]", i), "must be positive");
        }
      }
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
    if (m.ratio_margin < 0.0) rd.fail(r["range_margin"], "ratio.range_margin", "must not be negative");
  }

  const auto p = rd.required(root, "", "polynomial");
  rd.only_keys(p, "polynomial", {"center", "scale", "coefficients_m"});
  m.poly_center = rd.number_or(p, "polynomial", "center", 0.0);
  m.poly_scale = rd.number_or(p, "polynomial", "scale", 1.0);
  if (m.poly_scale == 0.0) rd.fail(p["scale"], "polynomial.scale", "must not be zero");
  const auto coef = rd.required(p, "polynomial", "coefficients_m");
  m.poly_m = rd.numbers(coef, "polynomial.coefficients_m");
  if (m.poly_m.empty()) rd.fail(coef, "polynomial.coefficients_m", "must hold at least one coefficient");

  if (const auto t = root["temperature"]) {
    rd.only_keys(t, "temperature", {"reference_c", "coefficient_m_per_c"});
    m.temperature_reference_c = rd.number_or(t, "temperature", "reference_c", m.temperature_reference_c);
    m.temperature_coef_m_per_c = rd.number_or(t, "temperature", "coefficient_m_per_c", 0.0);
  }

  if (const auto a = root["amplitude_reference"]) {
    rd.only_keys(a, "amplitude_reference", {"knots_m", "log_amplitude", "pixel_log_offset"});
    auto& ref = m.amplitude_reference;
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
      ref.pixel_log_offset = rd.numbers(pp, "amplitude_reference.pixel_log_offset");
      if (ref.pixel_log_offset.size() != kPixels) {
        rd.fail(pp, "amplitude_reference.pixel_log_offset",
                fmt::format("has {} values, expected one per pixel ({})", ref.pixel_log_offset.size(), kPixels));
      }
    }
  }

  if (const auto terms = root["terms"]) {
    if (!terms.IsSequence()) rd.fail(terms, "terms", "expected a list");
    for (std::size_t i = 0; i < terms.size(); ++i) {
      const auto n = terms[i];
      const std::string f = fmt::format("terms[{}]", i);
      rd.only_keys(n, f, {"covariate", "form", "knots", "values_m", "keys", "offsets_m", "amplitude_reference",
                          "amplitude_scale", "heldout_rmse_before_m", "heldout_rmse_after_m"});
      CalibrationTerm t;
      t.covariate = rd.text(rd.required(n, f, "covariate"), f + ".covariate");
      if (t.covariate.empty()) rd.fail(n, f + ".covariate", "must not be empty");
      const auto form_node = rd.required(n, f, "form");
      const auto form = term_form_from_string(rd.text(form_node, f + ".form"));
      if (!form) rd.fail(form_node, f + ".form", fmt::format("'{}' is not smooth, table or amplitude_interaction", form_node.Scalar()));
      t.form = *form;
      if (t.form == TermForm::kTable) {
        const auto kn = rd.required(n, f, "keys");
        t.keys = rd.integers(kn, f + ".keys");
        if (!strictly_increasing(t.keys)) rd.fail(kn, f + ".keys", "must be strictly increasing");
        const auto on = rd.required(n, f, "offsets_m");
        t.offsets_m = rd.numbers(on, f + ".offsets_m");
        if (t.offsets_m.size() != t.keys.size()) {
          rd.fail(on, f + ".offsets_m", fmt::format("has {} values for {} keys", t.offsets_m.size(), t.keys.size()));
        }
      } else {
        const auto kn = rd.required(n, f, "knots");
        t.knots = rd.numbers(kn, f + ".knots");
        if (t.knots.empty() || !strictly_increasing(t.knots)) rd.fail(kn, f + ".knots", "must be a non-empty, strictly increasing list");
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
      t.rmse_before_m = rd.number_or(n, f, "heldout_rmse_before_m", t.rmse_before_m);
      t.rmse_after_m = rd.number_or(n, f, "heldout_rmse_after_m", t.rmse_after_m);
      m.terms.push_back(std::move(t));
    }
  }

  if (const auto fit = root["fit"]) {
    rd.only_keys(fit, "fit", {"data", "rows", "rmse_m", "heldout_rmse_before_m", "heldout_rmse_after_m", "weighting"});
    if (fit["data"]) m.info.data = rd.text(fit["data"], "fit.data");
    if (fit["weighting"]) m.info.weighting = rd.text(fit["weighting"], "fit.weighting");
    m.info.rows = static_cast<std::size_t>(rd.number_or(fit, "fit", "rows", 0.0));
    m.info.rmse_m = rd.number_or(fit, "fit", "rmse_m", m.info.rmse_m);
    m.info.heldout_rmse_before_m = rd.number_or(fit, "fit", "heldout_rmse_before_m", m.info.heldout_rmse_before_m);
    m.info.heldout_rmse_after_m = rd.number_or(fit, "fit", "heldout_rmse_after_m", m.info.heldout_rmse_after_m);
  }
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

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
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
  } catch (const YAML::ParserException& e) {
    throw std::runtime_error(fmt::format("{}:{}: not valid YAML: {}", source_name, e.mark.line + 1, e.msg));
  }
  if (!root || root.IsNull()) throw std::runtime_error(fmt::format("{}: empty calibration file", source_name));
  CalibrationModel model;
  Reader rd(source_name);
  try {
    parse(root, rd, model.impl());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(fmt::format("{}:{}: {}", source_name, e.mark.line + 1, e.msg));
  }
  return model;
}

CalibrationModel CalibrationModel::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open calibration file", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return from_yaml(ss.str(), path);
}

std::string CalibrationModel::to_yaml() const {
  const Impl& m = *impl_;
  std::string y;
  y += "# tinyline calibration model (thesis 3.3): written by `tinyline calib fit`, applied by the driver.\n";
  y += "# Distance [m] = P(u) + temperature offset + terms, u = (X - center) / scale,\n";
  y += "# X = (b - Vle) / ((a Rsen - Vle) + (b - Vle)), Vle = leakage_offset + leakage_per_pulse * pulses.\n";
  y += fmt::format("format: {}\n", kFormat);
  y += "validity:                 # a read-out is used when low < a, b < high and a + b > min_sum + per_pulse * pulses / 10\n";
  y += fmt::format("  low: {}\n  high: {}\n  min_sum: {}\n  per_pulse: {}\n", num(m.validity.low),
                   num(m.validity.high), num(m.validity.min_sum), num(m.validity.per_pulse));
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
    y += "amplitude_reference:      # ln((a + b) / pulses) of the calibration target: the albedo covariate's reference\n";
    y += fmt::format("  knots_m: {}\n  log_amplitude: {}\n", list(ref.knots_m, "    "), list(ref.log_amplitude, "    "));
    if (!ref.pixel_log_offset.empty()) y += fmt::format("  pixel_log_offset: {}\n", list(ref.pixel_log_offset, "    "));
  }
  if (m.terms.empty()) {
    y += "terms: []                # effects found by the residual analysis (none)\n";
  } else {
    y += "terms:                   # effects found by the residual analysis, added to the distance\n";
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
  // Write beside the target and rename, so a reader never sees half a file.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write calibration file", path));
    out << to_yaml();
    out.flush();
    if (!out) throw std::runtime_error(fmt::format("{}: write failed", path));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(fmt::format("{}: cannot replace the calibration file", path));
  }
}

}  // namespace tinyline::tiny_laser_driver

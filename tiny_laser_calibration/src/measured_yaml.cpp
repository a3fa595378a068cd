// SPDX-License-Identifier: Apache-2.0
// Reading the measured figures (measured.hpp): every field named on error.
#include <set>
#include <string>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <tinyline/common/files.hpp>
#include <tinyline/common/yaml_fields.hpp>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/measured.hpp>

namespace tinyline::tiny_laser_calibration {

namespace {

using Fields = common::YamlFields<CalibrationDataError>;

/// root[key]: a non-empty list.
YAML::Node list(const YAML::Node& root, const Fields& f, const std::string& key) {
  const YAML::Node n = f.required(root, "", key);
  if (!n.IsSequence() || n.size() == 0) f.fail(n, key, "expected a non-empty list");
  return n;
}

/// A mapping of names, each at most once (yaml-cpp would keep both and show the first).
void unique_names(const YAML::Node& map, const Fields& f, const std::string& field) {
  std::set<std::string> seen;
  for (const auto& kv : map) {
    if (!kv.first.IsScalar()) f.fail(kv.first, field, "expected a name, not a list or mapping");
    if (!seen.insert(kv.first.Scalar()).second) f.fail(kv.first, field + "." + kv.first.Scalar(), "given twice");
  }
}

/// n[key] of a row must be a positive number (a spread, a variance, a reflectance).
void positive(const YAML::Node& n, const Fields& f, const std::string& at, const char* key, double v) {
  if (!(v > 0.0)) f.fail(n[key], at + "." + key, "must be positive");
}

void read_tables(const YAML::Node& root, const Fields& f, MeasuredData& d) {
  const auto t31 = list(root, f, "noise_vs_distance_cm");
  for (std::size_t i = 0; i < t31.size(); ++i) {
    const std::string at = fmt::format("noise_vs_distance_cm[{}]", i);
    f.only_keys(t31[i], at, {"truth", "mean", "var", "sd"});
    d.table31.push_back({f.number(t31[i], at, "truth"), f.number(t31[i], at, "mean"), f.number(t31[i], at, "var"),
                         f.number(t31[i], at, "sd")});
    positive(t31[i], f, at, "sd", d.table31.back().sd_cm);
    positive(t31[i], f, at, "var", d.table31.back().var_cm2);
  }
  const auto t32 = list(root, f, "materials_at_30cm");
  for (std::size_t i = 0; i < t32.size(); ++i) {
    const std::string at = fmt::format("materials_at_30cm[{}]", i);
    f.only_keys(t32[i], at, {"material", "mean_cm", "sd_cm", "reflectance"});
    d.table32.push_back({f.text(t32[i], at, "material"), f.number(t32[i], at, "mean_cm"), f.number(t32[i], at, "sd_cm"),
                         f.number(t32[i], at, "reflectance")});
    positive(t32[i], f, at, "reflectance", d.table32.back().reflectance);
    positive(t32[i], f, at, "sd_cm", d.table32.back().sd_cm);
    for (std::size_t j = 0; j + 1 < d.table32.size(); ++j) {
      if (d.table32[j].name == d.table32.back().name)
        f.fail(t32[i]["material"], at + ".material",
               fmt::format("'{}' has a row already (row {})", d.table32[j].name, j));
    }
  }
  const auto fits = f.required(root, "", "calibration_fits_cm");
  if (!fits.IsMap()) f.fail(fits, "calibration_fits_cm", "expected a mapping");
  unique_names(fits, f, "calibration_fits_cm");
  for (const auto& kv : fits) {
    const std::string name = kv.first.as<std::string>();
    f.only_keys(kv.second, "calibration_fits_cm." + name, {"var", "sd", "sd_over"});
    MeasuredFit fit;
    fit.name = name;
    fit.var_cm2 = f.number(kv.second, "calibration_fits_cm." + name, "var");
    if (kv.second["sd"]) fit.sd_cm = f.number(kv.second, "calibration_fits_cm." + name, "sd");
    d.fits.push_back(fit);
  }
}

void read_sensors(const YAML::Node& root, const Fields& f, MeasuredData& d) {
  const auto s = f.required(root, "", "real_sensor_polynomials");
  if (!s.IsMap() || s.size() == 0) f.fail(s, "real_sensor_polynomials", "expected a non-empty mapping");
  unique_names(s, f, "real_sensor_polynomials");
  for (const auto& kv : s) {
    RealSensorCurve c;
    c.name = kv.first.as<std::string>();
    const std::string at = "real_sensor_polynomials." + c.name;
    f.only_keys(kv.second, at, {"poly", "offsets_added", "stable_temperature", "temperature_sensi"});
    c.poly = f.numbers(kv.second, at, "poly");
    c.offsets = f.numbers(kv.second, at, "offsets_added");
    if (c.poly.size() != 7 || c.offsets.size() != 7)
      f.fail(kv.second, at, "poly and offsets_added need 7 coefficients");
    c.stable_temperature_decic = f.number(kv.second, at, "stable_temperature");
    c.temperature_sensi_cm_per_decic = f.number(kv.second, at, "temperature_sensi");
    d.sensors.push_back(std::move(c));
  }
}

}  // namespace

MeasuredData parse_measured_data(const std::string& text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw CalibrationDataError(fmt::format("{}:{}: not valid YAML: {}", source, e.mark.line + 1, e.msg));
  }
  if (!root || !root.IsMap())
    throw CalibrationDataError(fmt::format("{}: expected a mapping of measured figures", source));
  MeasuredData d;
  d.source = source;
  const Fields f(source);
  try {
    // Unknown and repeated keys are errors: a second value of a key was silently ignored.
    f.only_keys(
        root, "",
        {"sensor", "noise_vs_distance_cm", "materials_at_30cm", "calibration_fits_cm", "real_sensor_polynomials"});
    const auto sensor = f.required(root, "", "sensor");
    f.only_keys(sensor, "sensor",
                {"pulse_width_ns", "driver_delay_drift_ns", "warm_temperature_c", "accumulation_pulses", "range_m"});
    d.pulse_width_ns = f.number(sensor, "sensor", "pulse_width_ns");
    d.warm_temperature_c = f.number(sensor, "sensor", "warm_temperature_c");
    read_tables(root, f, d);
    read_sensors(root, f, d);
  } catch (const YAML::Exception& e) {
    throw CalibrationDataError(fmt::format("{}:{}: {}", source, e.mark.line + 1, e.msg));
  }
  return d;
}

MeasuredData load_measured_data(const std::string& path) {
  std::string text;
  try {
    text = files::read_text(path, "measured figures", kMaxMeasuredFileBytes);
  } catch (const files::FileError& e) {
    throw CalibrationDataError(e.what());
  }
  return parse_measured_data(text, path);
}

}  // namespace tinyline::tiny_laser_calibration

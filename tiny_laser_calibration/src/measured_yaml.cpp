// SPDX-License-Identifier: Apache-2.0
// Reading the measured figures (measured.hpp): every field named on error.
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

void read_tables(const YAML::Node& root, const Fields& f, MeasuredData& d) {
  const auto t31 = list(root, f, "noise_vs_distance_cm");
  for (std::size_t i = 0; i < t31.size(); ++i) {
    const std::string at = fmt::format("noise_vs_distance_cm[{}]", i);
    d.table31.push_back({f.number(t31[i], at, "truth"), f.number(t31[i], at, "mean"), f.number(t31[i], at, "var"),
                         f.number(t31[i], at, "sd")});
    if (!(d.table31.back().sd_cm > 0.0)) f.fail(t31[i], at + ".sd", "must be positive");
  }
  const auto t32 = list(root, f, "materials_at_30cm");
  for (std::size_t i = 0; i < t32.size(); ++i) {
    const std::string at = fmt::format("materials_at_30cm[{}]", i);
    d.table32.push_back({f.text(t32[i], at, "material"), f.number(t32[i], at, "mean_cm"), f.number(t32[i], at, "sd_cm"),
                         f.number(t32[i], at, "reflectance")});
    if (!(d.table32.back().reflectance > 0.0)) f.fail(t32[i], at + ".reflectance", "must be positive");
  }
  const auto fits = f.required(root, "", "calibration_fits_cm");
  if (!fits.IsMap()) f.fail(fits, "calibration_fits_cm", "expected a mapping");
  for (const auto& kv : fits) {
    const std::string name = kv.first.as<std::string>();
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
  for (const auto& kv : s) {
    RealSensorCurve c;
    c.name = kv.first.as<std::string>();
    const std::string at = "real_sensor_polynomials." + c.name;
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
    const auto sensor = f.required(root, "", "sensor");
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

// SPDX-License-Identifier: Apache-2.0
// The loop on the real sensor's measurements (measured.hpp, `calib measured`):
// the package's copy of the measured figures loads, every analysis runs on it,
// the accepted explanations beat the declared model out of sample, and bad
// files get errors naming the file, line and field.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/measured.hpp>
#include <tiny_laser_calibration/tool.hpp>

namespace fs = std::filesystem;
namespace cal = tinyline::tiny_laser_calibration;
using ::testing::HasSubstr;

namespace {

const std::string kMeasured = std::string(TINYLINE_SOURCE_DIR) + "/tiny_laser_calibration/data/measured.yaml";

std::string file_text(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(CalibrationMeasured, TheCommittedFiguresLoadWhole) {
  const auto d = cal::load_measured_data(kMeasured);
  EXPECT_EQ(d.table31.size(), 5u);
  EXPECT_EQ(d.table32.size(), 9u);
  EXPECT_EQ(d.fits.size(), 5u);
  ASSERT_EQ(d.sensors.size(), 5u);
  EXPECT_EQ(d.sensors[0].name, "R");
  EXPECT_DOUBLE_EQ(d.sensors[0].offsets[5], -15.0);  // the public driver's hand-made offsets, kept apart
  EXPECT_DOUBLE_EQ(d.table32.back().mean_cm, 39.8339);
}

TEST(CalibrationMeasured, Table32BiasIsExplainedBetterThanByTheDeclaredModelOutOfSample) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto a = cal::analyse_materials(d);
  // Before: each surface's bias beyond white paper's own (30.0705 cm).
  double s = 0.0;
  for (const auto& m : d.table32) s += std::pow(m.mean_cm - 30.0705, 2);
  EXPECT_NEAR(a.before_rmse_cm, std::sqrt(s / 8.0), 1e-9);
  ASSERT_GE(a.best, 0);
  const auto& best = a.hypotheses[static_cast<std::size_t>(a.best)];
  EXPECT_LT(best.loo_rmse_cm, a.before_rmse_cm) << best.effect;
  for (const auto& h : a.hypotheses) {
    EXPECT_EQ(h.loo_residual_cm.size(), 9u);
    EXPECT_FALSE(h.reading.empty());
  }
  // The charge slope at 30 cm comes from the real curves: k between 0 and 1, L rising.
  EXPECT_GT(a.slope.ratio, 0.0);
  EXPECT_LT(a.slope.ratio, 1.0);
  EXPECT_GT(a.slope.cm_per_unit_ratio, 0.0);
}

TEST(CalibrationMeasured, Table31AndTheFitsAreHeldAgainstTheirHypotheses) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto t31 = cal::analyse_distances(d);
  EXPECT_EQ(t31.hypotheses.size(), 3u);
  EXPECT_GT(t31.sd_log_slope, 0.5);  // the spread grows with distance
  const auto f = cal::analyse_fits(d);
  EXPECT_NEAR(f.discharge_variance_ratio, 1.442 / 0.7424, 1e-9);
  EXPECT_NEAR(f.noise_exponent, std::log(1.442 / 0.7424) / std::log(4.0), 1e-9);
  EXPECT_FALSE(f.readings.empty());
}

TEST(CalibrationMeasured, EachRealCurveIsHeldAgainstTheDeclaredPhysicalModel) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto cs = cal::analyse_curves(d);
  ASSERT_EQ(cs.size(), 5u);
  for (const auto& c : cs) {
    ASSERT_EQ(c.models.size(), 3u) << c.sensor;
    EXPECT_LT(c.k_min, c.k_max);
    // Nested models: each added effect can only lower the residual.
    EXPECT_LE(c.models[1].in_sample_rmse_cm, c.models[0].in_sample_rmse_cm + 1e-6) << c.sensor;
    EXPECT_LE(c.models[2].in_sample_rmse_cm, c.models[1].in_sample_rmse_cm + 1e-6) << c.sensor;
    EXPECT_GT(c.effective_pulse_ns, 0.0) << c.sensor;
  }
  // R: 0.09623 cm per 0.1 degC is 2 * 0.9623 cm / c = 64.2 ps per degC.
  EXPECT_NEAR(cs[0].delay_drift_ps_per_c, 64.2, 0.1);
}

TEST(CalibrationMeasured, OneCommandWritesTheReport) {
  const fs::path dir = fs::temp_directory_path() / "tinyline_calib_measured_report";
  fs::remove_all(dir);
  cal::CalibToolEnv env;
  env.measured_data = kMeasured;  // the default a fresh checkout's tinyline uses
  std::ostringstream out, err;
  ASSERT_EQ(cal::run_calib_command({"measured", "--report", dir.string()}, out, err, env), 0) << err.str();
  const std::string md = file_text((dir / "measured.md").string());
  EXPECT_THAT(md, HasSubstr("Table 3.2"));
  EXPECT_THAT(md, HasSubstr("Table 3.1"));
  EXPECT_THAT(md, HasSubstr("Section 3.5"));
  EXPECT_THAT(md, HasSubstr("factory curves"));
  EXPECT_TRUE(fs::exists(dir / "measured.json"));
  EXPECT_TRUE(fs::exists(dir / "measured_curves.csv"));
  fs::remove_all(dir);
}

TEST(CalibrationMeasured, BadFilesNameTheFileLineAndField) {
  auto error_of = [](const std::string& text) {
    try {
      (void)cal::parse_measured_data(text, "m.yaml");
    } catch (const cal::CalibrationDataError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(error_of("sensor: {pulse_width_ns: 40, warm_temperature_c: 48}\n"),
              HasSubstr("m.yaml:1: field 'noise_vs_distance_cm': missing"));
  std::string t = file_text(kMeasured);
  const auto at = t.find("mean: 50.1766");
  ASSERT_NE(at, std::string::npos);
  t.replace(at, 13, "mean: fifty");
  EXPECT_THAT(error_of(t), HasSubstr("field 'noise_vs_distance_cm[1].mean': 'fifty' is not a number"));
  EXPECT_THAT(error_of("["), HasSubstr("not valid YAML"));
  cal::CalibToolEnv env;
  std::ostringstream out, err;
  EXPECT_EQ(cal::run_calib_command({"measured", "--data", "/nonexistent/m.yaml"}, out, err, env), 1);
  EXPECT_THAT(err.str(), HasSubstr("/nonexistent/m.yaml': cannot open"));
}

// Regression: a repeated key, a negative sd_cm and two rows for one material
// were accepted (yaml-cpp shows the first of two keys; the rest was ignored).
TEST(CalibrationMeasured, RepeatedKeysNegativeSpreadsAndRepeatedMaterialsAreRefused) {
  auto error_of = [](const std::string& text) {
    try {
      (void)cal::parse_measured_data(text, "m.yaml");
    } catch (const cal::CalibrationDataError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string good = file_text(kMeasured);
  EXPECT_EQ(error_of(good), "no error");
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? t : t.replace(at, from.size(), to);
  };
  EXPECT_THAT(error_of(replaced("  warm_temperature_c: 48", "  warm_temperature_c: 48\n  warm_temperature_c: 20")),
              HasSubstr("field 'sensor.warm_temperature_c': given twice"));
  EXPECT_THAT(error_of(replaced("sd_cm: 0.4505", "sd_cm: -0.4505")),
              HasSubstr("field 'materials_at_30cm[0].sd_cm': must be positive"));
  EXPECT_THAT(error_of(replaced("material: black_cushion", "material: white_paper")),
              HasSubstr("field 'materials_at_30cm[1].material': 'white_paper' has a row already"));
  EXPECT_THAT(error_of(replaced("  J: {poly", "  R: {poly")),
              HasSubstr("field 'real_sensor_polynomials.R': given twice"));
  EXPECT_THAT(error_of(replaced("sd_cm: 0.4505", "sd-cm: 0.4505")),
              HasSubstr("'materials_at_30cm[0].sd-cm': unknown key"));
}

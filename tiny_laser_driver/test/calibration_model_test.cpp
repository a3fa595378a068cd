// SPDX-License-Identifier: Apache-2.0
// The calibration model the driver applies: validity rule, Eq. 3.16 ratio,
// polynomial, temperature offset, discovered terms, and the YAML round trip
// with its errors.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/calibration_impl.hpp>

namespace tl = tinyline::tiny_laser_driver;
using ::testing::HasSubstr;

namespace {

tl::Readout readout(double a, double b, int pulses = 100, double temperature = 48.0, int pixel = 100) {
  tl::Readout r;
  r.a = a;
  r.b = b;
  r.pulses = pulses;
  r.temperature_c = temperature;
  r.pixel = pixel;
  return r;
}

// L = 2 X metres (so X = 0.25 reads 0.5 m), Rsen 1.1, leakage 0.5 + 0.01 p, 1 mm/degC below 48 degC.
tl::CalibrationModel simple_model() {
  tl::CalibrationModel m;
  auto& i = m.impl();
  i.sensitivity_ratio = 1.1;
  i.leakage_offset = 0.5;
  i.leakage_per_pulse = 0.01;
  i.poly_center = 0.0;
  i.poly_scale = 1.0;
  i.poly_m = {0.0, 2.0};
  i.ratio_min = 0.1;
  i.ratio_max = 0.9;
  i.temperature_reference_c = 48.0;
  i.temperature_coef_m_per_c = 0.001;
  return m;
}

std::string expect_load_error(const std::string& yaml) {
  try {
    (void)tl::CalibrationModel::from_yaml(yaml, "calib.yaml");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << yaml;
  return {};
}

// The smallest complete file: every section `calib fit` writes, each but the
// polynomial on one line (8 lines). minimal(name, text) leaves section `name`
// out and appends `text`.
std::string minimal(const std::string& section = "", const std::string& replacement = "") {
  const std::vector<std::pair<std::string, std::string>> parts = {
      {"format", "format: tinyline_calibration/1\n"},
      {"polynomial", "polynomial:\n  center: 0\n  scale: 1\n  coefficients_m: [0.1, 2.0]\n"},
      {"validity", "validity: {low: 10, high: 230, min_sum: 10, per_pulse: 0.4}\n"},
      {"ratio",
       "ratio: {sensitivity_ratio: 1, leakage_offset: 0, leakage_per_pulse: 0, range: [0, 1], range_margin: 0.05}\n"},
      {"temperature", "temperature: {reference_c: 48, coefficient_m_per_c: 0}\n"},
  };
  std::string y;
  for (const auto& [name, text] : parts) y += name == section ? "" : text;
  return y + replacement;
}
const std::string kMinimal = minimal();

}  // namespace

TEST(CalibrationValidity, FollowsThePublicDriverRule) {
  const tl::ValidityRule rule;
  using V = tl::ValidityRule::Verdict;
  EXPECT_EQ(rule.check(readout(100, 100)), V::kValid);
  EXPECT_EQ(rule.check(readout(230, 100)), V::kSaturated);
  EXPECT_EQ(rule.check(readout(100, 231)), V::kSaturated);
  EXPECT_EQ(rule.check(readout(10, 100)), V::kTooDark);
  EXPECT_EQ(rule.check(readout(100, 9)), V::kTooDark);
  // a + b must exceed 10 + 0.4 * pulses / 10: at 700 pulses that is 38.
  EXPECT_EQ(rule.check(readout(19, 19, 700)), V::kTooDark);
  EXPECT_EQ(rule.check(readout(20, 19, 700)), V::kValid);
  EXPECT_EQ(rule.check(readout(std::nan(""), 100)), V::kTooDark);
}

TEST(CalibrationModel, RatioFollowsEq316) {
  const auto m = simple_model();
  const auto r = readout(120.0, 60.0, 100);
  const double vle = 0.5 + 0.01 * 100;
  const double x = (60.0 - vle) / ((120.0 * 1.1 - vle) + (60.0 - vle));
  const auto ev = m.evaluate(r);
  ASSERT_EQ(ev.status, tl::CalibrationEvaluation::Status::kValid);
  EXPECT_DOUBLE_EQ(ev.ratio, x);
  EXPECT_DOUBLE_EQ(ev.distance_m, 2.0 * x);
  EXPECT_DOUBLE_EQ(m.distance_m(r), 2.0 * x);
  EXPECT_DOUBLE_EQ(ev.reflectance, 4.0 * x * x * 180.0 / 100.0);
}

TEST(CalibrationModel, TemperatureOffsetBelowReference) {
  const auto m = simple_model();
  const double warm = m.distance_m(readout(120, 60, 100, 48.0));
  const double cold = m.distance_m(readout(120, 60, 100, 28.0));
  EXPECT_NEAR(cold - warm, 0.020, 1e-12);  // 1 mm/degC * 20 degC
}

TEST(CalibrationModel, InvalidAndOutOfRangeGiveNaNWithReason) {
  const auto m = simple_model();
  using S = tl::CalibrationEvaluation::Status;
  EXPECT_EQ(m.evaluate(readout(240, 60)).status, S::kSaturated);
  EXPECT_TRUE(std::isnan(m.distance_m(readout(240, 60))));
  EXPECT_EQ(m.evaluate(readout(5, 60)).status, S::kTooDark);
  // X close to 1: far outside [0.1, 0.9] + 5% margin.
  const auto ev = m.evaluate(readout(11, 220));
  EXPECT_EQ(ev.status, S::kOutOfRange);
  EXPECT_TRUE(std::isnan(ev.distance_m));
  EXPECT_GT(ev.ratio, 0.9);
}

TEST(CalibrationModel, TermsAddToTheDistance) {
  auto m = simple_model();
  tl::CalibrationTerm table;
  table.covariate = "pixel";
  table.form = tl::TermForm::kTable;
  table.keys = {99, 100};
  table.offsets_m = {0.5, 0.01};
  tl::CalibrationTerm smooth;
  smooth.covariate = "humidity";
  smooth.form = tl::TermForm::kSmooth;
  smooth.knots = {0.0, 100.0};
  smooth.values = {0.0, 0.1};
  tl::CalibrationTerm inter;
  inter.covariate = "t_s";
  inter.form = tl::TermForm::kAmplitudeInteraction;
  inter.knots = {0.0};
  inter.values = {0.002};
  inter.amplitude_reference = 100.0;
  inter.amplitude_scale = 40.0;
  m.impl().terms = {table, smooth, inter};
  m.impl().resolve();
  ASSERT_EQ(m.extra_covariates(), std::vector<std::string>{"humidity"});

  auto r = readout(120, 60);
  const double base = simple_model().distance_m(r);
  r.extra = {50.0};
  // pixel 100 -> +0.01, humidity 50 -> +0.05, (180 - 100) / 40 * 0.002 -> +0.004
  EXPECT_NEAR(m.distance_m(r), base + 0.01 + 0.05 + 0.004, 1e-12);
  r.extra = {250.0};  // beyond the last knot: the end value
  EXPECT_NEAR(m.distance_m(r), base + 0.01 + 0.1 + 0.004, 1e-12);
  r.pixel = 7;  // not in the table: no offset
  EXPECT_NEAR(m.distance_m(r), base + 0.1 + 0.004, 1e-12);
  r.extra.clear();  // the driver could not supply the covariate
  const auto ev = m.evaluate(r);
  EXPECT_EQ(ev.status, tl::CalibrationEvaluation::Status::kMissingCovariate);
  EXPECT_NEAR(ev.distance_m, base + 0.004, 1e-12);
}

TEST(CalibrationYaml, RoundTripKeepsEveryDistance) {
  auto m = simple_model();
  m.impl().sensitivity_ratio_per_pixel.assign(272, 1.0);
  m.impl().sensitivity_ratio_per_pixel[100] = 0.97;
  tl::CalibrationTerm t;
  t.covariate = "reflectance";
  t.form = tl::TermForm::kSmooth;
  t.knots = {0.1, 1.0, 3.0};
  t.values = {0.03, 0.001, -0.0123456789};
  m.impl().terms = {t};
  m.impl().amplitude_reference.knots_m = {0.1, 1.0, 2.0};
  m.impl().amplitude_reference.log_amplitude = {3.0, 0.5, -1.0};
  m.impl().amplitude_reference.pixel_log_offset.assign(272, 0.01);
  m.impl().resolve();
  m.impl().info.data = "rail \"A\".csv";

  const auto path = std::filesystem::temp_directory_path() / "tinyline_calib_roundtrip.yaml";
  m.save(path.string());
  const auto back = tl::CalibrationModel::load(path.string());
  std::filesystem::remove(path);
  EXPECT_EQ(back.to_yaml(), m.to_yaml());
  EXPECT_EQ(back.impl().info.data, "rail \"A\".csv");
  auto probe = readout(100, 60, 100, 40.0, 100);
  EXPECT_EQ(back.evaluate(probe).albedo, m.evaluate(probe).albedo);
  EXPECT_TRUE(std::isfinite(m.evaluate(probe).albedo));
  for (int px : {99, 100}) {
    for (double a = 20; a < 200; a += 7) {
      auto r = readout(a, 200 - a, 100, 40.0, px);
      const double d0 = m.distance_m(r), d1 = back.distance_m(r);
      if (std::isnan(d0)) {
        EXPECT_TRUE(std::isnan(d1));
      } else {
        EXPECT_EQ(d0, d1) << "a=" << a << " px=" << px;  // bit-exact: shortest round-trip formatting
      }
    }
  }
}

TEST(CalibrationYaml, MinimalFileLoads) {
  const auto m = tl::CalibrationModel::from_yaml(kMinimal, "calib.yaml");
  EXPECT_NEAR(m.distance_m(readout(100, 100)), 0.1 + 2.0 * 0.5, 1e-12);
}

TEST(CalibrationYaml, ErrorsNameFileLineAndField) {
  EXPECT_THAT(expect_load_error(""), HasSubstr("calib.yaml: empty calibration file"));
  EXPECT_THAT(expect_load_error("format: [unclosed\n"), HasSubstr("calib.yaml:"));
  EXPECT_THAT(expect_load_error("format: other/2\npolynomial: {coefficients_m: [1]}\n"),
              HasSubstr("calib.yaml:1: field 'format'"));
  EXPECT_THAT(expect_load_error("format: tinyline_calibration/1\n"), HasSubstr("field 'polynomial': missing"));
  EXPECT_THAT(expect_load_error(minimal("temperature", "temperature:\n  refrence_c: 40\n")),
              HasSubstr("calib.yaml:9: field 'temperature.refrence_c': unknown key"));
  EXPECT_THAT(expect_load_error("format: tinyline_calibration/1\npolynomial:\n  coefficients_m: [0.1, abc]\n"),
              HasSubstr("calib.yaml:3: field 'polynomial.coefficients_m[1]': 'abc' is not a number"));
  EXPECT_THAT(expect_load_error("format: tinyline_calibration/1\npolynomial:\n  coefficients_m: []\n"),
              HasSubstr("at least one coefficient"));
  EXPECT_THAT(expect_load_error(minimal("ratio", "ratio:\n  sensitivity_ratio_per_pixel: [1, 1]\n")),
              HasSubstr("has 2 values, expected one per pixel (272)"));
  EXPECT_THAT(expect_load_error(minimal("ratio", "ratio:\n  sensitivity_ratio: -1\n")),
              HasSubstr("ratio.sensitivity_ratio': must be positive"));
  EXPECT_THAT(
      expect_load_error(kMinimal +
                        "terms:\n  - covariate: pixel\n    form: table\n    keys: [3, 2]\n    offsets_m: [0, 0]\n"),
      HasSubstr("calib.yaml:12: field 'terms[0].keys': must be strictly increasing"));
  EXPECT_THAT(expect_load_error(kMinimal + "terms:\n  - covariate: pixel\n    form: wiggly\n"),
              HasSubstr("terms[0].form': 'wiggly' is not a term form"));
  EXPECT_THAT(expect_load_error(kMinimal +
                                "terms:\n  - covariate: t_s\n    form: smooth\n    knots: [0, 1]\n    values_m: [0]\n"),
              HasSubstr("has 1 values for 2 knots"));
  EXPECT_THAT(expect_load_error(minimal("validity", "validity: {low: 300, high: 230}\n")),
              HasSubstr("low must be below high"));
  EXPECT_THAT(expect_load_error(kMinimal + "amplitude_reference:\n  knots_m: [0.1, 1]\n  log_amplitude: [1]\n"),
              HasSubstr("calib.yaml:11: field 'amplitude_reference.log_amplitude': has 1 values for 2 knots"));
}

TEST(CalibrationYaml, ARepeatedKeyIsRefusedNamingFileLineAndField) {
  // yaml-cpp keeps both; a lookup sees the first, so the second was ignored.
  EXPECT_THAT(expect_load_error(kMinimal + "polynomial:\n  center: 0\n  scale: 1\n  coefficients_m: [9]\n"),
              HasSubstr("calib.yaml:9: field 'polynomial': given twice"));
  EXPECT_THAT(expect_load_error(minimal(
                  "temperature", "temperature:\n  reference_c: 48\n  coefficient_m_per_c: 0\n  reference_c: 20\n")),
              HasSubstr("calib.yaml:11: field 'temperature.reference_c': given twice"));
  EXPECT_THAT(expect_load_error(kMinimal + "terms:\n  - covariate: pixel\n    form: table\n    keys: [1]\n"
                                           "    offsets_m: [0]\n    keys: [2]\n"),
              HasSubstr("calib.yaml:14: field 'terms[0].keys': given twice"));
}

// yaml-cpp reads the first document and drops the rest: a file that goes on
// after `---` (two calibrations pasted together) is refused, not half read.
TEST(CalibrationYaml, ASecondYamlDocumentIsRefusedNamingFileAndLine) {
  const auto lines = static_cast<int>(std::count(kMinimal.begin(), kMinimal.end(), '\n'));
  EXPECT_THAT(expect_load_error(kMinimal + "---\n" + kMinimal),
              HasSubstr(fmt::format("calib.yaml:{}: a second YAML document ('---')", lines + 1)));
  EXPECT_THAT(expect_load_error(kMinimal + "---\nformat: other\n"), HasSubstr("a second YAML document"));
  // An explicit start of the first and only document is fine; a stray ',' is an error, not a hang.
  EXPECT_NO_THROW((void)tl::CalibrationModel::from_yaml("---\n" + kMinimal, "calib.yaml"));
  EXPECT_THAT(expect_load_error(kMinimal + ",\n"), HasSubstr("calib.yaml:"));
}

TEST(CalibrationYaml, AFileWithoutASectionOrFieldThatCalibFitWritesIsRefused) {
  for (const char* section : {"polynomial", "validity", "ratio", "temperature"}) {
    EXPECT_THAT(expect_load_error(minimal(section)), HasSubstr(fmt::format("field '{}': missing", section)));
  }
  EXPECT_THAT(expect_load_error(minimal("ratio",
                                        "ratio: {sensitivity_ratio: 1, leakage_offset: 0, "
                                        "leakage_per_pulse: 0, range_margin: 0.05}\n")),
              HasSubstr("calib.yaml:8: field 'ratio.range': missing"));
  EXPECT_THAT(expect_load_error(minimal("polynomial", "polynomial: {center: 0, coefficients_m: [0.1, 2]}\n")),
              HasSubstr("field 'polynomial.scale': missing"));
}

TEST(CalibrationYaml, APolynomialWithAnAbsurdNumberOfCoefficientsIsRefused) {
  std::string coefficients = "[0.1, 2";
  for (int i = 2; i < 500; ++i) coefficients += ", 0";
  EXPECT_THAT(expect_load_error(
                  minimal("polynomial", "polynomial: {center: 0, scale: 1, coefficients_m: " + coefficients + "]}\n")),
              HasSubstr("calib.yaml:5: field 'polynomial.coefficients_m': has 500 coefficients, at most 13"));
  // Degree 12, the fitter's largest, loads.
  std::string twelve = "[0.1, 2";
  for (int i = 2; i <= 12; ++i) twelve += ", 0";
  EXPECT_NO_THROW((void)tl::CalibrationModel::from_yaml(
      minimal("polynomial", "polynomial: {center: 0, scale: 1, coefficients_m: " + twelve + "]}\n"), "calib.yaml"));
}

TEST(CalibrationYaml, APolynomialThatReadsOutsideThePhysicalRangeIsRefused) {
  // Each reads absurdly somewhere on the fitted ratio range [0, 1].
  for (const std::string coefficients : {"[-1e19]", "[-5, 0.1]", "[0.1, 1e308, 1e308]", "[0.1, 20]"}) {
    EXPECT_THAT(expect_load_error(
                    minimal("polynomial", "polynomial: {center: 0, scale: 1, coefficients_m: " + coefficients + "}\n")),
                HasSubstr("calib.yaml:5: field 'polynomial.coefficients_m': reads"))
        << coefficients;
  }
  // Within half a metre of 0-6 m on the fitted range: a fit's noisy ends, accepted.
  EXPECT_NO_THROW((void)tl::CalibrationModel::from_yaml(
      minimal("polynomial", "polynomial: {center: 0, scale: 1, coefficients_m: [-0.3, 6.6]}\n"), "calib.yaml"));
}

TEST(CalibrationYaml, AFifoOrADeviceIsRefusedInsteadOfReadForEver) {
  EXPECT_THROW((void)tl::CalibrationModel::load("/dev/zero"), std::runtime_error);
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("calib_fifo_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const auto fifo = (dir / "calib.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  try {
    (void)tl::CalibrationModel::load(fifo);
    ADD_FAILURE() << "loaded a FIFO";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("not a regular file"));
  }
  std::filesystem::remove_all(dir);
  // A file past the size limit.
  const auto big = std::filesystem::temp_directory_path() / fmt::format("calib_big_{}.yaml", ::getpid());
  {
    std::ofstream out(big);
    out << kMinimal << "# " << std::string(tl::kMaxCalibrationFileBytes, 'x') << "\n";
  }
  try {
    (void)tl::CalibrationModel::load(big.string());
    ADD_FAILURE() << "loaded a file past the limit";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("more than the limit"));
  }
  std::filesystem::remove(big);
}

TEST(CalibrationYaml, MissingFileIsAClearError) {
  try {
    (void)tl::CalibrationModel::load("/nonexistent/calib.yaml");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("calibration file '/nonexistent/calib.yaml': cannot open"));
  }
}

TEST(CalibrationModel, PublicDriverPolynomialOfSensorK) {
  // The public driver's sensor K: usable on about k in [0.35, 0.8].
  const std::vector<double> poly = {2.147918234375362e+06,  -7.736068312640203e+06, 1.154494186428487e+07,
                                    -9.137795412258314e+06, 4.045684724836031e+06,  -9.494901699902674e+05,
                                    9.219599710241470e+04};
  const auto m = tl::CalibrationModel::from_public_driver(poly, {0, 0, 0, 0, 0, 0, 0}, 440, 0.05623);
  // Its usable stretch (monotone, 0-3 m) lies in that bracket and holds 5-200 cm.
  EXPECT_GE(m.impl().ratio_min, 0.35);
  EXPECT_LE(m.impl().ratio_max, 0.85);
  EXPECT_LT(m.impl().ratio_min, 0.5);
  EXPECT_GT(m.impl().ratio_max, 0.78);
  // The public driver's own formula at k = 0.6, t = 42.0 degC.
  const double k = 0.6;
  double cm = 0.0;
  for (double c : poly) cm = cm * k + c;
  cm += (440 - 420) * 0.05623;
  const auto r = readout(80.0, 120.0, 100, 42.0);
  EXPECT_NEAR(m.distance_m(r), cm / 100.0, 1e-9);
  // Survives its own YAML.
  const auto back = tl::CalibrationModel::from_yaml(m.to_yaml(), "k.yaml");
  EXPECT_EQ(back.distance_m(r), m.distance_m(r));
}

TEST(CalibrationModel, DocsExampleReadsAsWritten) {
  // docs/calibration.md section 7, as a user would write it.
  const auto model = tl::CalibrationModel::from_yaml(kMinimal, "calib.yaml");
  tl::Readout r{.a = 120.5, .b = 60.2, .pulses = 400, .temperature_c = 41.3, .pixel = 136, .t_s = 12.0, .extra = {}};
  EXPECT_TRUE(model.extra_covariates().empty());
  const double d = model.distance_m(r);
  const auto ev = model.evaluate(r);
  EXPECT_EQ(ev.status, tl::CalibrationEvaluation::Status::kValid);
  EXPECT_DOUBLE_EQ(d, ev.distance_m);
  EXPECT_TRUE(std::isnan(ev.albedo));  // no amplitude reference in this model
  EXPECT_EQ(tl::to_string(ev.status), "valid");
}

TEST(CalibrationModel, NonFiniteInputsNeverGiveAValidNaN) {
  const auto m = simple_model();
  using S = tl::CalibrationEvaluation::Status;
  const double nan = std::nan("");
  const double inf = std::numeric_limits<double>::infinity();
  for (double a : {nan, inf, -inf, 0.0, -5.0, 120.0}) {
    for (double b : {nan, inf, -inf, 0.0, -5.0, 60.0}) {
      for (int pulses : {0, -10, 100}) {
        auto r = readout(a, b, pulses);
        const auto ev = m.evaluate(r);
        if (ev.status == S::kValid || ev.status == S::kMissingCovariate) {
          EXPECT_TRUE(std::isfinite(ev.distance_m)) << a << " " << b << " " << pulses;
        } else {
          EXPECT_TRUE(std::isnan(ev.distance_m));
        }
      }
    }
  }
  auto r = readout(120, 60);
  r.temperature_c = nan;
  const auto ev = m.evaluate(r);
  EXPECT_EQ(ev.status, S::kMissingCovariate);
  EXPECT_DOUBLE_EQ(ev.distance_m, m.distance_m(readout(120, 60, 100, 48.0)));  // at the reference temperature
  r = readout(120, 60);
  r.pixel = 999;  // out of range: the common Rsen
  EXPECT_TRUE(std::isfinite(m.distance_m(r)));
}

// Regression: range_margin 1e300 switched the out-of-range check off.
TEST(CalibrationYaml, ARangeMarginBeyondTheFittedRangeIsRefused) {
  EXPECT_THAT(expect_load_error(minimal("ratio",
                                        "ratio: {sensitivity_ratio: 1, leakage_offset: 0, leakage_per_pulse: "
                                        "0, range: [0, 1], range_margin: 1e300}\n")),
              HasSubstr("field 'ratio.range_margin': must be 0-1"));
}

// SPDX-License-Identifier: Apache-2.0
// The loop on the real sensor's measurements (measured.hpp, `calib measured`):
// the package's copy of the measured figures loads, every analysis runs on it,
// the accepted explanations beat the declared model out of sample, and bad
// files get errors naming the file, line and field.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/measured.hpp>
#include <tiny_laser_calibration/tool.hpp>
#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/calibration_impl.hpp>

namespace fs = std::filesystem;
namespace cal = tinyline::tiny_laser_calibration;
namespace tl = tinyline::tiny_laser_driver;
using ::testing::HasSubstr;

namespace {

const std::string kMeasured = std::string(TINYLINE_SOURCE_DIR) + "/tiny_laser_calibration/data/measured.yaml";

std::string file_text(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A read-out the model reads as `distance_m` (bisection on k = b / (a + b)) whose light per pulse is q times
// the reference's 1 charge_unit: pulses chosen so that a + b is near 150 charge_unit.
tl::Readout readout_reading(const tl::CalibrationModel& model, double distance_m, double q, double temperature_c) {
  tl::Readout r;
  r.temperature_c = temperature_c;
  r.pulses = std::clamp(static_cast<int>(std::lround(150.0 / q)), 20, 700);
  const double sum = q * r.pulses;
  const auto& m = model.impl();
  double lo = m.ratio_min, hi = m.ratio_max;
  for (int i = 0; i < 100; ++i) {
    const double k = 0.5 * (lo + hi);
    r.b = k * sum;
    r.a = sum - r.b;
    (model.evaluate(r).declared_distance_m < distance_m ? lo : hi) = k;
  }
  return r;
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

const cal::EffectHypothesis& form_of(const cal::MaterialAnalysis& a, const std::string& form) {
  for (const auto& h : a.hypotheses) {
    if (h.form == form) return h;
  }
  throw std::runtime_error("no hypothesis " + form);
}

// The goal: every surface other than the calibration target predicted from
// the others (the form re-fitted without it) to 0.3 cm RMS, by a form the
// physics allows, chosen out of sample with a size penalty.
TEST(CalibrationMeasured, Table32BiasIsExplainedToTheGoalOutOfSample) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto a = cal::analyse_materials(d);
  // Before: each surface's bias beyond white paper's own (30.0705 cm).
  double s = 0.0;
  for (const auto& m : d.table32) s += std::pow(m.mean_cm - 30.0705, 2);
  EXPECT_NEAR(a.before_rmse_cm, std::sqrt(s / 8.0), 1e-9);
  ASSERT_GE(a.best, 0);
  const auto& best = a.hypotheses[static_cast<std::size_t>(a.best)];
  EXPECT_LE(best.loo_rmse_cm, 0.3) << best.form;
  EXPECT_EQ(best.form, "bias = c1 ln q + c2 ln^2 q");
  // No surface, IC foam (q = 0.08, an extrapolation) included, left further than 0.3 cm.
  for (std::size_t i = 0; i < d.table32.size(); ++i) {
    if (std::isfinite(best.loo_residual_cm[i])) {
      EXPECT_LT(std::abs(best.loo_residual_cm[i]), 0.3) << d.table32[i].name;
    }
  }
  // The straight walk it nests does not reach the goal, and the cubic one is not worth its size.
  EXPECT_GT(form_of(a, "bias = c ln q").loo_rmse_cm, 1.0);
  EXPECT_GT(form_of(a, "bias = c1 ln q + c2 ln^2 q + c3 ln^3 q").score_cm, best.score_cm);
  // Charge trapping fits the table in sample but predicts IC foam from the others badly.
  const auto& trap = form_of(a, "bias = D (eps/(q+eps) - eps/(1+eps))");
  EXPECT_LT(trap.in_sample_rmse_cm, 0.35);
  EXPECT_GT(trap.loo_rmse_cm, 1.0);
  EXPECT_FALSE(a.drivers.empty());  // the choice rests on a few surfaces, and the report names them
  for (const auto& h : a.hypotheses) {
    EXPECT_EQ(h.loo_residual_cm.size(), 9u);
    EXPECT_FALSE(h.reading.empty());
  }
  // The charge slope at 30 cm comes from the real curves: k between 0 and 1, L rising.
  EXPECT_GT(a.slope.ratio, 0.0);
  EXPECT_LT(a.slope.ratio, 1.0);
  EXPECT_GT(a.slope.cm_per_unit_ratio, 0.0);
}

// The chosen walk as the driver applies it: Table 3.2's surfaces at 30 cm, as
// read-outs of real sensor R's curve that read each surface's measured mean,
// with that surface's light per pulse relative to the calibration target's.
// After the term every surface reads white paper's distance.
TEST(CalibrationMeasured, TheDriverAppliesTheWalkSoDarkAndBrightSurfacesReadOneDistance) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto a = cal::analyse_materials(d);
  const auto& r = d.sensors[0];
  auto model = tl::CalibrationModel::from_public_driver(r.poly, r.offsets, r.stable_temperature_decic,
                                                        r.temperature_sensi_cm_per_decic);
  model.impl().amplitude_reference.knots_m = {0.05, 2.0};
  model.impl().amplitude_reference.log_amplitude = {0.0, 0.0};  // 1 charge_unit per pulse from the target
  const tl::CalibrationModel before = model;
  model.impl().terms.push_back(cal::material_walk_term(a));
  model.impl().resolve();
  const auto loaded = tl::CalibrationModel::from_yaml(model.to_yaml(), "walk.yaml");
  const double white_reflectance = d.table32.front().reflectance;
  double before_ss = 0.0, after_ss = 0.0;
  for (const auto& m : d.table32) {
    const double q = m.reflectance / white_reflectance;
    const auto ro = readout_reading(before, m.mean_cm / 100.0, q, 10.0 * r.stable_temperature_decic / 100.0);
    ASSERT_NEAR(before.distance_m(ro), m.mean_cm / 100.0, 1e-6) << m.name;
    const double after = loaded.distance_m(ro);
    before_ss += std::pow(m.mean_cm - 30.0705, 2);
    after_ss += std::pow(100.0 * after - 30.0705, 2);
    EXPECT_NEAR(100.0 * after, 30.0705, 0.3) << m.name;
  }
  EXPECT_NEAR(std::sqrt(before_ss / 8.0), a.before_rmse_cm, 1e-6);
  EXPECT_LT(std::sqrt(after_ss / 8.0), 0.2);  // in sample: the term fitted on all nine
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

// Scored held out by blocks of distance (each fifth of the curve predicted
// from the other four), not in sample, where a nested model cannot lose.
TEST(CalibrationMeasured, EachRealCurveIsHeldAgainstTheDeclaredPhysicalModel) {
  const auto d = cal::load_measured_data(kMeasured);
  const auto cs = cal::analyse_curves(d);
  ASSERT_EQ(cs.size(), 5u);
  for (const auto& c : cs) {
    ASSERT_EQ(c.models.size(), 3u) << c.sensor;
    EXPECT_LT(c.k_min, c.k_max);
    for (const auto& m : c.models) {
      EXPECT_GT(m.loo_rmse_cm, m.in_sample_rmse_cm) << c.sensor << " " << m.form;  // extrapolating costs
    }
    ASSERT_GE(c.best, 0) << c.sensor;
    for (const auto& m : c.models) EXPECT_LE(c.models[static_cast<std::size_t>(c.best)].loo_rmse_cm, m.loo_rmse_cm);
    EXPECT_GT(c.effective_pulse_ns, 0.0) << c.sensor;
  }
  // R, J and T: the pulse shape predicts the left-out distances at least 10 % better than Eq. 3.16, but
  // only with Rsen and the tilt on their bounds, which the report says; K: the added effects do not
  // predict better held out, and the declared model stays.
  for (std::size_t i : {0u, 1u, 4u}) {
    const auto& c = cs[i];
    EXPECT_EQ(c.best, 2) << c.sensor;
    EXPECT_LT(c.models[2].loo_rmse_cm, 0.9 * c.models[0].loo_rmse_cm) << c.sensor;
    EXPECT_THAT(c.models[2].bound, HasSubstr("on its bound")) << c.sensor;
    EXPECT_THAT(c.models[2].reading, HasSubstr("on its bound")) << c.sensor;
  }
  EXPECT_EQ(cs[3].sensor, "K");
  EXPECT_EQ(cs[3].best, 0);
  // No curve is the declared model to its noise: the best held-out error is still 0.8 cm or more.
  for (const auto& c : cs) EXPECT_GT(c.models[static_cast<std::size_t>(c.best)].loo_rmse_cm, 0.8) << c.sensor;
  // R: 0.09623 cm per 0.1 degC is 2 * 0.9623 cm / c = 64.2 ps per degC.
  EXPECT_NEAR(cs[0].delay_drift_ps_per_c, 64.2, 0.1);
}

TEST(CalibrationMeasured, TheWalkIsAppliedOnlyToACalibrationThatCanComputeTheLight) {
  const fs::path dir = fs::temp_directory_path() / "tinyline_calib_measured_apply";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto d = cal::load_measured_data(kMeasured);
  const auto& r = d.sensors[0];
  auto model = tl::CalibrationModel::from_public_driver(r.poly, r.offsets, r.stable_temperature_decic,
                                                        r.temperature_sensi_cm_per_decic);
  model.save((dir / "no_reference.yaml").string());
  cal::CalibToolEnv env;
  env.measured_data = kMeasured;
  std::ostringstream out, err;
  EXPECT_EQ(cal::run_calib_command(
                {"measured", "--apply", (dir / "no_reference.yaml").string(), "-o", (dir / "out.yaml").string()}, out,
                err, env),
            1);
  EXPECT_THAT(err.str(), HasSubstr("no amplitude_reference"));
  EXPECT_FALSE(fs::exists(dir / "out.yaml"));
  model.impl().amplitude_reference.knots_m = {0.05, 2.0};
  model.impl().amplitude_reference.log_amplitude = {0.0, 0.0};
  model.save((dir / "calib.yaml").string());
  ASSERT_EQ(
      cal::run_calib_command({"measured", "--apply", (dir / "calib.yaml").string(), "-o", (dir / "out.yaml").string()},
                             out, err, env),
      0)
      << err.str();
  const auto loaded = tl::CalibrationModel::load((dir / "out.yaml").string());
  ASSERT_EQ(loaded.impl().terms.size(), 1u);
  EXPECT_EQ(loaded.impl().terms[0].form, tl::TermForm::kLightWalk);
  // Malformed walk terms are refused with the field named.
  std::string y = file_text((dir / "out.yaml").string());
  auto refused = [](const std::string& text) {
    try {
      (void)tl::CalibrationModel::from_yaml(text, "w.yaml");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const auto ref = y.find("    reference: 1");
  ASSERT_NE(ref, std::string::npos);
  std::string bad = y;
  bad.replace(ref, 16, "    reference: 0");
  EXPECT_THAT(refused(bad), HasSubstr("terms[0].reference"));
  bad = y;
  bad.erase(ref, y.find('\n', ref) - ref + 1);
  EXPECT_THAT(refused(bad), HasSubstr("reference"));
  fs::remove_all(dir);
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
  // The curves' columns say which residuals are held out (by blocks of distance) and which are in sample.
  const std::string curves = file_text((dir / "measured_curves.csv").string());
  EXPECT_EQ(curves.substr(0, curves.find('\n')),
            "sensor,k,l_cm,declared_heldout_residual_cm,best_heldout_residual_cm,best_in_sample_residual_cm");
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

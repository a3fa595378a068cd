// SPDX-License-Identifier: Apache-2.0
// The residual loop on data from the simulator (sim/), with its
// pluggable effects (sim/effects.hpp) configured per sensor instance: the
// declared-physics sensor (sim/config/sensors/tiny_tof_declared.yaml) plus one
// undeclared effect at a time, on the simulated calibration rail
// (sim::CalibrationRail), fitted as the thesis did: leakage and Rsen measured
// apart first (3.3.3). Each test asserts that the effect is named and that the
// held-out error after its term is within 20% of the simulator's noise floor:
// the held-out error of the declared model on the same rail, same seeds, with
// the effect switched off (on white paper that twin must name nothing: the
// null case).
//
// Every 8th effective pixel, one set per rail visit, 38 positions visited
// twice (the material cases: 27 positions x 7 surfaces): about a second per
// test. The loop's power comes from the target distances and the sets, not
// from the pixel count. Every test passes for rail seeds 1-8 (checked when the
// tests were written; 7 is the one kept).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sim/rail.hpp>
#include <sim/sensor_params.hpp>
#include <tiny_laser_calibration/discovery.hpp>

#include "sim_discovery_cases.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace sim = tinyline::sim;
namespace tt = tinyline::tiny_laser_calibration::testing;
using ::testing::HasSubstr;

namespace {

using tt::declared_sensor;
using tt::RailPlan;

cal::CalibrationDataset simulate(const sim::SensorParams& params, const RailPlan& plan) {
  return tt::simulate_rail(params, plan);
}

// Table 3.2's matte surfaces and their mean reading at 30 cm [cm].
const std::vector<std::pair<std::string, double>> kTable32MatteCm = {
    {"white_paper", 30.0705}, {"black_cushion", 30.7909}, {"cloth_bag", 30.9971}, {"styrofoam", 30.9759},
    {"white_towel", 30.3708}, {"cardboard", 31.0308},     {"ic_foam", 39.8339}};

// Every rail position visited once per matte surface, 0.15-0.8 m (Table 3.2 is at
// 0.3 m; IC foam is too dark to range much further).
RailPlan matte_surfaces_plan() {
  RailPlan plan;
  plan.materials.clear();
  for (const auto& [m, cm] : kTable32MatteCm) plan.materials.push_back(m);
  plan.visits = static_cast<int>(plan.materials.size());
  plan.to_m = 0.8;
  plan.step_m = 0.025;
  return plan;
}

// Leakage and Rsen measured apart, as the thesis did (sim_rail_session.hpp).
cal::DiscoveryParams measured_constants(const sim::SensorParams& params) {
  const auto c = tt::measure_rail_constants(params);
  cal::DiscoveryParams p;
  p.declared.fit_leakage = false;
  p.declared.leakage_offset = 0.0;
  p.declared.leakage_per_pulse = c.leakage_per_pulse;
  p.declared.sensitivity_ratio = c.sensitivity_ratio;
  return p;
}

std::string named(const cal::DiscoveryResult& r) {
  std::string s;
  for (const auto& e : r.effects) s += e.covariate + "/" + std::string(tl::to_string(e.form)) + " ";
  return s.empty() ? "(none)" : s;
}

struct Outcome {
  cal::DiscoveryResult result;
  double floor_m = 0.0;  ///< held-out RMSE of the declared model on the effect-free twin
};

// The sensor with `effect`, and its twin without it (the noise floor; names nothing).
Outcome run(const sim::EffectSpec& effect, const RailPlan& plan, bool twin_must_be_null = true) {
  Outcome o;
  sim::SensorParams with = declared_sensor();
  with.effects.push_back(effect);
  o.result = cal::discover_effects(simulate(with, plan), measured_constants(with));
  const auto null = cal::discover_effects(simulate(declared_sensor(), plan), measured_constants(declared_sensor()));
  EXPECT_TRUE(null.status.ok()) << null.status.message;
  if (twin_must_be_null) {
    EXPECT_TRUE(null.effects.empty()) << "the effect-free twin names " << named(null);
  }
  o.floor_m = null.rmse_before_m;
  std::printf("%s: held-out RMSE %.2f cm -> %.2f cm, noise floor %.2f cm, named %s (twin: %s)\n",
              sim::effect_type(effect), 100 * o.result.rmse_before_m, 100 * o.result.rmse_after_m, 100 * o.floor_m,
              named(o.result).c_str(), named(null).c_str());
  return o;
}

void expect_named_and_at_floor(const Outcome& o, const std::string& covariate) {
  const auto& r = o.result;
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  ASSERT_FALSE(r.effects.empty()) << "nothing named";
  EXPECT_EQ(r.effects.front().covariate, covariate) << named(r);
  EXPECT_LT(r.rmse_after_m, 1.2 * o.floor_m)
      << "held-out error after " << r.rmse_after_m << " m, noise floor " << o.floor_m << " m";
  EXPECT_GT(r.rmse_before_m, 1.2 * o.floor_m) << "the injected effect is too small to matter";
  if (!r.effects.front().written) return;  // a time-since-power-on term one session cannot confirm
  ASSERT_FALSE(r.model.impl().terms.empty());
  EXPECT_EQ(r.model.impl().terms.front().covariate, covariate);
}

// One case of sim_discovery_cases.cpp at the tests' seed: named, and the
// held-out error after within 20 % of the effect-free twin's.
tt::CaseOutcome expect_case(const std::string& name) {
  const auto& c = tt::discovery_case(name);
  auto o = tt::run_case(c, 7);
  std::printf("%s: held-out RMSE %.2f cm -> %.2f cm, noise floor %.2f cm, named %s (twin: %zu effects)\n", name.c_str(),
              100 * o.result.rmse_before_m, 100 * o.result.rmse_after_m, 100 * o.floor_m, o.names().c_str(),
              o.twin.effects.size());
  for (const auto& e : o.twin.effects)
    std::printf("  twin: %s %s: %s\n", e.covariate.c_str(), tl::to_string(e.form).data(), e.reading.c_str());
  for (const auto& e : o.result.effects)
    std::printf("  %s %s: %s\n", e.covariate.c_str(), tl::to_string(e.form).data(), e.reading.c_str());
  // The strongest candidates of each round and the bar they had to clear: why a case names what it names.
  for (std::size_t k = 0; k < o.result.rounds.size(); ++k) {
    std::printf("  round %zu (z > %.2f in round 0):", k, o.result.z_threshold);
    for (std::size_t j = 0; j < std::min<std::size_t>(4, o.result.rounds[k].size()); ++j) {
      const auto& sc = o.result.rounds[k][j];
      std::printf(" %s/%s gain %.3f z %.1f;", sc.covariate.c_str(), tl::to_string(sc.form).data(), sc.gain, sc.z);
    }
    std::printf("\n");
  }
  EXPECT_TRUE(o.result.status.ok()) << o.result.status.message;
  if (!o.result.status.ok()) return o;
  EXPECT_TRUE(o.named) << "named " << o.names();
  EXPECT_LT(o.result.rmse_after_m, 1.2 * o.floor_m);
  EXPECT_GT(o.result.rmse_before_m, c.min_before_over_floor * o.floor_m)
      << "the injected effect is too small to matter";
  if (c.twin_must_be_null) {
    EXPECT_TRUE(o.twin.effects.empty()) << "the effect-free twin names something";
  }
  if (!o.result.effects.empty()) {
    EXPECT_FALSE(o.result.effects.front().reading.empty());
  }
  return o;
}

}  // namespace

TEST(CalibrationSimDiscovery, NullCaseNamesNothingAndKeepsTheError) {
  RailPlan plan;
  // A measured column with no effect (a covariate effect of zero strength): a distractor.
  sim::CovariateEffect humidity;
  humidity.ns_per_unit = 0.0;
  plan.extra_columns = {humidity.name};
  sim::SensorParams s = declared_sensor();
  s.effects.push_back(humidity);
  const auto r = cal::discover_effects(simulate(s, plan), measured_constants(s));
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_TRUE(r.effects.empty()) << named(r);
  EXPECT_EQ(r.rmse_after_m, r.rmse_before_m);
  EXPECT_TRUE(r.model.impl().terms.empty());
  EXPECT_THAT(r.candidates, ::testing::Contains("humidity_pct"));
  EXPECT_THAT(r.candidates, ::testing::Contains("pixel"));
  ASSERT_FALSE(r.rounds.empty());
  for (const auto& c : r.rounds[0]) EXPECT_FALSE(c.passes) << c.covariate << " " << tl::to_string(c.form);
  std::printf("null: held-out RMSE %.2f cm, %zu candidates scored\n", 100 * r.rmse_before_m, r.rounds[0].size());
}

TEST(CalibrationSimDiscovery, MaterialBiasOfTable32IsNamed) {
  // Table 3.2: calibrated on white paper at 30.07 cm,
  // other surfaces read up to +9.8 cm long (IC foam). As subsurface path per material
  // (a range offset is half the extra optical path). The driver cannot know the
  // material, so the term must follow what it can measure: the surface's albedo.
  // The matte surfaces only: the simulated metals return a specular lobe, so their
  // albedo changes across the line by a factor of ten while their offset does not,
  // and no function of albedo can be both (a per-material term needs the material).
  sim::MaterialBiasEffect bias;
  const RailPlan plan = matte_surfaces_plan();
  for (const auto& [m, cm] : kTable32MatteCm) bias.path_mm[m] = 2.0 * 10.0 * (cm - 30.0705);
  // The effect-free twin may name an amplitude term of its own: the charge ratio of a
  // dim read-out is a biased estimate (a ratio of noisy charges), which the declared
  // model does not represent and dark surfaces expose.
  const auto o = run(bias, plan, /*twin_must_be_null=*/false);
  expect_named_and_at_floor(o, "albedo");
  EXPECT_GT(o.result.rmse_before_m, 1.8 * o.floor_m);
}

TEST(CalibrationSimDiscovery, TimeDriftIsNamed) {
  // A delay drift with time since power-on that the MCU temperature does not see: a
  // slow oscillation (a linear drift during the warm-up is mostly absorbed by the
  // declared temperature offset, which rises with time too).
  sim::TimeDriftEffect drift;
  drift.ns_per_hour = 1.0;
  drift.sine_amplitude_ns = 0.3;  // +-4.5 cm
  drift.sine_period_s = 600.0;
  RailPlan plan;
  // From power-on, a 912 s session. During the warm-up (time constant 120 s) the
  // temperature is a monotonic function of time, so a drift then is also a function of
  // temperature; the warm two thirds of the session tell the two apart.
  plan.set_period_s = 12.0;
  const auto o = run(drift, plan);
  expect_named_and_at_floor(o, "t_s");
}

TEST(CalibrationSimDiscovery, MeasuredCovariateColumnIsNamed) {
  // A covariate measured alongside (its own CSV column) that shifts the timing.
  sim::CovariateEffect humidity;
  humidity.ns_per_unit = 0.02;  // +-0.3 ns over the +-15 % swing: +-4.5 cm
  humidity.period_s = 30.0;     // faster than a smooth function of time over the session can follow
  humidity.random_walk_per_sqrt_s = 0.5;
  RailPlan plan;
  plan.extra_columns = {humidity.name};
  const auto o = run(humidity, plan);
  // Named by its column; the form may be the distance smooth (a delay) or a gain on A: a small delay moves charge
  // from A to B in proportion to the signal, which a gain of A mimics.
  expect_named_and_at_floor(o, "humidity_pct");
}

TEST(CalibrationSimDiscovery, RangeWalkIsNamedAsAnAmplitudeEffect) {
  // Amplitude-dependent timing (range walk). On one surface the amplitude follows the
  // distance and the polynomial absorbs the walk; surfaces of different albedo expose it.
  sim::RangeWalkEffect walk;
  walk.ns_per_decade = 0.4;
  const auto o = run(walk, matte_surfaces_plan(), /*twin_must_be_null=*/false);
  const auto& r = o.result;
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  ASSERT_FALSE(r.effects.empty()) << "nothing named";
  EXPECT_THAT(r.effects.front().covariate,
              ::testing::AnyOf("amplitude_per_pulse", "amplitude", "reflectance", "albedo", "pulses"))
      << named(r);
  EXPECT_LT(r.rmse_after_m, 1.2 * o.floor_m);
  EXPECT_GT(r.rmse_before_m, 1.2 * o.floor_m);
}

TEST(CalibrationSimDiscovery, FixedPatternGateSkewIsAbsorbedByThePerPixelSensitivityRatio) {
  // A per-pixel gate skew moves charge between the gates of that pixel: to first
  // order a per-pixel change of the charge ratio, which the declared model's per-pixel
  // Rsen (Eq. 3.16) already absorbs. Nothing is left to name; the error stays at the floor.
  sim::FixedPatternEffect skew;
  skew.sigma_ps = 200.0;  // 3 cm per pixel
  const auto o = run(skew, RailPlan{});
  ASSERT_TRUE(o.result.status.ok()) << o.result.status.message;
  EXPECT_TRUE(o.result.effects.empty()) << named(o.result);
  EXPECT_LT(o.result.rmse_before_m, 1.2 * o.floor_m);
  // With one Rsen for every pixel the skew is left over, and the loop names the pixel.
  sim::SensorParams with = declared_sensor();
  with.effects.push_back(skew);
  cal::DiscoveryParams p = measured_constants(with);
  p.declared.sensitivity_ratio_mode = cal::SensitivityRatioMode::kFixed;
  const auto fixed = cal::discover_effects(simulate(with, RailPlan{}), p);
  ASSERT_TRUE(fixed.status.ok()) << fixed.status.message;
  ASSERT_FALSE(fixed.effects.empty());
  EXPECT_EQ(fixed.effects.front().covariate, "pixel") << named(fixed);
  EXPECT_EQ(fixed.effects.front().form, tl::TermForm::kTable);
}

// --- effects where the physics puts them: on the charges, the pixels, the timing with a lag

TEST(CalibrationSimDiscovery, AmbientLightOnBothCapacitorsIsNamedOnTheCharges) { expect_case("ambient_light"); }

// Two warm-ups from different ambient temperatures: the only data that can tell a
// lagged temperature from the time since power-on (sim_discovery_cases.cpp).
TEST(CalibrationSimDiscovery, DelayFollowingALaggedTemperatureIsNamed) { expect_case("temperature_lag"); }

// A gain on capacitor A of pixel 176 (the published firmware's hand-made factor), found
// from the data on a rail of two surfaces (sim_discovery_cases.cpp says why two): named as
// a gain of A, or of B by the inverse factor (the ratio cannot tell the two apart).
TEST(CalibrationSimDiscovery, AGainOnOnePixelsCapacitorIsFoundFromTheData) { expect_case("odd_pixel_gain"); }

// A charge per pulse on capacitor B of pixels 136-199, on a sensor with one Rsen (a
// per-pixel Rsen half absorbs it): named as a charge on B per pulse over a bank of
// pixels, the bank's own pixels standing out from the others in the fitted values.
TEST(CalibrationSimDiscovery, ExtraLeakageOfOneCapacitorInABankOfPixelsIsNamed) {
  const auto o = expect_case("group_leakage");
  ASSERT_FALSE(o.result.effects.empty());
  EXPECT_EQ(o.result.effects.front().form, tl::TermForm::kChargeBPerPulse);
  const auto& terms = o.result.model.impl().terms;
  ASSERT_FALSE(terms.empty());
  const auto& t = terms.front();
  const int bank = tl::covariate_parameter(t.covariate);
  ASSERT_GT(bank, 0) << t.covariate;
  // Every group inside 136-199 reads more charge than every group outside it (by at
  // least half the injected 0.03 charge_unit per pulse).
  double inside = 1e9, outside = -1e9;
  for (std::size_t g = 0; g < t.knots.size(); ++g) {
    const int first = 8 + static_cast<int>(t.knots[g]) * bank, last = first + bank - 1;
    if (first >= 136 && last <= 199) inside = std::min(inside, t.values[g]);
    if (last < 136 || first > 199) outside = std::max(outside, t.values[g]);
  }
  EXPECT_GT(inside - outside, 0.015) << o.result.effects.front().reading;
}

// Not yet met (disabled so `make test` stays green; run with --gtest_also_run_disabled_tests).
// At seed 7 the loop names today:
//  - readout_nonlinearity: the declared fit survives (the simulator saturates before the
//    transfer curve, the ceiling comes from the data's plateau): 2.99 -> 2.14 cm against a
//    2.62 cm floor, but named as ratio x amplitude (a distance form, gain 0.376, z 4.7) ahead
//    of charge/readout (gain 0.357, z 3.7, under the bar of 3.91), and 30 % compression now
//    moves the driver's read-outs less than 1.2 x the floor;
//  - channel_offset: nothing (3.42 cm against a 2.62 cm floor; one/charge_a gain 0.308, z 3.2):
//    the constant charge shows on the low-pulse read-outs the driver does not choose, which
//    the loop does not score.

TEST(CalibrationSimDiscovery, DISABLED_ReadOutNonlinearityIsNamedOnTheCharges) { expect_case("readout_nonlinearity"); }

TEST(CalibrationSimDiscovery, DISABLED_ChannelOffsetIsNamedOnCapacitorB) { expect_case("channel_offset"); }

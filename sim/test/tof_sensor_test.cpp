// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <sstream>

#include <sim/fidelity.hpp>
#include <sim/rail.hpp>
#include <sim/tof_sensor.hpp>

using namespace tinyline::sim;

namespace {

constexpr int kCentre = 136;
const std::vector<int> kRaw{20, 100, 200, 400, 700};

double ratio(const PulseCharges& pc, int i) {
  const auto k = static_cast<std::size_t>(i);
  return pc.qb[k] / (pc.qa[k] + pc.qb[k]);
}

double intensity(const PulseCharges& pc, int i) {
  const auto k = static_cast<std::size_t>(i);
  return pc.qa[k] + pc.qb[k];
}

PulseCharges charges_at(CalibrationRail& rail, double d, double t_s = 3600.0) {
  rail.set_target_distance(d);
  return rail.sensor().pulse_charges(rail.world(), rail.T_world_sensor(), t_s);
}

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

}  // namespace

TEST(TofSensor, PixelGeometryFollowsLensAndLine) {
  SensorParams p;
  p.lens.focal_mm = 8.0;
  const TofLineSensor s(p);
  EXPECT_EQ(s.pixels(), 272);
  EXPECT_TRUE(s.is_dark(0));
  EXPECT_TRUE(s.is_dark(7));
  EXPECT_FALSE(s.is_dark(8));
  EXPECT_FALSE(s.is_dark(263));
  EXPECT_TRUE(s.is_dark(264));
  // Symmetric about the line's middle; the first and last effective pixels
  // look out at atan(2.55 mm / 8 mm) (pixel centres, 20 um pitch).
  EXPECT_NEAR(s.pixel_angle_rad(135), -s.pixel_angle_rad(136), 1e-12);
  EXPECT_NEAR(s.pixel_angle_rad(263), std::atan(2.55 / 8.0), 1e-9);
  EXPECT_NEAR(s.pixel_angle_rad(8), -std::atan(2.55 / 8.0), 1e-9);
  EXPECT_GT(s.pixel_angle_rad(200), s.pixel_angle_rad(100));  // +x for higher indices
  EXPECT_NEAR(s.pixel_direction(136).norm(), 1.0, 1e-12);
}

TEST(TofSensor, RatioRisesWithDistanceAndEnergyFallsAsInverseSquare) {
  SensorParams p;
  p.effects.clear();
  CalibrationRail rail(p);
  double prev = -1.0;
  for (double d = 0.05; d <= 2.5; d += 0.05) {
    const double x = ratio(charges_at(rail, d), kCentre);
    EXPECT_GT(x, prev) << d;
    prev = x;
  }
  const double i1 = intensity(charges_at(rail, 0.5), kCentre), i2 = intensity(charges_at(rail, 1.0), kCentre);
  EXPECT_NEAR(i1 / i2, 4.0, 0.05);
  // Radiometric anchor: white paper at 30 cm gives Table 3.2's 6.92 per pulse (within the pixel's PRNU).
  EXPECT_NEAR(intensity(charges_at(rail, 0.3), kCentre), kWhitePaperFigure, 0.5);
}

TEST(TofSensor, AlbedoAndIncidenceScaleTheReturn) {
  SensorParams p;
  p.effects.clear();
  CalibrationRail paper(p), foam(p, RailParams{"ic_foam"});
  const double ip = intensity(charges_at(paper, 0.3), kCentre), ifoam = intensity(charges_at(foam, 0.3), kCentre);
  EXPECT_NEAR(ifoam / ip, 0.5699 / 6.92, 0.01);
  // A tilted Lambertian target returns cos(incidence) less.
  World w;
  Eigen::Isometry3d T = at(0, 0, 0.5);
  T.linear() = Eigen::AngleAxisd(M_PI / 3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  w.add({"tilted", PlaneShape{}, T, *w.materials().find("white_paper")});
  const TofLineSensor s(p);
  std::vector<PixelTruth> truth;
  const auto pc = s.pulse_charges(w, Eigen::Isometry3d::Identity(), 3600, &truth);
  EXPECT_NEAR(truth[kCentre].incidence_rad, M_PI / 3, 0.01);
  EXPECT_NEAR(intensity(pc, kCentre) / ip, 0.5 * (0.3 * 0.3) / (truth[kCentre].range_m * truth[kCentre].range_m), 0.05);
}

TEST(TofSensor, SameSeedAndIndexGiveTheSameSet) {
  CalibrationRail rail(SensorParams{});
  rail.set_target_distance(0.6);
  const SensorSet a = rail.measure(100.0, kRaw, 7), b = rail.measure(100.0, kRaw, 7), c = rail.measure(100.0, kRaw, 8);
  ASSERT_EQ(a.readouts.size(), 5u);
  EXPECT_EQ(a.readouts[3].a, b.readouts[3].a);
  EXPECT_EQ(a.readouts[3].b, b.readouts[3].b);
  EXPECT_EQ(a.temperature_c, b.temperature_c);
  EXPECT_NE(a.readouts[3].a, c.readouts[3].a);
  SensorParams other;
  other.seed = 2;
  CalibrationRail rail2(other);
  rail2.set_target_distance(0.6);
  EXPECT_NE(rail2.measure(100.0, kRaw, 7).readouts[3].a, a.readouts[3].a);
}

TEST(TofSensor, ReadoutsAreQuantisedSaturateAndGrowWithPulses) {
  CalibrationRail rail(SensorParams{});
  rail.set_target_distance(0.2);  // bright: the long read-outs saturate
  const SensorSet s = rail.measure(3600.0, kRaw, 1);
  const auto& px = rail.sensor().params().pixel;
  for (const auto& r : s.readouts) {
    for (std::size_t i = 0; i < r.a.size(); ++i) {
      EXPECT_LE(r.a[i], px.full_scale + 1e-9);
      EXPECT_LE(r.b[i], px.full_scale + 1e-9);
      EXPECT_NEAR(std::round(r.a[i] * 10.0), r.a[i] * 10.0, 1e-6);  // 0.1 charge-unit steps
    }
  }
  const auto i = static_cast<std::size_t>(kCentre);
  EXPECT_LT(s.readouts[0].a[i], s.readouts[1].a[i]);
  EXPECT_GT(s.readouts[4].b[i], 230.0);      // saturated at 700 pulses
  EXPECT_EQ(select_readout(s, kCentre), 0);  // only the 20-pulse read-out is usable
  EXPECT_NEAR(s.t_end_s - s.t_start_s, 700.0 / rail.sensor().params().emitter.pulse_rate_hz, 1e-12);
}

TEST(TofSensor, DarkSetsShowLeakageAndSensitivityRatio) {
  SensorParams p;
  p.environment.ambient_charge_per_pulse = 0.0;
  p.pixel.adc_offset_a = 0.0;
  p.pixel.adc_offset_b = 0.0;
  CalibrationRail rail(p);
  MeasureOptions off;
  off.laser_on = false;
  off.noise = false;
  const SensorSet s = rail.measure(3600.0, std::vector<int>{500}, 1, off);
  const auto i = static_cast<std::size_t>(kCentre);
  const double t_ms = 1e3 * 500 / p.emitter.pulse_rate_hz;
  EXPECT_NEAR(s.readouts[0].b[i], rail.sensor().leakage_per_ms(kCentre) * t_ms, 1e-9);
  EXPECT_NEAR(s.readouts[0].a[i] * rail.sensor().sensitivity_ratio(kCentre), s.readouts[0].b[i], 1e-9);
  // Pixels differ: R_sen has a spread.
  EXPECT_NE(rail.sensor().sensitivity_ratio(100), rail.sensor().sensitivity_ratio(101));
  // A channel offset is constant: it does not grow with the pulses.
  p.pixel.adc_offset_b = -1.5;
  CalibrationRail offset(p);
  const SensorSet o1 = offset.measure(3600.0, std::vector<int>{100, 500}, 1, off);
  EXPECT_NEAR(o1.readouts[0].b[i] - rail.measure(3600.0, std::vector<int>{100}, 1, off).readouts[0].b[i], -1.5, 1e-9);
  EXPECT_NEAR(o1.readouts[1].b[i] - s.readouts[0].b[i], -1.5, 1e-9);
}

// The capacitor saturates before its read-out's transfer curve: with more light
// the read-out rises to a plateau of full_scale (1 - nonlinearity) and stays
// there, so a saturated read-out is told by its level, never read as a dim one.
TEST(TofSensor, ReadOutNonlinearityActsAfterSaturation) {
  SensorParams p;
  p.pixel.knee = p.pixel.full_scale;  // hard saturation
  p.pixel.nonlinearity = 0.3;
  p.pixel.adc_offset_a = 0.0;
  p.pixel.adc_offset_b = 0.0;
  CalibrationRail rail(p);
  rail.set_target_distance(0.3);
  MeasureOptions clean;
  clean.noise = false;
  const std::vector<int> pulses{20, 100, 200, 400, 700, 1400, 2800};
  const SensorSet s = rail.measure(3600.0, pulses, 0, clean);
  const auto i = static_cast<std::size_t>(kCentre);
  const double top = p.pixel.full_scale * (1.0 - p.pixel.nonlinearity);
  for (std::size_t k = 1; k < pulses.size(); ++k) {
    EXPECT_GE(s.readouts[k].a[i], s.readouts[k - 1].a[i] - 1e-9) << pulses[k] << " pulses";
    EXPECT_GE(s.readouts[k].b[i], s.readouts[k - 1].b[i] - 1e-9) << pulses[k] << " pulses";
    EXPECT_LE(std::max(s.readouts[k].a[i], s.readouts[k].b[i]), top + 1e-9);
  }
  EXPECT_NEAR(std::max(s.readouts.back().a[i], s.readouts.back().b[i]), top, 1e-9);  // the plateau is reached
}

TEST(TofSensor, NoiseIsCorrelatedAcrossNonDestructiveReadouts) {
  CalibrationRail rail(SensorParams{});
  rail.set_target_distance(1.5);  // no read-out saturates
  MeasureOptions clean;
  clean.noise = false;
  const SensorSet mean = rail.measure(3600.0, kRaw, 0, clean);
  const auto i = static_cast<std::size_t>(kCentre);
  std::vector<double> e3, e4;
  for (std::uint64_t k = 1; k <= 400; ++k) {
    const SensorSet s = rail.measure(3600.0, kRaw, k);
    e3.push_back(s.readouts[3].b[i] - mean.readouts[3].b[i]);
    e4.push_back(s.readouts[4].b[i] - mean.readouts[4].b[i]);
  }
  double s33 = 0, s44 = 0, s34 = 0;
  for (std::size_t k = 0; k < e3.size(); ++k) {
    s33 += e3[k] * e3[k];
    s44 += e4[k] * e4[k];
    s34 += e3[k] * e4[k];
  }
  const double corr = s34 / std::sqrt(s33 * s44);
  EXPECT_GT(corr, 0.5);  // the 700-pulse read-out carries the 400-pulse read-out's noise
  EXPECT_GT(s44, s33);   // and adds its own
}

TEST(TofSensor, WarmUpDriftsTheDelay) {
  SensorParams p;
  p.effects.clear();
  CalibrationRail rail(p);
  rail.set_target_distance(0.3);
  const TofLineSensor& s = rail.sensor();
  EXPECT_NEAR(s.temperature_c(0.0), p.thermal.ambient_c, 1e-12);
  EXPECT_NEAR(s.temperature_c(20 * p.thermal.time_constant_s), p.thermal.warm_c, 1e-6);
  // Cold, the driver delay is shorter: the sensor reads short (Figure 3.11).
  const double cold = ratio(s.pulse_charges(rail.world(), rail.T_world_sensor(), 0.0), kCentre);
  const double warm = ratio(s.pulse_charges(rail.world(), rail.T_world_sensor(), 3600.0), kCentre);
  EXPECT_LT(cold, warm);
  // The set reports the MCU reading in 0.1 degC steps.
  const SensorSet set = rail.measure(10.0, kRaw, 3);
  EXPECT_NEAR(set.temperature_c * 10.0, std::round(set.temperature_c * 10.0), 1e-9);
  EXPECT_NEAR(set.temperature_c, s.temperature_c(set.t_end_s), 0.5);
}

TEST(TofSensor, BaselineShadowAndEmitterSideDrag) {
  // A thin stick 20 cm in front of a wall 60 cm away. The emitter sits at +x:
  // the stick's shadow on the wall falls on the -x side of the stick as the
  // receiver sees it; on the +x (emitter) side the wall is lit and the
  // blurred pixels mix stick and wall (the "distance drag" of 4.4.2).
  SensorParams p;
  p.effects.clear();
  World w;
  w.add({"wall", PlaneShape{}, at(0, 0, 0.6), *w.materials().find("wall_paint")});
  w.add({"stick", RodShape{{0, -0.2, 0.2}, {0, 0.2, 0.2}, 0.005}, Eigen::Isometry3d::Identity(),
         *w.materials().find("wood")});
  const TofLineSensor s(p);
  std::vector<PixelTruth> truth;
  const auto pc = s.pulse_charges(w, Eigen::Isometry3d::Identity(), 3600, &truth);
  int first = -1, last = -1;
  for (int i = 0; i < s.pixels(); ++i) {
    if (truth[static_cast<std::size_t>(i)].object == 1) {
      if (first < 0) first = i;
      last = i;
    }
  }
  ASSERT_GT(first, 0);
  // Wall pixels just left of the stick are in its shadow (not lit); right of it they are lit.
  int shadowed = 0;
  for (int i = first - 12; i < first; ++i) shadowed += truth[static_cast<std::size_t>(i)].lit ? 0 : 1;
  EXPECT_GE(shadowed, 3);
  EXPECT_TRUE(truth[static_cast<std::size_t>(last + 3)].lit);
  EXPECT_TRUE(truth[static_cast<std::size_t>(first - 1)].mixed || truth[static_cast<std::size_t>(first)].mixed);
  // Shadowed wall pixels get far less light than lit wall pixels at the same range.
  EXPECT_LT(intensity(pc, first - 4), 0.5 * intensity(pc, last + 15));
  // Emitter side: the pixel right after the stick reads between stick and wall.
  const double x_stick = ratio(pc, (first + last) / 2), x_wall = ratio(pc, last + 20), x_edge = ratio(pc, last + 1);
  EXPECT_GT(x_edge, x_stick + 0.1 * (x_wall - x_stick));
  EXPECT_LT(x_edge, x_wall - 0.1 * (x_wall - x_stick));
}

TEST(TofSensor, CrosstalkOnlyWhenPulsesLandInTheGates) {
  // Two sensors side by side in one plane, both looking at a wall.
  SensorParams p;
  p.effects.clear();
  World w;
  w.add({"wall", PlaneShape{}, at(0, 0, 0.8), *w.materials().find("wall_paint")});
  const TofLineSensor s(p);
  ForeignEmitter other;
  other.name = "other";
  other.T_world_sensor = at(0.05, 0, 0);
  other.emitter = p.emitter;
  other.pulse_rate_hz = p.emitter.pulse_rate_hz;
  other.on_intervals = {{0.0, 1e9}};
  MeasureOptions clean;
  clean.noise = false;
  const std::vector<int> sched{100};
  const SensorSet alone = s.measure(w, Eigen::Isometry3d::Identity(), 10.0, sched, 1, {}, clean);
  // Pulses in step with ours: every pulse lands in our gates.
  other.first_pulse_s = 10.0;
  const SensorSet synced = s.measure(w, Eigen::Isometry3d::Identity(), 10.0, sched, 1, std::span(&other, 1), clean);
  EXPECT_EQ(synced.crosstalk_pulses, 100);
  const auto i = static_cast<std::size_t>(kCentre);
  EXPECT_GT(synced.readouts[0].a[i] + synced.readouts[0].b[i], 1.5 * (alone.readouts[0].a[i] + alone.readouts[0].b[i]));
  // Half a pulse period apart: the other's light arrives while our gates are shut.
  other.first_pulse_s = 10.0 + 0.5 / p.emitter.pulse_rate_hz;
  const SensorSet apart = s.measure(w, Eigen::Isometry3d::Identity(), 10.0, sched, 1, std::span(&other, 1), clean);
  EXPECT_EQ(apart.crosstalk_pulses, 0);
  EXPECT_DOUBLE_EQ(apart.readouts[0].a[i], alone.readouts[0].a[i]);
  // Switched off during our set: nothing.
  other.first_pulse_s = 10.0;
  other.on_intervals = {{0.0, 5.0}};
  const SensorSet off = s.measure(w, Eigen::Isometry3d::Identity(), 10.0, sched, 1, std::span(&other, 1), clean);
  EXPECT_EQ(off.crosstalk_pulses, 0);
}

TEST(TofSensor, PluggableEffectsShiftTheRatioTheirOwnWay) {
  SensorParams base;
  base.effects.clear();
  const TofLineSensor plain(base);
  World w;
  w.add({"wall", PlaneShape{}, at(0, 0, 0.8), *w.materials().find("ic_foam")});
  const auto ref = plain.pulse_charges(w, Eigen::Isometry3d::Identity(), 3600);

  SensorParams fp = base;
  fp.effects.push_back(FixedPatternEffect{300.0, 0.0, 5});
  const auto pf = TofLineSensor(fp).pulse_charges(w, Eigen::Isometry3d::Identity(), 3600);
  int changed = 0;
  for (int i = 20; i < 250; ++i) changed += std::abs(ratio(pf, i) - ratio(ref, i)) > 1e-4 ? 1 : 0;
  EXPECT_GT(changed, 200);
  EXPECT_NEAR(intensity(pf, 100), intensity(ref, 100), 1e-9);  // charge moves between gates only

  SensorParams mb = base;
  MaterialBiasEffect mbe;
  mbe.path_mm["ic_foam"] = 100.0;
  mb.effects.emplace_back(mbe);
  const auto pm = TofLineSensor(mb).pulse_charges(w, Eigen::Isometry3d::Identity(), 3600);
  EXPECT_GT(ratio(pm, kCentre), ratio(ref, kCentre) + 0.005);

  SensorParams tr = base;
  tr.effects.push_back(TrapDelayEffect{0.83, 1.34});
  const auto pt = TofLineSensor(tr).pulse_charges(w, Eigen::Isometry3d::Identity(), 3600);
  EXPECT_GT(ratio(pt, kCentre), ratio(ref, kCentre));

  SensorParams td = base;
  td.effects.push_back(TimeDriftEffect{2.0, 0.0, 600.0});
  const TofLineSensor drift(td);
  EXPECT_GT(ratio(drift.pulse_charges(w, Eigen::Isometry3d::Identity(), 7200), kCentre),
            ratio(drift.pulse_charges(w, Eigen::Isometry3d::Identity(), 3600), kCentre));

  SensorParams cv = base;
  cv.effects.push_back(CovariateEffect{"humidity_pct", 50.0, 20.0, 100.0, 0.5, 0.05});
  CalibrationRail rail(cv);
  const SensorSet a = rail.measure(25.0, std::vector<int>{100}, 1), b = rail.measure(75.0, std::vector<int>{100}, 2);
  ASSERT_EQ(a.covariates.count("humidity_pct"), 1u);
  EXPECT_GT(a.covariates.at("humidity_pct"), 55.0);  // sine peak near t = 25 s
  EXPECT_LT(b.covariates.at("humidity_pct"), 45.0);
}

TEST(TofSensor, RejectsImpossibleParameters) {
  SensorParams p;
  p.pixel.knee = 300.0;
  EXPECT_THROW(TofLineSensor{p}, std::invalid_argument);
  SensorParams q;
  const TofLineSensor s(q);
  World w;
  EXPECT_THROW((void)s.measure(w, Eigen::Isometry3d::Identity(), 0.0, std::vector<int>{}, 0), std::invalid_argument);
  EXPECT_THROW((void)s.measure(w, Eigen::Isometry3d::Identity(), 0.0, std::vector<int>{200, 100}, 0),
               std::invalid_argument);
  // Nothing in view: every pixel is dark but the set is well formed.
  const SensorSet empty = s.measure(w, Eigen::Isometry3d::Identity(), 0.0, std::vector<int>{100}, 0);
  EXPECT_TRUE(std::isnan(empty.truth[kCentre].range_m));
  EXPECT_EQ(select_readout(empty, kCentre), -1);
}

TEST(Rail, CalibrationCsvHasTheIssueColumns) {
  SensorParams p;
  p.effects.push_back(CovariateEffect{});
  CalibrationRail rail(p);
  RailSweep sweep;
  sweep.distances_m = {0.3, 0.6};
  sweep.sets_per_distance = 2;
  sweep.pixels = {130, 136};
  const auto rows = run_sweep(rail, sweep, {"humidity_pct"});
  ASSERT_EQ(rows.size(), 2u * 2u * 5u * 2u);  // distances x sets x read-outs x pixels
  std::ostringstream out;
  write_calibration_csv(out, rows, true, {"humidity_pct"});
  const std::string text = out.str();
  EXPECT_EQ(text.substr(0, text.find('\n')), "t_s,pixel,pulses,a,b,temperature_c,distance_m,material,humidity_pct");
  EXPECT_NE(text.find(",white_paper,"), std::string::npos);
  EXPECT_NEAR(rows.front().distance_m, 0.3 / std::cos(rail.sensor().pixel_angle_rad(130)), 1e-6);
  // Fixed discharge: one read-out per set at the pulses that fill 40 %.
  sweep.discharge_fraction = 0.4;
  const auto fixed = run_sweep(rail, sweep);
  EXPECT_EQ(fixed.size(), 2u * 2u * 2u);
  const auto& r = fixed.front();
  EXPECT_NEAR(std::max(r.a * rail.sensor().sensitivity_ratio(130), r.b), 100.0, 35.0);
}

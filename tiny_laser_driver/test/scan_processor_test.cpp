// SPDX-License-Identifier: Apache-2.0
// Host-side processing: read-out selection, the calibration model per pixel,
// status, intensity, reflectance and ray angles; held against the public
// driver's own formula with a real sensor's calibration (the public driver's).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <tiny_laser_driver/calibration_impl.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tl = tinyline::tiny_laser_driver;

namespace {

constexpr std::uint16_t kPulses[5] = {20, 100, 200, 400, 700};

// distance_cm = 300 k, k = b / (a + b): easy to check by hand.
tl::CalibrationModel linear_model() {
  return tl::CalibrationModel::from_public_driver({0, 0, 0, 0, 0, 300, 0}, {}, 450, 0);
}

// Sensor K of the public driver.
const std::vector<double> kPolyK = {2.147918234375362e+06,  -7.736068312640203e+06, 1.154494186428487e+07,
                                    -9.137795412258314e+06, 4.045684724836031e+06,  -9.494901699902674e+05,
                                    9.219599710241470e+04};

// A set whose pixel p reads a = ka * pulses, b = kb * pulses (charge units) at every read-out.
tl::RawSet make_set(double ka, double kb, std::uint16_t temp_decic = 450) {
  tl::RawSet s;
  for (int i = 0; i < 5; ++i) {
    tl::RawFrame f;
    f.index = static_cast<std::uint16_t>(i);
    f.last = i == 4;
    f.pulses = kPulses[i];
    f.temperature_decic = temp_decic;
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      f.a[p] = static_cast<std::int16_t>(std::lround(10.0 * ka * kPulses[i]));
      f.b[p] = static_cast<std::int16_t>(std::lround(10.0 * kb * kPulses[i]));
    }
    s.frames.push_back(f);
  }
  return s;
}

}  // namespace

TEST(ScanProcessor, RayAnglesFollowThePinholeModel) {
  const tl::OpticsParams wide{3.6, 5.12};
  EXPECT_NEAR(tl::pixel_angle_rad(wide, 8), -std::atan(2.55 / 3.6), 1e-12);   // first effective pixel centre
  EXPECT_NEAR(tl::pixel_angle_rad(wide, 263), std::atan(2.55 / 3.6), 1e-12);  // last
  EXPECT_NEAR(tl::pixel_angle_rad(wide, 135) + tl::pixel_angle_rad(wide, 136), 0.0, 1e-12);
  // The public driver's field of view: pi - 2 atan(2 f / L).
  const double fov = tl::pixel_angle_rad(wide, 263) - tl::pixel_angle_rad(wide, 8);
  EXPECT_NEAR(fov, M_PI - 2 * std::atan(2 * 3.6 / 5.12), 0.01);
  const tl::OpticsParams narrow{8.0, 5.12};
  EXPECT_LT(tl::pixel_angle_rad(narrow, 263), tl::pixel_angle_rad(wide, 263));
  tl::ScanProcessor proc(linear_model(), wide);
  for (std::size_t p = 1; p < tl::kPixels; ++p) EXPECT_GT(proc.angles_rad()[p], proc.angles_rad()[p - 1]);
}

TEST(ScanProcessor, RefusesImpossibleOptics) {
  EXPECT_THROW(tl::ScanProcessor(linear_model(), tl::OpticsParams{0.0, 5.12}), std::invalid_argument);
  EXPECT_THROW(tl::ScanProcessor(linear_model(), tl::OpticsParams{3.6, -1.0}), std::invalid_argument);
  EXPECT_THROW(tl::ScanProcessor(linear_model(), tl::OpticsParams{NAN, 5.12}), std::invalid_argument);
}

TEST(ScanProcessor, TakesTheMostPulsesThatAreNotSaturated) {
  tl::ScanProcessor proc(linear_model(), {});
  // 0.3 / 0.1 per pulse: a = 210, b = 70 at 700 pulses, not saturated.
  auto set = make_set(0.3, 0.1);
  // Pixel 100: saturated at 700 (a = 245), fine at 400 (a = 140, b = 60).
  set.frames[4].a[100] = 2450;
  set.frames[3].a[100] = 1400;
  set.frames[3].b[100] = 600;
  // Pixel 101: saturated everywhere.
  for (auto& f : set.frames) f.b[101] = 2400;
  // Pixel 102: too dark (b below 10 at every read-out).
  for (auto& f : set.frames) f.b[102] = 50;
  const auto out = proc.process(set);
  EXPECT_EQ(out.status[50], tl::PixelStatus::kValid);
  EXPECT_EQ(out.readout[50], 4);
  EXPECT_EQ(out.pulses[50], 700);
  EXPECT_NEAR(out.distance_m[50], 3.0 * 70 / 280, 1e-6);
  EXPECT_NEAR(out.intensity[50], 280.0 / 700, 1e-6);
  EXPECT_NEAR(out.reflectance[50], 75.0 * 75.0 * 280.0 / 70.0, 1e-2);  // distance_cm^2 (a + b) / (pulses / 10)

  EXPECT_EQ(out.status[100], tl::PixelStatus::kValid);
  EXPECT_EQ(out.readout[100], 3);
  EXPECT_EQ(out.pulses[100], 400);
  EXPECT_NEAR(out.distance_m[100], 3.0 * 60 / 200, 1e-6);

  EXPECT_EQ(out.status[101], tl::PixelStatus::kSaturated);
  EXPECT_TRUE(std::isnan(out.distance_m[101]));
  EXPECT_EQ(out.pulses[101], 20);  // the fewest-pulse read-out's light, a lower bound
  EXPECT_EQ(out.status[102], tl::PixelStatus::kTooDark);
  EXPECT_TRUE(std::isnan(out.distance_m[102]));
  EXPECT_EQ(out.readout[102], 4);

  for (std::size_t p : {0, 7, 264, 271}) {
    EXPECT_EQ(out.status[p], tl::PixelStatus::kDarkPixel);
    EXPECT_TRUE(std::isnan(out.distance_m[p]));
  }
  EXPECT_EQ(out.valid, 254);
  EXPECT_EQ(out.saturated, 1);
  EXPECT_EQ(out.too_dark, 1);
  EXPECT_NEAR(out.saturated_share(), 1.0 / 256, 1e-12);
  EXPECT_DOUBLE_EQ(out.temperature_c, 45.0);
}

TEST(ScanProcessor, ARatioOutsideTheCalibratedRangeIsOutOfRange) {
  const auto k = tl::CalibrationModel::from_public_driver(kPolyK, {}, 440, 0.05623);
  tl::ScanProcessor proc(k, {});
  const auto out = proc.process(make_set(0.3, 0.02));  // k = 0.0625, far below where K is monotone
  EXPECT_EQ(out.status[100], tl::PixelStatus::kOutOfRange);
  EXPECT_TRUE(std::isnan(out.distance_m[100]));
  EXPECT_EQ(out.out_of_range, 256);
}

TEST(ScanProcessor, ADistanceTheSensorCannotMeasureIsNeverPublishedAsValid) {
  // Pixel terms pushing 1.5 m to 11.5 m, -3.5 m, about 1e308 m and +inf.
  auto model = linear_model();
  auto& m = model.impl();
  for (int copy = 0; copy < 2; ++copy) {
    tl::CalibrationTerm t;
    t.covariate = "pixel";
    t.form = tl::TermForm::kTable;
    t.keys = {100, 101, 102, 103};
    t.offsets_m = {copy == 0 ? 10.0 : 0.0, copy == 0 ? -5.0 : 0.0, copy == 0 ? 1e308 : 0.0, 1e308};
    m.terms.push_back(t);
  }
  m.resolve();
  tl::ScanProcessor proc(model, {});
  const auto out = proc.process(make_set(0.15, 0.15));  // k = 0.5: 1.5 m before the terms
  for (std::size_t p : {100, 101, 102, 103}) {
    EXPECT_EQ(out.status[p], tl::PixelStatus::kOutOfRange) << p;
    EXPECT_TRUE(std::isnan(out.distance_m[p])) << p;
  }
  EXPECT_EQ(out.status[99], tl::PixelStatus::kValid);
  EXPECT_NEAR(out.distance_m[99], 1.5, 1e-5);
  EXPECT_EQ(out.out_of_range, 4);
  EXPECT_EQ(out.valid, 252);
}

TEST(ScanProcessor, AgreesWithThePublicDriverOnARealSensorsCalibration) {
  // The public driver: dist_cm = sum poly[i] k^(6-i) + (stable - t) * sensi, k = b / (a + b),
  // t the packed word / 100 in 0.1 degC; pixel valid when 10 < a, b < 230 and a + b > 10 + 0.4 pulses/10.
  const auto k_model = tl::CalibrationModel::from_public_driver(kPolyK, {}, 440, 0.05623);
  tl::ScanProcessor proc(k_model, {});
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ratio(0.48, 0.78), amp(0.05, 0.9);  // K rises on about [0.45, 0.83]
  double worst_cm = 0.0;
  int compared = 0;
  for (int trial = 0; trial < 50; ++trial) {
    tl::RawSet set = make_set(0.1, 0.1, static_cast<std::uint16_t>(400 + trial));
    std::array<double, tl::kPixels> kk{}, per_pulse{};
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      kk[p] = ratio(rng);
      per_pulse[p] = amp(rng);
      for (auto& f : set.frames) {
        const double sum = per_pulse[p] * f.pulses;
        f.a[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * (1.0 - kk[p])));
        f.b[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * kk[p]));
      }
    }
    const auto out = proc.process(set);
    for (std::size_t p = tl::kDarkPixels; p < tl::kPixels - tl::kDarkPixels; ++p) {
      // The reference: the highest read-out the public rule accepts.
      double ref_cm = 0.0;
      for (int i = 4; i >= 0; --i) {
        const auto& f = set.frames[static_cast<std::size_t>(i)];
        const double a = f.a[p] / 10.0, b = f.b[p] / 10.0;
        if (a >= 230 || b >= 230) continue;
        if (!(a > 10 && b > 10 && a + b > 10 + 0.4 * f.pulses / 10)) break;
        const double k = b / (a + b);
        double d = 0.0;
        for (double c : kPolyK) d = d * k + c;
        ref_cm = d + (440.0 - f.temperature_decic) * 0.05623;
        break;
      }
      if (ref_cm <= 0.0) continue;
      ASSERT_EQ(out.status[p], tl::PixelStatus::kValid) << "pixel " << p;
      worst_cm = std::max(worst_cm, std::abs(100.0 * out.distance_m[p] - ref_cm));
      ++compared;
    }
  }
  EXPECT_GT(compared, 5000);
  EXPECT_LT(worst_cm, 0.01);  // float output of a 1e7-coefficient polynomial: well under a millimetre
}

TEST(ScanProcessor, DistanceFramesKeepTheFirmwareDistances) {
  tl::ScanProcessor proc(linear_model(), {});
  tl::DistanceFrame f;
  for (std::size_t p = 0; p < tl::kPixels; ++p) f.distance[p] = static_cast<std::int16_t>(p * 3);
  f.distance[50] = 0;
  tl::ProcessedScan out;
  proc.process_distance(f, 0.001, out);
  EXPECT_NEAR(out.distance_m[100], 0.3, 1e-6);
  EXPECT_EQ(out.status[50], tl::PixelStatus::kTooDark);
  EXPECT_EQ(out.status[3], tl::PixelStatus::kDarkPixel);
  EXPECT_TRUE(std::isnan(out.intensity[100]));
  EXPECT_EQ(out.valid, 255);
}

TEST(ScanProcessor, AnEmptySetIsAllInvalidNotACrash) {
  tl::ScanProcessor proc(linear_model(), {});
  const auto out = proc.process(tl::RawSet{});
  EXPECT_EQ(out.valid, 0);
  EXPECT_EQ(out.status[100], tl::PixelStatus::kTooDark);
}

TEST(UniformScanLayout, EachBinTakesItsNearestPixel) {
  tl::ScanProcessor proc(linear_model(), tl::OpticsParams{3.6, 5.12});
  const auto l = tl::uniform_scan_layout(proc.angles_rad());
  ASSERT_EQ(l.pixel_of_bin.size(), 256u);
  EXPECT_EQ(l.pixel_of_bin.front(), 8);
  EXPECT_EQ(l.pixel_of_bin.back(), 263);
  EXPECT_FLOAT_EQ(static_cast<float>(l.angle_min_rad), proc.angles_rad()[8]);
  // Nearest pixel: off by at most half the larger of the bin step and the pixel spacing (widest mid-line).
  const double spacing = proc.angles_rad()[136] - proc.angles_rad()[135];
  EXPECT_LE(l.max_error_rad, std::max(l.angle_increment_rad, spacing) / 2 + 1e-6);
  for (std::size_t i = 1; i < l.pixel_of_bin.size(); ++i) EXPECT_GE(l.pixel_of_bin[i], l.pixel_of_bin[i - 1]);
  for (std::size_t i = 0; i < l.pixel_of_bin.size(); ++i) {
    const double a = l.angle_min_rad + i * l.angle_increment_rad;
    const auto p = l.pixel_of_bin[i];
    if (p > 8) {
      EXPECT_LE(std::abs(proc.angles_rad()[p] - a), std::abs(proc.angles_rad()[p - 1] - a) + 1e-7);
    }
    if (p < 263) {
      EXPECT_LE(std::abs(proc.angles_rad()[p] - a), std::abs(proc.angles_rad()[p + 1] - a) + 1e-7);
    }
  }
}

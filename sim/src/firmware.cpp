// SPDX-License-Identifier: Apache-2.0
#include <sim/firmware.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/QR>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/fit.hpp>

#include <sim/fidelity.hpp>
#include <sim/rail.hpp>

namespace tinyline::sim {

namespace tld = tiny_laser_driver;
namespace cal = tiny_laser_calibration;

tld::CalibrationModel factory_calibration(const SensorParams& params) {
  // A white-paper sweep without noise, across the line and through the
  // warm-up, read out with the firmware's own accumulation buffer: the data
  // a factory would take, in the form the firmware will see.
  CalibrationRail rail(params);
  MeasureOptions clean;
  clean.noise = false;
  cal::CalibrationDataset data;
  data.source = "factory sweep";
  const int n = rail.sensor().pixels(), dark = params.lens.dark_pixels;
  std::vector<int> pixels;
  for (int i = dark + 4; i < n - dark - 4; i += 16) pixels.push_back(i);
  std::uint64_t index = 0;
  double t_row = 0.0;
  for (double t : {60.0, 240.0, 3600.0}) {
    for (double d = 0.05; d <= 3.0 + 1e-9; d += 0.05) {
      rail.set_target_distance(d);
      const SensorSet s = rail.measure(t, params.acquisition.distance_pulses, index++, clean);
      t_row += 1.0;
      for (int px : pixels) {
        const auto i = static_cast<std::size_t>(px);
        if (std::isnan(s.truth[i].range_m)) continue;
        for (const auto& ro : s.readouts) {
          tld::Readout r;
          r.a = ro.a[i];
          r.b = ro.b[i];
          r.pulses = ro.pulses;
          r.temperature_c = s.true_temperature_c;
          r.pixel = px;
          r.t_s = t_row;  // one frame: the fit keeps the read-out the firmware would
          data.add(r, s.truth[i].range_m);
        }
      }
    }
  }
  cal::DeclaredFitParams fp;
  fp.degree = 6;
  fp.sensitivity_ratio_mode = cal::SensitivityRatioMode::kFixed;  // the public driver's k = b / (a + b)
  fp.sensitivity_ratio = 1.0;
  fp.fit_leakage = true;
  fp.fit_temperature = true;
  fp.temperature_reference_c = params.thermal.warm_c;
  fp.selection = cal::ReadoutSelection::kDriver;
  const cal::DeclaredFitResult fit = cal::fit_declared_model(data, fp);
  if (!fit.status.ok()) throw std::runtime_error("factory calibration failed: " + fit.status.message);
  return fit.model;
}

std::vector<std::uint16_t> firmware_distances(const SensorSet& set, const tld::CalibrationModel& model) {
  const std::size_t n = set.readouts.empty() ? 0 : set.readouts.front().a.size();
  std::vector<std::uint16_t> out(n, 0);
  const std::size_t dark = tld::kDarkPixels;
  for (std::size_t i = dark; i + dark < n; ++i) {  // dark pixels carry no range
    const int k = select_readout(set, static_cast<int>(i));
    if (k < 0) continue;
    const auto& ro = set.readouts[static_cast<std::size_t>(k)];
    tld::Readout r;
    r.a = ro.a[i];
    r.b = ro.b[i];
    r.pulses = ro.pulses;
    r.temperature_c = set.temperature_c;
    r.pixel = static_cast<int>(i);
    r.t_s = ro.t_s;
    const double units = 1e4 * model.distance_m(r);  // 0.1 mm
    if (std::isfinite(units) && units >= 1.0 && units <= 65535.0)
      out[i] = static_cast<std::uint16_t>(std::lround(units));
  }
  return out;
}

tld::OpticsParams driver_optics(const SensorParams& params) {
  tld::OpticsParams o;
  o.focal_mm = params.lens.focal_mm;
  o.sensor_length_mm = params.lens.sensor_length_mm;
  return o;
}

std::vector<tld::RawFrame> raw_frames(const SensorSet& set) {
  std::vector<tld::RawFrame> frames;
  const double t = std::clamp(set.temperature_c, 0.0, 65.4);
  for (std::size_t k = 0; k < set.readouts.size(); ++k) {
    const auto& ro = set.readouts[k];
    tld::RawFrame f;
    f.index = static_cast<std::uint16_t>(k);
    f.last = (k + 1 == set.readouts.size());
    f.temperature_decic = static_cast<std::uint16_t>(std::lround(t * 10.0));
    f.pulses = static_cast<std::uint16_t>(ro.pulses);
    const std::size_t n = std::min<std::size_t>(ro.a.size(), tld::kPixels);
    for (std::size_t i = 0; i < n; ++i) {
      f.a[i] = static_cast<std::int16_t>(std::clamp(std::lround(ro.a[i] * 10.0), -32768L, 32767L));
      f.b[i] = static_cast<std::int16_t>(std::clamp(std::lround(ro.b[i] * 10.0), -32768L, 32767L));
    }
    frames.push_back(f);
  }
  return frames;
}

// ---------------------------------------------------------------------------- published

namespace {

// The factory sweep's (k, polynomial target) pairs: white paper from 5 cm to
// 3 m, warm, noise-free, one pixel in eight; per pixel the read-out the
// firmware keeps (the last one not saturated) when it is valid.
void published_factory_samples(const SensorParams& params, const PublishedFirmware& fw, std::vector<double>& ks,
                               std::vector<double>& targets_cm) {
  CalibrationRail rail(params);
  MeasureOptions lit_options;
  lit_options.noise = false;
  MeasureOptions dark_options = lit_options;
  dark_options.laser_on = false;
  const auto& pulses = params.acquisition.distance_pulses;
  const int n = rail.sensor().pixels(), dark = params.lens.dark_pixels;
  const double warm_s = 3600.0;
  std::uint64_t index = 0;
  for (double d = 0.05; d <= 3.0 + 1e-9; d += 0.025, ++index) {
    rail.set_target_distance(d);
    const SensorSet lit = rail.measure(warm_s, pulses, index, lit_options);
    const SensorSet off = rail.measure(warm_s, pulses, index, dark_options);
    const double ambient = PublishedFirmware::ambient_counts_per_pulse(off, dark);
    for (int px = dark + 4; px < n - dark - 4; px += 8) {
      const auto i = static_cast<std::size_t>(px);
      if (std::isnan(lit.truth[i].range_m)) continue;
      for (auto ro = lit.readouts.rbegin(); ro != lit.readouts.rend(); ++ro) {
        const double a = 10.0 * ro->a[i], b = 10.0 * ro->b[i];
        if (a >= fw.saturation_counts() || b >= fw.saturation_counts()) continue;
        const double ambient_coef = ambient * ro->pulses;
        double bot = fw.params().sensitivity_ratio * a - ambient_coef;
        if (px == fw.params().compensated_pixel) bot *= fw.params().compensated_pixel_factor;
        const double top = b - ambient_coef;
        if (bot >= 0.0 && bot <= 2500.0 && bot + top > 100.0 + 0.4 * ro->pulses) {
          const double k = top / (bot + top);
          ks.push_back(k);
          targets_cm.push_back(100.0 * lit.truth[i].range_m - 3.4 + 10.0 * k);  // the firmware adds 3.4 - 10 k
        }
        break;
      }
    }
  }
}

}  // namespace

PublishedFirmware::PublishedFirmware(const SensorParams& params)
    : fw_(params.firmware), dark_pixels_(params.lens.dark_pixels) {
  std::vector<double> ks, targets;
  published_factory_samples(params, *this, ks, targets);
  if (ks.size() < 20)
    throw std::runtime_error("published firmware: the factory sweep left too few valid read-outs to fit");
  Eigen::MatrixXd A(static_cast<Eigen::Index>(ks.size()), 7);
  Eigen::VectorXd y(static_cast<Eigen::Index>(ks.size()));
  for (std::size_t r = 0; r < ks.size(); ++r) {
    double power = 1.0;
    for (int c = 6; c >= 0; --c) {  // poly[0] multiplies k^6, poly[6] is the constant
      A(static_cast<Eigen::Index>(r), c) = power;
      power *= ks[r];
    }
    y(static_cast<Eigen::Index>(r)) = targets[r];
  }
  const Eigen::VectorXd c = A.colPivHouseholderQr().solve(y);
  for (int j = 0; j < 7; ++j) poly_[static_cast<std::size_t>(j)] = c(j);
}

double PublishedFirmware::ambient_counts_per_pulse(const SensorSet& dark, int dark_pixels) {
  if (dark.readouts.empty()) return 0.0;
  const Readout& r = dark.readouts.back();
  const auto n = static_cast<int>(r.a.size());
  double sum = 0.0;
  int count = 0;
  for (int i = dark_pixels; i < n - dark_pixels; ++i) {
    sum += 0.5 * (r.a[static_cast<std::size_t>(i)] + r.b[static_cast<std::size_t>(i)]);
    ++count;
  }
  return count > 0 && r.pulses > 0 ? 10.0 * sum / count / r.pulses : 0.0;
}

double PublishedFirmware::distance_cm(double a, double b, int pulses, int pixel, double ambient) const {
  // Src/main.c, in its order of operations.
  const double ambient_coef = ambient * pulses;
  const double top = b - ambient_coef;
  double bot = fw_.sensitivity_ratio * a - ambient_coef;
  if (pixel == fw_.compensated_pixel) bot *= fw_.compensated_pixel_factor;
  if (bot > 2500 || bot < 0) return 0.0;
  double dist = 0.0;
  if (bot + top > 100 + 0.4 * pulses) {
    const double k = top / (bot + top);
    const auto& p = poly_;
    dist = p[0] * k * k * k * k * k * k + p[1] * k * k * k * k * k + p[2] * k * k * k * k + p[3] * k * k * k +
           p[4] * k * k + p[5] * k + p[6] + 3.4 - 10 * k;
  }
  return dist > 0 ? dist : 0.0;
}

PublishedCycle PublishedFirmware::compute(const SensorSet& lit, const SensorSet& dark) const {
  PublishedCycle c;
  c.ambient_counts_per_pulse = ambient_counts_per_pulse(dark, dark_pixels_);
  for (const Readout& r : lit.readouts) {
    ReadoutCounts& rc = c.readouts.emplace_back();
    rc.pulses = r.pulses;
    for (std::size_t i = 0; i < r.a.size(); ++i) {
      rc.a.push_back(static_cast<double>(std::lround(10.0 * r.a[i])));
      rc.b.push_back(static_cast<double>(std::lround(10.0 * r.b[i])));
    }
  }
  const std::size_t n = std::min(tld::kPixels, lit.readouts.empty() ? 0 : lit.readouts.front().a.size());
  for (const ReadoutCounts& rc : c.readouts) {  // the cycle starts from cleared data
    for (std::size_t i = 0; i < n; ++i) {
      if (rc.a[i] >= saturation_counts() || rc.b[i] >= saturation_counts()) continue;  // keeps an earlier value
      const double cm = distance_cm(rc.a[i], rc.b[i], rc.pulses, static_cast<int>(i), c.ambient_counts_per_pulse);
      c.distance[i] = static_cast<std::uint16_t>(std::min(cm * 100.0, 65535.0));
    }
  }
  for (const auto& [dst, src] : kPublishedPixelCopies)
    c.distance[static_cast<std::size_t>(dst)] = c.distance[static_cast<std::size_t>(src)];
  return c;
}

}  // namespace tinyline::sim

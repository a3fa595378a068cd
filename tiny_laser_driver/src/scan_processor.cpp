// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/scan_processor.hpp>

#include <tiny_laser_driver/param_tables.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace tinyline::tiny_laser_driver {

namespace {
constexpr std::size_t kFirst = kDarkPixels;
constexpr std::size_t kLast = kPixels - kDarkPixels - 1;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

bool is_dark(std::size_t p) { return p < kFirst || p > kLast; }

bool has_distance(const CalibrationEvaluation& ev) {
  using S = CalibrationEvaluation::Status;
  return ev.status == S::kValid || ev.status == S::kMissingCovariate;
}

// A distance the sensor cannot measure (Eq. 3.4) is no measurement, whatever
// the calibration says: published as out of range, never as a valid range
// (+inf would read "no return" in a LaserScan).
bool is_measurement(const CalibrationEvaluation& ev) {
  return has_distance(ev) && ev.distance_m >= kPhysicalMinDistanceM && ev.distance_m <= kPhysicalMaxDistanceM;
}

void clear_pixel(ProcessedScan& out, std::size_t p, PixelStatus s) {
  out.distance_m[p] = kNaNf;
  out.range_sd_m[p] = kNaNf;
  out.intensity[p] = kNaNf;
  out.reflectance[p] = kNaNf;
  out.pulses[p] = 0;
  out.readout[p] = -1;
  out.status[p] = s;
}
}  // namespace

common::Status OpticsParams::validate() const { return common::within_table(*this); }

double pixel_angle_rad(const OpticsParams& optics, std::size_t pixel) {
  const double pitch_mm = optics.sensor_length_mm / static_cast<double>(kPixels - 2 * kDarkPixels);
  const double u_mm = (static_cast<double>(pixel) - (kPixels - 1) / 2.0) * pitch_mm;
  return std::atan(u_mm / optics.focal_mm);
}

ScanProcessor::ScanProcessor(CalibrationModel model, OpticsParams optics) : model_(std::move(model)), optics_(optics) {
  if (const common::Status why = optics_.validate(); !why.ok()) throw std::invalid_argument("optics: " + why.message);
  for (std::size_t p = 0; p < kPixels; ++p) angles_[p] = static_cast<float>(pixel_angle_rad(optics_, p));
}

ProcessedScan ScanProcessor::process(const RawSet& set, double t_s) const {
  ProcessedScan out;
  process(set, t_s, out);
  return out;
}

void ScanProcessor::process(const RawSet& set, double t_s, ProcessedScan& out) const {
  using S = CalibrationEvaluation::Status;
  const ValidityRule& rule = model_.validity();
  const double temperature_c = set.temperature_decic() / 10.0;
  out.temperature_c = temperature_c;
  out.valid = out.saturated = out.too_dark = out.out_of_range = out.stale = 0;
  const int n = static_cast<int>(set.frames.size());
  Readout r;
  r.temperature_c = temperature_c;
  r.t_s = t_s;
  for (std::size_t p = 0; p < kPixels; ++p) {
    if (is_dark(p) || n == 0) {
      clear_pixel(out, p, is_dark(p) ? PixelStatus::kDarkPixel : PixelStatus::kTooDark);
      continue;
    }
    r.pixel = static_cast<int>(p);
    // The read-out with the most pulses that is not saturated: the most light
    // short of the capacitors' limit (4.4.1: "the previous readout data is used").
    int chosen = -1;
    for (int k = n - 1; k >= 0; --k) {
      const RawFrame& f = set.frames[static_cast<std::size_t>(k)];
      r.a = charge_units(f.a[p]);
      r.b = charge_units(f.b[p]);
      r.pulses = f.pulses;
      if (rule.check(r) != ValidityRule::Verdict::kSaturated) {
        chosen = k;
        break;
      }
    }
    if (chosen < 0) {
      // Saturated at every read-out: report the fewest-pulse one's light (a lower bound).
      clear_pixel(out, p, PixelStatus::kSaturated);
      out.pulses[p] = set.frames[0].pulses;
      out.readout[p] = 0;
      out.intensity[p] = static_cast<float>((r.a + r.b) / r.pulses);
      ++out.saturated;
      continue;
    }
    out.readout[p] = static_cast<std::int8_t>(chosen);
    out.pulses[p] = static_cast<std::uint16_t>(r.pulses);
    out.intensity[p] = static_cast<float>((r.a + r.b) / r.pulses);
    const CalibrationEvaluation ev = model_.evaluate(r);
    if (is_measurement(ev)) {
      const double d_m = ev.distance_m;
      const double d_cm = 100.0 * d_m;
      out.distance_m[p] = static_cast<float>(d_m);
      out.range_sd_m[p] = static_cast<float>(ev.range_sd_m);
      out.reflectance[p] =
          static_cast<float>(d_cm * d_cm * (r.a + r.b) / (r.pulses / 10.0));  // the sensor's reflectance figure
      out.status[p] = PixelStatus::kValid;
      ++out.valid;
      continue;
    }
    out.distance_m[p] = kNaNf;
    out.range_sd_m[p] = kNaNf;
    out.reflectance[p] = kNaNf;
    if (ev.status == S::kOutOfRange || has_distance(ev)) {
      out.status[p] = PixelStatus::kOutOfRange;
      ++out.out_of_range;
    } else {
      out.status[p] = PixelStatus::kTooDark;
      ++out.too_dark;
    }
  }
}

void ScanProcessor::process_distance(const DistanceFrame& frame, double unit_m, ProcessedScan& out) const {
  out.temperature_c = std::numeric_limits<double>::quiet_NaN();
  out.valid = out.saturated = out.too_dark = out.out_of_range = out.stale = 0;
  for (std::size_t p = 0; p < kPixels; ++p) {
    if (is_dark(p)) {
      clear_pixel(out, p, PixelStatus::kDarkPixel);
      continue;
    }
    const std::uint16_t v = frame.distance[p];
    if (v == 0) {  // the firmware sends 0 for no range
      clear_pixel(out, p, PixelStatus::kTooDark);
      ++out.too_dark;
      continue;
    }
    clear_pixel(out, p, PixelStatus::kValid);
    out.distance_m[p] = static_cast<float>(v * unit_m);
    ++out.valid;
  }
}

UniformScanLayout uniform_scan_layout(const std::array<float, kPixels>& angles, std::size_t bins) {
  UniformScanLayout l;
  if (bins < 2) bins = 2;
  l.angle_min_rad = angles[kFirst];
  l.angle_max_rad = angles[kLast];
  l.angle_increment_rad = (l.angle_max_rad - l.angle_min_rad) / static_cast<double>(bins - 1);
  l.pixel_of_bin.resize(bins);
  const auto begin = angles.begin() + kFirst;
  const auto end = angles.begin() + kLast + 1;
  for (std::size_t i = 0; i < bins; ++i) {
    const double a = l.angle_min_rad + static_cast<double>(i) * l.angle_increment_rad;
    auto it = std::lower_bound(begin, end, static_cast<float>(a));
    if (it == end) --it;
    if (it != begin && std::abs(*(it - 1) - a) <= std::abs(*it - a)) --it;
    l.pixel_of_bin[i] = static_cast<std::uint16_t>(it - angles.begin());
    l.max_error_rad = std::max(l.max_error_rad, std::abs(*it - a));
  }
  return l;
}

}  // namespace tinyline::tiny_laser_driver

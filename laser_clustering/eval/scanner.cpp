// SPDX-License-Identifier: Apache-2.0
#include "scanner.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <sim/firmware.hpp>
#include <sim/rail.hpp>
#include <sim/tof_sensor.hpp>
#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_calibration/fit.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tinyline::laser_clustering::eval {

namespace {

namespace tld = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;

std::string resolve(const std::string& config) {
  const std::filesystem::path p(config);
  if (p.is_absolute() || std::filesystem::exists(p)) return p.string();
  return (std::filesystem::path(TINYLINE_SOURCE_DIR) / "sim/config/sensors" / p).string();
}

sim::SensorParams load(const SimScannerOptions& o) {
  sim::SensorParams p = sim::load_sensor_params(resolve(o.sensor_config));
  if (!o.raw_pulses.empty()) p.acquisition.raw_pulses = o.raw_pulses;
  if (const common::Status why = p.validate(); !why.ok()) throw std::runtime_error("sim scanner: " + why.message);
  return p;
}

tld::RawSet to_raw(const sim::SensorSet& set) {
  tld::RawSet raw;
  raw.frames = sim::raw_frames(set);
  return raw;
}

struct Calibration {
  tld::CalibrationModel model;
  double rmse_m = 0.0;
};

// The calibration for the working range: the declared model fitted by the
// calibration tool's fitter to a white-paper rail over every effective pixel
// (per-pixel R_sen, leakage). Rows carry the set's start time, so the
// fitter's frames are the sets and it keeps, per pixel and set, the read-out
// the driver uses (the rail's CSV stamps each read-out with its own time).
Calibration calibrate(const SimScannerOptions& o, const sim::SensorParams& params) {
  sim::CalibrationRail rail(params);
  std::vector<int> pixels;
  for (int p = params.lens.dark_pixels; p < params.lens.pixels - params.lens.dark_pixels; ++p) pixels.push_back(p);
  cal::CalibrationDataset data;
  data.source = "simulated white-paper rail";
  double t = o.t_start_s;
  std::uint64_t index = 1u << 30;  // not the scans' indices
  for (double d = 0.05; d <= o.calibration_max_m + 1e-9; d += o.calibration_step_m) {
    rail.set_target_distance(d);
    for (int k = 0; k < o.calibration_sets; ++k) {
      const sim::SensorSet set = rail.measure(t, params.acquisition.raw_pulses, index++);
      for (const auto& r : sim::calibration_rows(set, rail.world(), pixels)) {
        tld::Readout ro;
        ro.a = r.a;
        ro.b = r.b;
        ro.pulses = r.pulses;
        ro.temperature_c = r.temperature_c;
        ro.pixel = r.pixel;
        ro.t_s = set.t_start_s;
        data.add(ro, r.distance_m);
      }
      t += std::max(0.05, set.t_end_s - set.t_start_s);
    }
  }
  const auto fit = cal::fit_declared_model(data);
  if (!fit.status.ok()) throw std::runtime_error("sim scanner: calibration fit failed: " + fit.status.message);
  return {fit.model, fit.rmse_m};
}

// White paper's reflectance figure through the driver's processing (a wall
// 15-45 cm ahead, pixels near the axis): the reference of the dark threshold.
double white_reflectance(const SimScannerOptions& o, const sim::SensorParams& params,
                         const tld::ScanProcessor& processor) {
  sim::CalibrationRail rail(params);
  std::vector<double> white;
  std::uint64_t index = (1u << 30) + 100000;
  for (double d = 0.15; d <= 0.45 + 1e-9; d += 0.05) {
    rail.set_target_distance(d);
    const sim::SensorSet set = rail.measure(o.t_start_s, params.acquisition.raw_pulses, index++);
    const tld::ProcessedScan scan = processor.process(to_raw(set), set.t_start_s);
    for (int p = params.lens.pixels / 2 - 40; p <= params.lens.pixels / 2 + 40; ++p) {
      const auto u = static_cast<std::size_t>(p);
      if (scan.status[u] == tld::PixelStatus::kValid) white.push_back(scan.reflectance[u]);
    }
  }
  if (white.empty()) throw std::runtime_error("sim scanner: no valid white-paper pixel between 15 and 45 cm");
  std::nth_element(white.begin(), white.begin() + static_cast<std::ptrdiff_t>(white.size() / 2), white.end());
  return white[white.size() / 2];
}

class SimScanner : public Scanner {
 public:
  explicit SimScanner(const SimScannerOptions& o)
      : options_(o),
        params_(load(o)),
        sensor_(params_),
        calibration_(calibrate(o, params_)),
        processor_(calibration_.model, sim::driver_optics(params_)) {
    white_reflectance_ = white_reflectance(o, params_, processor_);
  }

  SimulatedScan scan(const sim::World& world, const Eigen::Isometry3d& T_world_sensor, std::uint64_t index) override {
    const sim::SensorSet set =
        sensor_.measure(world, T_world_sensor, options_.t_start_s, params_.acquisition.raw_pulses, index);
    processor_.process(to_raw(set), set.t_start_s, processed_);
    SimulatedScan s;
    const std::size_t first = tld::kDarkPixels, n = tld::kPixels - 2 * tld::kDarkPixels;
    s.scan.angle_rad.resize(n);
    s.scan.range_m.resize(n);
    s.scan.reflectance.resize(n);
    s.truth_object.resize(n);
    s.truth_mixed.resize(n);
    saturated_.assign(n, 0);
    intensity_.assign(n, 0.0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double dark = options_.min_reflectance_of_white * white_reflectance_;
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t p = first + k;
      s.scan.angle_rad[k] = processor_.angles_rad()[p];
      s.truth_object[k] = set.truth[p].object;
      s.truth_mixed[k] = set.truth[p].mixed ? 1 : 0;
      const bool valid = processed_.status[p] == tld::PixelStatus::kValid;
      const double d = processed_.distance_m[p], refl = processed_.reflectance[p];
      const bool keep = valid && d >= options_.min_range_m && d <= options_.max_range_m && refl >= dark;
      s.scan.range_m[k] = keep ? d : nan;
      s.scan.reflectance[k] = keep ? refl : nan;
      saturated_[k] = processed_.status[p] == tld::PixelStatus::kSaturated;
      intensity_[k] = processed_.intensity[p];
    }
    // Saturated pixels: their fewest-pulse light as a reflectance lower bound,
    // as the nodes do (line_scan.hpp).
    (void)laser_clustering::saturated_reflectance_bound(s.scan, saturated_, intensity_);
    return s;
  }

  std::string describe() const override {
    return fmt::format(
        "simulated {} ({} mm lens, fan +-{:.0f} deg, 256 px), raw mode {} pulses, the driver's ScanProcessor with a "
        "declared model fitted to a white-paper rail 5-{:.0f} cm every {:.1f} cm (in-sample RMSE {:.1f} mm), returns "
        "below {:.0f} % of white paper's reflectance dropped",
        params_.name, params_.lens.focal_mm, params_.emitter.fan_half_angle_deg,
        fmt::join(params_.acquisition.raw_pulses, "/"), options_.calibration_max_m * 100,
        options_.calibration_step_m * 100, calibration_.rmse_m * 1e3, options_.min_reflectance_of_white * 100);
  }

 private:
  SimScannerOptions options_;
  sim::SensorParams params_;
  sim::TofLineSensor sensor_;
  Calibration calibration_;
  tld::ScanProcessor processor_;
  tld::ProcessedScan processed_;
  double white_reflectance_ = 0.0;
  std::vector<std::uint8_t> saturated_;
  std::vector<double> intensity_;
};

}  // namespace

std::unique_ptr<Scanner> make_sim_scanner(const SimScannerOptions& options) {
  return std::make_unique<SimScanner>(options);
}

SimCalibrationSummary write_sim_calibration(const SimScannerOptions& options, const std::string& path) {
  const sim::SensorParams params = load(options);
  const Calibration c = calibrate(options, params);
  c.model.save(path);
  const tld::ScanProcessor processor(c.model, sim::driver_optics(params));
  return {c.rmse_m, white_reflectance(options, params, processor)};
}

}  // namespace tinyline::laser_clustering::eval

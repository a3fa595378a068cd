#include "sim_scanner.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <sim/rail.hpp>
#include <sim/tof_sensor.hpp>
#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/calibration_fit.hpp>

namespace tinyline::laser_clustering::eval {

namespace {

namespace tld = tinyline::tiny_laser_driver;

std::string resolve(const std::string& config) {
  const std::filesystem::path p(config);
  if (p.is_absolute() || std::filesystem::exists(p)) return p.string();
  return (std::filesystem::path(TINYLINE_SOURCE_DIR) / "sim/config/sensors" / p).string();
}

sim::SensorParams load(const SimScannerOptions& o) {
  sim::SensorParams p = sim::load_sensor_params(resolve(o.sensor_config));
  if (!o.raw_pulses.empty()) p.acquisition.raw_pulses = o.raw_pulses;
  if (const auto why = p.validate(); !why.empty()) throw std::runtime_error("sim scanner: " + why);
  return p;
}

class SimScanner : public Scanner {
 public:
  explicit SimScanner(const SimScannerOptions& o)
      : options_(o), params_(load(o)), sensor_(params_) {
    // The calibration the driver would load: the declared model fitted to a
    // white-paper rail over every effective pixel (per-pixel R_sen).
    // Rows carry the set's start time, so that the fitter's frames are the
    // sets and it keeps, per pixel and set, the read-out the driver would use
    // (the sim's rail CSV stamps each read-out with its own time).
    sim::CalibrationRail rail(params_);
    std::vector<int> pixels;
    for (int p = params_.lens.dark_pixels; p < params_.lens.pixels - params_.lens.dark_pixels; ++p) pixels.push_back(p);
    tld::CalibrationDataset data;
    data.source = "simulated white-paper rail";
    double t = o.t_start_s;
    std::uint64_t index = 1u << 30;  // not the scans' indices
    for (double d = 0.05; d <= o.calibration_max_m + 1e-9; d += o.calibration_step_m) {
      rail.set_target_distance(d);
      for (int k = 0; k < o.calibration_sets; ++k) {
        const sim::SensorSet set = rail.measure(t, params_.acquisition.raw_pulses, index++);
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
    const auto fit = tld::fit_declared_model(data);
    if (!fit.ok) throw std::runtime_error("sim scanner: calibration fit failed: " + fit.reason);
    model_ = fit.model;
    calibration_rmse_m_ = fit.rmse_m;
    // White paper's reflectance figure, the reference of the dark threshold:
    // the rail's pixels near the axis between 15 and 45 cm.
    std::vector<double> white;
    for (std::size_t i = 0; i < data.size(); ++i) {
      const auto& r = data.readouts[i];
      if (data.distance_m[i] < 0.15 || data.distance_m[i] > 0.45 || std::abs(r.pixel - params_.lens.pixels / 2) > 40) continue;
      if (model_.validity().check(r) != tld::ValidityRule::Verdict::kValid) continue;
      const double d_cm = 100.0 * data.distance_m[i];
      white.push_back(d_cm * d_cm * (r.a + r.b) / (r.pulses / 10.0));
    }
    if (white.empty()) throw std::runtime_error("sim scanner: no valid white-paper read-out between 15 and 45 cm");
    std::nth_element(white.begin(), white.begin() + static_cast<std::ptrdiff_t>(white.size() / 2), white.end());
    white_reflectance_ = white[white.size() / 2];
    for (int p = 0; p < sensor_.pixels(); ++p) {
      if (!sensor_.is_dark(p)) pixels_.push_back(p);
    }
  }

  SimulatedScan scan(const sim::World& world, const Eigen::Isometry3d& T_world_sensor, std::uint64_t index) override {
    const auto& schedule = params_.acquisition.raw_pulses;
    const sim::SensorSet set = sensor_.measure(world, T_world_sensor, options_.t_start_s, schedule, index);
    SimulatedScan s;
    const std::size_t n = pixels_.size();
    s.scan.angle_rad.resize(n);
    s.scan.range_m.resize(n);
    s.scan.reflectance.resize(n);
    s.truth_object.resize(n);
    s.truth_mixed.resize(n);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t k = 0; k < n; ++k) {
      const int p = pixels_[k];
      s.scan.angle_rad[k] = sensor_.pixel_angle_rad(p);
      s.truth_object[k] = set.truth[static_cast<std::size_t>(p)].object;
      s.truth_mixed[k] = set.truth[static_cast<std::size_t>(p)].mixed ? 1 : 0;
      s.scan.range_m[k] = nan;
      s.scan.reflectance[k] = nan;
      // The driver: the valid read-out with the most pulses.
      for (std::size_t j = set.readouts.size(); j-- > 0;) {
        const auto& r = set.readouts[j];
        tld::Readout ro;
        ro.a = r.a[static_cast<std::size_t>(p)];
        ro.b = r.b[static_cast<std::size_t>(p)];
        ro.pulses = r.pulses;
        ro.temperature_c = set.temperature_c;
        ro.pixel = p;
        ro.t_s = r.t_s;
        if (model_.validity().check(ro) != tld::ValidityRule::Verdict::kValid) continue;
        const double d = model_.distance_m(ro);
        const double d_cm = 100.0 * d;
        const double reflectance = d_cm * d_cm * (ro.a + ro.b) / (ro.pulses / 10.0);
        if (std::isfinite(d) && d >= options_.min_range_m && d <= options_.max_range_m &&
            reflectance >= options_.min_reflectance_of_white * white_reflectance_) {
          s.scan.range_m[k] = d;
          s.scan.reflectance[k] = reflectance;
        }
        break;
      }
    }
    return s;
  }

  std::string describe() const override {
    return fmt::format("simulated {} ({} mm lens, fan +-{:.0f} deg, {} px), raw mode {} pulses, driver processing with a "
                       "declared model fitted to a white-paper rail 5-{:.0f} cm every {:.1f} cm (in-sample RMSE {:.1f} mm), returns below "
                       "{:.0f} % of white paper's reflectance dropped",
                       params_.name, params_.lens.focal_mm, params_.emitter.fan_half_angle_deg, pixels_.size(),
                       fmt::join(params_.acquisition.raw_pulses, "/"), options_.calibration_max_m * 100,
                       options_.calibration_step_m * 100, calibration_rmse_m_ * 1e3,
                       options_.min_reflectance_of_white * 100);
  }

 private:
  SimScannerOptions options_;
  sim::SensorParams params_;
  sim::TofLineSensor sensor_;
  tld::CalibrationModel model_;
  double calibration_rmse_m_ = 0.0;
  double white_reflectance_ = 0.0;
  std::vector<int> pixels_;
};

}  // namespace

std::unique_ptr<Scanner> make_sim_scanner(const SimScannerOptions& options) { return std::make_unique<SimScanner>(options); }

}  // namespace tinyline::laser_clustering::eval

// SPDX-License-Identifier: Apache-2.0
// Host-side processing of the raw mode (thesis 5.3.1, Algorithm 3): per
// pixel, the read-out with the most pulses that is not saturated (thresholds
// in the charge unit, from the calibration's validity rule, as the public
// driver does), the calibration model on it, validity, intensity and
// reflectance, and the ray angle of each pixel.
//
// Core code: no bus, no I/O, no allocation per scan.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/protocol.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::tiny_laser_driver {

/// The receiver's optics: what maps a pixel to its ray.
struct OpticsParams {
  double focal_mm = 3.6;           ///< receiver lens focal length [mm] (3.6 or 8 mm shipped)
  double sensor_length_mm = 5.12;  ///< length of the 256 effective pixels [mm] (the sensor's data)

  /// InvalidArgument naming the field outside its parameter table's range
  /// (both rules are single fields': nothing spans them).
  [[nodiscard]] common::Status validate() const;
};

/// Ray angle of pixel `pixel` (0-271, dark ones included) in the sensor's x-z
/// plane [rad]: atan(u / f), u the pixel centre's offset from the middle of
/// the line, +x for higher indices (the simulator's convention).
[[nodiscard]] double pixel_angle_rad(const OpticsParams& optics, std::size_t pixel);

/// Per-pixel status; the values are tinyline_msgs/LineScan's STATUS_* constants.
enum class PixelStatus : std::uint8_t {
  kValid = 0,
  kSaturated = 1,   ///< every read-out saturated
  kTooDark = 2,     ///< the highest non-saturated read-out has too little light
  kDarkPixel = 3,   ///< one of the 8 masked pixels at each end
  kOutOfRange = 4,  ///< the charge ratio lies outside the calibrated range
  kStale = 5,       ///< the value has not changed for many fresh measurements while its neighbours' have
};

/// One processed scan. Arrays are indexed by transmitted pixel (0-271).
struct ProcessedScan {
  static constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  std::array<float, kPixels> distance_m{};  ///< along the pixel's ray; NaN unless kValid
  std::array<float, kPixels> intensity{};   ///< (a + b) / pulses of the chosen read-out [charge_unit per pulse]
  std::array<float, kPixels>
      reflectance{};  ///< distance_cm^2 (a + b) / (pulses / 10) (the sensor's reflectance figure); NaN unless kValid
  /// SD of the range from the calibration's noise law at this read-out's light [m]; NaN unless
  /// kValid and the calibration has a `noise` section.
  std::array<float, kPixels> range_sd_m{};
  std::array<std::uint16_t, kPixels> pulses{};  ///< pulses of the chosen read-out (0: none)
  std::array<std::int8_t, kPixels> readout{};   ///< index of the chosen read-out in the set (-1: none)
  std::array<PixelStatus, kPixels> status{};
  double temperature_c = std::numeric_limits<double>::quiet_NaN();          ///< MCU temperature of the set
  int valid = 0, saturated = 0, too_dark = 0, out_of_range = 0, stale = 0;  ///< counts over the 256 effective pixels

  /// Share of the effective pixels saturated at every read-out.
  [[nodiscard]] double saturated_share() const { return saturated / static_cast<double>(kPixels - 2 * kDarkPixels); }
};

class ScanProcessor {
 public:
  /// Throws std::invalid_argument when the optics are impossible (validate()).
  ScanProcessor(CalibrationModel model, OpticsParams optics);

  /// Processes one raw set into `out` (no allocation). `t_s` is the time
  /// since the sensor started [s], for calibration terms that use it.
  void process(const RawSet& set, double t_s, ProcessedScan& out) const;
  [[nodiscard]] ProcessedScan process(const RawSet& set, double t_s = 0.0) const;

  /// A distance-only frame (unsigned firmware distances in units of
  /// `unit_m`, 0 = invalid): distance and status only (no intensity in that mode).
  void process_distance(const DistanceFrame& frame, double unit_m, ProcessedScan& out) const;

  [[nodiscard]] const std::array<float, kPixels>& angles_rad() const { return angles_; }
  [[nodiscard]] const CalibrationModel& model() const { return model_; }
  [[nodiscard]] const OpticsParams& optics() const { return optics_; }

 private:
  CalibrationModel model_;
  OpticsParams optics_;
  std::array<float, kPixels> angles_{};
};

/// sensor_msgs/LaserScan needs equal angle steps; the pixels' rays are not
/// (atan). A layout of `bins` equal steps from the first to the last
/// effective pixel's angle, each bin taking its nearest pixel (never
/// interpolating across an edge): angular error at most half the larger of
/// the step and the local pixel spacing (0.16 deg at 3.6 mm, 0.07 deg at 8 mm).
struct UniformScanLayout {
  double angle_min_rad = 0.0;
  double angle_max_rad = 0.0;
  double angle_increment_rad = 0.0;
  std::vector<std::uint16_t> pixel_of_bin;  ///< transmitted pixel index of each bin
  /// Largest |bin angle - its pixel's angle| [rad].
  double max_error_rad = 0.0;
};
[[nodiscard]] UniformScanLayout uniform_scan_layout(const std::array<float, kPixels>& angles_rad,
                                                    std::size_t bins = kPixels - 2 * kDarkPixels);

}  // namespace tinyline::tiny_laser_driver

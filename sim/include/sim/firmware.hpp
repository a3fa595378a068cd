// SPDX-License-Identifier: Apache-2.0
// What the simulated sensor's MCU computes itself, in its two firmware
// profiles (sensor_params.hpp FirmwareProfile; docs/simulator.md).
//
// thesis_raw, distance-only mode (thesis 4.4.1, Algorithm 2): the firmware
// reads the capacitors at each count of its accumulation buffer (default
// the firmware's accumulation buffer: 10, 100, 200, 400, 550, 700),
// keeps per pixel the read-out with the most pulses that is valid under the
// public driver's rule, and maps it to a distance with its on-board
// calibration: the public driver's form, one 6th-degree polynomial in
// k = b / (a + b) for all pixels (no per-pixel sensitivity ratio) plus a
// linear temperature term, fitted at the "factory" on a noise-free
// white-paper sweep. Output: uint16 in 0.1 mm along the pixel's ray, rounded;
// 0 = no distance (dark pixel, too dark, saturated, outside the calibrated
// range or beyond 6.5535 m).
//
// published (the public STM32 firmware's Src/main.c and Src/itcallback.cpp):
// per accumulation cycle and read-out, per pixel, the discharges in ADC
// counts with an ambient level subtracted from both and capacitor A scaled by
// the sensitivity ratio (and once more on one compensated pixel);
// k = top / (bot + top); no distance unless 0 <= bot <= 2500 and
// bot + top > 100 + 0.4 pulses; distance_cm = polynomial(k) + 3.4 - 10 k;
// written as (uint16)(cm * 100) only while neither capacitor is saturated, so
// a pixel saturated at the later read-outs keeps an earlier read-out's value.
// The cycle starts from cleared data; before sending, pixel 176 takes pixel
// 175's value and pixel 16 pixel 17's (as the firmware does). The polynomial
// is fitted at the "factory" in that form on a noise-free white-paper sweep.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/protocol.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

#include <sim/tof_sensor.hpp>

namespace tinyline::sim {

// ---------------------------------------------------------------------------- thesis_raw

/// The factory calibration of a sensor for the thesis firmware's distance
/// mode (see above). Deterministic for given parameters; takes about a second.
[[nodiscard]] tiny_laser_driver::CalibrationModel factory_calibration(const SensorParams& params);

/// Distance per pixel [0.1 mm] as the thesis firmware's distance mode computes it (0 = none).
[[nodiscard]] std::vector<std::uint16_t> firmware_distances(const SensorSet& set,
                                                            const tiny_laser_driver::CalibrationModel& model);

/// A set as wire frames: one raw frame per read-out (charges x 10, rounded,
/// clamped to int16; index, last flag, temperature and pulses/10 packed).
[[nodiscard]] std::vector<tiny_laser_driver::RawFrame> raw_frames(const SensorSet& set);

/// The receiver lens as the driver's scan processing takes it.
[[nodiscard]] tiny_laser_driver::OpticsParams driver_optics(const SensorParams& params);

// ---------------------------------------------------------------------------- published

/// The pixels the published firmware overwrites with a neighbour's value
/// before sending: (destination, source).
inline constexpr std::array<std::pair<int, int>, 2> kPublishedPixelCopies{{{176, 175}, {16, 17}}};

/// One read-out as the published firmware's ADC gives it: the discharge of
/// each capacitor in ADC counts (ten times the charge unit).
struct ReadoutCounts {
  int pulses = 0;
  std::vector<double> a, b;
};

/// What one accumulation cycle of the published firmware computed.
struct PublishedCycle {
  std::vector<ReadoutCounts> readouts;    ///< in pulse order
  double ambient_counts_per_pulse = 0.0;  ///< the level subtracted from both capacitors, per pulse
  std::array<std::uint16_t, tiny_laser_driver::kPixels> distance{};  ///< the words sent [0.1 mm]
};

class PublishedFirmware {
 public:
  /// Fits the factory polynomial for this sensor (about a second).
  explicit PublishedFirmware(const SensorParams& params);

  /// The cycle's distances from its read-outs (`lit`) and a laser-off
  /// accumulation of the same schedule (`dark`), from which the ambient level
  /// is measured.
  [[nodiscard]] PublishedCycle compute(const SensorSet& lit, const SensorSet& dark) const;

  /// One read-out of one pixel: the distance the firmware writes [cm], 0 for none.
  [[nodiscard]] double distance_cm(double a_counts, double b_counts, int pulses, int pixel,
                                   double ambient_counts_per_pulse) const;
  /// The ambient level [counts per pulse] of a laser-off set: the mean
  /// discharge of both capacitors over the effective pixels at its last read-out.
  [[nodiscard]] static double ambient_counts_per_pulse(const SensorSet& dark, int dark_pixels);

  [[nodiscard]] const std::array<double, 7>& polynomial() const { return poly_; }
  [[nodiscard]] const FirmwareParams& params() const { return fw_; }
  /// The discharge [counts] from which a capacitor counts as saturated.
  [[nodiscard]] double saturation_counts() const { return 10.0 * fw_.saturation_charge; }

 private:
  FirmwareParams fw_;
  int dark_pixels_ = 8;
  std::array<double, 7> poly_{};
};

}  // namespace tinyline::sim

// What the simulated sensor's MCU computes itself.
//
// Distance-only mode (thesis 4.4.1, Algorithm 2): the firmware reads the
// capacitors at each count of its accumulation buffer (default
// the firmware's accumulation buffer: 10, 100, 200, 400, 550, 700),
// keeps per pixel the read-out with the most pulses that is valid under the
// public driver's rule, and maps it to a distance with its on-board
// calibration. The on-board calibration is the public driver's form: one
// 6th-degree polynomial in k = b / (a + b) for all pixels (no per-pixel
// sensitivity ratio) plus a linear temperature term, fitted at the "factory"
// on a noise-free white-paper sweep. Output: millimetres along the pixel's
// ray, rounded, as int16; 0 = no distance (dark pixel, too dark, saturated,
// outside the calibrated range or beyond 32.767 m).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/protocol.hpp>

#include <sim/tof_sensor.hpp>

namespace tinyline::sim {

/// The factory calibration of a sensor (see above). Deterministic for given
/// parameters; takes about a second.
[[nodiscard]] tiny_laser_driver::CalibrationModel factory_calibration(const SensorParams& params);

/// Distance per pixel [mm] as the firmware computes it (0 = none).
[[nodiscard]] std::vector<std::int16_t> firmware_distances_mm(const SensorSet& set,
                                                                const tiny_laser_driver::CalibrationModel& model);

/// A set as wire frames: one raw frame per read-out (charges x 10, rounded,
/// clamped to int16; index, last flag, temperature and pulses/10 packed).
[[nodiscard]] std::vector<tiny_laser_driver::RawFrame> raw_frames(const SensorSet& set);

}  // namespace tinyline::sim

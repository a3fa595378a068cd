// The evaluation's scanner: the project's simulated TOF line sensor
// (sim/tof_sensor.hpp) in raw mode, and the driver's processing of its
// read-outs: per pixel the valid read-out with the most pulses (the validity
// rule of calibration.hpp), distance from a CalibrationModel fitted by the
// calibration tool's fitter (tiny_laser_driver/calibration_fit.hpp) to a
// simulated white-paper rail, reflectance = distance_cm^2 (a + b) / (pulses / 10).
#pragma once

#include <memory>
#include <string>

#include "harness.hpp"

namespace tinyline::laser_clustering::eval {

struct SimScannerOptions {
  /// Sensor YAML (relative paths resolve against the source tree's sim/config/sensors).
  std::string sensor_config = "tiny_tof_8mm.yaml";
  /// Sensor time of the scans [s]: warm by default (the driver delay has settled).
  double t_start_s = 3600.0;
  /// The calibration rail: white paper from 5 cm to this far, this step, sets per distance.
  double calibration_max_m = 1.0;
  double calibration_step_m = 0.025;
  int calibration_sets = 2;
};

/// Builds the sensor and fits its calibration (a few seconds). Throws
/// std::runtime_error when the sensor config cannot be read or the fit fails.
[[nodiscard]] std::unique_ptr<Scanner> make_sim_scanner(const SimScannerOptions& options = {});

}  // namespace tinyline::laser_clustering::eval

// SPDX-License-Identifier: Apache-2.0
// The evaluation's scanner: the project's simulated TOF line sensor
// (sim/tof_sensor.hpp) in raw mode, its sets as wire frames
// (sim/firmware.hpp), processed by the driver's ScanProcessor
// (tiny_laser_driver/scan_processor.hpp: per pixel the read-out with the
// most pulses that is not saturated, the calibration, validity, reflectance
// = distance_cm^2 (a + b) / (pulses / 10)) with a calibration the calibration
// tool's fitter fits to a simulated white-paper rail over the working range;
// then pixels without a usable return dropped (see the options).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <laser_clustering/line_scan.hpp>
#include <sim/world.hpp>

namespace tinyline::laser_clustering::eval {

/// One calibrated scan with the ground truth of every pixel.
struct SimulatedScan {
  laser_clustering::LineScan scan;
  std::vector<sim::ObjectId> truth_object;  ///< per pixel: what its central ray hits (sim::kNoObject: nothing)
  std::vector<std::uint8_t> truth_mixed;    ///< per pixel: its footprint spans several surfaces
};

/// Produces scans of a world from a sensor pose. `index` seeds the scan's noise.
class Scanner {
 public:
  virtual ~Scanner() = default;
  virtual SimulatedScan scan(const sim::World& world, const Eigen::Isometry3d& T_world_sensor, std::uint64_t index) = 0;
  /// One line for reports (sensor model, lens, calibration).
  [[nodiscard]] virtual std::string describe() const = 0;
};

struct SimScannerOptions {
  /// Sensor YAML (relative paths resolve against the source tree's sim/config/sensors).
  std::string sensor_config = "tiny_tof_8mm.yaml";
  /// Raw-mode read-out schedule [pulses, ascending]; empty keeps the
  /// sensor's. The firmware's buffer P_n is configurable (thesis 5.3.1):
  /// close work needs fewer pulses than the default 20..700, which saturate
  /// every pixel nearer than about 20 cm. (The shipped calibrations of the
  /// simulated sensors cover 15-200 cm: the working range here is nearer.)
  std::vector<int> raw_pulses;
  /// Sensor time of the scans [s]: warm by default (the driver delay has settled).
  double t_start_s = 3600.0;
  /// The calibration rail: white paper from 5 cm to this far, this step, sets per distance.
  double calibration_max_m = 1.0;
  double calibration_step_m = 0.025;
  int calibration_sets = 2;
  /// A pixel whose reflectance figure is below this fraction of white
  /// paper's is no return (STATUS_TOO_DARK): the leakage of the longest
  /// read-out passes the wire protocol's validity rule in pixels that see
  /// nothing, and lens halo lights pixels beside a bright object; both would
  /// report ranges of nothing.
  double min_reflectance_of_white = 0.02;
  /// Ranges outside the sensor's span are no return (STATUS_OUT_OF_RANGE).
  double min_range_m = 0.05, max_range_m = 2.0;
};

/// The simulated sensor and the driver's processing, calibrated as above.
/// Builds the sensor and fits its calibration (a few seconds). Throws
/// std::runtime_error when the sensor config cannot be read or the fit fails.
[[nodiscard]] std::unique_ptr<Scanner> make_sim_scanner(const SimScannerOptions& options = {});

struct SimCalibrationSummary {
  double rmse_m = 0.0;             ///< in-sample RMSE of the fit on the rail [m]
  double white_reflectance = 0.0;  ///< white paper's reflectance figure through the driver's processing
};

/// Fits the calibration the scanner uses and writes it where the driver's
/// `calibration` parameter reads it (CalibrationModel::save), so that a
/// launch file on the simulator processes scans exactly as the evaluation
/// does. Throws std::runtime_error as make_sim_scanner.
SimCalibrationSummary write_sim_calibration(const SimScannerOptions& options, const std::string& path);

}  // namespace tinyline::laser_clustering::eval

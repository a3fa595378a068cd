// SPDX-License-Identifier: Apache-2.0
// A calibration session on the simulated rail, recorded as a bag the way a
// user records one: the simulator's virtual sensor node (raw scans + its
// ground-truth topic) and the bag recorder on one bus, stepped on sim time by
// the deterministic executor, while the test moves the scene's target from
// one rail position to the next between sets. Feeds `tinyline calib collect`
// in the tests and in docs/calibration.md (calibration_sim_rail_bag).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <sim/sensor_params.hpp>
#include <tiny_laser_calibration/data.hpp>

namespace tinyline::tiny_laser_calibration::testing {

struct SimRailSession {
  std::string scene;  ///< scene YAML with a plane named `target` facing the sensor
  std::string target = "target";
  std::vector<double> distances_m;  ///< rail positions, visited in this order
  int sets_per_distance = 3;
  double power_on_age_s = 3600.0;  ///< sensor time at the start (0: the warm-up is in the data)
  std::string ns = "/rail";        ///< the sensor node's namespace: topics ns/raw_scan, ns/scan_truth
  std::string bag_path;
};

struct SimRailSessionResult {
  std::size_t raw_scans = 0, truths = 0;  ///< messages the recorder wrote
  std::size_t dropped = 0;                ///< messages the recorder could not take
  std::string error;                      ///< empty on success
};

/// Records the session; never throws (error says what failed).
[[nodiscard]] SimRailSessionResult record_sim_rail_session(const SimRailSession& session);

/// What the thesis measured before fitting (3.3.3), as `sim_rail_csv --constants`
/// does on the simulated sensor: the leakage per pulse with the laser off in the
/// dark (b regressed on the pulses through 0), and the sensitivity ratio under
/// even ambient light with the laser off (sum b / sum a). Fitting both from rail
/// data instead leaves Vle and the per-pixel Rsen poorly separated, and the error
/// that leaves falls with the amplitude.
struct RailConstants {
  double leakage_per_pulse = 0.0;  ///< [charge_unit per pulse]
  double sensitivity_ratio = 1.0;
};
[[nodiscard]] RailConstants measure_rail_constants(const tinyline::sim::SensorParams& params);

/// A rail session on the simulator straight into the calibration data set
/// (no bus, no bag: the residual loop's tests and sweeps): the target visits
/// every position `visits` times in shuffled order, one raw set per
/// `sets_per_visit`, every `pixel_step`-th effective pixel.
struct RailPlan {
  double from_m = 0.15, to_m = 2.0, step_m = 0.05;
  int visits = 2;
  int sets_per_visit = 1;
  int pixel_step = 8;
  int pixel_from = -1, pixel_to = -1;                 ///< pixels used (default: every effective one)
  double set_period_s = 2.0;                          ///< sensor time between sets (the rail moves meanwhile)
  double power_on_s = 0.0;                            ///< sensor time of the first set: 0 = the warm-up is in the data
  std::vector<std::string> materials{"white_paper"};  ///< pass v visits every position with material v
  std::vector<std::string> extra_columns;             ///< covariate effects recorded as columns
  std::uint64_t seed = 7;                             ///< visit order and noise
  int session = -1;                                   ///< >= 0: a `session` column with this value (another warm-up)
};
[[nodiscard]] tinyline::tiny_laser_calibration::CalibrationDataset simulate_rail(
    const tinyline::sim::SensorParams& params, const RailPlan& plan);

}  // namespace tinyline::tiny_laser_calibration::testing

// SPDX-License-Identifier: Apache-2.0
// The Hydrus grasp in the physics simulator (sim/), end to end and
// deterministic: the robot of sim/config/scenes/hydrus4_grasp.yaml flies in
// and closes its links (ApproachParams); every set of every sensor is
// simulated with the crosstalk of the lasers that emit meanwhile, turned into
// wire frames, processed by the driver's ScanProcessor with its calibration,
// and fused and fitted by CircleEstimator, exactly as the nodes do, but on a
// stepped shared clock (no threads, no pty).
//
// Emission follows one of three schedules, in the same world:
//   all_on        no sequencing: every laser always on (crosstalk)
//   time_slicing  the thesis's sequence mode: one sensor per slot (rate / n)
//   colouring     Sequencer: the colour classes of the interference graph,
//                 recomputed as the joints move
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hydrus_fitting/trajectory.hpp"

namespace tinyline::hydrus_fitting::eval {

struct SimStudyParams {
  std::string scene_path;              ///< sim/config/scenes/hydrus4_grasp.yaml
  std::string robot_description;       ///< hydrus_fitting/config/hydrus4.yaml
  std::string calibration_path;        ///< tiny_laser_driver/config/calibration/sim_tiny_tof_3p6mm.yaml
  std::string schedule = "colouring";  ///< all_on | time_slicing | colouring
  ApproachParams approach;
  double start_s = 0.0;               ///< simulate [start_s, end_s) of the manoeuvre
  double end_s = -1.0;                ///< < 0: its whole duration
  double guard_s = 0.002;             ///< between slots (command latency)
  double corrupt_threshold_m = 0.05;  ///< a pixel whose range is off the truth by more is corrupted
  /// Give the estimator the base's pose (every 10 ms, like the joint
  /// states), so each scan is moved by the base's motion to the newest one's
  /// time, as circle_fitter does with hydrus_sim's base_pose.
  bool base_motion = true;
  std::uint64_t seed = 1;
};

/// One estimator update (after each slot, or each round of sets when all on).
struct SimUpdate {
  double t_s = 0.0;                                     ///< manoeuvre time of the newest set
  int status = 0;                                       ///< FitStatus
  double centre_error_m = -1.0;                         ///< |fitted - true centre| in the robot frame (-1: no fit)
  double radius_error_m = 0.0;                          ///< fitted - true radius
  double centre_x_m = 0, centre_y_m = 0, radius_m = 0;  ///< the fit (robot frame)
  double true_x_m = 0, true_y_m = 0;                    ///< the truth (robot frame)
  int points = 0, inliers = 0, self_filtered = 0;
  int sets = 0;                                ///< sets measured for this update
  int crosstalk_pulses = 0;                    ///< over those sets
  int valid_pixels = 0, corrupted_pixels = 0;  ///< over those sets: valid pixels on the cylinder (not mixed)
  int colours = 0;                             ///< slots in the schedule at this time
};

struct SimSensorRate {
  std::string sensor;
  int sets = 0;
  double rate_hz = 0.0;          ///< sets per second of simulated time
  double corrupted_share = 0.0;  ///< corrupted / valid pixels over its sets
};

struct SimStudyResult {
  std::string schedule;
  double simulated_s = 0.0;
  double set_period_s = 0.0;  ///< one raw set (last read-out / pulse rate)
  std::vector<SimUpdate> updates;
  std::vector<SimSensorRate> sensors;
};

/// Throws std::runtime_error / ConfigError / RobotModelError on bad files.
[[nodiscard]] SimStudyResult sim_study(const SimStudyParams& p);
[[nodiscard]] std::string sim_updates_csv(const std::vector<SimStudyResult>& runs);
[[nodiscard]] std::string sim_rates_csv(const std::vector<SimStudyResult>& runs);

}  // namespace tinyline::hydrus_fitting::eval

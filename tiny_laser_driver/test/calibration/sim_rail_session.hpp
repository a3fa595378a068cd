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

namespace tinyline::tiny_laser_driver::testing {

struct SimRailSession {
  std::string scene;                 ///< scene YAML with a plane named `target` facing the sensor
  std::string target = "target";
  std::vector<double> distances_m;   ///< rail positions, visited in this order
  int sets_per_distance = 3;
  double power_on_age_s = 3600.0;    ///< sensor time at the start (0: the warm-up is in the data)
  std::string ns = "/rail";          ///< the sensor node's namespace: topics ns/raw_scan, ns/scan_truth
  std::string bag_path;
};

struct SimRailSessionResult {
  std::size_t raw_scans = 0, truths = 0;  ///< messages the recorder wrote
  std::size_t dropped = 0;                ///< messages the recorder could not take
  std::string error;                      ///< empty on success
};

/// Records the session; never throws (error says what failed).
[[nodiscard]] SimRailSessionResult record_sim_rail_session(const SimRailSession& session);

}  // namespace tinyline::tiny_laser_driver::testing

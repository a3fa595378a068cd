// SPDX-License-Identifier: Apache-2.0
// `tinyline calib fit|diagnose|eval|collect`: the calibration command line as a
// library function, so tests drive it in-process and tools/commands/calib.cpp
// stays a thin wrapper. Not part of the driver's core: it writes files and
// runs the plot script.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace tinyline::tiny_laser_calibration {

struct CalibToolEnv {
  std::string python;         ///< interpreter that runs the plot script ("" = no plots)
  std::string plot_script;    ///< scripts/plots/calib_report.py
  std::string measured_data;  ///< the real sensor's measured figures (`calib measured`'s default --data)
};

/// Runs `tinyline calib ARGS...` (ARGS after "calib"). Returns the exit code:
/// 0 success, 1 failure (a message on `err` naming what and where), 2 bad usage.
int run_calib_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
                      const CalibToolEnv& env);

}  // namespace tinyline::tiny_laser_calibration

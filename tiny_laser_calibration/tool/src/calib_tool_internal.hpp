// SPDX-License-Identifier: Apache-2.0
// Pieces shared by the `tinyline calib` sub-commands.
#pragma once

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

#include <json/json.h>
#include <tinyline/common/cli.hpp>

#include <tiny_laser_calibration/tool.hpp>

namespace tinyline::tiny_laser_calibration::tool {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A number as JSON: null for NaN and infinities.
Json::Value json_number(double v);
/// `v` as JSON text with a final newline: indented, or on one line (indentation "").
std::string json_text(const Json::Value& v, const char* indentation = "  ");

/// `tinyline calib measured`'s options, as given (measured_report.cpp).
struct MeasuredOptions {
  std::string data;  ///< the measured figures (default: the package's measured.yaml)
  std::string report, apply, output;
  bool json = false;
};
void add_measured_options(cli::App& c, MeasuredOptions& o);
int cmd_measured(const MeasuredOptions& o, std::ostream& out, std::ostream& err, const CalibToolEnv& env);

/// Runs env.python env.plot_script DIR; 0 on success, else -1 with `message`.
int run_plot_script(const CalibToolEnv& env, const std::string& dir, std::string& message);

}  // namespace tinyline::tiny_laser_calibration::tool

// SPDX-License-Identifier: Apache-2.0
// Pieces shared by the `tinyline calib` sub-commands.
#pragma once

#include <iosfwd>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <tiny_laser_calibration/tool.hpp>

namespace tinyline::tiny_laser_calibration::tool {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Positionals, `--name value` options (`valued`) and flags; anything else
/// starting with '-' is a UsageError (negative numbers are positionals).
class Options {
 public:
  Options(const std::vector<std::string>& argv, const std::vector<std::string>& valued,
          const std::vector<std::string>& flags);
  [[nodiscard]] const std::vector<std::string>& positional() const { return positional_; }
  [[nodiscard]] bool flag(const std::string& f) const;
  [[nodiscard]] std::optional<std::string> value(const std::string& name) const;
  [[nodiscard]] double number(const std::string& name, double fallback) const;
  [[nodiscard]] int integer(const std::string& name, int fallback, int lo, int hi) const;

 private:
  std::vector<std::string> positional_;
  std::map<std::string, std::string> values_;
  std::vector<std::string> flags_;
};

std::string json_string(const std::string& s);
std::string json_number(double v);  ///< null for NaN/inf

/// `tinyline calib measured` (measured_report.cpp).
int cmd_measured(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err, const CalibToolEnv& env);

/// Runs env.python env.plot_script DIR; 0 on success, else -1 with `message`.
int run_plot_script(const CalibToolEnv& env, const std::string& dir, std::string& message);

}  // namespace tinyline::tiny_laser_calibration::tool

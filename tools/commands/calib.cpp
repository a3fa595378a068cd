// SPDX-License-Identifier: Apache-2.0
// tinyline calib fit|diagnose|eval|collect: the calibration tool. The logic
// lives in tiny_laser_calibration's tool library; this file finds the plot
// script and its Python and hands over.
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include <tiny_laser_calibration/tool.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"

namespace tinyline::tools {
namespace {

int calib(const std::vector<std::string>& args) {
  namespace fs = std::filesystem;
  tiny_laser_calibration::CalibToolEnv env;
  const fs::path share = share_dir();
  env.plot_script = (share / "scripts" / "plots" / "calib_report.py").string();
  env.measured_data = (share / "tiny_laser_calibration" / "data" / "measured.yaml").string();
  // The test virtual env has matplotlib; TINYLINE_PYTHON overrides, python3 is the last resort.
  if (const char* py = std::getenv("TINYLINE_PYTHON"); py && *py) {
    env.python = py;
  } else if (std::error_code ec; fs::exists(share / ".venv" / "bin" / "python", ec)) {
    env.python = (share / ".venv" / "bin" / "python").string();
  } else {
    env.python = "python3";
  }
  return tiny_laser_calibration::run_calib_command(args, std::cout, std::cerr, env);
}

// The calibration tool parses its own arguments (tiny_laser_calibration's
// tool library): everything after `calib`, --help included, goes to it.
CommandRun setup_calib(cli::App& cmd) {
  cmd.pass_through();
  return [&cmd] { return calib(cmd.remaining()); };
}

const CommandRegistration kCalib{"calib", "calibration: fit, discover effects, diagnose, eval, collect from bags",
                                 &setup_calib};

}  // namespace
}  // namespace tinyline::tools

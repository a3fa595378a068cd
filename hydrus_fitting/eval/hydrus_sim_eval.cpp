// SPDX-License-Identifier: Apache-2.0
// The Hydrus grasp in the physics simulator under the three emission
// schedules, written as CSV for docs/hydrus_fitting.md:
//
//   hydrus_sim_eval [--schedules all_on,time_slicing,colouring] [--start S] [--end S]
//                   [--scene YAML] [--robot YAML] [--calibration YAML]
//                   [--updates FILE] [--rates FILE] [--no-base-motion]
//
// The estimator gets the base's pose, as circle_fitter does in the launch
// file, so that each scan is moved by the base's own motion to the update's
// newest scan; --no-base-motion leaves the scans where the joints put them.
//
// Paths default to the source tree's hydrus4_grasp scene, hydrus4 robot and
// the simulated 3.6 mm sensor's calibration.
//
// scripts/plots/hydrus_grasp.py plots the centre error over time.
#include <chrono>
#include <iostream>
#include <string>
#include <vector>

#include <tinyline/common/cli.hpp>

#include "sim_study.hpp"
#include "write_output.hpp"

namespace cli = tinyline::cli;

namespace ev = tinyline::hydrus_fitting::eval;

namespace {}  // namespace

int main(int argc, char** argv) {
  const std::string src = TINYLINE_SOURCE_DIR;
  std::vector<std::string> schedules{"all_on", "time_slicing", "colouring"};
  std::string updates_path, rates_path;
  std::string scene = src + "/sim/config/scenes/hydrus4_grasp.yaml";
  std::string robot = src + "/hydrus_fitting/config/hydrus4.yaml";
  std::string calibration = src + "/tiny_laser_driver/config/calibration/sim_tiny_tof_3p6mm.yaml";
  double start_s = 0.0, end_s = -1.0;
  bool no_base_motion = false;
  cli::App app{
      "The Hydrus grasp in the physics simulator under the emission schedules, written as CSV for "
      "docs/hydrus_fitting.md.",
      "hydrus_sim_eval"};
  app.add_option("--schedules", schedules, "emission schedules, comma-separated")
      ->delimiter(',')
      ->check(cli::one_of({"all_on", "time_slicing", "colouring"}))
      ->capture_default_str();
  app.add_option("--start", start_s, "simulate the manoeuvre from this time [s]")
      ->check(cli::non_negative())
      ->capture_default_str();
  app.add_option("--end", end_s, "... to this time [s]; < 0: its whole duration")
      ->check(cli::finite())
      ->capture_default_str();
  app.add_option("--scene", scene, "scene YAML")->capture_default_str();
  app.add_option("--robot", robot, "robot description YAML")->capture_default_str();
  app.add_option("--calibration", calibration, "the drivers' calibration YAML")->capture_default_str();
  app.add_option("--updates", updates_path, "CSV of every circle update (default: stdout)");
  app.add_option("--rates", rates_path, "CSV of the update rates (default: stdout)");
  app.add_flag("--no-base-motion", no_base_motion, "leave the scans where the joints put them");
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  const bool base_motion = !no_base_motion;
  auto updates = ev::Output::open("hydrus_sim_eval", updates_path, {scene, robot, calibration});
  auto rates = ev::Output::open("hydrus_sim_eval", rates_path, {scene, robot, calibration});
  if (!updates || !rates) return 1;

  std::vector<ev::SimStudyResult> runs;
  try {
    for (const std::string& name : schedules) {
      ev::SimStudyParams p;
      p.scene_path = scene;
      p.robot_description = robot;
      p.calibration_path = calibration;
      p.schedule = name;
      p.start_s = start_s;
      p.end_s = end_s;
      p.base_motion = base_motion;
      const auto t0 = std::chrono::steady_clock::now();
      runs.push_back(ev::sim_study(p));
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::cerr << name << ": " << runs.back().updates.size() << " updates, " << runs.back().simulated_s
                << " s simulated in " << wall << " s\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "hydrus_sim_eval: " << e.what() << "\n";
    return 1;
  }
  bool ok = updates->write(ev::sim_updates_csv(runs));
  ok = rates->write(ev::sim_rates_csv(runs)) && ok;
  return ok ? 0 : 1;
}
